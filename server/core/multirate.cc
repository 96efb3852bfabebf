#include "core/multirate.h"

#include <Eigen/Dense>
#include <algorithm>
#include <cmath>
#include <limits>

#include "core/sparse_system.h"
#include "core/step.h"
#include "core/step_detail.h"

namespace conica {
static_assert(sizeof(Vec3) == 3 * sizeof(double), "a std::vector<Vec3> is 3 n contiguous doubles");

namespace {

// In-place LU with partial pivoting of the n x n row-major matrix a (leading dimension ld);
// false when singular.
bool lu_factor(double* a, int n, int ld, int* pivot) {
  for (int k = 0; k < n; ++k) {
    int p = k;
    double best = std::abs(a[k * ld + k]);
    for (int r = k + 1; r < n; ++r)
      if (std::abs(a[r * ld + k]) > best) best = std::abs(a[(p = r) * ld + k]);
    if (!(best > 0)) return false;
    pivot[k] = p;
    if (p != k)
      for (int c = 0; c < n; ++c) std::swap(a[k * ld + c], a[p * ld + c]);
    const double inv = 1.0 / a[k * ld + k];
    for (int r = k + 1; r < n; ++r) {
      const double l = a[r * ld + k] *= inv;
      if (l != 0)
        for (int c = k + 1; c < n; ++c) a[r * ld + c] -= l * a[k * ld + c];
    }
  }
  return true;
}

void lu_solve(const double* a, int n, int ld, const int* pivot, double* b) {
  for (int k = 0; k < n; ++k) std::swap(b[k], b[pivot[k]]);
  for (int r = 1; r < n; ++r) {
    double s = b[r];
    for (int c = 0; c < r; ++c) s -= a[r * ld + c] * b[c];
    b[r] = s;
  }
  for (int r = n - 1; r >= 0; --r) {
    double s = b[r];
    for (int c = r + 1; c < n; ++c) s -= a[r * ld + c] * b[c];
    b[r] = s / a[r * ld + r];
  }
}

// The region from the candidates in *near (squared distance, node): the closest first, at most
// lm's capacity, by node index, into lm->nodes and lm->x0; dx reset.
void finish_region(const std::vector<Vec3>& x, const Vec3& center,
                   std::vector<std::pair<double, int>>* near, LocalModel* lm) {
  const int num = std::min<int>(lm->capacity, static_cast<int>(near->size()));
  std::partial_sort(near->begin(), near->begin() + num, near->end());
  // By node index: the same nodes make the same region wherever the probe is among them (the
  // builder reuses W then).
  std::sort(near->begin(), near->begin() + num,
            [](const auto& a, const auto& b) { return a.second < b.second; });
  lm->num = num;
  lm->center0 = center;
  for (int a = 0; a < num; ++a) {
    lm->nodes[a] = (*near)[a].second;
    lm->x0[a] = x[lm->nodes[a]];
    lm->dx[a].setZero();  // a fresh model: the next answer starts from its base state
  }
  lm->fresh = true;
}

// The region of a probe at `center`: the free nodes within `reach` of it at positions x (near:
// scratch, reserved).
void choose_region(const Model& m, const std::vector<Vec3>& x, const Vec3& center, double reach,
                   std::vector<std::pair<double, int>>* near, LocalModel* lm) {
  near->clear();
  for (int i = 0; i < m.num_nodes(); ++i) {
    if (m.fixed[i] == 7) continue;
    const double d2 = (x[i] - center).squaredNorm();
    if (d2 < reach * reach) near->emplace_back(d2, i);
  }
  finish_region(x, center, near, lm);
}

// Surface contact's region around the tool at `pose`: the free nodes of the surface triangles
// that come within `reach` of it (near: scratch of three times the triangles, reserved).
void choose_surface_region(const Model& m, const std::vector<Vec3>& x, const Vec3& pose,
                           double reach, std::vector<std::pair<double, int>>* near,
                           LocalModel* lm) {
  near->clear();
  for (int t = 0; t < static_cast<int>(m.surface.size()); ++t) {
    const auto& f = m.surface[t];
    // Every point of the triangle is at least |x0 - pose| - (its longest edge from x0) away.
    const double e =
        std::sqrt(std::max((x[f[1]] - x[f[0]]).squaredNorm(), (x[f[2]] - x[f[0]]).squaredNorm()));
    if ((x[f[0]] - pose).norm() - e > reach || triangle_distance(m, x, t, pose) >= reach) continue;
    for (int i : f)
      if (m.fixed[i] != 7) near->emplace_back((x[i] - pose).squaredNorm(), i);
  }
  // Each node once (a node is shared by the triangles around it).
  std::sort(near->begin(), near->end(),
            [](const auto& a, const auto& b) { return a.second < b.second; });
  near->erase(std::unique(near->begin(), near->end(),
                          [](const auto& a, const auto& b) { return a.second == b.second; }),
              near->end());
  finish_region(x, pose, near, lm);
}

// The layer's force (and lumped blocks) of surface probe k with its tool at the proxy of p, over
// the triangles `tris` at positions x, into force / block (added; the caller zeroes them); the
// tool's side into *tool when given (its stiffness when `terms` asks for it).
void layer_forces(const Model& m, int k, const ProbeState& p, const std::vector<Vec3>& x,
                  const std::vector<int>& tris, Vec3* force, Mat3* block, Mat3* pair = nullptr,
                  ToolContact* tool = nullptr, unsigned terms = kToolForceOnly) {
  ToolContact c;
  if (!tool) tool = &c;
  *tool = ToolContact{};
  if (!p.active || !p.proxy_placed) return;
  tool_contact(m, k, probe_radius(m, k, p), p.proxy, x, tris.data(), static_cast<int>(tris.size()),
               tool, force, block, terms, nullptr, pair);
}

// The lists of 3 x 3 blocks per region node that LocalModel keeps (coupled, held): node `owner`'s
// list (kMaxCoupled entries from owner * kMaxCoupled, count[owner] in use) holds the nodes it is
// coupled with. The slot of `member` in it: its entry, or the next free one; -1 when full.
int coupling_slot(const std::vector<int>& count, const std::vector<int>& node, int owner,
                  int member) {
  const int base = owner * LocalModel::kMaxCoupled;
  for (int e = 0; e < count[owner]; ++e)
    if (node[base + e] == member) return e;
  return count[owner] < LocalModel::kMaxCoupled ? count[owner] : -1;
}

// Adds K to `member`'s block in `owner`'s list at `slot` (coupling_slot), appending it if new.
void add_coupling(std::vector<int>& count, std::vector<int>& node, std::vector<Mat3>& blocks,
                  int owner, int slot, int member, const Mat3& K) {
  const int at = owner * LocalModel::kMaxCoupled + slot;
  if (slot == count[owner]) {
    node[at] = member;
    blocks[at] = K;
    ++count[owner];
  } else {
    blocks[at] += K;
  }
}

}  // namespace

void warm_start(const LocalModel& last, const std::vector<Vec3>& served, LocalModel* fresh) {
  if (!fresh->fresh) return;
  int j = 0;  // both regions are sorted by node index (finish_region)
  for (int a = 0; a < fresh->num; ++a) {
    const int i = fresh->nodes[a];
    while (j < last.num && last.nodes[j] < i) ++j;
    if (j < last.num && last.nodes[j] == i) {
      const Vec3 d = served[i] - fresh->x0[a];
      if (std::isfinite(d.squaredNorm())) fresh->dx[a] = d;
    }
  }
}

LocalModel::LocalModel(int cap)
    : capacity(cap),
      nodes(cap, -1),
      x0(cap, Vec3::Zero()),
      f0(cap, Vec3::Zero()),
      b0(cap, Mat3::Zero()),
      w(9 * static_cast<size_t>(cap) * cap, 0.0),
      winv(9 * static_cast<size_t>(cap) * cap, 0.0),
      f(cap, Vec3::Zero()),
      dx(cap, Vec3::Zero()),
      dx_last(cap, Vec3::Zero()),
      step(cap, Vec3::Zero()),
      dfdc(cap, Mat3::Zero()),
      jac(9 * static_cast<size_t>(cap) * cap, 0.0),
      rhs(3 * static_cast<size_t>(cap), 0.0),
      g(12 * static_cast<size_t>(cap), 0.0),
      wdx(3 * static_cast<size_t>(cap), 0.0),
      pivot(4 * static_cast<size_t>(cap), 0),
      coupled_count(cap, 0),
      coupled_node(static_cast<size_t>(kMaxCoupled) * cap, -1),
      coupled(static_cast<size_t>(kMaxCoupled) * cap, Mat3::Zero()),
      held_count(cap, 0),
      held_node(static_cast<size_t>(kMaxCoupled) * cap, -1),
      held(static_cast<size_t>(kMaxCoupled) * cap, Mat3::Zero()),
      hb(cap, Vec3::Zero()),
      u_free(cap, Vec3::Zero()),
      wu(3 * static_cast<size_t>(cap), 0.0) {}

SurfaceScratch::SurfaceScratch(const Model& m)
    : candidates(m.probes.size(), ContactCandidates(m)),
      force(m.num_nodes(), Vec3::Zero()),
      block(m.num_nodes(), Mat3::Zero()),
      pair(6 * m.surface.size(), Mat3::Zero()),
      region(m.num_nodes(), -1) {}

LocalModelBuilder::LocalModelBuilder(const Model& m)
    : factor_(std::make_unique<SystemFactor>(m, SystemFactor::Kind::kSupernodal)),
      held_(m.probes.size(), std::vector<Mat3>(m.num_nodes(), Mat3::Zero())),
      held_next_(held_),
      held_pairs_(m.probes.size()),
      region_of_(m.num_nodes(), -1),
      layer_force_(m.num_nodes(), Vec3::Zero()),
      regions_(m.probes.size()) {
  for (HeldPairs& h : held_pairs_) {
    h.tris.assign(m.surface.size(), -1);
    h.pair.assign(6 * m.surface.size(), Mat3::Zero());
  }
  held_pairs_next_ = held_pairs_;
  if (m.options.exact_compliance && (m.bulk_modulus > 0 || m.shear_modulus > 0) &&
      !m.tetrahedra.empty()) {
    exact_ = std::make_unique<SystemFactor>(m, SystemFactor::Kind::kSupernodal);
    exact_next_ = std::make_unique<SystemFactor>(m, SystemFactor::Kind::kSupernodal);
  }
  near_.reserve(std::max(m.num_nodes(), 3 * static_cast<int>(m.surface.size())));
}

LocalModelBuilder::~LocalModelBuilder() = default;

SystemFactor* LocalModelBuilder::last(Workspace& ws) {
  return ws.factor && ws.factor->current->kind() == SystemFactor::Kind::kSupernodal
             ? ws.factor->current.get()
             : current_.get();
}

bool LocalModelBuilder::begin_refactor(const Model& m, State& s, Workspace& ws) {
  if (pending_.load(std::memory_order_acquire) != kNone) return false;
  // The system of the body's next step (BDF2: of its 2 / 3 step once the state has the last one).
  const double h = detail::implicit_h(m, s);
  detail::prepare_system_at(m, s, ws, h);
  factor_->assemble(m, ws);
  // W's own factor: the tetrahedra's element terms with their exact Hessians, so that W is the
  // response a converged body step gives ((1) in haptic_contact); the Gauss-Newton factor above
  // stays the body's preconditioner (the exact one, handed over, took the liver's CG from 4.3 to
  // 11.6 iterations per Newton iteration). Where the exact tangent is not positive definite, W
  // comes from the Gauss-Newton factor.
  if (exact_next_) exact_next_->assemble(m, ws, &s.x);
  for (size_t k = 0; k < m.probes.size(); ++k) {  // what the contact stage put in the system
    const ProbeState& p = s.probes[k];
    std::vector<Mat3>& held = held_next_[k];
    if (m.probes[k].contact == ContactModel::kSurface) {  // the layer's faces' pair blocks
      std::fill(held.begin(), held.end(), Mat3::Zero());
      HeldPairs& hp = held_pairs_next_[k];
      hp.num = 0;
      for (int t = 0; t < ws.contact.num_pairs; ++t) {
        if (ws.contact.pair_probe[t] != static_cast<int>(k)) continue;
        const Mat3* K = ws.contact.pair.data() + 6 * t;
        const auto& tri = m.surface[ws.contact.pair_tris[t]];
        for (int a = 0; a < 3; ++a) held[tri[a]] += K[a];
        hp.tris[hp.num] = ws.contact.pair_tris[t];
        std::copy(K, K + 6, hp.pair.begin() + 6 * hp.num);
        ++hp.num;
      }
      continue;
    }
    const double R = probe_radius(m, static_cast<int>(k), p), kc = m.probes[k].stiffness;
    for (int i = 0; i < m.num_nodes(); ++i) {
      Vec3 f, dir;
      Mat3 dfdc;
      held[i] = p.active && node_contact(s.x[i], m.normal[i], p.center, R, kc, &f, &dfdc, &dir)
                    ? Mat3(kc * dir * dir.transpose())
                    : Mat3::Zero();
    }
  }
  pending_.store(kAssembled, std::memory_order_release);
  return true;
}

void LocalModelBuilder::factor_pending() {
  if (pending_.load(std::memory_order_acquire) != kAssembled) return;
  const bool ok = factor_->factorize();
  exact_next_ok_ = ok && exact_next_ && exact_next_->factorize();
  pending_.store(ok ? kFactored : kFailed, std::memory_order_release);
}

int LocalModelBuilder::finish_refactor(const Model& m, Workspace& ws) {
  const int state = pending_.load(std::memory_order_acquire);
  if (state == kNone || state == kAssembled) return 0;
  pending_.store(kNone, std::memory_order_release);
  if (state == kFailed) {  // the factor in hand (if any) stays: it still describes its system
    ++failures_;
    return -1;
  }
  generation_ = ++factorizations_;
  std::swap(held_, held_next_);
  std::swap(held_pairs_, held_pairs_next_);
  std::swap(exact_, exact_next_);
  exact_ok_ = exact_next_ok_;
  // The fresh factor is the best preconditioner the body's next step can have (kFactorCG): hand
  // it over and keep the one it had as the next scratch.
  if (ws.factor) {
    std::swap(ws.factor->current, factor_);
    ws.factor->wanted = false;
    ws.factor->age = 0;
    if (factor_->kind() != SystemFactor::Kind::kSupernodal)  // the first hand-over only
      factor_ = std::make_unique<SystemFactor>(m, SystemFactor::Kind::kSupernodal);
  } else {
    std::swap(current_, factor_);
    if (!factor_) factor_ = std::make_unique<SystemFactor>(m, SystemFactor::Kind::kSupernodal);
  }
  return 1;
}

bool LocalModelBuilder::refactor(const Model& m, State& s, Workspace& ws) {
  if (!begin_refactor(m, s, ws)) return false;
  factor_pending();
  return finish_refactor(m, ws) > 0;
}

bool LocalModelBuilder::build(const Model& m, const State& s, Workspace& ws, int k, double margin,
                              LocalModel* lm) {
  lm->valid = false;
  lm->num = 0;
  if (generation_ == 0) return false;
  const int nn = m.num_nodes();
  const ProbeState& p = s.probes[k];
  const Vec3 c = p.center;
  const double R = probe_radius(m, k, p), kc = m.probes[k].stiffness;
  const bool surface = m.probes[k].contact == ContactModel::kSurface;
  if (surface) {
    choose_surface_region(m, s.x, p.proxy_placed ? p.proxy : c, R + margin, &near_, lm);
    lm->center0 = c;
    std::fill(layer_force_.begin(), layer_force_.end(), Vec3::Zero());
    layer_forces(m, k, p, s.x, ws.contact.candidates[k].triangles, layer_force_.data(), nullptr);
  } else {
    choose_region(m, s.x, c, R + margin, &near_, lm);
  }
  const int num = lm->num;
  lm->h = detail::substep_of(m);
  for (int a = 0; a < num; ++a) {
    const int i = lm->nodes[a];
    Vec3 f, dir;
    Mat3 dfdc;
    if (surface)
      lm->f0[a] = layer_force_[i];
    else
      lm->f0[a] = p.active && node_contact(s.x[i], m.normal[i], c, R, kc, &f, &dfdc, &dir)
                      ? f
                      : Vec3::Zero();
    lm->b0[a] = held_[k][i];
    lm->held_count[a] = 0;
  }
  if (surface) {  // B0's face couplings within the region (dx is zero outside it)
    for (int a = 0; a < num; ++a) region_of_[lm->nodes[a]] = a;
    const HeldPairs& hp = held_pairs_[k];
    constexpr int kA[3] = {0, 0, 1}, kB[3] = {1, 2, 2};
    for (int t = 0; t < hp.num; ++t) {
      const auto& tri = m.surface[hp.tris[t]];
      for (int j = 0; j < 3; ++j) {
        const int ra = region_of_[tri[kA[j]]], rb = region_of_[tri[kB[j]]];
        const Mat3& K = hp.pair[6 * t + 3 + j];
        if (ra < 0 || rb < 0 || K.squaredNorm() == 0) continue;
        const int eab = coupling_slot(lm->held_count, lm->held_node, ra, rb),
                  eba = coupling_slot(lm->held_count, lm->held_node, rb, ra);
        if (eab < 0 || eba < 0) {  // no room (a node on more faces than a surface has): lumped
          lm->b0[ra] += K;
          lm->b0[rb] += K;
          continue;
        }
        add_coupling(lm->held_count, lm->held_node, lm->held, ra, eab, rb, K);
        add_coupling(lm->held_count, lm->held_node, lm->held, rb, eba, ra, K);
      }
    }
    for (int a = 0; a < num; ++a) region_of_[lm->nodes[a]] = -1;
  }
  // W_RR = h^2 A^-1 restricted to the region: the region's unit vectors solved at once (their
  // solves on a fixed axis give zero), unless the same region has them from the same factor.
  Region& reg = regions_[k];
  const int n3 = 3 * num, ld = 3 * lm->capacity, n = 3 * nn;
  const bool same = reg.generation == generation_ && reg.num == num &&
                    std::equal(lm->nodes.begin(), lm->nodes.begin() + num, reg.nodes.begin());
  if (!same) {
    reg.w.resize(static_cast<size_t>(n3) * n3);
    (exact_ok_ ? exact_.get() : last(ws))->inverse_block(lm->nodes.data(), num, reg.w.data(), n3);
    const double hs = detail::implicit_h(m, s), h2 = hs * hs;
    for (double& v : reg.w) v *= h2;
    // W^-1 on the free axes (a fixed axis has a zero row and column in W), for the joint
    // solve's energy (haptic_contact).
    std::vector<int> free_axes;
    for (int r = 0; r < n3; ++r)
      if (reg.w[static_cast<size_t>(r) * n3 + r] > 0) free_axes.push_back(r);
    const int nf = static_cast<int>(free_axes.size());
    Eigen::MatrixXd wf(nf, nf);
    for (int r = 0; r < nf; ++r)
      for (int c = 0; c < nf; ++c)
        wf(r, c) = 0.5 * (reg.w[static_cast<size_t>(free_axes[r]) * n3 + free_axes[c]] +
                          reg.w[static_cast<size_t>(free_axes[c]) * n3 + free_axes[r]]);
    const Eigen::MatrixXd wfi =
        nf > 0 ? Eigen::MatrixXd(wf.ldlt().solve(Eigen::MatrixXd::Identity(nf, nf)))
               : Eigen::MatrixXd();
    reg.winv.assign(static_cast<size_t>(n3) * n3, 0.0);
    for (int r = 0; r < nf; ++r)
      for (int c = 0; c < nf; ++c)
        reg.winv[static_cast<size_t>(free_axes[r]) * n3 + free_axes[c]] = wfi(r, c);
    reg.generation = generation_;
    reg.num = num;
    reg.nodes.assign(lm->nodes.begin(), lm->nodes.begin() + num);
    ++solves_;
  }
  for (int row = 0; row < n3; ++row) {
    std::copy(reg.w.begin() + static_cast<size_t>(row) * n3,
              reg.w.begin() + static_cast<size_t>(row + 1) * n3, lm->w.begin() + row * ld);
    std::copy(reg.winv.begin() + static_cast<size_t>(row) * n3,
              reg.winv.begin() + static_cast<size_t>(row + 1) * n3, lm->winv.begin() + row * ld);
  }
  // The region's free motion over the next body step: A^-1 h M v (the momentum the body carries,
  // no force changed; W / h^2 = A^-1), one solve of the whole body. Without it the answers
  // between hand-overs pushed a region at rest where the body's nodes were moving on, and rose
  // 2.8 times as steeply as the converged body's in the liver's early press, a sawtooth at the
  // body's rate that each hand-over cut back (docs/performance.md).
  // A BDF2 step (backward Euler of step h' = 2h / 3 from x^, v^; core/implicit.cc) moves the body
  // by A^-1 M ((1 + h' mu) (x^ - x) + h' v^) with no force changed (A is its system).
  for (int a = 0; a < num; ++a) lm->u_free[a].setZero();
  if (num > 0) {
    r_.assign(static_cast<size_t>(n), 0.0);
    z_.resize(std::max(z_.size(), static_cast<size_t>(n)));
    const bool bdf2 = detail::bdf2_step(m, s);
    const double hs = detail::implicit_h(m, s), mfac = 1 + hs * m.options.mass_damping;
    for (int i = 0; i < nn; ++i) {
      const Vec3 xh = bdf2 ? detail::bdf2_start_shift(s, i) : Vec3::Zero();
      const Vec3 vh = bdf2 ? detail::bdf2_start_velocity(s, i) : s.v[i];
      for (int c = 0; c < 3; ++c) r_[c * nn + i] = m.mass[i] * (mfac * xh[c] + hs * vh[c]);
    }
    (exact_ok_ ? exact_.get() : last(ws))->solve_many(r_.data(), z_.data(), 1);
    for (int a = 0; a < num; ++a)
      for (int c = 0; c < 3; ++c) lm->u_free[a][c] = z_[c * nn + lm->nodes[a]];
  }
  lm->ticks = 0;
  lm->valid = true;
  return true;
}

double tissue_share_stiffness(const Model& m) {
  std::vector<double> l(m.rest_length);
  if (l.empty()) return 0;
  std::nth_element(l.begin(), l.begin() + l.size() / 2, l.end());
  return m.contact_modulus * l[l.size() / 2];
}

void estimate_local_model(const Model& m, const std::vector<Vec3>& x, int k, const Vec3& center,
                          double radius, double margin, double kt,
                          std::vector<std::pair<double, int>>* near, LocalModel* lm) {
  if (m.probes[k].contact == ContactModel::kSurface)
    choose_surface_region(m, x, center, radius + margin, near, lm);
  else
    choose_region(m, x, center, radius + margin, near, lm);
  const int num = lm->num;
  lm->valid = false;  // an estimate, not a body step's model
  const int ld = 3 * lm->capacity;
  for (int a = 0; a < num; ++a) {
    lm->f0[a].setZero();
    lm->b0[a].setZero();
    lm->held_count[a] = 0;
  }
  for (int r = 0; r < 3 * num; ++r)
    for (int c = 0; c < 3 * num; ++c) {
      const int i = lm->nodes[r / 3];
      lm->w[r * ld + c] = r == c && m.free_axes[i][r % 3] > 0 && kt > 0 ? 1.0 / kt : 0.0;
      lm->winv[r * ld + c] = r == c && m.free_axes[i][r % 3] > 0 && kt > 0 ? kt : 0.0;
    }
}

bool refactor_due(const SolverOptions& o, bool factored, int steps_since, double cg_per_newton,
                  bool rolled_back) {
  if (!factored || rolled_back) return true;
  if (o.refactor_every > 0 && steps_since >= o.refactor_every) return true;
  if (cg_per_newton < 0) return o.refactor_every == 0;  // no CG count to ask: every step
  return cg_per_newton > o.refactor_iterations;
}

bool step_body(const Model& body, const SolverOptions& served, State& s, Workspace& ws,
               LocalModelBuilder& builder, int* since_factor, bool defer) {
  if (defer && builder.finish_refactor(body, ws) != 0) *since_factor = 0;
  const Counters c0 = s.counters;
  step(body, s, ws);
  // With kFactorCG the factor in hand preconditions CG, and CG's count says how well it still
  // describes the body; block-Jacobi CG's count says nothing about it.
  const double cg = ws.factor ? static_cast<double>(s.counters.cg_iterations - c0.cg_iterations) /
                                    std::max<std::uint64_t>(
                                        1, s.counters.newton_iterations - c0.newton_iterations)
                              : -1.0;
  if (!refactor_due(served, builder.factored(), ++*since_factor, cg,
                    s.counters.rollbacks != c0.rollbacks) ||
      builder.pending())
    return false;
  if (defer && builder.factored()) return builder.begin_refactor(body, s, ws);
  *since_factor = 0;
  return builder.refactor(body, s, ws);
}

int ticks_per_body_step(const Model& served) {
  const double r = 1.0 / (served.options.dt * served.options.body_rate_hz);
  return std::max(1, static_cast<int>(std::lround(r)));
}

Model body_model(const Model& served) {
  Model b = served;
  b.options.dt = served.options.dt * ticks_per_body_step(served);
  b.options.refactor_every = 0;
  b.options.refactor_iterations = std::numeric_limits<int>::max();
  // The tick solves the proxy against the body's predicted positions, jointly with the local
  // model; a body step that moved it again, against its own positions at the step's start and
  // with the nodes held, would press a whole body step's travel into the layer at once.
  for (ProbeSpec& p : b.probes) p.hold_proxy = p.contact == ContactModel::kSurface;
  return b;
}

void prime_workspace(Workspace& ws) {
  if (ws.factor) ws.factor->wanted = false;
}

void haptic_contact(const Model& m, LocalModel& lm, int k, const Vec3& center, double radius,
                    ProbeState* probe, std::vector<Vec3>* x, SurfaceScratch* surface) {
  constexpr int kMaxNewton = 20;
  // Surface contact: at most this many layer evaluations per solve of (1) (each one integrates
  // the layer over the tool's candidate triangles, tens of microseconds), so a tick stays bounded
  // where Newton is slow; the solve then ends on the best iterate found (one more evaluation
  // restores that iterate's forces when the last backtracking fails). 8 rather than 16: the
  // phantom's per-tick bench (1e-4 R tolerance) tick CPU p99 / max 579-601 / 1,552-1,583 us ->
  // 355-435 / 608-655 us, per-tick RMS against the body solved every tick 0.795 -> 0.817 %.
  // A fresh model's two solves share the budget (at most half of it for the first).
  // (LocalModel::layer_budget: 8.)
  const int max_layer_evaluations = lm.layer_budget;
  int evaluations = 0;
  // The base state moves on by its free motion (LocalModel::u_free), in proportion to the time
  // since the hand-over: (1) becomes R = dx - frac u_free - W [f - f0 + B0 dx], the energy below
  // gains -(W^-1 frac u_free) . dx.
  // At most one body step of it; a model handed over late (LocalModel::ticks < 0) moves none.
  const double frac =
      lm.valid && lm.h > 0 ? std::clamp(lm.ticks * m.options.dt / lm.h, 0.0, 1.0) : 0.0;
  ++lm.ticks;
  const int num = lm.num, n3 = 3 * num, ld = 3 * lm.capacity;
  const bool layer = m.probes[k].contact == ContactModel::kSurface && x && surface;
  probe->center = center;
  probe->active = true;
  if (radius > 0) probe->radius = radius;
  const double R = layer ? probe_radius(m, k, *probe) : radius > 0 ? radius : m.probes[k].radius;
  const double kc = m.probes[k].stiffness;
  int* act = lm.pivot.data() + 3 * lm.capacity;  // the active nodes (in contact now or at x0)
  int* piv = lm.pivot.data();
  int na = 0;
  for (int a = 0; a < num; ++a)  // (a non-finite start, which a failed solve could leave: 0)
    if (!std::isfinite(lm.dx[a].squaredNorm())) lm.dx[a].setZero();

  ContactCandidates* cand = layer ? &surface->candidates[k] : nullptr;
  ToolContact tool;                      // the layer's side of the tool at the last evaluation
  bool pairs_complete = false;           // the last evaluation's pair blocks all in the region
  unsigned tool_terms = kToolForceOnly;  // the joint solve asks for the tool's stiffness
  if (layer)  // the region's indices by node, for the layer's pair blocks (reset on the way out)
    for (int a = 0; a < num; ++a) surface->region[lm.nodes[a]] = a;
  // f and dfdc = df/dx at x0 + dx: the node law, or the layer at the held proxy (dfdc = -B, its
  // lumped blocks; the region's positions x0 + dx go into x, where the layer reads them).
  auto forces = [&]() {
    if (layer) {
      for (int a = 0; a < num; ++a) {
        const int i = lm.nodes[a];
        (*x)[i] = lm.x0[a] + lm.dx[a];
        surface->force[i].setZero();
        surface->block[i].setZero();
      }
      for (int t : cand->triangles)
        for (int i : m.surface[t]) {
          surface->force[i].setZero();
          surface->block[i].setZero();
        }
      ++evaluations;
      const int nt = static_cast<int>(cand->triangles.size());
      std::fill(surface->pair.begin(), surface->pair.begin() + 6 * nt, Mat3::Zero());
      layer_forces(m, k, *probe, *x, cand->triangles, surface->force.data(), surface->block.data(),
                   surface->pair.data(), &tool, tool_terms);
      for (int a = 0; a < num; ++a) {
        lm.f[a] = surface->force[lm.nodes[a]];
        lm.dfdc[a] = -surface->block[lm.nodes[a]];
        lm.coupled_count[a] = 0;
      }
      // The pair blocks, column by column over the region (a pair with a corner outside it, or
      // past a column's room, stays in the lumped diagonal instead: a slower Newton, same answer).
      constexpr int kPairs[6][2] = {{0, 0}, {1, 1}, {2, 2}, {0, 1}, {0, 2}, {1, 2}};
      auto couple = [&](int row, int col, const Mat3& K) {
        const int slot = coupling_slot(lm.coupled_count, lm.coupled_node, col, row);
        if (slot < 0) return false;
        add_coupling(lm.coupled_count, lm.coupled_node, lm.coupled, col, slot, row, K);
        return true;
      };
      bool complete = true;
      for (int q = 0; q < nt && complete; ++q) {
        const auto& tri = m.surface[cand->triangles[q]];
        for (int j = 0; j < 6 && complete; ++j) {
          const Mat3& K = surface->pair[6 * q + j];
          if (K.squaredNorm() == 0) continue;
          const int ra = surface->region[tri[kPairs[j][0]]],
                    rb = surface->region[tri[kPairs[j][1]]];
          if (ra < 0 || rb < 0) {
            complete = false;
            break;
          }
          complete = couple(ra, rb, K) && (ra == rb || couple(rb, ra, K));
        }
      }
      // B_a = d f_a / d p: the row sums of the pair blocks, which carry the sphere's curvature
      // term besides the pressure term of the lumped blocks (tool_contact's node_pair), so that
      // the joint Newton matrix is the Jacobian of the terms it keeps.
      pairs_complete = complete;
      if (complete)
        for (int a = 0; a < num; ++a) {
          Mat3 sum = Mat3::Zero();
          const int base = a * LocalModel::kMaxCoupled;
          for (int e = 0; e < lm.coupled_count[a]; ++e) sum += lm.coupled[base + e];
          lm.dfdc[a] = -sum;
        }
      if (!complete)  // the lumped blocks alone
        for (int a = 0; a < num; ++a) {
          lm.coupled_count[a] = 1;
          lm.coupled_node[a * LocalModel::kMaxCoupled] = a;
          lm.coupled[a * LocalModel::kMaxCoupled] = -lm.dfdc[a];
        }
      return;
    }
    for (int a = 0; a < num; ++a) {
      Vec3 dir;
      if (!node_contact(lm.x0[a] + lm.dx[a], m.normal[lm.nodes[a]], center, R, kc, &lm.f[a],
                        &lm.dfdc[a], &dir)) {
        lm.f[a].setZero();
        lm.dfdc[a].setZero();
      }
    }
  };
  // The forces and the active set at x0 + dx; R = dx - W [f - f0 + B0 dx] into lm.rhs (only the
  // active nodes carry a nonzero bracket); returns |R|_inf.
  auto residual = [&]() {
    forces();
    for (int a = 0; a < num; ++a) {  // B0 dx
      Vec3 v = lm.b0[a] * lm.dx[a];
      const int base = a * LocalModel::kMaxCoupled;
      for (int e = 0; e < lm.held_count[a]; ++e)
        v += lm.held[base + e] * lm.dx[lm.held_node[base + e]];
      lm.hb[a] = v;
    }
    na = 0;
    for (int a = 0; a < num; ++a)
      if (lm.f[a].squaredNorm() > 0 || lm.dfdc[a].squaredNorm() > 0 || lm.f0[a].squaredNorm() > 0 ||
          lm.b0[a].squaredNorm() > 0)
        act[na++] = a;
    double worst = 0;
    for (int row = 0; row < n3; ++row) {
      double s = 0;
      for (int t = 0; t < na; ++t) {
        const int b = act[t];
        const Vec3 q = lm.f[b] - lm.f0[b] + lm.hb[b];
        const double* wr = &lm.w[row * ld + 3 * b];
        s += wr[0] * q[0] + wr[1] * q[1] + wr[2] * q[2];
      }
      lm.rhs[row] = lm.dx[row / 3][row % 3] - frac * lm.u_free[row / 3][row % 3] - s;
      worst = std::max(worst, std::abs(lm.rhs[row]));
    }
    return worst;
  };
  // (W Q)_{row, active column}, Q = B0 + df/dx: the node law's dfdc (its node force depends on
  // x - c only), the layer's -K over the nodes it couples.
  auto wq = [&](int row, int t, int cb) {
    const int b = act[t];
    const double* wr = &lm.w[row * ld + 3 * b];
    const int base = b * LocalModel::kMaxCoupled;
    double s = 0;
    for (int e = 0; e < lm.held_count[b]; ++e) {  // B0's face couplings (symmetric blocks)
      const double* we = &lm.w[row * ld + 3 * lm.held_node[base + e]];
      const Mat3& K = lm.held[base + e];
      s += we[0] * K(0, cb) + we[1] * K(1, cb) + we[2] * K(2, cb);
    }
    if (!layer) {
      const Mat3 q = lm.b0[b] + lm.dfdc[b];
      return s + wr[0] * q(0, cb) + wr[1] * q(1, cb) + wr[2] * q(2, cb);
    }
    const Mat3& q0 = lm.b0[b];
    s += wr[0] * q0(0, cb) + wr[1] * q0(1, cb) + wr[2] * q0(2, cb);
    for (int e = 0; e < lm.coupled_count[b]; ++e) {
      const double* we = &lm.w[row * ld + 3 * lm.coupled_node[base + e]];
      const Mat3& K = lm.coupled[base + e];
      s -= we[0] * K(0, cb) + we[1] * K(1, cb) + we[2] * K(2, cb);
    }
    return s;
  };
  // J = I - W Q has identity columns off the active set: LU of its active block J_AA in jac.
  auto factor_jacobian = [&]() {
    const int n = 3 * na;
    for (int r = 0; r < n; ++r)
      for (int c = 0; c < n; ++c)
        lm.jac[r * ld + c] = (r == c ? 1.0 : 0.0) - wq(3 * act[r / 3] + r % 3, c / 3, c % 3);
    return lu_factor(lm.jac.data(), n, ld, piv);
  };
  // Every row's step from the active block's d_A (and the proxy's step dp, surface contact):
  // rhs_r = -R_r + (W Q)_{rA} d_A + (W B)_r dp, as W v with the node vectors v = Q_A d_A + B dp
  // (lm.step holds v), O((3 |R|)^2) instead of a (W Q) product per entry.
  auto region_step = [&](const double* dA, const Vec3& dp) {
    for (int a = 0; a < num; ++a) lm.step[a].setZero();
    for (int q = 0; q < na; ++q) {
      const int b = act[q];
      const Vec3 db(dA[3 * q], dA[3 * q + 1], dA[3 * q + 2]);
      const int hbase = b * LocalModel::kMaxCoupled;
      for (int e = 0; e < lm.held_count[b]; ++e)
        lm.step[lm.held_node[hbase + e]] += lm.held[hbase + e] * db;
      if (!layer) {
        lm.step[b] += (lm.b0[b] + lm.dfdc[b]) * db;
        continue;
      }
      lm.step[b] += lm.b0[b] * db - lm.dfdc[b] * dp;
      const int base = b * LocalModel::kMaxCoupled;
      for (int e = 0; e < lm.coupled_count[b]; ++e)
        lm.step[lm.coupled_node[base + e]] -= lm.coupled[base + e] * db;
    }
    for (int row = 0; row < n3; ++row) {
      const double* wr = &lm.w[row * ld];
      double sum = -lm.rhs[row];
      for (int a = 0; a < num; ++a)
        sum += wr[3 * a] * lm.step[a][0] + wr[3 * a + 1] * lm.step[a][1] +
               wr[3 * a + 2] * lm.step[a][2];
      lm.rhs[row] = sum;
    }
  };

  // The node law's Newton converges quadratically, to round-off; the layer's (its lumped blocks
  // in J) linearly, so it stops where the force is settled. The device force is the proxy's
  // coupling, which the region's last few digits barely move: on the phantom's press-hold-slide
  // (bench_multirate --per-tick), stopping at 1e-4 R instead of 1e-7 R changes the per-tick force
  // by 0.014 % RMS (0.1 % at most) and leaves the error against the converged body (0.795 % RMS)
  // as it was, while the tick's CPU p99 falls from 1.49-1.84 ms to 0.58-0.60 ms
  // (docs/performance.md).
  const double layer_tol = lm.layer_tolerance;  // of the tool radius, of node motion (1e-4)
  const double tol = (layer ? layer_tol : 1e-9) * std::max(R, 1e-6);
  double res = 0;
  int it = 0;
  double* d = lm.g.data();  // the active block's step (3 na <= 3 capacity)
  // With no node active (no force at dx nor at the base state), (1) is R = dx - frac u_free and
  // its answer dx = frac u_free: taken at once, so that a region started away from it (a fresh
  // model's warm start, warm_start) follows the body instead of staying where it was while the
  // node law's Newton has no active row to move it by (the joint solve steps its proxy row).
  auto settle_free = [&]() {
    if (na > 0 || res <= tol) return;
    for (int a = 0; a < num; ++a) lm.dx[a] = frac * lm.u_free[a];
    res = residual();
  };
  // Newton on (1) from the current dx.
  int budget = max_layer_evaluations;
  auto solve = [&]() {
    evaluations = 0;
    res = n3 > 0 ? residual() : 0;
    settle_free();
    for (it = 0; it < kMaxNewton && res > tol && na > 0; ++it) {
      if (layer && evaluations >= budget) break;
      if (!factor_jacobian()) break;
      // J d = -R: the active rows by the LU, then each other row d_r = -R_r + (W Q)_{rA} d_A.
      for (int r = 0; r < 3 * na; ++r) d[r] = -lm.rhs[3 * act[r / 3] + r % 3];
      lu_solve(lm.jac.data(), 3 * na, ld, piv, d);
      region_step(d, Vec3::Zero());  // the step of every row (the active ones reproduce d)
      // Backtracking: the full step, or halves of it until the residual falls (the node law: the
      // smallest tried if none does; the layer: the last iterate, and the solve ends there).
      for (int a = 0; a < num; ++a) {
        lm.dx_last[a] = lm.dx[a];
        lm.step[a] = Vec3(lm.rhs[3 * a], lm.rhs[3 * a + 1], lm.rhs[3 * a + 2]);
      }
      const double res0 = res;
      double alpha = 1;
      bool fell = false;
      for (int tries = 0; tries < 8; ++tries, alpha *= 0.5) {
        if (layer && evaluations >= budget) break;
        for (int a = 0; a < num; ++a) lm.dx[a] = lm.dx_last[a] + alpha * lm.step[a];
        res = residual();
        if ((fell = res < res0)) break;
      }
      if (layer && !fell) {
        for (int a = 0; a < num; ++a) lm.dx[a] = lm.dx_last[a];
        res = residual();  // the forces and active set of the iterate kept
        break;
      }
    }
  };
  // Surface contact, frictionless and unbonded: the proxy p and the region solved together, (1)
  // and the proxy's equilibrium R_p = F_c(p - t) - F_l(p, x) = 0 (F_c the coupling's force at the
  // device target t, F_l the layer's push on the tool), by Newton on the Schur complement in p.
  // The layer's forces depend on x - p only, so d f_a / d p = B_a (the row sum of the pair
  // blocks) and d R_p / d x_a = -B_a^T:
  //   [ J        -W B ] [dx]   [-R_x]
  //   [ -B^T  H - K_l ] [dp] = [-R_p],   J = I - W Q (as above), H the coupling's Hessian,
  // K_l the layer's stiffness for the tool with the nodes held. The pair blocks carry the
  // pressure term sum p' n n^T and the sphere's curvature term -sum p / r (I - n n^T), and K_l
  // their sum (the tool's exact stiffness), so that the Newton matrix is the Hessian of the
  // energy below less the faces' turning under the tool. The curvature term is what a slide
  // needs: without it (the pressure term alone, a positive definite matrix) the phantom's
  // per-tick bench took 8 evaluations on 55 ticks of its slide (bench_multirate
  // BENCH_TICK_BY_EVALUATIONS), with it at most 6 anywhere. Where a pair block falls outside the
  // region, B and K_l keep the pressure term alone. With u = J^-1 (-R_x), Y = J^-1 (-W B):
  //   S dp = -R_p + B^T u,  S = H - K_l + B^T Y,  dx = u - Y dp,
  // three more solves with J's factor per iteration. S is the proxy's stiffness with the region
  // giving way as (1) says: the device's stiffness dF/dt = H (S^-1 H - I) (H (H - K_l)^-1 K_l when
  // W = 0, the nodes held). Solved alone, as update_proxy then (1) with the proxy held once a tick,
  // the two chase each other over tens of ticks (the proxy sees a layer stiffer than the body
  // under it): a lift at 10 mm/s read 14 % below the quasi-static response (docs/contact.md).
  const double g_stop = 0.9 * kContactDepthFraction * R;
  Vec3 rp = Vec3::Zero();  // R_p
  Mat3 S = Mat3::Zero();   // the Schur complement of the last factored iterate
  bool have_s = false;
  double* wu = lm.wu.data();
  auto joint_solve = [&]() {
    evaluations = 0;
    tool_terms = kToolAll;
    const Coupling link = coupling(m, k, R);
    const Vec3 t = probe->center;
    // Depth: at most the proxy update's depth plus its rate (the update bounds a tick's sinking).
    const double g_limit = std::min(g_stop, probe->depth + kProxyDepthRate * R);
    const double max_dp = 0.05 * R;  // m, a Newton step's proxy move at most
    res = residual();
    settle_free();
    const double kpp = link.k + std::max(0.0, -tool.stiffness_psd.trace() / 3);
    for (int row = 0; row < n3; ++row) {
      double z = 0;
      if (frac > 0)
        for (int c = 0; c < n3; ++c) z += lm.winv[row * ld + c] * frac * lm.u_free[c / 3][c % 3];
      wu[row] = z;
    }
    auto merit = [&]() {
      rp = link.force(probe->proxy - t) - tool.force;
      return std::max(res, rp.cwiseAbs().maxCoeff() / kpp);
    };
    double mer = merit();
    // The joint system is the stationarity of the energy
    //   Pi(dx, p) = 1/2 dx^T (W^-1 - B0) dx + f0^T dx + E_l(x0 + dx, p) + E_c(p - t)
    // (its gradient is W^-1 R_x in dx and R_p in p), and the Newton matrix premultiplied by
    // diag(W^-1, I) is its Hessian with the layer's pair blocks (less the faces' turning): each
    // step where that matrix is positive definite is a descent direction for Pi, backtracked
    // until Pi falls enough (Armijo); a step that is not (slope >= 0) ends the solve. A merit on
    // the residuals instead stalled (measured when the pair blocks held the pressure term
    // alone): what they leave out is, with the region's large motion against a small proxy
    // step, the leading error of R_p.
    // After residual() (tool holds the layer at this iterate); leaves W^-1 dx in lm.wdx, what
    // the next step's slope starts from.
    auto energy = [&]() {
      double e = tool.energy + link.energy(probe->proxy - t);
      for (int row = 0; row < n3; ++row) e -= wu[row] * lm.dx[row / 3][row % 3];
      const double* dxf = reinterpret_cast<const double*>(lm.dx.data());  // 3 num entries
      for (int row = 0; row < n3; ++row) {
        const double* wi = &lm.winv[row * ld];
        double z = 0;
        for (int c = 0; c < n3; ++c) z += wi[c] * dxf[c];
        lm.wdx[row] = z;
        e += 0.5 * dxf[row] * z;
      }
      for (int q = 0; q < na; ++q) {
        const int a = act[q];
        e += lm.f0[a].dot(lm.dx[a]) - 0.5 * lm.dx[a].dot(lm.hb[a]);
      }
      return e;
    };
    double pi = energy();     // (wu: W^-1 times the base state's free motion so far, below)
    double* u = lm.g.data();  // then the three columns of Y, each ld long
    // At the current iterate: J's factor, u, Y, S and the right-hand side of S dp.
    Vec3 rhs_p;
    auto schur = [&]() {
      const int n = 3 * na;
      if (na > 0 && !factor_jacobian()) return false;
      for (int r = 0; r < n; ++r) u[r] = -lm.rhs[3 * act[r / 3] + r % 3];
      if (n > 0) lu_solve(lm.jac.data(), n, ld, piv, u);
      for (int cc = 0; cc < 3; ++cc) {
        double* y = u + (cc + 1) * ld;
        for (int r = 0; r < n; ++r) {
          const int row = 3 * act[r / 3] + r % 3;
          double sum = 0;
          for (int q = 0; q < na; ++q) {  // (W B)_{row, cc}, B_b = -dfdc_b
            const int b = act[q];
            const double* wr = &lm.w[row * ld + 3 * b];
            sum -=
                wr[0] * lm.dfdc[b](0, cc) + wr[1] * lm.dfdc[b](1, cc) + wr[2] * lm.dfdc[b](2, cc);
          }
          y[r] = -sum;
        }
        if (n > 0) lu_solve(lm.jac.data(), n, ld, piv, y);
      }
      // S = H - K_l + B^T Y and the right-hand side -R_p + B^T u.
      const Mat3 H = link.hessian(probe->proxy - t);
      Mat3 Jpp = H - (pairs_complete ? tool.stiffness : tool.stiffness_psd);
      S = Jpp;
      rhs_p = -rp;
      for (int q = 0; q < na; ++q) {
        const Mat3 Bt = -lm.dfdc[act[q]].transpose();
        for (int cc = 0; cc < 3; ++cc)
          S.col(cc) += Bt * Vec3(u[(cc + 1) * ld + 3 * q], u[(cc + 1) * ld + 3 * q + 1],
                                 u[(cc + 1) * ld + 3 * q + 2]);
        rhs_p += Bt * Vec3(u[3 * q], u[3 * q + 1], u[3 * q + 2]);
      }
      return have_s = true;
    };
    for (it = 0; it < kMaxNewton && mer > tol && evaluations < budget; ++it) {
      const int n = 3 * na;
      if (!schur()) break;
      const Eigen::PartialPivLU<Mat3> lu(S);
      Vec3 dp = lu.solve(rhs_p);
      if (!std::isfinite(dp.squaredNorm())) break;
      if (dp.norm() > max_dp) dp *= max_dp / dp.norm();
      // The region's step: d_A = u - Y dp, then every row d_r = -R_r + (W Q)_{rA} d_A + (W B)_r dp.
      for (int r = 0; r < n; ++r)
        for (int cc = 0; cc < 3; ++cc) u[r] -= u[(cc + 1) * ld + r] * dp[cc];
      region_step(u, dp);
      for (int a = 0; a < num; ++a) {
        lm.dx_last[a] = lm.dx[a];
        lm.step[a] = Vec3(lm.rhs[3 * a], lm.rhs[3 * a + 1], lm.rhs[3 * a + 2]);
      }
      // Pi's slope along the step: (W^-1 dx - B0 dx + f0 - f) . d + R_p . dp.
      double slope = rp.dot(dp);
      for (int row = 0; row < n3; ++row) slope -= wu[row] * lm.rhs[row];
      for (int row = 0; row < n3; ++row) slope += lm.wdx[row] * lm.rhs[row];
      for (int q = 0; q < na; ++q) {
        const int a = act[q];
        slope += (lm.f0[a] - lm.f[a] - lm.hb[a]).dot(lm.step[a]);
      }
      const Vec3 p_last = probe->proxy;
      const double pi0 = pi, mer0 = mer;
      double alpha = 1;
      bool fell = false;
      for (int tries = 0; tries < 10 && evaluations < budget && slope < 0; ++tries, alpha *= 0.5) {
        for (int a = 0; a < num; ++a) lm.dx[a] = lm.dx_last[a] + alpha * lm.step[a];
        probe->proxy = p_last + alpha * dp;
        res = residual();
        pi = energy();
        mer = merit();
        // Pi falls enough, or (near the answer, where Pi's change is below the layer
        // quadrature's rounding) the residuals fall.
        if ((fell = (pi <= pi0 + 1e-4 * alpha * slope || mer < mer0) &&
                    (tool.depth <= g_limit || tool.depth <= probe->depth)))
          break;
      }
      if (!fell) {
        for (int a = 0; a < num; ++a) lm.dx[a] = lm.dx_last[a];
        probe->proxy = p_last;
        res = residual();
        pi = energy();
        mer = merit();
        break;
      }
    }
    // The device's stiffness needs S: at the start when no step was taken (the answer held).
    if (it == 0) schur();
    tool_terms = kToolForceOnly;
  };
  const bool joint = layer && m.probes[k].friction == 0 && !m.probes[k].bonded;
  Vec3 last_proxy = probe->proxy;
  if (layer) {
    // Surface contact: the proxy moves first, against the nodes where the last answer left them
    // (update_proxy: its jumps, placement, swept crossings and depth rate), then (1) is solved
    // with it, jointly with the proxy where the tool is frictionless and unbonded, else with the
    // proxy held (a one-tick stagger, as in the single-rate step). A fresh model (a body step
    // just handed over) starts at the body's state, which is in equilibrium with the proxy the
    // body step held, not with the proxy of the last tick: the region is first solved against
    // the last tick's proxy, so that the proxy moves against the nodes the last answer would have
    // left under this model, not against a body a whole body step behind.
    if (lm.fresh && probe->proxy_placed) {
      budget = max_layer_evaluations / 2;
      solve();
      budget = std::max(max_layer_evaluations / 2, max_layer_evaluations - evaluations);
    }
    for (int a = 0; a < num; ++a) (*x)[lm.nodes[a]] = lm.x0[a] + lm.dx[a];
    last_proxy = probe->proxy;
    update_proxy(m, k, *x, cand, probe);
  }
  lm.fresh = false;
  const int evaluations_before = evaluations;
  // An estimate (lm.valid false: W a diagonal guess, no body step's model within reach) keeps the
  // proxy held: solving it jointly against a guessed compliance buys no accuracy, and the soak's
  // churning client, answered from estimates almost every tick, paid 12 -> 67 us of tick CPU at
  // p50 for it (bench_multirate --churn).
  const bool jointly = joint && lm.valid && probe->active && probe->proxy_placed;
  lm.proxy_fallback = false;
  if (jointly) {
    const Vec3 updated = probe->proxy, velocity = probe->proxy_velocity;
    joint_solve();
    const Coupling link = coupling(m, k, R);
    const Vec3 e = probe->proxy - probe->center;
    // A joint solve that ran out of its evaluations far from the proxy's equilibrium (the layer
    // pushing on the tool much harder or softer than the coupling pulls) would serve the
    // coupling's force at a proxy the region has moved into or away from: on the fine liver in
    // real time (before warm_start), a hand-over tick whose first solve took most of the budget
    // left the region 0.16 mm into a proxy at the device's target and served 0.18 N where the
    // ticks around it served 0.97 N. The proxy is moved instead as a held-proxy tick moves it,
    // against the region as the solve left it (its depth rate, swept crossings, the coupling's
    // force and stiffness from the proxy's own equilibrium): nearer the converged answer
    // (SurfaceMultirateTest.AJointSolveCutShortMovesTheProxyAlone: 2.7 against 5.5 N, converged
    // 1.0 N, for a 0.6 mm jump in one tick with 4 evaluations).
    const double f_scale = std::max(tool.force.norm(), link.force(e).norm());
    if (tool.faces > 0 && rp.norm() > lm.joint_fallback * f_scale &&
        rp.norm() > lm.joint_fallback * 1e-2 * link.k * R) {
      lm.proxy_fallback = true;
      update_proxy(m, k, *x, cand, probe);
    } else {
      // The device's side at the joint answer: the coupling's force, its stiffness with the
      // region giving way, the tool's depth and faces; the proxy's velocity (a motion, not a
      // jump: the update's) and the surface point it rides on from here.
      probe->force = link.force(e);
      probe->depth = tool.depth;
      probe->contacts = tool.faces;
      probe->stiffness.setZero();
      if (have_s && tool.faces > 0) {
        const Mat3 H = link.hessian(e) + 1e-9 * link.k * Mat3::Identity();
        probe->stiffness = H * (S.partialPivLu().solve(H) - Mat3::Identity());
      } else if (tool.faces > 0) {
        probe->stiffness = link.device_stiffness(e, tool.stiffness);
      }
      const double dt = m.options.dt;
      if ((velocity * dt - (updated - last_proxy)).norm() <= 1e-9 * R + 1e-12 &&
          velocity.squaredNorm() > 0)
        probe->proxy_velocity = (probe->proxy - last_proxy) / dt;
      anchor_proxy(m, *x, cand->triangles.data(), static_cast<int>(cand->triangles.size()),
                   kCandidateReach * R, probe);
    }
  } else {
    solve();
  }
  lm.newton_iterations = it;
  lm.layer_evaluations = evaluations_before + evaluations;
  lm.residual = res;
  // Surface contact: the device has the coupling force and stiffness of the joint answer (or of
  // the proxy's update where the proxy was held), and x the region at x0 + dx (the last
  // evaluation wrote it: both solves end on their final iterate).
  if (layer) {
    for (int a = 0; a < num; ++a) surface->region[lm.nodes[a]] = -1;
    return;
  }

  probe->force.setZero();
  probe->stiffness.setZero();
  probe->contacts = 0;
  for (int a = 0; a < num; ++a) {
    probe->force -= lm.f[a];
    if (lm.f[a].squaredNorm() > 0) ++probe->contacts;
  }
  // Stiffness dF/dc = sum_a dfdc_a (I - G_a), G = dx/dc = -J^-1 W S, S the stacked dfdc (the
  // node force depends on x - c, so df/dc = -dfdc and dR/dc = W S); dfdc is zero off the active
  // set, so only G_A is needed: J_AA G_A = -(W S)_A.
  if (na > 0 && probe->contacts > 0 && factor_jacobian()) {
    const int n = 3 * na;
    for (int cc = 0; cc < 3; ++cc) {
      double* col = d + cc * ld;
      for (int r = 0; r < n; ++r) {
        const int row = 3 * act[r / 3] + r % 3;
        double s = 0;
        for (int t = 0; t < na; ++t) {
          const int b = act[t];
          const double* wr = &lm.w[row * ld + 3 * b];
          s += wr[0] * lm.dfdc[b](0, cc) + wr[1] * lm.dfdc[b](1, cc) + wr[2] * lm.dfdc[b](2, cc);
        }
        col[r] = -s;
      }
      lu_solve(lm.jac.data(), n, ld, piv, col);
    }
    for (int t = 0; t < na; ++t) {
      Mat3 G;
      for (int r = 0; r < 3; ++r)
        for (int cc = 0; cc < 3; ++cc) G(r, cc) = d[cc * ld + 3 * t + r];
      probe->stiffness += lm.dfdc[act[t]] * (Mat3::Identity() - G);
    }
  }
  if (x)
    for (int a = 0; a < num; ++a) (*x)[lm.nodes[a]] = lm.x0[a] + lm.dx[a];
}

double joint_proxy_step(const Model& held, const Model& free, int k, State* s, Workspace* ws,
                        int iterations, double tol) {
  std::unique_ptr<Workspace> own;
  if (!ws) {
    own = std::make_unique<Workspace>(held);
    ws = own.get();
  }
  const State start = *s;
  const Vec3 target = start.probes[k].center;
  const double R = probe_radius(free, k, start.probes[k]);
  const Coupling link = coupling(free, k, R);
  // The step holding the proxy at p into *out, and the proxy's residual there, R_p(p) =
  // F_c(p - t) - F_l(p, x(p)): the coupling's force less the layer's push on the tool.
  auto residual = [&](const Vec3& p, State* out) {
    *out = start;
    out->probes[k].proxy = p;
    out->probes[k].proxy_placed = true;
    out->probes[k].anchor = -1;
    step(held, *out, *ws);
    ToolContact tool;
    tool_contact(free, k, R, p, out->x, nullptr, 0, &tool, nullptr, nullptr, kToolForceOnly);
    return Vec3(link.force(p - target) - tool.force);
  };
  // The plain step (the proxy where *s holds it), then the proxy's update against the nodes it
  // leaves: the first guess, and the placement of a proxy not yet placed.
  State end = start;
  {
    step(held, end, *ws);
    ProbeState& r = end.probes[k];
    r.center = target;
    r.anchor = -1;
    update_proxy(free, k, end.x, nullptr, &r, 64);
    if (!r.active || !r.proxy_placed) {
      *s = end;
      return 0;
    }
  }
  Vec3 p = end.probes[k].proxy;
  const double e = 1e-6 * R;  // m, the difference step
  State scratch;
  Vec3 rp = residual(p, &end);
  for (int it = 0; it < iterations && rp.norm() > tol * link.k; ++it) {
    Mat3 J;
    for (int a = 0; a < 3; ++a)
      J.col(a) =
          (residual(p + e * Vec3::Unit(a), &scratch) - residual(p - e * Vec3::Unit(a), &scratch)) /
          (2 * e);
    Vec3 dp = J.partialPivLu().solve(-rp);
    if (!std::isfinite(dp.squaredNorm())) break;
    if (dp.norm() > 0.1 * R) dp *= 0.1 * R / dp.norm();
    bool fell = false;
    for (int tries = 0; tries < 20 && !fell; ++tries, dp *= 0.5) {
      const Vec3 r = residual(p + dp, &scratch);
      if ((fell = r.norm() < rp.norm())) {
        p += dp;
        rp = r;
        std::swap(end, scratch);
      }
    }
    if (!fell) break;
  }
  // The probe as the served tick leaves it: the coupling's force at the joint answer.
  ProbeState& q = end.probes[k];
  q.center = target;
  q.proxy = p;
  q.force = link.force(p - target);
  ToolContact tool;
  tool_contact(free, k, R, p, end.x, nullptr, 0, &tool, nullptr, nullptr, kToolForceOnly);
  q.depth = tool.depth;
  q.contacts = tool.faces;
  *s = end;
  return rp.norm() / link.k;
}

}  // namespace conica
