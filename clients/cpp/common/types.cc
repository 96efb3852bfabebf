#include "common/types.h"

#include <cerrno>
#include <cmath>
#include <cstdlib>
#include <sstream>

namespace conica::client {

std::optional<double> parse_double(const std::string& text) {
  const auto b = text.find_first_not_of(" \t\r");
  if (b == std::string::npos) return std::nullopt;
  const auto e = text.find_last_not_of(" \t\r");
  const std::string s = text.substr(b, e - b + 1);
  char* end = nullptr;
  errno = 0;
  const double v = std::strtod(s.c_str(), &end);
  if (end != s.c_str() + s.size() || errno == ERANGE || !std::isfinite(v)) return std::nullopt;
  return v;
}

std::optional<Vec3> parse_vec3(const std::string& text) {
  std::stringstream ss(text);
  std::string part;
  Vec3 v;
  int n = 0;
  while (std::getline(ss, part, ',')) {
    if (n == 3) return std::nullopt;
    const auto d = parse_double(part);
    if (!d) return std::nullopt;
    v[n++] = *d;
  }
  if (n != 3) return std::nullopt;
  return v;
}

std::optional<Vec3> parse_axis(const std::string& text) {
  std::string s = text;
  double sign = 1;
  if (!s.empty() && (s[0] == '-' || s[0] == '+') && s.size() == 2) {
    sign = s[0] == '-' ? -1 : 1;
    s = s.substr(1);
  }
  if (s == "x") return Vec3(sign, 0, 0);
  if (s == "y") return Vec3(0, sign, 0);
  if (s == "z") return Vec3(0, 0, sign);
  const auto v = parse_vec3(text);
  if (!v || !(v->norm() > 0)) return std::nullopt;
  return v->normalized();
}

}  // namespace conica::client
