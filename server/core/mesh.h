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

// Coordinates in metres once a scene has applied its unit scale; readers return file units.
struct Mesh {
  std::vector<Vec3> nodes;                     // (num_nodes)
  std::vector<std::array<int, 4>> tetrahedra;  // node indices, positive orientation
  std::vector<std::array<int, 8>> hexahedra;   // VTK/Gmsh order: bottom 0-3, top 4-7
  std::vector<std::array<int, 3>> triangles;   // surface triangles given by the file, if any
  std::vector<Region> regions;
};

}  // namespace conica
