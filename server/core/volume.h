// Volume stiffness: what pair springs cannot give a body.
//
// A lattice of pair springs obeys the Cauchy relations (C12 = C44): its Poisson ratio is at most
// 1/4 and its bulk and shear moduli are tied to each other, while soft tissue and silicone are
// nearly incompressible (nu about 0.49). With a bulk modulus kappa (Pa) every element e of rest
// volume V0 stores
//   W_e = (kappa V0 / 2) (J - 1)^2,   J = V / V0,
// so it pushes its nodes with f_a = -kappa (J - 1) dV/dx_a: a pressure p = -kappa (J - 1) on its
// faces. At small strain the body's bulk modulus grows by kappa and its shear modulus is
// unchanged, so nu = (3 K - 2 G) / (2 (3 K + G)) with K = K_springs + kappa.
//
// Volumes: a tetrahedron's is exact; a hexahedron's is the volume of its trilinear map, exact by
// 2 x 2 x 2 Gauss points (det of the map's Jacobian is at most quadratic per coordinate), with
// the VTK node order (bottom 0-3, top 4-7, counter-clockwise seen from the top). Volumes are
// signed; J uses the signed rest volume, so either orientation works.
//
// The implicit solver takes the Gauss-Newton part of the element Hessian, (kappa / V0) g g^T with
// g = dV/dx: positive semi-definite (the dropped kappa (J - 1) d2V/dx2 is indefinite).
#pragma once

#include <Eigen/Geometry>

#include "core/mesh.h"

namespace conica {

// Signed volume (m^3) of tetrahedron x[0..3] and dV/dx_a into g[0..3].
double tet_volume_gradient(const Vec3* x, Vec3* g);

// Signed trilinear volume (m^3) of hexahedron x[0..7] (VTK order) and dV/dx_a into g[0..7].
// With vq and gq: also the share of each Gauss point q (det of the map's Jacobian there, weight
// 1) in vq[q] and its gradient in gq[8 q + a]; the shares sum to the volume.
double hex_volume_gradient(const Vec3* x, Vec3* g, double* vq = nullptr, Vec3* gq = nullptr);

}  // namespace conica
