// The element terms (core/element_terms.h): energies, forces and what the implicit system keeps.
#include "core/element_terms.h"

#include <algorithm>
#include <cmath>
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
                            std::vector<Vec3>& force) {
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
  const int nh = static_cast<int>(m.hexahedra.size());
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
                           std::vector<Vec3>& force) {
  const Vec3* b = m.shear_b.data();
  const double* v0 = m.shear_v0.data();
  double* coef = E.shear_coef.data();
  for (const auto& t : m.tetrahedra) shear_element<4>(m, x, t, 1, b, v0, coef, force);
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
  for (size_t e = 0; e < m.hexahedra.size(); ++e) element(8, 8);
}

void element_forces(const Model& m, const State& s, Workspace& ws) {
  for_each_term(m, [&](auto term) { term.add_forces(m, s.x, ws.elements, ws.force); });
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

template void element_term_forces<4>(const Model&, int, const Vec3*, Vec3*);
template void element_term_forces<8>(const Model&, int, const Vec3*, Vec3*);
template void element_term_hessian<4>(const Model&, int, const Vec3*, double*);
template void element_term_hessian<8>(const Model&, int, const Vec3*, double*);

}  // namespace conica
