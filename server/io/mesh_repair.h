// Checks and safe repairs of a volume mesh, and the topology the body builder and contact use.
#pragma once

#include <array>
#include <string>
#include <vector>

#include "core/body.h"
#include "core/mesh.h"

namespace conica::io {

struct RepairOptions {
  // Nodes closer than merge_tolerance * (bounding-box diagonal) are one node.
  double merge_tolerance = 1e-9;
  // An element is flat when |volume| <= volume_tolerance * (longest edge)^3.
  double volume_tolerance = 1e-9;
};

// What repair() found, by kind; each count is also what it fixed (or dropped).
struct MeshReport {
  int duplicate_nodes = 0;         // merged into an earlier node at the same position
  int bad_index_elements = 0;      // referencing a node index out of range: dropped
  int repeated_node_elements = 0;  // naming one node twice (after merging): dropped
  int zero_volume_tetrahedra = 0;  // flat: dropped
  int zero_volume_hexahedra = 0;   // flat: dropped
  int inverted_tetrahedra = 0;     // negative volume: flipped to positive orientation
  int inverted_hexahedra = 0;      // negative volume: top and bottom faces swapped
  int distorted_hexahedra = 0;     // corner Jacobians of mixed sign: kept, reported only
  int degenerate_triangles = 0;    // repeating a node or out of range: dropped
  int unreferenced_nodes = 0;      // used by no element: dropped, indices remapped
  bool clean() const;
};

// Human-readable lines "duplicate nodes: 2 (merged)", one per kind; "clean" if none.
std::string to_string(const MeshReport& report);

// Repairs what is safe, in this order: merge duplicate nodes, drop elements with bad or
// repeated nodes, drop flat elements, flip inverted ones, drop unreferenced nodes. Regions
// follow their elements. Never fails; non-finite coordinates make their elements flat.
MeshReport repair(Mesh& mesh, const RepairOptions& options = {});

// The same report without changing the mesh.
MeshReport inspect(const Mesh& mesh, const RepairOptions& options = {});

// Signed tetrahedron volume: the core's (core/body.h).
using conica::tet_volume;

// Volume of a trilinear hexahedron (VTK order: bottom 0-3 counter-clockwise seen from the top
// 4-7), V = integral of det J over the unit cube; 2x2x2 Gauss points make it exact.
double hex_volume(const std::array<Vec3, 8>& x);

// Sum of element volumes (file units^3).
double total_volume(const Mesh& mesh);

struct BoundingBox {
  Vec3 min = Vec3::Zero();
  Vec3 max = Vec3::Zero();
};
// Of the finite nodes; zero box for a mesh without any.
BoundingBox bounding_box(const Mesh& mesh);

// Unique edges (i < j, sorted) of the tetrahedra: one spring each. (num_edges)
std::vector<std::array<int, 2>> unique_edges(const Mesh& mesh);

// Unique springs of the whole mesh: the 6 edges of each tetrahedron and the 28 node pairs of
// each hexahedron (12 edges, 12 face diagonals, 4 body diagonals), sorted, i < j.
std::vector<std::array<int, 2>> spring_pairs(const Mesh& mesh);

// Faces used by exactly one tetrahedron, oriented outward (right-hand normal pointing away
// from their tet) for positively oriented tets, in tet order.
std::vector<std::array<int, 3>> surface_triangles(const Mesh& mesh);

}  // namespace conica::io
