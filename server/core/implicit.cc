// Backward Euler. Newton on  M (x1 - x0 - h v0) = h^2 f(x1, (x1 - x0) / h); each iteration solves
//   A dx = h^2 f - M (x1 - x0 - h v0),   A = M (1 + h mu) + sum_s [alpha d d^T + beta (I - d d^T)]
//                                            + contact,
// alpha = h^2 k_ax + h a b c, beta = h^2 max(0, T / l) (step.h), plus h^2 kappa / |V0| g g^T per
// element with volume stiffness (volume.h), restricted to free axes, by a
// matrix-free conjugate gradient with a block-Jacobi (3 x 3 per node) preconditioner and fixed
// budgets, then takes the longest step (1, 1/2, ...) that makes no spring shorter than its
// hard-stop length.
//
// Node vectors are component-major: entry c n + i is component c of node i. For springs in runs
// (lattices, step.h) the product and the preconditioner's assembly then read and write each run's
// nodes i + t and j + t as contiguous streams, chunk by chunk, like the force pass; other meshes
// gather and scatter spring by spring.
#include <algorithm>
#include <cmath>
#include <tuple>
#include <type_traits>
#include <utility>

#include "core/element_terms.h"
#include "core/sparse_system.h"
#include "core/step_detail.h"

namespace conica::detail {
namespace {

// w = p_j - p_i for the springs of a run: pi, pj point at the run's first node on each side of
// component-major p (n nodes per component, `stride` apart).
[[gnu::noinline]] void run_differences(int n, int stride, const double* __restrict pi,
                                       const double* __restrict pj, double* __restrict wx,
                                       double* __restrict wy, double* __restrict wz) {
  for (int t = 0; t < n; ++t) {
    wx[t] = pj[t] - pi[t];
    wy[t] = pj[stride + t] - pi[stride + t];
    wz[t] = pj[2 * stride + t] - pi[2 * stride + t];
  }
}

// Springs not in runs: w = p_j - p_i gathered spring by spring.
[[gnu::noinline]] void gather_differences(int ns, int stride, const double* __restrict p,
                                          const int* __restrict si, const int* __restrict sj,
                                          double* __restrict wx, double* __restrict wy,
                                          double* __restrict wz) {
  for (int k = 0; k < ns; ++k) {
    const int i = si[k], j = sj[k];
    wx[k] = p[j] - p[i];
    wy[k] = p[stride + j] - p[stride + i];
    wz[k] = p[2 * stride + j] - p[2 * stride + i];
  }
}

// In place: w <- beta w + (alpha - beta)(d.w) d, each spring's block times its w.
[[gnu::noinline]] void spring_blocks_times(int n, const double* __restrict ux,
                                           const double* __restrict uy, const double* __restrict uz,
                                           const double* __restrict alpha,
                                           const double* __restrict beta, double* __restrict wx,
                                           double* __restrict wy, double* __restrict wz) {
  for (int t = 0; t < n; ++t) {
    const double c = (alpha[t] - beta[t]) * (ux[t] * wx[t] + uy[t] * wy[t] + uz[t] * wz[t]);
    wx[t] = beta[t] * wx[t] + c * ux[t];
    wy[t] = beta[t] * wy[t] + c * uy[t];
    wz[t] = beta[t] * wz[t] + c * uz[t];
  }
}

// y += sign t over a run's nodes on one side (y at the run's first node on that side).
[[gnu::noinline]] void add_run(int n, int stride, double sign, const double* __restrict tx,
                               const double* __restrict ty, const double* __restrict tz,
                               double* __restrict y) {
  for (int t = 0; t < n; ++t) {
    y[t] += sign * tx[t];
    y[stride + t] += sign * ty[t];
    y[2 * stride + t] += sign * tz[t];
  }
}

// y_i -= t, y_j += t for a run whose two node ranges do not overlap.
[[gnu::noinline]] void add_run_pair(int n, int stride, const double* __restrict tx,
                                    const double* __restrict ty, const double* __restrict tz,
                                    double* __restrict yi, double* __restrict yj) {
  for (int t = 0; t < n; ++t) {
    yi[t] -= tx[t];
    yi[stride + t] -= ty[t];
    yi[2 * stride + t] -= tz[t];
    yj[t] += tx[t];
    yj[stride + t] += ty[t];
    yj[2 * stride + t] += tz[t];
  }
}

// The six entries (00, 11, 22, 01, 02, 12) of every spring's block beta I + (alpha - beta) d d^T,
// entry e of spring t at b[e * ldb + t].
[[gnu::noinline]] void block_entries(int n, const double* __restrict ux,
                                     const double* __restrict uy, const double* __restrict uz,
                                     const double* __restrict alpha, const double* __restrict beta,
                                     int ldb, double* __restrict b) {
  for (int t = 0; t < n; ++t) {
    const double ab = alpha[t] - beta[t], be = beta[t];
    const double x = ux[t], y = uy[t], z = uz[t];
    b[t] = be + ab * x * x;
    b[ldb + t] = be + ab * y * y;
    b[2 * ldb + t] = be + ab * z * z;
    b[3 * ldb + t] = ab * x * y;
    b[4 * ldb + t] = ab * x * z;
    b[5 * ldb + t] = ab * y * z;
  }
}

// D += b over a run's nodes on one side (six component-major entries, `stride` apart).
[[gnu::noinline]] void add_entries(int n, int stride, const double* __restrict b, int ldb,
                                   double* __restrict d) {
  for (int e = 0; e < 6; ++e)
    for (int t = 0; t < n; ++t) d[e * stride + t] += b[e * ldb + t];
}

// Pre = P inv(P D P + I - P) P per node (P: the free-axis mask), from the six entries of D.
[[gnu::noinline]] void invert_blocks(int nn, const double* __restrict d,
                                     const double* __restrict free, double* __restrict pre) {
  for (int i = 0; i < nn; ++i) {
    const double fa = free[i], fb = free[nn + i], fc = free[2 * nn + i];
    const double a00 = fa * d[i] + (1 - fa), a11 = fb * d[nn + i] + (1 - fb);
    const double a22 = fc * d[2 * nn + i] + (1 - fc);
    const double a01 = fa * fb * d[3 * nn + i], a02 = fa * fc * d[4 * nn + i];
    const double a12 = fb * fc * d[5 * nn + i];
    const double c00 = a11 * a22 - a12 * a12, c01 = a02 * a12 - a01 * a22;
    const double c02 = a01 * a12 - a02 * a11, c11 = a00 * a22 - a02 * a02;
    const double c12 = a01 * a02 - a00 * a12, c22 = a00 * a11 - a01 * a01;
    const double det = a00 * c00 + a01 * c01 + a02 * c02;
    const double inv = det > 0 ? 1.0 / det : 0.0;  // D is positive definite; 0: no preconditioning
    pre[i] = fa * c00 * inv;
    pre[nn + i] = fb * c11 * inv;
    pre[2 * nn + i] = fc * c22 * inv;
    pre[3 * nn + i] = fa * fb * c01 * inv;
    pre[4 * nn + i] = fa * fc * c02 * inv;
    pre[5 * nn + i] = fb * fc * c12 * inv;
  }
}

// z = Pre r per node; returns r.z.
[[gnu::noinline]] double precondition(int nn, const double* __restrict pre,
                                      const double* __restrict r, double* __restrict z) {
  double rz = 0;
  for (int i = 0; i < nn; ++i) {
    const double x = r[i], y = r[nn + i], w = r[2 * nn + i];
    const double zx = pre[i] * x + pre[3 * nn + i] * y + pre[4 * nn + i] * w;
    const double zy = pre[3 * nn + i] * x + pre[nn + i] * y + pre[5 * nn + i] * w;
    const double zz = pre[4 * nn + i] * x + pre[5 * nn + i] * y + pre[2 * nn + i] * w;
    z[i] = zx;
    z[nn + i] = zy;
    z[2 * nn + i] = zz;
    rz += x * zx + y * zy + w * zz;
  }
  return rz;
}

double dot(int n, const double* __restrict a, const double* __restrict b) {
  double s = 0;
  for (int k = 0; k < n; ++k) s += a[k] * b[k];
  return s;
}

// Springs that x + t dx would make shorter than their hard-stop length (measured along their
// current direction, so an inversion counts) and than they are now; x and dx component-major.
[[gnu::noinline]] int count_blocked(int ns, int nn, const double* __restrict px,
                                    const double* __restrict py, const double* __restrict pz,
                                    const double* __restrict dx, double t, const int* __restrict si,
                                    const int* __restrict sj, const double* __restrict ux,
                                    const double* __restrict uy, const double* __restrict uz,
                                    const double* __restrict lmin, const double* __restrict len) {
  int blocked = 0;
  for (int k = 0; k < ns; ++k) {
    const int i = si[k], j = sj[k];
    const double ex = px[j] - px[i] + t * (dx[j] - dx[i]);
    const double ey = py[j] - py[i] + t * (dx[nn + j] - dx[nn + i]);
    const double ez = pz[j] - pz[i] + t * (dx[2 * nn + j] - dx[2 * nn + i]);
    const double l = ex * ux[k] + ey * uy[k] + ez * uz[k];
    blocked += (l < lmin[k]) & (l < len[k]);
  }
  return blocked;
}

// Largest squared node displacement of component-major dx.
[[gnu::noinline]] double max_node_motion2(int nn, const double* __restrict dx) {
  double m = 0;
  for (int i = 0; i < nn; ++i) {
    const double x = dx[i], y = dx[nn + i], z = dx[2 * nn + i];
    m = std::max(m, x * x + y * y + z * z);
  }
  return m;
}

// The Newton iteration is done once its update dx (component-major, before the line search)
// moves no node farther than options.newton_tolerance (0: never; the whole budget runs).
bool newton_converged(const Model& m, int nn, const double* dx) {
  const double tol = m.options.newton_tolerance;
  return tol > 0 && max_node_motion2(nn, dx) <= tol * tol;
}

// y = A p on free axes (component-major).
void apply_system(const Model& m, Workspace& ws, const double* p, double* y) {
  const int nn = m.num_nodes();
  const double* __restrict sm = ws.system.mass.data();
  for (int c = 0; c < 3; ++c)
    for (int i = 0; i < nn; ++i) y[c * nn + i] = sm[i] * p[c * nn + i];
  for (int q = 0; q < ws.contact.num_nodes; ++q) {
    const int i = ws.contact.nodes[q];
    const Vec3& cn = ws.contact.n[i];
    const double s = cn.x() * p[i] + cn.y() * p[nn + i] + cn.z() * p[2 * nn + i];
    y[i] += s * cn.x();
    y[nn + i] += s * cn.y();
    y[2 * nn + i] += s * cn.z();
    const Mat3& B = ws.contact.block[i];  // a surface probe's layer (core/contact.h)
    if (B.squaredNorm() == 0) continue;
    const Vec3 yi = ws.system.h2 * (B * Vec3(p[i], p[nn + i], p[2 * nn + i]));
    y[i] += yi.x();
    y[nn + i] += yi.y();
    y[2 * nn + i] += yi.z();
  }
  for (int t = 0; t < ws.contact.num_pairs; ++t) {  // the surface layers' faces
    const auto& tri = m.surface[ws.contact.pair_tris[t]];
    const Mat3* K = ws.contact.pair.data() + 6 * t;
    Vec3 pa[3], ya[3];
    for (int a = 0; a < 3; ++a) pa[a] = Vec3(p[tri[a]], p[nn + tri[a]], p[2 * nn + tri[a]]);
    ya[0] = K[0] * pa[0] + K[3] * pa[1] + K[4] * pa[2];
    ya[1] = K[3] * pa[0] + K[1] * pa[1] + K[5] * pa[2];
    ya[2] = K[4] * pa[0] + K[5] * pa[1] + K[2] * pa[2];
    for (int a = 0; a < 3; ++a)
      for (int c = 0; c < 3; ++c) y[c * nn + tri[a]] += ws.system.h2 * ya[a][c];
  }
  double* const w = ws.system.chunk.data();
  constexpr int kC = SpringLayout::kChunkSprings;
  if (ws.layout.runs.empty()) {
    // Spring by spring, kC at a time so that the products stay in L1 between the passes.
    const int ns = m.num_springs();
    for (int k0 = 0; k0 < ns; k0 += kC) {
      const int n = std::min(kC, ns - k0);
      gather_differences(n, nn, p, m.spring_i.data() + k0, m.spring_j.data() + k0, w, w + kC,
                         w + 2 * kC);
      spring_blocks_times(n, ws.springs.ux.data() + k0, ws.springs.uy.data() + k0,
                          ws.springs.uz.data() + k0, ws.system.alpha.data() + k0,
                          ws.system.beta.data() + k0, w, w + kC, w + 2 * kC);
      for (int t = 0; t < n; ++t) {
        const int i = m.spring_i[k0 + t], j = m.spring_j[k0 + t];
        for (int c = 0; c < 3; ++c) {
          y[c * nn + i] -= w[c * kC + t];
          y[c * nn + j] += w[c * kC + t];
        }
      }
    }
  } else {
    for (const SpringLayout::Chunk& ch : ws.layout.chunks) {
      for (int q = ch.first_run; q < ch.last_run; ++q) {
        const SpringLayout::Run& r = ws.layout.runs[q];
        const int t = r.k - ch.k0;
        run_differences(r.n, nn, p + r.i, p + r.j, w + t, w + kC + t, w + 2 * kC + t);
      }
      spring_blocks_times(ch.k1 - ch.k0, ws.springs.ux.data() + ch.k0, ws.springs.uy.data() + ch.k0,
                          ws.springs.uz.data() + ch.k0, ws.system.alpha.data() + ch.k0,
                          ws.system.beta.data() + ch.k0, w, w + kC, w + 2 * kC);
      for (int q = ch.first_run; q < ch.last_run; ++q) {
        const SpringLayout::Run& r = ws.layout.runs[q];
        const int t = r.k - ch.k0;
        if (r.j - r.i >= r.n) {
          add_run_pair(r.n, nn, w + t, w + kC + t, w + 2 * kC + t, y + r.i, y + r.j);
        } else {
          add_run(r.n, nn, -1.0, w + t, w + kC + t, w + 2 * kC + t, y + r.i);
          add_run(r.n, nn, 1.0, w + t, w + kC + t, w + 2 * kC + t, y + r.j);
        }
      }
    }
  }
  const double h2 = ws.system.h2;
  const bool tangent = ws.elements.tangent;
  for_each_element(m, [&](auto n, int e, const auto& nodes) {
    constexpr int N = decltype(n)::value;
    if constexpr (N == 4)
      if (tangent) {
        tet_tangent_times(ws.elements.tet_tangent.data() + 45 * static_cast<size_t>(e), nodes, nn,
                          p, y);
        return;
      }
    double P[3][N], Y[3][N] = {};
    for (int a = 0; a < N; ++a)
      for (int c = 0; c < 3; ++c) P[c][a] = p[c * nn + nodes[a]];
    for_each_term_reversed(m,
                           [&](auto term) { term.template times<N>(m, ws.elements, h2, e, P, Y); });
    for (int a = 0; a < N; ++a)
      for (int c = 0; c < 3; ++c) y[c * nn + nodes[a]] += Y[c][a];
  });
  const double* __restrict f = ws.system.free.data();
  for (int k = 0; k < 3 * nn; ++k) y[k] *= f[k];
}

// The symmetric block b added to node i's diagonal block in d (nn nodes, six component-major
// entries 00 11 22 01 02 12).
void add_diagonal_block(int i, int nn, const Mat3& b, double* d) {
  d[i] += b(0, 0);
  d[nn + i] += b(1, 1);
  d[2 * nn + i] += b(2, 2);
  d[3 * nn + i] += b(0, 1);
  d[4 * nn + i] += b(0, 2);
  d[5 * nn + i] += b(1, 2);
}

// The block-Jacobi preconditioner: inverse of every node's 3 x 3 diagonal block of A.
void build_preconditioner(const Model& m, Workspace& ws) {
  const int nn = m.num_nodes();
  double* __restrict d = ws.system.diag.data();
  const double* __restrict sm = ws.system.mass.data();
  for (int c = 0; c < 3; ++c)
    for (int i = 0; i < nn; ++i) {
      d[c * nn + i] = sm[i];
      d[(3 + c) * nn + i] = 0;
    }
  for (int q = 0; q < ws.contact.num_nodes; ++q) {
    const int i = ws.contact.nodes[q];
    add_node_block(i, nn, ws.contact.n[i], 1.0, d);
    const Mat3& B = ws.contact.block[i];  // a surface probe's layer (core/contact.h)
    if (B.squaredNorm() == 0) continue;
    add_diagonal_block(i, nn, ws.system.h2 * B, d);
  }
  for (int t = 0; t < ws.contact.num_pairs; ++t) {  // the surface layers' faces: K_aa
    const auto& tri = m.surface[ws.contact.pair_tris[t]];
    for (int a = 0; a < 3; ++a)
      add_diagonal_block(tri[a], nn, ws.system.h2 * ws.contact.pair[6 * t + a], d);
  }
  double* const b = ws.system.chunk.data();
  constexpr int kC = SpringLayout::kChunkSprings;
  if (ws.layout.runs.empty()) {
    const int ns = m.num_springs();
    for (int k0 = 0; k0 < ns; k0 += kC) {
      const int n = std::min(kC, ns - k0);
      block_entries(n, ws.springs.ux.data() + k0, ws.springs.uy.data() + k0,
                    ws.springs.uz.data() + k0, ws.system.alpha.data() + k0,
                    ws.system.beta.data() + k0, kC, b);
      for (int t = 0; t < n; ++t)
        for (int node : {m.spring_i[k0 + t], m.spring_j[k0 + t]})
          for (int e = 0; e < 6; ++e) d[e * nn + node] += b[e * kC + t];
    }
  } else {
    for (const SpringLayout::Chunk& ch : ws.layout.chunks) {
      block_entries(ch.k1 - ch.k0, ws.springs.ux.data() + ch.k0, ws.springs.uy.data() + ch.k0,
                    ws.springs.uz.data() + ch.k0, ws.system.alpha.data() + ch.k0,
                    ws.system.beta.data() + ch.k0, kC, b);
      for (int q = ch.first_run; q < ch.last_run; ++q) {
        const SpringLayout::Run& r = ws.layout.runs[q];
        const int t = r.k - ch.k0;
        add_entries(r.n, nn, b + t, kC, d + r.i);
        add_entries(r.n, nn, b + t, kC, d + r.j);
      }
    }
  }
  const bool tangent = ws.elements.tangent;
  for_each_element(m, [&](auto n, int e, const auto& nodes) {
    constexpr int N = decltype(n)::value;
    if constexpr (N == 4)
      if (tangent) {
        double H[144];
        expand_tet_tangent(ws.elements.tet_tangent.data() + 45 * static_cast<size_t>(e), H);
        using Block = Eigen::Map<const Eigen::Matrix<double, 3, 3, Eigen::RowMajor>, 0,
                                 Eigen::OuterStride<12>>;
        for (int a = 0; a < 4; ++a)  // block (a, a): row 3 a, column 3 a
          add_diagonal_block(nodes[a], nn, Mat3(Block(H + 39 * a)), d);
        return;
      }
    for_each_term_reversed(m, [&](auto term) {
      term.template diagonal<N>(m, ws.elements, ws.system.h2, e, nodes, nn, d);
    });
  });
  invert_blocks(nn, d, ws.system.free.data(), ws.system.pre.data());
}

// alpha = h^2 k_ax + h a b c and beta = h^2 max(0, T / l) of n springs of one card (damper c)
// from the values the force pass kept (card units -> node units).
[[gnu::noinline]] void coefficients(int n, double h, double c, const double* __restrict a,
                                    const double* __restrict b, const double* __restrict tangent,
                                    const double* __restrict load, const double* __restrict length,
                                    double* __restrict alpha, double* __restrict beta) {
  for (int k = 0; k < n; ++k) {
    const double kax = std::min(a[k] * b[k] * tangent[k], 1e300);
    alpha[k] = h * h * kax + h * a[k] * b[k] * c;
    beta[k] = h * h * std::max(0.0, -a[k] * load[k] / std::max(length[k], 1e-300));
  }
}

void system_coefficients(const Model& m, Workspace& ws, double h) {
  for (const SpringGroup& g : m.groups) {
    const int k = g.begin;
    coefficients(g.end - k, h, g.card.damping, m.force_scale.data() + k,
                 m.deflection_scale.data() + k, ws.springs.tangent.data() + k,
                 ws.springs.load.data() + k, ws.springs.length.data() + k,
                 ws.system.alpha.data() + k, ws.system.beta.data() + k);
  }
}

// Preconditioned CG from dx = 0 on A dx = rhs within the budget; returns the iterations taken.
// precondition(r, z) sets z = P r and returns r.z; z_ready: ws.system.z holds P rhs already.
template <typename Precondition>
int pcg(const Model& m, Workspace& ws, Precondition&& precondition, bool z_ready = false) {
  const int nn = m.num_nodes(), n3 = 3 * nn;
  double* __restrict dx = ws.system.dx.data();
  double* __restrict r = ws.system.r.data();
  double* __restrict z = ws.system.z.data();
  double* __restrict p = ws.system.p.data();
  double* __restrict ap = ws.system.ap.data();
  const double* __restrict rhs = ws.system.rhs.data();
  std::fill(dx, dx + n3, 0.0);
  std::copy(rhs, rhs + n3, r);
  ws.system.indefinite = false;
  double rz = z_ready ? dot(n3, r, z) : precondition(r, z);
  std::copy(z, z + n3, p);
  const double bnorm2 = dot(n3, r, r);
  const double tol2 = m.options.cg_tolerance * m.options.cg_tolerance * bnorm2;
  int it = 0;
  for (; it < m.options.cg_iterations && bnorm2 > 0; ++it) {
    apply_system(m, ws, p, ap);
    const double pap = dot(n3, p, ap);
    if (!(pap > 0)) {
      ws.system.indefinite = true;
      break;
    }
    const double step = rz / pap;
    double rr = 0;
    for (int k = 0; k < n3; ++k) {
      dx[k] += step * p[k];
      r[k] -= step * ap[k];
      rr += r[k] * r[k];
    }
    if (rr <= tol2) {
      ++it;
      break;
    }
    const double rz_new = precondition(r, z);
    const double beta = rz_new / rz;
    rz = rz_new;
    for (int k = 0; k < n3; ++k) p[k] = z[k] + beta * p[k];
  }
  return it;
}

// CG with the block-Jacobi preconditioner.
int solve(const Model& m, Workspace& ws) {
  const int nn = m.num_nodes();
  const double* pre = ws.system.pre.data();
  return pcg(m, ws, [nn, pre](const double* r, double* z) { return precondition(nn, pre, r, z); });
}

// CG with the factor's A_f^-1 as the preconditioner (LinearSolver::kFactorCG).
int solve_factored(const Model& m, Workspace& ws, SystemFactor& factor, bool z_ready) {
  const int n3 = 3 * m.num_nodes();
  return pcg(
      m, ws,
      [n3, &factor](const double* r, double* z) {
        factor.precondition(r, z);
        return dot(n3, r, z);
      },
      z_ready);
}

// One Newton iteration's solve with LinearSolver::kFactorCG: takes a factor the worker finished,
// asks for a new one when wanted (assembled here; factored by the worker, or here without one),
// then CG with the factor in use, or with the block-Jacobi preconditioner until there is one.
// CG's first preconditioned residual is the estimate already in ws.system.z when `estimated`, the
// factor that made it, is still the one in use.
int factored_solve(const Model& m, State& s, Workspace& ws, const SystemFactor* estimated) {
  FactorScratch& F = *ws.factor;
  int st = F.next_state.load(std::memory_order_acquire);
  if (st == FactorScratch::kFactored || st == FactorScratch::kFailed) {
    if (st == FactorScratch::kFactored) {
      std::swap(F.current, F.next);
      ++s.counters.factorizations;
    } else {
      ++s.counters.factor_failures;
    }
    F.next_state.store(FactorScratch::kIdle, std::memory_order_release);
    st = FactorScratch::kIdle;
  }
  if (F.wanted && st == FactorScratch::kIdle) {
    F.next->assemble(m, ws);
    F.wanted = false;
    F.age = 0;
    if (F.worker) {
      F.next_state.store(FactorScratch::kAssembled, std::memory_order_release);
      F.next_state.notify_one();
    } else if (F.next->factorize()) {  // allocates inside CHOLMOD: no worker to do it
      std::swap(F.current, F.next);
      ++s.counters.factorizations;
    } else {
      ++s.counters.factor_failures;
    }
  }
  int it;
  if (F.current->factored()) {
    it = solve_factored(m, ws, *F.current, F.current.get() == estimated);
  } else {
    build_preconditioner(m, ws);
    it = solve(m, ws);
  }
  if (it > m.options.refactor_iterations) F.wanted = true;
  return it;
}

}  // namespace

// The tetrahedra's exact tangent for this Newton iteration (SolverOptions::exact_tangent; the
// workspace holds room for it only then), or the Gauss-Newton blocks.
void prepare_tangent(const Model& m, const State& s, Workspace& ws, double h2) {
  ElementScratch& E = ws.elements;
  E.tangent = !m.tetrahedra.empty() && E.tet_tangent.size() == 45 * m.tetrahedra.size();
  if (E.tangent) prepare_tet_tangents(m, s.x, h2, E);
}

void prepare_system_at(const Model& m, State& s, Workspace& ws, double h) {
  const int nn = m.num_nodes();
  const double mfac = 1.0 + h * m.options.mass_damping;
  for (int i = 0; i < nn; ++i) ws.system.mass[i] = m.mass[i] * mfac;
  evaluate_forces(m, s, ws, true);
  ws.system.h2 = h * h;
  system_coefficients(m, ws, h);
  for_each_term(m, [&](auto term) { term.prepare_system(m, h * h, ws.elements); });
  prepare_tangent(m, s, ws, h * h);
}

void system_product(const Model& m, State& s, Workspace& ws, double h, const double* p, double* y) {
  prepare_system_at(m, s, ws, h);
  apply_system(m, ws, p, y);
}

namespace {

// Whether a surface probe touches the body: its contact layer switches on and off as nodes
// enter and leave the tool, where a full Newton step can throw a node that the layer did not
// hold at the step's start deep into it (or out of it), so the step is backtracked on the
// residual (implicit_newton).
bool layer_in_contact(const Model& m, const State& s) {
  for (size_t q = 0; q < m.probes.size(); ++q)
    if (m.probes[q].contact == ContactModel::kSurface && s.probes[q].active &&
        s.probes[q].proxy_placed && s.probes[q].contacts > 0)
      return true;
  return false;
}

// -h^2 times backward Euler's residual at node i, h^2 f - M (x1 - x0 - h v0), the forces
// evaluated at s.x (all axes).
Vec3 step_residual(const Model& m, const State& s, const Workspace& ws, double h, int i) {
  return h * h * ws.force[i] - m.mass[i] * (s.x[i] - ws.system.x0[i] - h * ws.system.v0[i]);
}

// Its squared norm on free axes.
double residual_norm2(const Model& m, const State& s, const Workspace& ws, double h) {
  double r2 = 0;
  for (int i = 0; i < m.num_nodes(); ++i)
    r2 += step_residual(m, s, ws, h, i).cwiseProduct(m.free_axes[i]).squaredNorm();
  return r2;
}

// Backward Euler's Newton iteration, each linear system solved by solve_system (returns its CG
// iterations). Each step is shortened so that no spring ends shorter than its hard-stop length;
// with a surface probe in contact it is then backtracked (halved, at most kContactBacktracks
// times) while it multiplies the residual by more than ten: the layer's lumped blocks only describe
// the nodes it holds at the iterate, so a step from a state where a node was free of the tool can
// overshoot into the barrier (or off the tool) and the fixed budget would end on that state. The
// forces of the accepted iterate are the next iteration's. estimate(r, z) (false: none) puts in z
// (ws.system.z) an estimate of A^-1 r without the system (the factor's preconditioner), which
// ends the iteration once it is within the Newton tolerance; otherwise CG starts from it.
template <class SolveSystem, class Estimate>
void implicit_newton(const Model& m, State& s, Workspace& ws, SolveSystem&& solve_system,
                     Estimate&& estimate) {
  constexpr int kContactBacktracks = 6;
  // A full update may raise the residual on its way (the lumped blocks are not the layer's exact
  // Jacobian) and still converge; one that multiplies it by more than ten is what overshoots (a
  // node thrown into the barrier). Halving every update that raises it at all slows quasi-static
  // steps: a flat punch's press on the 2.5 mm Hertz block (conica-lab contact, 5 held steps a
  // level) read 47 % from Sneddon with it, 35 % with this and 29 % with no backtracking.
  constexpr double kGrowth2 = 100;  // on the squared norm
  // BDF2 (SolverOptions::bdf2): backward Euler of step 2h / 3 from x^ = (4 x_n - x_n-1) / 3 and
  // v^ = (4 v_n - v_n-1) / 3; x0, v0 and h below are those.
  const bool bdf2 = bdf2_step(m, s);
  const bool keep_prev = m.options.bdf2 && s.x_prev.size() == s.x.size();
  const double h = implicit_h(m, s);
  const int nn = m.num_nodes(), ns = m.num_springs();
  for (int i = 0; i < nn; ++i) {
    ws.system.x0[i] = s.x[i];
    ws.system.v0[i] = s.v[i];
    if (bdf2) {  // on free axes: a fixed axis keeps its position (a prescribed path included)
      const Vec3& free = m.free_axes[i];
      ws.system.x0[i] += bdf2_start_shift(s, i).cwiseProduct(free);
      ws.system.v0[i] = bdf2_start_velocity(s, i).cwiseProduct(free);
    }
    if (keep_prev) {
      s.x_prev[i] = s.x[i];
      s.v_prev[i] = s.v[i];
    }
    s.x[i] = ws.system.x0[i] + h * ws.system.v0[i].cwiseProduct(m.free_axes[i]);  // predictor
  }
  hard_stop(m, s, ws);  // the predictor must not cross solid height either
  const double mfac = 1.0 + h * m.options.mass_damping;
  for (int i = 0; i < nn; ++i) ws.system.mass[i] = m.mass[i] * mfac;
  const bool backtrack = layer_in_contact(m, s);
  bool evaluated = false;  // the forces at s.x are in ws (from the last backtracking)

  for (int it = 0; it < m.options.newton_iterations; ++it) {
    if (!evaluated) {
      for (int i = 0; i < nn; ++i) s.v[i] = (s.x[i] - ws.system.x0[i]) / h;
      evaluate_forces(m, s, ws, true);
    }
    evaluated = false;
    // rhs = -h^2 R = h^2 f - M (x1 - x0 - h v0), on free axes.
    for (int i = 0; i < nn; ++i) {
      const Vec3 res = step_residual(m, s, ws, h, i);
      for (int c = 0; c < 3; ++c) ws.system.rhs[c * nn + i] = res[c] * ws.system.free[c * nn + i];
    }
    // Converged already? The update the factor alone estimates (its preconditioner applied to
    // the residual: CG's first direction) moves no node farther than the Newton tolerance, and no
    // spring nearer its hard stop than it has room for: it is applied, and the system's
    // preparation and solve, which would find an update of that size, are left out.
    if (m.options.newton_tolerance > 0 && estimate(ws.system.rhs.data(), ws.system.z.data())) {
      const double* dz = ws.system.z.data();
      if (newton_converged(m, nn, dz) &&
          ws.springs.slack > 2 * std::sqrt(max_node_motion2(nn, dz))) {
        for (int i = 0; i < nn; ++i) s.x[i] += Vec3(dz[i], dz[nn + i], dz[2 * nn + i]);
        ++s.counters.newton_estimates;
        break;
      }
    }
    ws.system.h2 = h * h;
    system_coefficients(m, ws, h);
    for_each_term(m, [&](auto term) { term.prepare_system(m, h * h, ws.elements); });
    prepare_tangent(m, s, ws, h * h);
    s.counters.cg_iterations += solve_system();
    if (ws.system.indefinite && ws.elements.tangent) {
      // CG met a direction of non-positive curvature: the exact tangent is indefinite here (a
      // strongly compressed element). This iteration solves with the Gauss-Newton blocks.
      ws.elements.tangent = false;
      ++s.counters.indefinite_tangents;
      s.counters.cg_iterations += solve_system();
    }
    ++s.counters.newton_iterations;

    // Line search: never make a spring shorter than its hard-stop length (unless it was already
    // and the step does not shorten it further). Measured along its direction, a spring's length
    // changes by at most the motion of its two ends: a step that moves no node by half the
    // smallest room to the hard stop (at these positions, from the force pass) needs no test.
    const double* dx = ws.system.dx.data();
    double step_len = 1.0;
    if (!(ws.springs.slack > 2 * std::sqrt(max_node_motion2(nn, dx)))) {
      for (int tries = 0; tries < 12; ++tries) {
        if (count_blocked(ns, nn, ws.springs.px.data(), ws.springs.py.data(), ws.springs.pz.data(),
                          dx, step_len, m.spring_i.data(), m.spring_j.data(), ws.springs.ux.data(),
                          ws.springs.uy.data(), ws.springs.uz.data(), ws.layout.min_length.data(),
                          ws.springs.length.data()) == 0)
          break;
        step_len *= 0.5;
      }
    }
    if (backtrack) {
      double r0 = 0;
      for (int j = 0; j < 3 * nn; ++j) r0 += ws.system.rhs[j] * ws.system.rhs[j];
      for (int i = 0; i < nn; ++i) ws.system.x_base[i] = s.x[i];
      for (int tries = 0;; ++tries, step_len *= 0.5) {
        for (int i = 0; i < nn; ++i) {
          s.x[i] = ws.system.x_base[i] + step_len * Vec3(dx[i], dx[nn + i], dx[2 * nn + i]);
          s.v[i] = (s.x[i] - ws.system.x0[i]) / h;
        }
        evaluate_forces(m, s, ws, true);
        if (tries == kContactBacktracks || residual_norm2(m, s, ws, h) < kGrowth2 * r0) break;
      }
      evaluated = true;
    } else {
      for (int i = 0; i < nn; ++i) s.x[i] += step_len * Vec3(dx[i], dx[nn + i], dx[2 * nn + i]);
    }
    if (newton_converged(m, nn, dx)) break;
  }
  for (int i = 0; i < nn; ++i)
    s.v[i] = ((s.x[i] - ws.system.x0[i]) / h).cwiseProduct(m.free_axes[i]);
  // The next step has this one as its previous (x_prev, v_prev were set above).
  s.has_prev = keep_prev;
}

}  // namespace

void integrate_implicit(const Model& m, State& s, Workspace& ws) {
  implicit_newton(
      m, s, ws,
      [&] {
        build_preconditioner(m, ws);
        return solve(m, ws);
      },
      [](const double*, double*) { return false; });  // block-Jacobi: no estimate of the update
}

// integrate_implicit with LinearSolver::kFactorCG: the same Newton iteration and line search,
// each system solved by factored_solve (a factor renewed every refactor_every steps).
void integrate_implicit_factored(const Model& m, State& s, Workspace& ws) {
  FactorScratch& F = *ws.factor;
  if (m.options.refactor_every > 0 && ++F.age >= m.options.refactor_every) F.wanted = true;
  // The factor whose preconditioner made this iteration's estimate (in ws.system.z, CG's first
  // preconditioned residual when the solve keeps that factor).
  const SystemFactor* estimated = nullptr;
  implicit_newton(
      m, s, ws, [&] { return factored_solve(m, s, ws, std::exchange(estimated, nullptr)); },
      [&](const double* r, double* z) {
        if (!F.current->factored()) return false;
        F.current->precondition(r, z);
        estimated = F.current.get();
        return true;
      });
}

}  // namespace conica::detail
