// Compile step: everything a Workspace derives from a Model (the spring layout in runs and
// chunks, hard-stop lengths, the active region's network modulus and the far field's stability
// bounds) and each stage's scratch, sized once.
#include <Eigen/Eigenvalues>
#include <algorithm>
#include <bit>
#include <cmath>
#include <cstdint>
#include <limits>
#include <vector>

#include "core/body.h"
#include "core/contact.h"
#include "core/sparse_system.h"
#include "core/step_detail.h"
#include "core/volume.h"

namespace conica {

using namespace detail;

namespace {

// Springs in runs and chunks, hard-stop lengths and the per-node spring lists.
SpringLayout compile_layout(const Model& m) {
  SpringLayout L;
  const size_t ns = m.num_springs(), nn = m.num_nodes();
  // Runs, cut at group boundaries and into pieces of at most kChunk springs; chunks of whole
  // pieces of one group, about kChunk springs each.
  constexpr int kChunk = SpringLayout::kChunkSprings;
  auto& runs = L.runs;
  auto& chunks = L.chunks;
  using Chunk = SpringLayout::Chunk;
  for (int g = 0; g < static_cast<int>(m.groups.size()); ++g) {
    const int end = m.groups[g].end;
    Chunk chunk{g, static_cast<int>(runs.size()), 0, m.groups[g].begin, 0};
    for (int k = m.groups[g].begin; k < end;) {
      int n = 1;
      while (k + n < end && n < kChunk && m.spring_i[k + n] == m.spring_i[k] + n &&
             m.spring_j[k + n] == m.spring_j[k] + n)
        ++n;
      if (k + n - chunk.k0 > kChunk) {
        chunk.last_run = static_cast<int>(runs.size());
        chunk.k1 = k;
        chunks.push_back(chunk);
        chunk = Chunk{g, chunk.last_run, 0, k, 0};
      }
      runs.push_back({k, n, m.spring_i[k], m.spring_j[k]});
      k += n;
    }
    chunk.last_run = static_cast<int>(runs.size());
    chunk.k1 = end;
    if (chunk.k1 > chunk.k0) chunks.push_back(chunk);
  }
  constexpr size_t kMinMeanRun = 4;  // shorter runs: the gather kernels are faster
  if (ns < kMinMeanRun * runs.size()) {
    runs.clear();
    chunks.clear();
  }
  L.spring_group.assign(ns, 0);
  for (size_t g = 0; g < m.groups.size(); ++g)
    for (int k = m.groups[g].begin; k < m.groups[g].end; ++k)
      L.spring_group[k] = static_cast<int>(g);
  for (const SpringGroup& g : m.groups) {
    L.tangent_limit.push_back(1.5 * (g.law ? g.law->rest_stiffness() : g.card.hooke_k) +
                              g.card.maxwell_k);
    L.has_maxwell |= g.card.maxwell_k > 0;
  }
  L.node_spring_start.assign(nn + 1, 0);
  for (size_t k = 0; k < ns; ++k) {
    ++L.node_spring_start[m.spring_i[k] + 1];
    ++L.node_spring_start[m.spring_j[k] + 1];
  }
  for (size_t i = 0; i < nn; ++i) L.node_spring_start[i + 1] += L.node_spring_start[i];
  L.node_springs.assign(2 * ns, 0);
  {
    std::vector<int> fill(L.node_spring_start.begin(), L.node_spring_start.end() - 1);
    for (size_t k = 0; k < ns; ++k) {
      L.node_springs[fill[m.spring_i[k]]++] = static_cast<int>(k);
      L.node_springs[fill[m.spring_j[k]]++] = static_cast<int>(k);
    }
  }
  L.spring_chunk.assign(ns, 0);
  for (size_t c = 0; c < chunks.size(); ++c)
    for (int k = chunks[c].k0; k < chunks[c].k1; ++k) L.spring_chunk[k] = static_cast<int>(c);
  L.min_length.assign(ns, 0);
  L.min_length2.assign(ns, 0);
  for (const SpringGroup& g : m.groups) {
    for (int k = g.begin; k < g.end; ++k) {
      const double l0 = m.rest_length[k];
      double lmin = m.options.min_length_fraction * l0;
      if (g.law) lmin = std::max(lmin, l0 - g.law->remaining_stroke() / m.deflection_scale[k]);
      if (!m.options.hard_stop) lmin = -std::numeric_limits<double>::infinity();
      L.min_length[k] = lmin;
      L.min_length2[k] = lmin * lmin;
    }
  }
  return L;
}

// The active region's network modulus and the far field's interval and inertia.
RegionBounds compile_bounds(const Model& m) {
  RegionBounds B;
  const size_t nn = m.num_nodes();
  // Network modulus E = sum(k_ax l0^2) / (6 V) (isotropic central-force network, nu = 1/4) and the
  // mean axial stiffness per node, from the stiffness of every spring at rest (K0; k_t(delta0)
  // for a pre-compressed conical card).
  const double volume = body_volume(m);
  double kl2 = 0, ksum = 0;
  for (const SpringGroup& g : m.groups) {
    const double k0 = g.law ? g.law->rest_stiffness() : g.card.hooke_k;
    for (int k = g.begin; k < g.end; ++k) {
      const double kax = m.force_scale[k] * m.deflection_scale[k] * k0;
      kl2 += kax * m.rest_length[k] * m.rest_length[k];
      ksum += kax;
    }
  }
  B.modulus = volume > 0 ? kl2 / (6 * volume) : 1.0;
  B.node_stiffness = nn > 0 ? 2 * ksum / nn : 1.0;
  // Multi-rate far field: omega^2 <= max_i 2 sum(a b K0) / m_i over free nodes (Gershgorin on
  // M^-1 K in the linear phase), and symplectic Euler needs H omega < 2.
  {
    std::vector<double> node_k(nn, 0.0);
    for (const SpringGroup& g : m.groups) {
      const double k0 = (g.law ? g.law->rest_stiffness() : g.card.hooke_k) + g.card.maxwell_k;
      for (int k = g.begin; k < g.end; ++k) {
        const double kax = m.force_scale[k] * m.deflection_scale[k] * k0;
        node_k[m.spring_i[k]] += kax;
        node_k[m.spring_j[k]] += kax;
      }
    }
    double omega2 = 0;
    for (size_t i = 0; i < nn; ++i)
      if (m.fixed[i] != 7) omega2 = std::max(omega2, 2 * node_k[i] * m.inv_mass[i]);
    const double dt = m.options.dt;
    B.far_max_every = omega2 > 0 ? std::max(1, int(0.9 * 2 / (dt * std::sqrt(omega2)))) : 1;
    // The light nodes (edges and corners of a lattice, small cells of a mesh) set that bound; the
    // automatic interval is the typical node's (median of 2 sum(a b K0) / m), and far nodes
    // lighter than their springs allow at that interval step with a larger inertia
    // m' = H^2 2 sum(a b K0) / (2 * 0.9)^2 (their weight and damping keep the true mass), so that
    // every row of M'^-1 K meets H omega < 2 with the 0.9 margin.
    std::vector<double> rate;
    for (size_t i = 0; i < nn; ++i)
      if (m.fixed[i] != 7) rate.push_back(2 * node_k[i] * m.inv_mass[i]);
    int typical = B.far_max_every;
    if (!rate.empty()) {
      std::nth_element(rate.begin(), rate.begin() + rate.size() / 2, rate.end());
      const double w2 = rate[rate.size() / 2];
      if (w2 > 0) typical = std::max(B.far_max_every, int(0.9 * 2 / (dt * std::sqrt(w2))));
    }
    // Measured instead: the largest eigenvalue of M^-1 K (linear phase, at rest) by Lanczos, and
    // the dampers' explicit damping, which lowers the bound (see far_spectral_bound).
    B.measured_every = 0;
    double ratio = 0;  // largest dashpot / stiffness ratio of a group, s
    for (const SpringGroup& g : m.groups) {
      const double k = (g.law ? g.law->k0() : g.card.hooke_k) + g.card.maxwell_k;
      if (k > 0) ratio = std::max(ratio, g.card.damping / k);
    }
    // Symplectic Euler with explicit damping g on a mode omega^2 = lambda is stable while
    // H^2 lambda + 2 H g < 4; with the 0.9 margin on H omega: <= 1.8^2. An inertia raised by a
    // factor s on every far node divides lambda and the dashpots' part of g by s: the smallest s
    // that keeps an interval of n ticks stable.
    auto raise_for = [&](int n) {
      const double H = n * dt, room = 1.8 * 1.8 - 2 * H * m.options.mass_damping;
      if (!(room > 0)) return std::numeric_limits<double>::infinity();
      return std::max(1.0, (H * H * B.far_lambda + 2 * H * ratio * B.far_lambda) / room);
    };
    if (m.options.active_region && m.options.active_far_every >= 0) {
      B.far_lambda = far_spectral_bound(m);
      B.far_gamma = m.options.mass_damping + ratio * B.far_lambda;
      // The interval is the longest that needs s <= 1.1 (far frequencies within 5 %).
      for (int n = 1; n < 64 && raise_for(n) <= 1.1; ++n) B.measured_every = n;
      // A mesh whose few lightest, stiffest nodes set the spectrum keeps the typical node's
      // interval with their inertia raised (below) when that is longer.
      typical = std::max(typical, B.measured_every);
    }
    B.far_every = m.options.active_far_every < 0    ? 0
                  : m.options.active_far_every == 0 ? typical
                                                    : m.options.active_far_every;
    B.far_inv_mass = m.inv_mass;
    const double H = std::max(B.far_every, 1) * dt;
    const bool raise = B.measured_every == 0 || B.far_every > B.measured_every;
    B.far_raise = 1;
    if (!raise && B.far_every > 0) {
      B.far_raise = raise_for(B.far_every);
      for (size_t i = 0; i < nn; ++i) B.far_inv_mass[i] = m.inv_mass[i] / B.far_raise;
    }
    for (size_t i = 0; i < nn && raise; ++i)
      if (node_k[i] > 0)
        B.far_inv_mass[i] =
            std::min(m.inv_mass[i], (2 * 0.9) * (2 * 0.9) / (H * H * 2 * node_k[i]));
  }
  return B;
}

SpringScratch spring_scratch(const Model& m) {
  SpringScratch S;
  const size_t ns = m.num_springs(), nn = m.num_nodes();
  S.deflection.assign(ns, 0);
  S.load.assign(ns, 0);
  S.tangent.assign(ns, 0);
  S.length.assign(ns, 0);
  S.ux.assign(ns, 1.0);
  S.uy.assign(ns, 0);
  S.uz.assign(ns, 0);
  for (size_t k = 0; k < ns; ++k) {  // directions at rest until the first force evaluation
    const Vec3 u = m.rest[m.spring_j[k]] - m.rest[m.spring_i[k]];
    if (u.norm() > 0) {
      S.ux[k] = u.x() / u.norm();
      S.uy[k] = u.y() / u.norm();
      S.uz[k] = u.z() / u.norm();
    }
  }
  for (auto* v : {&S.px, &S.py, &S.pz, &S.fx, &S.fy, &S.fz}) v->assign(nn, 0.0);
  for (auto* v : {&S.chunk_ux, &S.chunk_uy, &S.chunk_uz, &S.chunk_length, &S.chunk_deflection,
                  &S.chunk_load, &S.chunk_tangent})
    v->assign(SpringLayout::kChunkSprings, 0.0);
  return S;
}

ElementScratch element_scratch(const Model& m) {
  ElementScratch E;
  if (m.shear_modulus > 0) {
    E.shear_coef.assign(m.shear_v0.size(), 0.0);
    E.element_lap.assign(16 * m.tetrahedra.size() + 64 * m.hexahedra.size(), 0.0);
  }
  if ((m.shear_modulus > 0 || m.bulk_modulus > 0) && m.options.exact_tangent &&
      m.options.integrator == Integrator::kImplicitEuler)
    E.tet_tangent.assign(45 * m.tetrahedra.size(), 0.0);
  if (m.bulk_modulus > 0) {
    E.volume_grad.assign(4 * m.tetrahedra.size() + 8 * m.hexahedra.size(), Vec3::Zero());
    E.volume_coef.assign(m.tetrahedra.size() + m.hexahedra.size(), 0.0);
    if (m.spread_modulus > 0) {
      E.spread_grad.assign(64 * m.hexahedra.size(), Vec3::Zero());
      E.spread_coef.assign(m.hexahedra.size(), 0.0);
    }
  }
  return E;
}

ContactScratch contact_scratch(const Model& m) {
  ContactScratch C;
  const size_t nn = m.num_nodes();
  C.n.assign(nn, Vec3::Zero());
  C.block.assign(nn, Mat3::Zero());
  C.v_ref.assign(nn, Vec3::Zero());
  C.nodes.assign(nn, 0);
  C.in_contact.assign(nn, 0);
  C.candidates.assign(m.probes.size(), ContactCandidates(m));
  size_t surface_probes = 0;
  for (const ProbeSpec& p : m.probes) surface_probes += p.contact == ContactModel::kSurface;
  C.pair_tris.assign(surface_probes * m.surface.size(), 0);
  C.pair_probe.assign(C.pair_tris.size(), 0);
  C.pair.assign(6 * C.pair_tris.size(), Mat3::Zero());
  return C;
}

SystemScratch system_scratch(const Model& m) {
  SystemScratch Y;
  const size_t ns = m.num_springs(), nn = m.num_nodes();
  Y.alpha.assign(ns, 0);
  Y.beta.assign(ns, 0);
  for (auto* v : {&Y.x0, &Y.v0, &Y.x_base}) v->assign(nn, Vec3::Zero());
  Y.mass.assign(nn, 0.0);
  Y.free.assign(3 * nn, 0.0);
  for (size_t i = 0; i < nn; ++i)
    for (int c = 0; c < 3; ++c) Y.free[c * nn + i] = m.free_axes[i][c];
  for (auto* v : {&Y.diag, &Y.pre}) v->assign(6 * nn, 0.0);
  for (auto* v : {&Y.rhs, &Y.r, &Y.z, &Y.p, &Y.ap, &Y.dx}) v->assign(3 * nn, 0.0);
  Y.chunk.assign(6 * SpringLayout::kChunkSprings, 0.0);
  return Y;
}

}  // namespace

Workspace::Workspace(const Model& m)
    : layout(compile_layout(m)),
      bounds(compile_bounds(m)),
      force(m.num_nodes(), Vec3::Zero()),
      springs(spring_scratch(m)),
      elements(element_scratch(m)),
      contact(contact_scratch(m)),
      system(system_scratch(m)) {
  good.x.assign(m.num_nodes(), Vec3::Zero());
  good.v.assign(m.num_nodes(), Vec3::Zero());
  good.maxwell.assign(m.num_springs(), 0);
  if (m.options.integrator == Integrator::kImplicitEuler &&
      m.options.linear_solver == LinearSolver::kFactorCG)
    factor = std::make_unique<FactorScratch>(m);
  good.stick.resize(m.planes.size());
  for (size_t q = 0; q < m.planes.size(); ++q)
    if (m.planes[q].friction > 0) good.stick[q].assign(m.num_nodes(), Vec3::Zero());
}

Workspace::~Workspace() = default;
Workspace::Workspace(Workspace&&) noexcept = default;
Workspace& Workspace::operator=(Workspace&&) noexcept = default;

void options_changed(const Model& m, State& s, Workspace& ws) {
  const int old_every = ws.bounds.far_every;
  ws = Workspace(m);
  if (ws.bounds.far_every == old_every) return;
  RegionState& r = s.region;
  r.far_phase = 0;
  r.num_active = -1;
  std::fill(r.impulse.begin(), r.impulse.end(), Vec3::Zero());
  for (auto* f : {&r.far_fx, &r.far_fy, &r.far_fz}) std::fill(f->begin(), f->end(), 0.0);
}

double far_spectral_bound(const Model& m) {
  // Lanczos on A = M^-1/2 K M^-1/2 over the free axes, K = sum a b (K0 + k_m) d d^T at rest.
  // The largest Ritz value plus its residual |beta_j s_j| bounds the eigenvalue it converges to
  // from above; 40 iterations resolve the top of a lattice's spectrum to about 1 %.
  const int nn = m.num_nodes(), ns = m.num_springs();
  std::vector<double> w(3 * nn), q(3 * nn, 0.0), qprev(3 * nn, 0.0), y(3 * nn), kax(ns);
  std::vector<Vec3> dir(ns);
  for (const SpringGroup& g : m.groups) {
    const double k0 = (g.law ? g.law->k0() : g.card.hooke_k) + g.card.maxwell_k;
    for (int k = g.begin; k < g.end; ++k) {
      kax[k] = m.force_scale[k] * m.deflection_scale[k] * k0;
      const Vec3 u = m.rest[m.spring_j[k]] - m.rest[m.spring_i[k]];
      dir[k] = u / std::max(u.norm(), 1e-300);
    }
  }
  for (int i = 0; i < nn; ++i)
    for (int c = 0; c < 3; ++c) w[3 * i + c] = std::sqrt(m.inv_mass[i]) * m.free_axes[i][c];
  auto apply = [&](const std::vector<double>& x, std::vector<double>& out) {
    std::fill(out.begin(), out.end(), 0.0);
    for (int k = 0; k < ns; ++k) {
      const int i = 3 * m.spring_i[k], j = 3 * m.spring_j[k];
      const Vec3 xi(w[i] * x[i], w[i + 1] * x[i + 1], w[i + 2] * x[i + 2]);
      const Vec3 xj(w[j] * x[j], w[j + 1] * x[j + 1], w[j + 2] * x[j + 2]);
      const Vec3 f = kax[k] * dir[k].dot(xj - xi) * dir[k];
      for (int c = 0; c < 3; ++c) {
        out[i + c] -= f[c];
        out[j + c] += f[c];
      }
    }
    for (int t = 0; t < 3 * nn; ++t) out[t] *= w[t];
  };
  // Deterministic start with every mode present: a fixed pseudo-random vector.
  std::uint64_t seed = 0x9e3779b97f4a7c15ULL;
  double norm = 0;
  for (int t = 0; t < 3 * nn; ++t) {
    seed = seed * 6364136223846793005ULL + 1442695040888963407ULL;
    q[t] = (double(seed >> 11) / double(1ULL << 53) - 0.5) * (w[t] > 0);
    norm += q[t] * q[t];
  }
  if (!(norm > 0)) return 0;
  for (double& v : q) v /= std::sqrt(norm);
  constexpr int kIter = 40;
  std::vector<double> alpha, beta;
  double b = 0;
  for (int it = 0; it < kIter; ++it) {
    apply(q, y);
    double a = 0;
    for (int t = 0; t < 3 * nn; ++t) a += q[t] * y[t];
    for (int t = 0; t < 3 * nn; ++t) y[t] -= a * q[t] + b * qprev[t];
    alpha.push_back(a);
    double nb = 0;
    for (double v : y) nb += v * v;
    nb = std::sqrt(nb);
    beta.push_back(nb);
    if (!(nb > 1e-12 * std::abs(a))) break;
    qprev.swap(q);
    for (int t = 0; t < 3 * nn; ++t) q[t] = y[t] / nb;
    b = nb;
  }
  const int k = static_cast<int>(alpha.size());
  Eigen::MatrixXd T = Eigen::MatrixXd::Zero(k, k);
  for (int i = 0; i < k; ++i) {
    T(i, i) = alpha[i];
    if (i + 1 < k) T(i, i + 1) = T(i + 1, i) = beta[i];
  }
  Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd> eig(T);
  const double theta = eig.eigenvalues()(k - 1);
  const double residual = std::abs(beta[k - 1] * eig.eigenvectors()(k - 1, k - 1));
  return theta + residual;
}

}  // namespace conica
