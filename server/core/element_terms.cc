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
    Mat3 F = Mat3::Zero();
    for (int a = 0; a < N; ++a) F.noalias() += x[a] * b[a].transpose();
    Mat3 P;
    double c;
    isochoric_yeoh(F.data(), m.shear_modulus, m.shear_stiffening, P.data(), &c);
    P *= *v0;
    for (int a = 0; a < N; ++a) f[a].noalias() -= P * b[a];
    *coef++ = *v0++ * m.shear_modulus * c;
  }
  for (int a = 0; a < N; ++a) force[nodes[a]] += f[a];
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
  auto element = [&](const int* nodes, int n, double v0, Vec3* gq) {
    const double v = element_volume(x, nodes, n, g, gq ? vq : nullptr, gq);
    *coef = m.bulk_modulus / std::abs(v0);
    const double p = -*coef * (v - v0);
    for (int a = 0; a < n; ++a) force[nodes[a]] += p * g[a];
    g += n;
    ++coef;
    return v;
  };
  const int nt = static_cast<int>(m.tetrahedra.size());
  for (int e = 0; e < nt; ++e) element(m.tetrahedra[e].data(), 4, m.tet_rest_volume[e], nullptr);
  const int nh = static_cast<int>(m.hexahedra.size());
  for (int e = 0; e < nh; ++e) {
    const int* nodes = m.hexahedra[e].data();
    const double v0 = m.hex_rest_volume[e];
    Vec3* gq = spread ? E.spread_grad.data() + 64 * e : nullptr;
    const Vec3* gh = g;  // this hexahedron's dV/dx
    const double v = element(nodes, 8, v0, gq);
    if (!spread) continue;
    // Spread: force -(8 kappa_s / |V0|) sum_q d_q G_q with G_q = g_q - g / 8.
    const double cs = 8 * m.spread_modulus / std::abs(v0);
    E.spread_coef[e] = cs;
    const double* v0q = m.hex_rest_gauss.data() + 8 * e;
    const double mean = (v - v0) / 8;
    for (int q = 0; q < 8; ++q) {
      const double dq = -cs * ((vq[q] - v0q[q]) - mean);
      for (int a = 0; a < 8; ++a) {
        gq[8 * q + a] -= gh[a] / 8;
        force[nodes[a]] += dq * gq[8 * q + a];
      }
    }
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
    const bool spread = N == 8 && m.spread_modulus > 0;
    double v, v0;
    if constexpr (N == 4) {
      v = tet_volume_gradient(x, g);
      v0 = m.tet_rest_volume[e];
    } else {
      v = hex_volume_gradient(x, g, spread ? vq : nullptr, spread ? gq : nullptr);
      v0 = m.hex_rest_volume[e];
    }
    const double p = -m.bulk_modulus / std::abs(v0) * (v - v0);
    for (int a = 0; a < N; ++a) f[a] += p * g[a];
    if constexpr (N == 8) {
      if (spread) {  // as VolumeTerm::add_forces
        const double cs = 8 * m.spread_modulus / std::abs(v0);
        const double* v0q = m.hex_rest_gauss.data() + 8 * e;
        const double mean = (v - v0) / 8;
        for (int q = 0; q < 8; ++q) {
          const double dq = -cs * ((vq[q] - v0q[q]) - mean);
          for (int a = 0; a < 8; ++a) f[a] += dq * (gq[8 * q + a] - g[a] / 8);
        }
      }
    }
  }
  if (m.shear_modulus > 0) {
    const int points = N == 4 ? 1 : 8;
    const Vec3* b = m.shear_b.data() + (N == 4 ? 4 * e : 4 * nt + 64 * e);
    const double* v0 = m.shear_v0.data() + (N == 4 ? e : nt + 8 * e);
    for (int q = 0; q < points; ++q, b += N) {
      Mat3 F = Mat3::Zero();
      for (int a = 0; a < N; ++a) F.noalias() += x[a] * b[a].transpose();
      Mat3 P;
      double c;
      isochoric_yeoh(F.data(), m.shear_modulus, m.shear_stiffening, P.data(), &c);
      P *= v0[q];
      for (int a = 0; a < N; ++a) f[a].noalias() -= P * b[a];
    }
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
