// Element stage: the volume, Gauss-point spread and shear terms of tetrahedra and hexahedra
// (core/volume.h), added to ws.force, with what the implicit system needs kept.
#include <Eigen/Cholesky>
#include <algorithm>
#include <bit>
#include <cmath>
#include <cstdint>
#include <limits>
#include <vector>

#include "core/body.h"
#include "core/contact.h"
#include "core/step_detail.h"
#include "core/volume.h"

namespace conica {
namespace detail {
namespace {

// Shear stiffness forces of one element on N nodes with `points` tetrahedra / Gauss points
// (core/volume.h), added to ws.force; advances b, v0 and coef past the element.
template <int N>

void shear_element(const Model& m, const State& s, const std::array<int, N>& nodes, int points,
                   const Vec3*& b, const double*& v0, double*& coef, Workspace& ws) {
  Vec3 x[N], f[N];
  for (int a = 0; a < N; ++a) {
    x[a] = s.x[nodes[a]];
    f[a].setZero();
  }
  for (int q = 0; q < points; ++q, b += N) {
    Mat3 F = Mat3::Zero();
    for (int a = 0; a < N; ++a) F.noalias() += x[a] * b[a].transpose();
    Mat3 P;
    double jm;
    isochoric_neo_hookean(F.data(), m.shear_modulus, P.data(), &jm);
    P *= *v0;
    for (int a = 0; a < N; ++a) f[a].noalias() -= P * b[a];
    *coef++ = *v0++ * m.shear_modulus * jm;
  }
  for (int a = 0; a < N; ++a) ws.force[nodes[a]] += f[a];
}

}  // namespace

// Pressure forces of the elements' volume stiffness and the hexahedra's Gauss-point spread
// (core/volume.h), added to ws.force; every element's dV/dx (and the spread's gradients) are kept
// for the implicit system.
void volume_forces(const Model& m, const State& s, Workspace& ws) {
  if (!(m.bulk_modulus > 0)) return;
  const bool spread = m.spread_modulus > 0;
  Vec3* g = ws.volume_grad.data();
  double* coef = ws.volume_coef.data();
  double vq[8];
  auto element = [&](const int* nodes, int n, double v0, Vec3* gq) {
    const double v = element_volume(s.x, nodes, n, g, gq ? vq : nullptr, gq);
    *coef = m.bulk_modulus / std::abs(v0);
    const double p = -*coef * (v - v0);
    for (int a = 0; a < n; ++a) ws.force[nodes[a]] += p * g[a];
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
    Vec3* gq = spread ? ws.spread_grad.data() + 64 * e : nullptr;
    const Vec3* gh = g;  // this hexahedron's dV/dx
    const double v = element(nodes, 8, v0, gq);
    if (!spread) continue;
    // Spread: force -(8 kappa_s / |V0|) sum_q d_q G_q with G_q = g_q - g / 8.
    const double cs = 8 * m.spread_modulus / std::abs(v0);
    ws.spread_coef[e] = cs;
    const double* v0q = m.hex_rest_gauss.data() + 8 * e;
    const double mean = (v - v0) / 8;
    for (int q = 0; q < 8; ++q) {
      const double dq = -cs * ((vq[q] - v0q[q]) - mean);
      for (int a = 0; a < 8; ++a) {
        gq[8 * q + a] -= gh[a] / 8;
        ws.force[nodes[a]] += dq * gq[8 * q + a];
      }
    }
  }
}

// Shear stiffness forces (core/volume.h), added to ws.force.
void shear_forces(const Model& m, const State& s, Workspace& ws) {
  if (!(m.shear_modulus > 0)) return;
  const Vec3* b = m.shear_b.data();
  const double* v0 = m.shear_v0.data();
  double* coef = ws.shear_coef.data();
  for (const auto& t : m.tetrahedra) shear_element<4>(m, s, t, 1, b, v0, coef, ws);
  for (const auto& h : m.hexahedra) shear_element<8>(m, s, h, 8, b, v0, coef, ws);
}

}  // namespace detail

}  // namespace conica
