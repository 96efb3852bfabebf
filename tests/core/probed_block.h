// A probed block shared by the stage tests: an 8 x 8 x 4 lattice of 40 x 40 x 20 mm, clamped at its
// base, conical springs of a soft tissue (E ~ 1.2 kPa), one 5 mm probe.
#pragma once

#include "core/body.h"

namespace conica::testing_meshes {

inline BodySpec ProbedBlock(Integrator integ) {
  BodySpec b;
  b.mesh = make_box_lattice(Vec3(0.04, 0.04, 0.02), {8, 8, 4});
  b.density = 1000;
  SpringCard c;
  c.stiffness_cap = 1e3;
  // Strain mapping: a column of side L0 = 10 mm, so E ~ K0 / L0 ~ 1.2 kPa: soft tissue.
  c.conical = ConicalCard{5e7, 1e-3, 2e-3, 8e-3, 10e-3, 3};
  c.damping = 0;
  b.groups.push_back({"tissue", c, kAllFamilies, {}, Vec3::Zero(), 10});
  FixedSelector base;
  base.kind = FixedSelector::Kind::kPlane;
  b.fixed.push_back(base);
  b.options.integrator = integ;
  b.options.mass_damping = 30;
  b.probes.push_back(ProbeSpec{5e-3, 0, ContactModel::kNodes});
  return b;
}

}  // namespace conica::testing_meshes
