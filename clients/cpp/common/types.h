// Small shared vocabulary of the clients: SI vectors and "x,y,z" / "-z" parsing for command lines.
#pragma once

#include <Eigen/Core>
#include <optional>
#include <string>

namespace conica::client {

using Vec3 = Eigen::Vector3d;  // m, N or m/s, per the name that holds it
using Mat3 = Eigen::Matrix3d;  // row-major on the wire, Eigen column-major here

// "x,y,z" -> vector (all three finite). Empty optional on anything else.
std::optional<Vec3> parse_vec3(const std::string& text);

// An axis: "x", "+y", "-z" or "x,y,z" (normalised; must be non-zero). Empty optional otherwise.
std::optional<Vec3> parse_axis(const std::string& text);

// Strict number parsing: the whole string must be one finite number.
std::optional<double> parse_double(const std::string& text);

}  // namespace conica::client
