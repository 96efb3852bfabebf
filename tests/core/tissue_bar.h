// A lattice body the core tests share: a box of 1 cm cells of conical tissue springs (the
// paper's card, stiffness cap 20 K0, damper 0.01 N s/m per card) on a clamped base z = 0, mass
// damping 5 1/s and one 6 mm probe, with the active-region options given (far_every: the far
// field's interval, -1 frozen, 0 automatic).
#pragma once

#include <array>

#include "core/body.h"

namespace conica {

inline BodySpec TissueBar(std::array<int, 3> cells, bool active, double tolerance, int far_every) {
  BodySpec b;
  const double cell = 0.01;  // m
  b.mesh = make_box_lattice(Vec3(cell * cells[0], cell * cells[1], cell * cells[2]), cells);
  b.density = 1000;
  SpringCard c;
  c.conical = ConicalCard{2e8, 1e-3, 2e-3, 8e-3, 10e-3, 3};
  c.stiffness_cap = 20;
  c.damping = 0.01;
  b.groups.push_back({"tissue", c, kAllFamilies, {}, Vec3::Zero(), 10});
  FixedSelector base;
  base.kind = FixedSelector::Kind::kPlane;
  b.fixed.push_back(base);
  b.options.mass_damping = 5;
  b.options.active_region = active;
  b.options.active_tolerance = tolerance;
  b.options.active_far_every = far_every;
  b.probes.push_back(ProbeSpec{0.006, 0, ContactModel::kNodes});
  return b;
}

}  // namespace conica
