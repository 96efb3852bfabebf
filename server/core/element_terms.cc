// The element terms (core/element_terms.h): energies, forces and what the implicit system keeps.
#include "core/element_terms.h"

#include <Eigen/Cholesky>
#include <Eigen/Eigenvalues>
#include <algorithm>
#include <cmath>
#include <cstring>
#include <vector>

#include "core/volume.h"

namespace conica {
namespace {

// Shear stiffness forces of one element on N nodes with `points` tetrahedra / Gauss points
// (core/volume.h), added to force; advances b, v0 and coef past the element.
// The shear forces of one tetrahedron or Gauss point (shape gradients b[0..N), rest share v0)
// with its element's nodes at x[0..N), subtracted into f[0..N); returns isochoric_yeoh's
// Laplacian coefficient there.
template <int N>
double shear_point(const Model& m, const Vec3* x, const Vec3* b, double v0, Vec3* f) {
  Mat3 F = Mat3::Zero();
  for (int a = 0; a < N; ++a) F.noalias() += x[a] * b[a].transpose();
  Mat3 P;
  double c;
  isochoric_yeoh(F.data(), m.shear_modulus, m.shear_stiffening, P.data(), &c);
  P *= v0;
  for (int a = 0; a < N; ++a) f[a].noalias() -= P * b[a];
  return c;
}

template <int N>
void shear_element(const Model& m, const std::vector<Vec3>& xs, const std::array<int, N>& nodes,
                   int points, const Vec3*& b, const double*& v0, double*& coef,
                   std::vector<Vec3>& force) {
  Vec3 x[N], f[N];
  for (int a = 0; a < N; ++a) {
    x[a] = xs[nodes[a]];
    f[a].setZero();
  }
  for (int q = 0; q < points; ++q, b += N) {
    const double c = shear_point<N>(m, x, b, *v0, f);
    *coef++ = *v0++ * m.shear_modulus * c;
  }
  for (int a = 0; a < N; ++a) force[nodes[a]] += f[a];
}

// The volume term's forces on one element of rest volume v0 whose volume is v, dV/dx_a = g[a]
// (and, hexahedra with the spread, its Gauss-point shares vq[q] of rest share v0q[q] and their
// gradients gq[8 q + a], replaced by G_q = g_q - g / 8), each node's share passed to add(a, f_a)
// in the order the forces have always been summed (pressure first, then each Gauss point's
// spread). Returns kappa / |V0|.
template <int N, typename Add>
double volume_forces(const Model& m, double v, double v0, const Vec3* g, const double* vq,
                     const double* v0q, Vec3* gq, Add&& add) {
  const double coef = m.bulk_modulus / std::abs(v0);
  const double p = -coef * (v - v0);
  for (int a = 0; a < N; ++a) add(a, Vec3(p * g[a]));
  if (!gq) return coef;
  // Spread: force -(8 kappa_s / |V0|) sum_q d_q G_q with G_q = g_q - g / 8.
  const double cs = 8 * m.spread_modulus / std::abs(v0);
  const double mean = (v - v0) / 8;
  for (int q = 0; q < 8; ++q) {
    const double dq = -cs * ((vq[q] - v0q[q]) - mean);
    for (int a = 0; a < 8; ++a) {
      gq[8 * q + a] -= g[a] / 8;
      add(a, Vec3(dq * gq[8 * q + a]));
    }
  }
  return coef;
}

}  // namespace

// Pressure forces of the elements' volume stiffness and the hexahedra's Gauss-point spread; every
// element's dV/dx (and the spread's gradients) are kept for the implicit system.
void VolumeTerm::add_forces(const Model& m, const std::vector<Vec3>& x, ElementScratch& E,
                            std::vector<Vec3>& force, bool hexahedra) {
  const bool spread = m.spread_modulus > 0;
  Vec3* g = E.volume_grad.data();
  double* coef = E.volume_coef.data();
  double vq[8];
  const int nt = static_cast<int>(m.tetrahedra.size());
  for (int e = 0; e < nt; ++e) {
    const int* nodes = m.tetrahedra[e].data();
    const double v = element_volume(x, nodes, 4, g);
    *coef++ = volume_forces<4>(m, v, m.tet_rest_volume[e], g, nullptr, nullptr, nullptr,
                               [&](int a, const Vec3& f) { force[nodes[a]] += f; });
    g += 4;
  }
  const int nh = hexahedra ? static_cast<int>(m.hexahedra.size()) : 0;
  for (int e = 0; e < nh; ++e) {
    const int* nodes = m.hexahedra[e].data();
    Vec3* gq = spread ? E.spread_grad.data() + 64 * e : nullptr;
    const double v = element_volume(x, nodes, 8, g, gq ? vq : nullptr, gq);
    const double v0 = m.hex_rest_volume[e];
    *coef++ = volume_forces<8>(m, v, v0, g, vq, spread ? m.hex_rest_gauss.data() + 8 * e : nullptr,
                               gq, [&](int a, const Vec3& f) { force[nodes[a]] += f; });
    if (spread) E.spread_coef[e] = 8 * m.spread_modulus / std::abs(v0);
    g += 8;
  }
}

double VolumeTerm::energy(const Model& m, const std::vector<Vec3>& x) {
  double e = 0;
  Vec3 g[8];
  double vq[8];
  const bool spread = m.spread_modulus > 0;
  for (size_t t = 0; t < m.tetrahedra.size(); ++t) {
    const double d = element_volume(x, m.tetrahedra[t].data(), 4, g) - m.tet_rest_volume[t];
    e += 0.5 * m.bulk_modulus / std::abs(m.tet_rest_volume[t]) * d * d;
  }
  for (size_t h = 0; h < m.hexahedra.size(); ++h) {
    const double v0 = m.hex_rest_volume[h];
    const double d = element_volume(x, m.hexahedra[h].data(), 8, g, vq) - v0;
    e += 0.5 * m.bulk_modulus / std::abs(v0) * d * d;
    for (int q = 0; q < 8 && spread; ++q) {
      const double dq = vq[q] - m.hex_rest_gauss[8 * h + q] - d / 8;
      e += 0.5 * 8 * m.spread_modulus / std::abs(v0) * dq * dq;
    }
  }
  return e;
}

void ShearTerm::add_forces(const Model& m, const std::vector<Vec3>& x, ElementScratch& E,
                           std::vector<Vec3>& force, bool hexahedra) {
  const Vec3* b = m.shear_b.data();
  const double* v0 = m.shear_v0.data();
  double* coef = E.shear_coef.data();
  for (const auto& t : m.tetrahedra) shear_element<4>(m, x, t, 1, b, v0, coef, force);
  if (!hexahedra) return;
  for (const auto& h : m.hexahedra) shear_element<8>(m, x, h, 8, b, v0, coef, force);
}

double ShearTerm::energy(const Model& m, const std::vector<Vec3>& x) {
  double e = 0;
  const Vec3* b = m.shear_b.data();
  const double* v0 = m.shear_v0.data();
  auto point = [&](const int* nodes, int n) {
    const Mat3 F = deformation_gradient(x, nodes, n, b);
    Mat3 P;
    double c;
    e += *v0++ * isochoric_yeoh(F.data(), m.shear_modulus, m.shear_stiffening, P.data(), &c);
    b += n;
  };
  for (const auto& t : m.tetrahedra) point(t.data(), 4);
  for (const auto& h : m.hexahedra)
    for (int q = 0; q < 8; ++q) point(h.data(), 8);
  return e;
}

// The shear Laplacian of every element, h^2 sum_q c_q (b_qa . b_qb) (one q for a tetrahedron),
// into E.element_lap from the coefficients of the last force evaluation.
void ShearTerm::prepare_system(const Model& m, double h2, ElementScratch& E) {
  const Vec3* b = m.shear_b.data();
  const double* c = E.shear_coef.data();
  double* lap = E.element_lap.data();
  auto element = [&](int n, int points) {
    for (int k = 0; k < n * n; ++k) lap[k] = 0;
    for (int q = 0; q < points; ++q, b += n) {
      const double cq = h2 * *c++;
      for (int a = 0; a < n; ++a)
        for (int d = a; d < n; ++d) lap[n * a + d] += cq * b[a].dot(b[d]);
    }
    for (int a = 0; a < n; ++a)
      for (int d = 0; d < a; ++d) lap[n * a + d] = lap[n * d + a];
    lap += n * n;
  };
  for (size_t e = 0; e < m.tetrahedra.size(); ++e) element(4, 1);
  // Hexahedra: the Gauss points in the lanes (Model::hex_b), sum_q c_q (b_qa . b_qd) per pair.
  const double* hb = m.hex_b.data();
  for (size_t e = 0; e < m.hexahedra.size(); ++e, hb += 192, c += 8, lap += 64) {
    const Lanes8 cq = h2 * load_lanes(c);
    Lanes8 B[8][3];
    for (int a = 0; a < 8; ++a)
      for (int j = 0; j < 3; ++j) B[a][j] = load_lanes(hb + (3 * a + j) * 8);
    for (int a = 0; a < 8; ++a)
      for (int d = a; d < 8; ++d)
        lap[8 * a + d] = lap[8 * d + a] =
            lane_sum(cq * (B[a][0] * B[d][0] + B[a][1] * B[d][1] + B[a][2] * B[d][2]));
  }
}

namespace {

// Hexahedron e's volume, spread and shear terms in one pass over its Gauss points, with its nodes
// at x[0..8): the forces VolumeTerm::add_forces and ShearTerm::add_forces give it into f[0..8)
// (overwritten), and what they keep in E. At Gauss point q the map's Jacobian is F_q J0_q (F_q
// the deformation gradient the shear term takes, J0_q the rest map's), so the point's volume
// share is v0_q det F_q and its gradient v0_q cof(F_q) b_qa (v0_q the signed rest share): one F_q
// and one cofactor per point serve both terms, where the two passes built the map's Jacobian and
// F_q from the nodes each.
void hex_terms(const Model& m, int e, const Vec3* x, ElementScratch& E, Vec3* f) {
  // Every quantity of a Gauss point is a row of 8 lanes, one per point.
  const int nt = static_cast<int>(m.tetrahedra.size());
  const double* b = m.hex_b.data() + 192 * static_cast<size_t>(e);  // [(3 a + j) 8 + q]
  const Lanes8 w0 = load_lanes(m.shear_v0.data() + nt + 8 * e);     // |v0_q|
  const Lanes8 s0 = load_lanes(m.hex_rest_gauss.data() + 8 * e);    // v0_q, signed
  const double mu = m.shear_modulus, beta = m.shear_stiffening;
  Lanes8 B[8][3];  // b_qa component j
  for (int a = 0; a < 8; ++a)
    for (int j = 0; j < 3; ++j) B[a][j] = load_lanes(b + (3 * a + j) * 8);
  Lanes8 F[9] = {};  // F_ij at [3 i + j]
  for (int a = 0; a < 8; ++a)
    for (int i = 0; i < 3; ++i)
      for (int j = 0; j < 3; ++j) F[3 * i + j] += x[a][i] * B[a][j];
  // cof(F) = J F^-T: its columns are the cross products of F's columns.
  Lanes8 C[9];
  C[0] = F[4] * F[8] - F[7] * F[5];
  C[3] = F[7] * F[2] - F[1] * F[8];
  C[6] = F[1] * F[5] - F[4] * F[2];
  C[1] = F[5] * F[6] - F[8] * F[3];
  C[4] = F[8] * F[0] - F[2] * F[6];
  C[7] = F[2] * F[3] - F[5] * F[0];
  C[2] = F[3] * F[7] - F[6] * F[4];
  C[5] = F[6] * F[1] - F[0] * F[7];
  C[8] = F[0] * F[4] - F[3] * F[1];
  const Lanes8 J = F[0] * C[0] + F[3] * C[3] + F[6] * C[6];
  const Lanes8 vq = s0 * J;
  Lanes8 i1 = {};
  for (int k = 0; k < 9; ++k) i1 += F[k] * F[k];
  const Lanes8 y = inverse_cube_roots(J);  // J^(-1/3)
  // The shear stress, |v0_q| P_q = sF_q F_q - sC_q cof(F_q) (isochoric_yeoh's, with the
  // cofactor at hand; no stress where J <= 0, and the Laplacian's coefficient 1 there).
  const Lanes8 jm = y * y;
  const Lanes8 gy = 1 + 2 * beta * (jm * i1 - 3);
  const auto stressed = J > 0;
  const Lanes8 zero = {}, one = zero + 1;
  const Lanes8 sF = stressed ? w0 * mu * gy * jm : zero;
  const Lanes8 sC = sF * i1 / (3 * (stressed ? J : one));  // 0 where sF is
  const Lanes8 coef = w0 * mu * (stressed ? gy * jm : one);
  std::memcpy(E.shear_coef.data() + nt + 8 * e, &coef, sizeof coef);
  const double v = lane_sum(vq);
  const double v0 = m.hex_rest_volume[e];
  const double kv = m.bulk_modulus / std::abs(v0), p = -kv * (v - v0);
  E.volume_coef[nt + e] = kv;
  const bool spread = m.spread_modulus > 0;
  Lanes8 dq = {};
  if (spread) {
    const double cs = 8 * m.spread_modulus / std::abs(v0), mean = (v - v0) / 8;
    E.spread_coef[e] = cs;
    dq = -cs * ((vq - s0) - mean);
  }
  const double dmean = lane_sum(dq) / 8;
  // Per node and axis: gq_a = v0_q cof(F_q) b_qa (the gradient of point q's volume share), g_a
  // their sum; the forces p g_a + sum_q d_q G_qa - sum_q |v0_q| P_q b_qa, G_qa = gq_a - g_a / 8.
  Vec3* g = E.volume_grad.data() + 4 * nt + 8 * e;
  Vec3* G = spread ? E.spread_grad.data() + 64 * e : nullptr;
  for (int a = 0; a < 8; ++a)
    for (int i = 0; i < 3; ++i) {
      const Lanes8 cb = C[3 * i] * B[a][0] + C[3 * i + 1] * B[a][1] + C[3 * i + 2] * B[a][2];
      const Lanes8 fb = F[3 * i] * B[a][0] + F[3 * i + 1] * B[a][1] + F[3 * i + 2] * B[a][2];
      const Lanes8 gq = s0 * cb;
      const double ga = lane_sum(gq);
      g[a][i] = ga;
      f[a][i] = (p - dmean) * ga + lane_sum(dq * gq - (sF * fb - sC * cb));
      if (spread) {
        const Lanes8 Gq = gq - ga / 8;
        for (int q = 0; q < 8; ++q) G[8 * q + a][i] = Gq[q];
      }
    }
}

// Whether the hexahedra take hex_terms: both terms on, so that one F_q serves both.
bool hex_terms_fused(const Model& m) {
  return m.bulk_modulus > 0 && m.shear_modulus > 0 && !m.hexahedra.empty();
}

}  // namespace

void element_forces(const Model& m, const State& s, Workspace& ws) {
  if (!hex_terms_fused(m)) {
    for_each_term(m, [&](auto term) { term.add_forces(m, s.x, ws.elements, ws.force); });
    return;
  }
  ElementScratch& E = ws.elements;
  VolumeTerm::add_forces(m, s.x, E, ws.force, /*hexahedra=*/false);
  ShearTerm::add_forces(m, s.x, E, ws.force, /*hexahedra=*/false);
  const int nh = static_cast<int>(m.hexahedra.size());
  Vec3 x[8], f[8];
  for (int e = 0; e < nh; ++e) {
    const auto& nodes = m.hexahedra[e];
    for (int a = 0; a < 8; ++a) x[a] = s.x[nodes[a]];
    hex_terms(m, e, x, E, f);
    for (int a = 0; a < 8; ++a) ws.force[nodes[a]] += f[a];
  }
}

template <int N>
void element_term_forces(const Model& m, int e, const Vec3* x, Vec3* f) {
  for (int a = 0; a < N; ++a) f[a].setZero();
  const int nt = static_cast<int>(m.tetrahedra.size());
  if (m.bulk_modulus > 0) {
    Vec3 g[N], gq[64];
    double vq[8];
    auto add = [&](int a, const Vec3& fa) { f[a] += fa; };
    if constexpr (N == 4) {
      volume_forces<4>(m, tet_volume_gradient(x, g), m.tet_rest_volume[e], g, nullptr, nullptr,
                       nullptr, add);
    } else {
      const bool spread = m.spread_modulus > 0;
      const double v = hex_volume_gradient(x, g, spread ? vq : nullptr, spread ? gq : nullptr);
      volume_forces<8>(m, v, m.hex_rest_volume[e], g, vq,
                       spread ? m.hex_rest_gauss.data() + 8 * e : nullptr, spread ? gq : nullptr,
                       add);
    }
  }
  if (m.shear_modulus > 0) {
    const int points = N == 4 ? 1 : 8;
    const Vec3* b = m.shear_b.data() + (N == 4 ? 4 * e : 4 * nt + 64 * e);
    const double* v0 = m.shear_v0.data() + (N == 4 ? e : nt + 8 * e);
    for (int q = 0; q < points; ++q, b += N) shear_point<N>(m, x, b, v0[q], f);
  }
}

template <int N>
void element_term_hessian(const Model& m, int e, const Vec3* x, double* H) {
  constexpr int n = 3 * N;
  // The step: a millionth of the element's size (its bounding box's largest side).
  Vec3 lo = x[0], hi = x[0];
  for (int a = 1; a < N; ++a) {
    lo = lo.cwiseMin(x[a]);
    hi = hi.cwiseMax(x[a]);
  }
  const double eps = 1e-6 * std::max((hi - lo).maxCoeff(), 1e-12);
  Vec3 y[N], fp[N], fm[N];
  for (int a = 0; a < N; ++a) y[a] = x[a];
  for (int col = 0; col < n; ++col) {
    Vec3& yc = y[col / 3];
    const double keep = yc[col % 3];
    yc[col % 3] = keep + eps;
    element_term_forces<N>(m, e, y, fp);
    yc[col % 3] = keep - eps;
    element_term_forces<N>(m, e, y, fm);
    yc[col % 3] = keep;
    for (int a = 0; a < N; ++a)
      for (int i = 0; i < 3; ++i)
        H[(3 * a + i) * n + col] = -(fp[a][i] - fm[a][i]) / (2 * eps);  // H = -df/dx
  }
  for (int r = 0; r < n; ++r)
    for (int c = r + 1; c < n; ++c)
      H[r * n + c] = H[c * n + r] = 0.5 * (H[r * n + c] + H[c * n + r]);
}

namespace {

// The closed-form Hessian of tetrahedron e's element energy at x[0..4): its blocks (a, c) for a, c
// in [a0, 4) into H (row-major, (3 (4 - a0))^2), H[(3 a + i) n + 3 c + k] with a, c counted from
// a0.
//
// Per rest volume |V0| the energy is W(F) = (kappa / 2) (J - 1)^2 + psi(I1b) with
// psi = (mu / 2) ((I1b - 3) + beta (I1b - 3)^2) (core/volume.h), F = sum_a x_a b_a^T. With
// u_a = F^-T b_a, f_a = F b_a and g_a = G b_a, G = dI1b/dF = J^(-2/3) (2 F - (2/3) I1 F^-T),
// the directional derivative of the stress P = dW/dF along dF = e_k b_c^T, applied to b_a, is
//   dP b_a = c1 u_a + c2 g_a + c3 u_c u_a[k] + c4 e_k (b_c . b_a),
//   c1 = kappa J (2 J - 1) u_c[k] - (4/3) psi' J^(-2/3) f_c[k],   c2 = -(2/3) psi' u_c[k] + psi''
//   g_c[k], c3 = -kappa (J - 1) J + (2/3) psi' J^(-2/3) I1,                 c4 = 2 psi' J^(-2/3),
// (psi' = dpsi/dI1b, psi'' = mu beta), each term weighted by its rest volume.
void tet_hessian_blocks(const Model& m, int e, const Vec3* x, int a0, double* H) {
  Vec3 bl[4];
  const Vec3* b = bl;
  if (m.shear_modulus > 0) {
    b = m.shear_b.data() + 4 * e;
  } else {  // the shape gradients from the rest tetrahedron
    Vec3 xr[4];
    for (int a = 0; a < 4; ++a) xr[a] = m.rest[m.tetrahedra[e][a]];
    tet_shape_gradients(xr, bl);
  }
  Mat3 F = Mat3::Zero();
  for (int a = 0; a < 4; ++a) F.noalias() += x[a] * b[a].transpose();
  Mat3 cof;  // J F^-T
  cof.col(0) = F.col(1).cross(F.col(2));
  cof.col(1) = F.col(2).cross(F.col(0));
  cof.col(2) = F.col(0).cross(F.col(1));
  const double J = F.col(0).dot(cof.col(0));
  const int n = 3 * (4 - a0);
  if (J == 0) {  // degenerate: no F^-T (the forces push it apart; the hard stop keeps springs)
    for (int r = 0; r < n * n; ++r) H[r] = 0;
    return;
  }
  const double wv = m.bulk_modulus > 0 ? std::abs(m.tet_rest_volume[e]) * m.bulk_modulus : 0.0;
  const bool shear = m.shear_modulus > 0 && J > 0;  // isochoric_yeoh: no stress at J <= 0
  const double ws = shear ? m.shear_v0[e] : 0.0;
  const Mat3 FiT = cof / J;
  const double i1 = F.squaredNorm();
  const double y = shear ? inverse_cube_root(J) : 0.0, jm = y * y;  // J^(-2/3)
  const double d = jm * i1 - 3;
  const double psi1 = ws * 0.5 * m.shear_modulus * (1 + 2 * m.shear_stiffening * d);
  const double psi2 = ws * m.shear_modulus * m.shear_stiffening;
  const double kv = wv * J * (2 * J - 1);
  const double c3 = -wv * (J - 1) * J + (2.0 / 3.0) * psi1 * jm * i1;
  const double c4 = 2 * psi1 * jm;
  Vec3 u[4], f[4], g[4];
  for (int a = 0; a < 4; ++a) {
    u[a] = FiT * b[a];
    f[a] = F * b[a];
    g[a] = jm * (2 * f[a] - (2.0 / 3.0) * i1 * u[a]);
  }
  for (int c = a0; c < 4; ++c)
    for (int k = 0; k < 3; ++k) {
      const double c1 = kv * u[c][k] - (4.0 / 3.0) * psi1 * jm * f[c][k];
      const double c2 = -(2.0 / 3.0) * psi1 * u[c][k] + psi2 * g[c][k];
      const int col = 3 * (c - a0) + k;
      for (int a = a0; a < 4; ++a) {
        Vec3 v = c1 * u[a] + c2 * g[a] + (c3 * u[a][k]) * u[c];
        v[k] += c4 * b[c].dot(b[a]);
        for (int i = 0; i < 3; ++i) H[(3 * (a - a0) + i) * n + col] = v[i];
      }
    }
}

}  // namespace

void tet_term_hessian(const Model& m, int e, const Vec3* x, double* H) {
  tet_hessian_blocks(m, e, x, 0, H);
}

void expand_tet_tangent(const double* packed, double* H) {
  double T[81];
  for (int r = 0; r < 9; ++r)
    for (int c = r; c < 9; ++c) T[9 * r + c] = T[9 * c + r] = *packed++;
  // Rows and columns of nodes 1-3 are T's; node 0's are minus their sums (sum_a b_a = 0).
  for (int r = 0; r < 12; ++r)
    for (int c = 0; c < 12; ++c) {
      const int ar = r / 3, ac = c / 3, i = r % 3, k = c % 3;
      double v = 0;
      for (int a = ar == 0 ? 1 : ar; a <= (ar == 0 ? 3 : ar); ++a)
        for (int b = ac == 0 ? 1 : ac; b <= (ac == 0 ? 3 : ac); ++b)
          v += T[9 * (3 * (a - 1) + i) + 3 * (b - 1) + k];
      H[12 * r + c] = (ar == 0) != (ac == 0) ? -v : v;
    }
}

void tet_tangent_times(const double* packed, const std::array<int, 4>& nodes, int nn,
                       const double* p, double* y) {
  double d[9], z[9] = {};
  for (int a = 1; a < 4; ++a)
    for (int c = 0; c < 3; ++c) d[3 * (a - 1) + c] = p[c * nn + nodes[a]] - p[c * nn + nodes[0]];
  for (int r = 0; r < 9; ++r) {
    z[r] += packed[0] * d[r];
    for (int c = r + 1; c < 9; ++c) {
      z[r] += packed[c - r] * d[c];
      z[c] += packed[c - r] * d[r];
    }
    packed += 9 - r;
  }
  for (int c = 0; c < 3; ++c) {
    y[c * nn + nodes[0]] -= z[c] + z[3 + c] + z[6 + c];
    for (int a = 1; a < 4; ++a) y[c * nn + nodes[a]] += z[3 * (a - 1) + c];
  }
}

int prepare_tet_tangents(const Model& m, const std::vector<Vec3>& x, double h2, ElementScratch& E) {
  const int nt = static_cast<int>(m.tetrahedra.size());
  using Mat9 = Eigen::Matrix<double, 9, 9>;
  Mat9 T;
  Eigen::LLT<Mat9> llt;
  Eigen::SelfAdjointEigenSolver<Mat9> eig;
  int projected = 0;
  for (int e = 0; e < nt; ++e) {
    Vec3 xe[4];
    for (int a = 0; a < 4; ++a) xe[a] = x[m.tetrahedra[e][a]];
    tet_hessian_blocks(m, e, xe, 1, T.data());  // symmetric: row- or column-major alike
    T = 0.5 * (T + T.transpose()).eval();
    // No eigenvalue below -tol (the rotations of an element at rest are free, a compressed one's
    // soften): kept as it is, checked by a Cholesky factorisation of T + tol I (a pivoted LDL^T
    // of the singular T itself is not a reliable test). Otherwise (strongly compressed elements)
    // its negative eigenvalues are clamped to zero (projected Newton), so that the system stays
    // positive definite. tol is 1e-3 of the largest diagonal entry: a tenth of it projects most
    // elements of a body sagging under gravity, at the cost of an eigensolver each; thirty times
    // it let a node pressed into a block drive a body step astray (BodyWorkerTest).
    const double tol = 1e-3 * T.diagonal().cwiseAbs().maxCoeff();
    llt.compute(T + tol * Mat9::Identity());
    if (llt.info() != Eigen::Success) {
      ++projected;
      eig.compute(T);
      T = eig.eigenvectors() * eig.eigenvalues().cwiseMax(0.0).asDiagonal() *
          eig.eigenvectors().transpose();
    }
    double* t = E.tet_tangent.data() + 45 * static_cast<size_t>(e);
    for (int r = 0; r < 9; ++r)
      for (int c = r; c < 9; ++c) *t++ = h2 * T(r, c);
  }
  return projected;
}

template void element_term_forces<4>(const Model&, int, const Vec3*, Vec3*);
template void element_term_forces<8>(const Model&, int, const Vec3*, Vec3*);
template void element_term_hessian<4>(const Model&, int, const Vec3*, double*);
template void element_term_hessian<8>(const Model&, int, const Vec3*, double*);

}  // namespace conica
