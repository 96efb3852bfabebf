// Element terms: what a body's tetrahedra and hexahedra store beyond their pair springs
// (core/volume.h has the mechanics): the volume term (bulk modulus kappa, with the hexahedra's
// Gauss-point spread) and the isochoric neo-Hookean shear term (shear modulus mu).
//
// Every term is a type with the same members, and every path iterates the one list
// `ElementTerms` (for_each_term; the implicit system last to first, for_each_term_reversed):
//   active(m)                           the model has the term
//   energy(m, x)                        J, stored at positions x (potential_energy)
//   add_forces(m, x, E, force, hexahedra = true)
//                                       force += -dW/dx (N) at x (hexahedra too, or tetrahedra
//                                       only), keeping in E what the term's system block needs
//   prepare_system(m, h2, E)            once per Newton iteration, after the forces
//   times<N>(m, E, h2, e, P, Y)         Y += h^2 H_e P for element e of its kind (the implicit
//                                       system's product); P, Y gathered per node: [c][a] is
//                                       component c of the element's node a
//   diagonal<N>(m, E, h2, e, nodes, nn, d)  the node blocks of h^2 H_e added to d (six
//                                       component-major entries 00 11 22 01 02 12 per node)
//   block<N>(m, E, h2, e, a, b, B)      B += the 3 x 3 block (a, b) of h^2 H_e (the sparse
//                                       assembly, core/sparse_system.h)
// H_e is the term's Gauss-Newton Hessian on element e, positive semi-definite: exact at rest for
// the volume term; the shear term's Laplacian part mu J^(-2/3) (b_a . b_b) I. Elements are numbered
// per kind: N = 4 tetrahedra, N = 8 hexahedra (for_each_element visits tetrahedra first).
// A new term: a type with these members, its scratch in ElementScratch (core/step.h) sized in
// compile.cc, its name in ElementTerms; tests/core/element_terms_test.cc checks every listed term.
#pragma once

#include <array>
#include <type_traits>
#include <vector>

#include "core/model.h"
#include "core/step.h"

namespace conica {

// Calls f(std::integral_constant<int, N>{}, e, nodes) for every element: tetrahedra (N = 4, e
// their index) then hexahedra (N = 8).
template <typename F>
void for_each_element(const Model& m, F&& f) {
  const int nt = static_cast<int>(m.tetrahedra.size()), nh = static_cast<int>(m.hexahedra.size());
  for (int e = 0; e < nt; ++e) f(std::integral_constant<int, 4>{}, e, m.tetrahedra[e]);
  for (int e = 0; e < nh; ++e) f(std::integral_constant<int, 8>{}, e, m.hexahedra[e]);
}

namespace detail {
// Y += k (u . P) u over the element's N nodes (a rank-one block k u u^T).
template <int N>
inline void add_rank_one(const Vec3* u, double k, const double (&P)[3][N], double (&Y)[3][N]) {
  double s = 0;
  for (int a = 0; a < N; ++a) s += u[a].x() * P[0][a] + u[a].y() * P[1][a] + u[a].z() * P[2][a];
  s *= k;
  for (int a = 0; a < N; ++a)
    for (int c = 0; c < 3; ++c) Y[c][a] += s * u[a][c];
}
// The node block k u_a u_a^T added to d at node i (nn nodes, six component-major entries).
inline void add_node_block(int i, int nn, const Vec3& u, double k, double* d) {
  d[i] += k * u.x() * u.x();
  d[nn + i] += k * u.y() * u.y();
  d[2 * nn + i] += k * u.z() * u.z();
  d[3 * nn + i] += k * u.x() * u.y();
  d[4 * nn + i] += k * u.x() * u.z();
  d[5 * nn + i] += k * u.y() * u.z();
}
// B += k u v^T.
inline void add_outer(const Vec3& u, const Vec3& v, double k, double (&B)[3][3]) {
  for (int r = 0; r < 3; ++r)
    for (int c = 0; c < 3; ++c) B[r][c] += k * u[r] * v[c];
}
}  // namespace detail

// W_e = (kappa V0 / 2) (J - 1)^2 per element, and for hexahedra with a spread modulus kappa_s
// (8 kappa_s / |V0|) / 2 sum_q (d_q)^2, d_q a Gauss point's volume change less an eighth of the
// element's (core/volume.h). Its block: (kappa / |V0|) g g^T + (8 kappa_s / |V0|) sum_q G_q G_q^T.
struct VolumeTerm {
  static bool active(const Model& m) { return m.bulk_modulus > 0; }
  static double energy(const Model& m, const std::vector<Vec3>& x);
  static void add_forces(const Model& m, const std::vector<Vec3>& x, ElementScratch& E,
                         std::vector<Vec3>& force, bool hexahedra = true);
  static void prepare_system(const Model&, double, ElementScratch&) {}
  template <int N>
  static void times(const Model& m, const ElementScratch& E, double h2, int e,
                    const double (&P)[3][N], double (&Y)[3][N]) {
    const int nt = static_cast<int>(m.tetrahedra.size());
    const int k = N == 4 ? e : nt + e;
    detail::add_rank_one<N>(E.volume_grad.data() + (N == 4 ? 4 * e : 4 * nt + 8 * e),
                            h2 * E.volume_coef[k], P, Y);
    if constexpr (N == 8) {
      if (!(m.spread_modulus > 0)) return;
      const Vec3* gq = E.spread_grad.data() + 64 * e;
      const double cq = h2 * E.spread_coef[e];
      for (int q = 0; q < 8; ++q) detail::add_rank_one<N>(gq + 8 * q, cq, P, Y);
    }
  }
  template <int N>
  static void diagonal(const Model& m, const ElementScratch& E, double h2, int e,
                       const std::array<int, N>& nodes, int nn, double* d) {
    const int nt = static_cast<int>(m.tetrahedra.size());
    const Vec3* g = E.volume_grad.data() + (N == 4 ? 4 * e : 4 * nt + 8 * e);
    const double cg = h2 * E.volume_coef[N == 4 ? e : nt + e];
    const bool spread = N == 8 && m.spread_modulus > 0;
    const Vec3* gq = spread ? E.spread_grad.data() + 64 * e : nullptr;
    const double cq = spread ? h2 * E.spread_coef[e] : 0.0;
    for (int a = 0; a < N; ++a) {
      detail::add_node_block(nodes[a], nn, g[a], cg, d);
      if (spread)
        for (int q = 0; q < 8; ++q) detail::add_node_block(nodes[a], nn, gq[8 * q + a], cq, d);
    }
  }
  template <int N>
  static void block(const Model& m, const ElementScratch& E, double h2, int e, int a, int b,
                    double (&B)[3][3]) {
    const int nt = static_cast<int>(m.tetrahedra.size());
    const Vec3* g = E.volume_grad.data() + (N == 4 ? 4 * e : 4 * nt + 8 * e);
    detail::add_outer(g[a], g[b], h2 * E.volume_coef[N == 4 ? e : nt + e], B);
    if constexpr (N == 8) {
      if (!(m.spread_modulus > 0)) return;
      const Vec3* gq = E.spread_grad.data() + 64 * e;
      const double cq = h2 * E.spread_coef[e];
      for (int q = 0; q < 8; ++q) detail::add_outer(gq[8 * q + a], gq[8 * q + b], cq, B);
    }
  }
};

// W = v0 (mu / 2) (J^(-2/3) tr(F^T F) - 3) per tetrahedron and per hexahedron Gauss point
// (core/volume.h). Its block: the Laplacian sum_q v0 mu J^(-2/3) (b_qa . b_qb) I, assembled per
// Newton iteration into ElementScratch::element_lap.
struct ShearTerm {
  static bool active(const Model& m) { return m.shear_modulus > 0; }
  static double energy(const Model& m, const std::vector<Vec3>& x);
  static void add_forces(const Model& m, const std::vector<Vec3>& x, ElementScratch& E,
                         std::vector<Vec3>& force, bool hexahedra = true);
  static void prepare_system(const Model& m, double h2, ElementScratch& E);
  template <int N>
  static const double* laplacian(const Model& m, const ElementScratch& E, int e) {
    const int nt = static_cast<int>(m.tetrahedra.size());
    return E.element_lap.data() + (N == 4 ? 16 * e : 16 * nt + 64 * e);
  }
  template <int N>
  static void times(const Model& m, const ElementScratch& E, double, int e, const double (&P)[3][N],
                    double (&Y)[3][N]) {
    const double* lap = laplacian<N>(m, E, e);
    for (int a = 0; a < N; ++a)
      for (int b = 0; b < N; ++b) {
        const double l = lap[N * a + b];
        for (int c = 0; c < 3; ++c) Y[c][a] += l * P[c][b];
      }
  }
  template <int N>
  static void diagonal(const Model& m, const ElementScratch& E, double, int e,
                       const std::array<int, N>& nodes, int nn, double* d) {
    const double* lap = laplacian<N>(m, E, e);
    for (int a = 0; a < N; ++a)
      for (int c = 0; c < 3; ++c) d[c * nn + nodes[a]] += lap[(N + 1) * a];
  }
  template <int N>
  static void block(const Model& m, const ElementScratch& E, double, int e, int a, int b,
                    double (&B)[3][3]) {
    const double l = laplacian<N>(m, E, e)[N * a + b];
    for (int c = 0; c < 3; ++c) B[c][c] += l;
  }
};

template <typename... Terms>
struct TermList {
  template <typename F>
  static void for_each(F&& f) {
    (f(Terms{}), ...);
  }
  template <typename F>
  static void for_each_reversed(F&& f) {
    reversed<F, Terms...>(f);
  }

 private:
  template <typename F, typename First, typename... Rest>
  static void reversed(F& f) {
    if constexpr (sizeof...(Rest) > 0) reversed<F, Rest...>(f);
    f(First{});
  }
};
using ElementTerms = TermList<VolumeTerm, ShearTerm>;

// Calls f(term) for every term of ElementTerms that the model has, in the list's order.
template <typename F>
void for_each_term(const Model& m, F&& f) {
  ElementTerms::for_each([&](auto term) {
    if (decltype(term)::active(m)) f(term);
  });
}

// The same, last term first: the order in which the implicit system's product and diagonal add
// the terms (per element, into one sum; the element stage adds them first to last). The order
// fixes the last bits of the solve, which the calibrated phantom's even-layer compression
// (tests/lab/phantom_fit_test.cc) is known to be sensitive to.
template <typename F>
void for_each_term_reversed(const Model& m, F&& f) {
  ElementTerms::for_each_reversed([&](auto term) {
    if (decltype(term)::active(m)) f(term);
  });
}

// The element stage: every term's forces added to ws.force. With both the volume and the shear
// term on, the hexahedra take them in one pass over their Gauss points (one deformation gradient
// per point for both), the same forces to rounding.
void element_forces(const Model& m, const State& s, Workspace& ws);

// The forces of every element term on element e of its kind (N = 4: tetrahedron e, N = 8:
// hexahedron e) with its nodes at x[0..N) (N), into f[0..N) (overwritten).
template <int N>
void element_term_forces(const Model& m, int e, const Vec3* x, Vec3* f);

// The exact Hessian of the element terms' energy on element e of its kind at its nodes' positions
// x[0..N) (N/m), by central differences of element_term_forces (the terms' own second
// derivatives: the volume term's (V - V0) curvature and the shear term's isochoric coupling that
// the implicit system's Gauss-Newton blocks leave out), symmetrised, into H (row-major 3N x 3N,
// H[(3 a + i) 3N + 3 b + k] = d^2 W / dx_ai dx_bk). May be indefinite.
template <int N>
void element_term_hessian(const Model& m, int e, const Vec3* x, double* H);

// The same for tetrahedron e in closed form (the volume term and the isochoric Yeoh term, derived
// in element_terms.cc), into H (row-major 12 x 12). May be indefinite.
void tet_term_hessian(const Model& m, int e, const Vec3* x, double* H);

// The implicit system's exact tangent of every tetrahedron at positions x (SolverOptions::
// exact_tangent): h2 times the closed-form Hessian's 9 x 9 block over nodes 1-3 (an element's
// energy depends on its nodes through the edges x_a - x_0 alone, so the blocks with node 0 are
// minus sums of these), the upper triangle packed row by row (45 entries) into E.tet_tangent.
// An element whose block has an eigenvalue below -1e-3 of its largest diagonal entry (strongly
// compressed elements) has its negative eigenvalues clamped to zero (projected Newton). Returns
// how many had.
int prepare_tet_tangents(const Model& m, const std::vector<Vec3>& x, double h2, ElementScratch& E);

// One tetrahedron's packed tangent (45 entries, prepare_tet_tangents) as its full 12 x 12 matrix
// (row-major; the blocks with node 0 from the translation invariance).
void expand_tet_tangent(const double* packed, double* H);

// y += T p over one tetrahedron's nodes (component-major node vectors of nn nodes), T its packed
// tangent.
void tet_tangent_times(const double* packed, const std::array<int, 4>& nodes, int nn,
                       const double* p, double* y);

}  // namespace conica
