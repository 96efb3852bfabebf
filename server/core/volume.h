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
//
// Shear stiffness (shear_modulus mu > 0): each element (a tetrahedron, or each Gauss point of a
// hexahedron with its share v0 of the rest volume) stores the isochoric neo-Hookean energy
//   W = v0 (mu / 2) (J^(-2/3) tr(F^T F) - 3),   F = sum_a x_a b_a^T,
// b_a the gradient of node a's shape function at rest (rest coordinates), J = det F. It adds mu
// to the body's shear modulus and nothing to its bulk modulus, and unlike pair springs it keeps
// its shear stiffness under compression (d2W / dF13^2 = mu J^(-2/3) at a uniaxial state). The
// implicit system takes its Laplacian part, h^2 v0 mu J^(-2/3) (b_a . b_b) I.
//
// Shear stiffening (shear_stiffening beta >= 0, dimensionless): the shear term becomes Yeoh's
// second-order isochoric energy
//   W = v0 (mu / 2) ((I1b - 3) + beta (I1b - 3)^2),   I1b = J^(-2/3) tr(F^T F) >= 3,
// an isotropic stiffening that needs no pair spring's compression: its tangent shear modulus
// grows with the distortion, mu (1 + 2 beta (I1b - 3)), in every direction at once (pair springs
// stiffen only along themselves, and a compressed one pushes sideways: -f / l). beta = 0 is the
// neo-Hookean term. Yeoh's energy with mu, beta >= 0 is polyconvex, so it keeps the material
// strongly elliptic. The implicit system's Laplacian takes mu (1 + 2 beta (I1b - 3)) for mu.
#pragma once

#include <Eigen/Geometry>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <vector>

#include "core/mesh.h"

namespace conica {

// Signed volume (m^3) of tetrahedron x[0..3] and dV/dx_a into g[0..3].
double tet_volume_gradient(const Vec3* x, Vec3* g);

// Signed trilinear volume (m^3) of hexahedron x[0..7] (VTK order) and dV/dx_a into g[0..7].
// With vq and gq: also the share of each Gauss point q (det of the map's Jacobian there, weight
// 1) in vq[q] and its gradient in gq[8 q + a]; the shares sum to the volume.
double hex_volume_gradient(const Vec3* x, Vec3* g, double* vq = nullptr, Vec3* gq = nullptr);

// Volume of the element on nodes[0..n) of x (n = 4: tetrahedron, 8: hexahedron) and dV/dx_a into
// g[0..n); for a hexahedron also its Gauss-point shares and their gradients (see above).
double element_volume(const std::vector<Vec3>& x, const int* nodes, int n, Vec3* g,
                      double* vq = nullptr, Vec3* gq = nullptr);

// Deformation gradient sum_a x_a b_a^T of the element (or Gauss point) on nodes[0..n) of x.
Eigen::Matrix3d deformation_gradient(const std::vector<Vec3>& x, const int* nodes, int n,
                                     const Vec3* b);

// Rest shape-function gradients of a tetrahedron x[0..3]: b[a] with sum_a x_a b_a^T = I; returns
// the signed rest volume.
double tet_shape_gradients(const Vec3* x, Vec3* b);

// Rest shape-function gradients at the 8 Gauss points of hexahedron x[0..7]: b[8 q + a], and
// v0[q] the point's share of the rest volume (signed). Returns false for a degenerate point.
bool hex_shape_gradients(const Vec3* x, Vec3* b, double* v0);

namespace detail {
// inverse_cube_root's guess, within 3 % of x^(-1/3) for positive normal x.
inline double inverse_cube_root_guess(double x) {
  std::uint64_t i;
  std::memcpy(&i, &x, sizeof i);
  i = 0x553ef0ff289dd796ULL - i / 3;
  double y;
  std::memcpy(&y, &i, sizeof y);
  return y;
}
inline bool inverse_cube_root_in_range(double x) { return x > 1e-300 && x < 1e300; }
}  // namespace detail

// x^(-1/3) for x > 0, within a few units in the last place of 1 / std::cbrt(x) (four Newton
// steps on y^-3 = x from a guess made on the bits of x; std::cbrt itself outside 1e-300..1e300):
// no library call and no division, for the shear term's J^(-2/3) at every Gauss point.
inline double inverse_cube_root(double x) {
  if (!detail::inverse_cube_root_in_range(x)) return 1 / std::cbrt(x);
  double y = detail::inverse_cube_root_guess(x);
  const double t = x / 3;
  for (int k = 0; k < 4; ++k) y *= 4.0 / 3 - t * (y * y * y);  // 3e-2 -> 2e-3 -> 1e-5 -> 3e-10
  return y;
}

// Eight doubles side by side (GCC's and Clang's vector extension: the target's widest vectors,
// or pairs of them); a hexahedron's Gauss points take one lane each.
typedef double Lanes8 __attribute__((vector_size(64)));

// Eight doubles from p (no alignment asked), and the sum of the lanes.
inline Lanes8 load_lanes(const double* p) {
  Lanes8 v;
  std::memcpy(&v, p, sizeof v);
  return v;
}
inline double lane_sum(Lanes8 v) {
  return ((v[0] + v[1]) + (v[2] + v[3])) + ((v[4] + v[5]) + (v[6] + v[7]));
}

// inverse_cube_root of each lane: the Newton steps in the lanes, the guess and the range check
// one by one.
inline Lanes8 inverse_cube_roots(Lanes8 x) {
  Lanes8 y, t;
  bool in_range = true;
  for (int i = 0; i < 8; ++i) {
    const bool in = detail::inverse_cube_root_in_range(x[i]);
    in_range &= in;
    const double xi = in ? x[i] : 1.0;
    y[i] = detail::inverse_cube_root_guess(xi);
    t[i] = xi / 3;
  }
  for (int k = 0; k < 4; ++k) y *= 4.0 / 3 - t * (y * y * y);
  if (!in_range)
    for (int i = 0; i < 8; ++i)
      if (!detail::inverse_cube_root_in_range(x[i])) y[i] = 1 / std::cbrt(x[i]);
  return y;
}

// The shear term's energy density W / v0 (above) at deformation gradient F (3 x 3, column-major
// in f[9]) returned, its first Piola stress into p[9] and the Laplacian's coefficient per rest
// volume over mu, (1 + 2 beta (I1b - 3)) J^(-2/3) (dimensionless), into *coef. F with det <= 0:
// energy 0, stress 0, *coef 1 (the hard stop keeps springs from inverting). With beta = 0 every
// output is the neo-Hookean term's, bit for bit.
double isochoric_yeoh(const double* f, double mu, double beta, double* p, double* coef);

}  // namespace conica
