// Test meshes built from the box lattice (shared by the core tests).
#pragma once

#include <array>
#include <utility>

#include "core/body.h"

namespace conica::testing_meshes {

// Six tetrahedra per hexahedron around its 0-6 diagonal (conforming on a lattice), each
// positively oriented.
inline Mesh Tetrahedralised(const Mesh& hexes) {
  Mesh t;
  t.nodes = hexes.nodes;
  static constexpr int kTets[6][4] = {{0, 1, 2, 6}, {0, 2, 3, 6}, {0, 3, 7, 6},
                                      {0, 7, 4, 6}, {0, 4, 5, 6}, {0, 5, 1, 6}};
  for (const auto& h : hexes.hexahedra)
    for (const auto& q : kTets) {
      std::array<int, 4> e{h[q[0]], h[q[1]], h[q[2]], h[q[3]]};
      if (tet_volume(t.nodes[e[0]], t.nodes[e[1]], t.nodes[e[2]], t.nodes[e[3]]) < 0)
        std::swap(e[2], e[3]);
      t.tetrahedra.push_back(e);
    }
  return t;
}

}  // namespace conica::testing_meshes
