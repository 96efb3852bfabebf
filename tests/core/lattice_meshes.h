// Test meshes and bodies built from the box lattice (shared by the core tests).
#pragma once

#include <gtest/gtest.h>

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

// A 20 x 20 x 15 mm block (4 x 4 x 3 cells) of the EF30 card (the conical card fitted to Ecoflex
// 00-30) with its volume, spread (hexahedra only) and shear terms, density 1070 kg/m^3; hexahedra
// or tetrahedra; the card's damper `card_damping` (card units). No supports, probes or options.
inline BodySpec Ef30Block(bool tets, double card_damping = 0) {
  BodySpec b;
  b.mesh = make_box_lattice(Vec3(0.02, 0.02, 0.015), {4, 4, 3});
  if (tets) b.mesh = Tetrahedralised(b.mesh);
  b.density = 1070;
  SpringCard c;
  c.conical = ConicalCard{
      2.0638952894602549e9, 1.6662609498394193e-3, 4.8853058085019819e-3, 8e-3, 10e-3, 3};
  c.stiffness_cap = 1000;
  c.damping = card_damping;
  b.groups.push_back({"silicone", c, kAllFamilies, {}, Vec3::Zero(), 10});
  b.bulk_modulus = 137052.6;
  b.spread_modulus = tets ? 0 : 137052.6;
  b.shear_modulus = 15613.6;
  return b;
}

// A box lattice of cells^3 cubes of side `cell` (m), one spring group of `card`, density
// 1000 kg/m^3, mass damping 3 /s, gravity along -z.
inline Model Lattice(const SpringCard& card, std::array<int, 3> cells, double cell) {
  BodySpec b;
  b.mesh = make_box_lattice(Vec3(cell * cells[0], cell * cells[1], cell * cells[2]), cells);
  b.density = 1000;
  b.groups.push_back({"tissue", card, kAllFamilies, {}, Vec3::Zero(), 10});
  b.options.mass_damping = 3;
  b.options.gravity = Vec3(0, 0, -9.81);
  Model m;
  EXPECT_EQ(build_model(b, &m), "");
  return m;
}

}  // namespace conica::testing_meshes
