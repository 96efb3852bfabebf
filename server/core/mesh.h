// Volume meshes as plain data: what the readers produce and the body builder consumes.
#pragma once

#include <Eigen/Core>
#include <array>
#include <string>
#include <vector>

namespace conica {

using Vec3 = Eigen::Vector3d;

// A named set of elements (a Gmsh physical group, a VTK cell-data value).
struct Region {
  std::string name;
  int id = 0;                   // physical tag / cell-data value
  std::vector<int> tetrahedra;  // indices into Mesh::tetrahedra
  std::vector<int> hexahedra;   // indices into Mesh::hexahedra
};

// The faces of an element by its local node numbers, oriented outward for a positively
// oriented element (hexahedra in VTK/Gmsh order: bottom 0-3, top 4-7).
inline constexpr int kTetFaces[4][3] = {{0, 2, 1}, {0, 1, 3}, {1, 2, 3}, {0, 3, 2}};
inline constexpr int kHexFaces[6][4] = {{0, 3, 2, 1}, {4, 5, 6, 7}, {0, 1, 5, 4},
                                        {1, 2, 6, 5}, {2, 3, 7, 6}, {3, 0, 4, 7}};

// Coordinates in metres once a scene has applied its unit scale; readers return file units.
struct Mesh {
  std::vector<Vec3> nodes;                     // (num_nodes)
  std::vector<std::array<int, 4>> tetrahedra;  // node indices, positive orientation
  std::vector<std::array<int, 8>> hexahedra;   // VTK/Gmsh order: bottom 0-3, top 4-7
  std::vector<std::array<int, 3>> triangles;   // surface triangles given by the file, if any
  std::vector<Region> regions;
};

}  // namespace conica
