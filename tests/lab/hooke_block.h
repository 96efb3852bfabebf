// A soft block for the quasi-static and plate tests: a box lattice of nx x nx x nz cells
// (side x side x height, m) of one Hooke spring card (50 N/m, 10 mm) with shear (2 kPa) and bulk
// (20 kPa) terms, density 1000 kg/m^3. No supports, plates or options.
#pragma once

#include "core/body.h"

namespace conica::lab {

inline BodySpec HookeBlock(int nx, int nz, double side, double height) {
  BodySpec s;
  s.mesh = make_box_lattice(Vec3(side, side, height), {nx, nx, nz});
  s.density = 1000;
  SpringCard c;
  c.law = LawKind::kHooke;
  c.hooke_k = 50;  // N/m
  c.hooke_length = 0.01;
  s.groups.push_back({"all", c, kAllFamilies, {}, Vec3::Zero(), 10});
  s.shear_modulus = 2000;  // Pa
  s.bulk_modulus = 20000;  // Pa
  return s;
}

}  // namespace conica::lab
