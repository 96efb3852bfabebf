#include "lab/quasi_static.h"

#include <Eigen/Geometry>
#include <algorithm>
#include <chrono>
#include <cmath>
#include <limits>

#include "core/step.h"

namespace conica::lab {

namespace {
double out_of_balance(const Model& m, const Workspace& ws) {
  double r2 = 0;
  for (int i = 0; i < m.num_nodes(); ++i)
    r2 += ws.force[i].cwiseProduct(m.free_axes[i]).squaredNorm();
  return std::sqrt(r2);
}
}  // namespace

Curve quasi_static_curve(const Model& model, const LoadFn& load, const ReactionFn& reaction,
                         double travel, const QuasiStaticOptions& o, QuasiStaticStats* stats,
                         const IncrementFn& increment, const StopFn& stop) {
  Model m = model;
  SolverOptions& so = m.options;
  so.integrator = Integrator::kImplicitEuler;
  so.dt = o.dt;
  so.substeps = 1;
  so.newton_iterations = o.newton_iterations;
  so.cg_iterations = o.cg_iterations;
  so.cg_tolerance = o.cg_tolerance;
  so.mass_damping = 0;
  so.gravity.setZero();
  so.max_speed = std::numeric_limits<double>::infinity();
  so.active_region = false;
  so.bdf2 = false;                   // each step is one static Newton solve from rest: no history
  for (SpringGroup& g : m.groups) {  // elastic equilibrium: no rate terms
    g.card.damping = 0;
    g.card.maxwell_k = 0;
    g.card.maxwell_tau = 0;
  }
  State s = make_state(m);
  Workspace ws(m);
  QuasiStaticStats st;
  double f = 0;
  // Equilibrium at travel u from the current state; false when it does not settle.
  // Frictional plates: every iteration's return mapping starts from the stick points of the last
  // equilibrium, so what an iteration that has not converged does to them (a node that slides
  // only on its way) is not kept; the points are committed where the increment settles.
  std::vector<std::vector<Vec3>> stick(m.planes.size());
  bool stalled = false;  // the last settle_at stopped on a stall
  auto settle_at = [&](double u, double* rel) {
    load(m, s, u);
    for (size_t q = 0; q < m.planes.size(); ++q) stick[q] = s.planes[q].stick;
    double last = std::numeric_limits<double>::quiet_NaN();
    // The best settle value so far, by iteration: an increment whose best has not fallen by 1 %
    // in the last kStall iterations has stalled (a body drifting along a soft mode past its
    // stability limit, never settling); more iterations of the same would not settle it.
    constexpr int kStall = 50;
    std::vector<double> best;
    best.reserve(o.max_iterations);
    stalled = false;
    for (int it = 0; it < o.max_iterations; ++it) {
      std::fill(s.v.begin(), s.v.end(), Vec3::Zero());
      s.time = 0;
      for (size_t q = 0; q < m.planes.size(); ++q)
        std::copy(stick[q].begin(), stick[q].end(), s.planes[q].stick.begin());
      const auto t0 = std::chrono::steady_clock::now();
      step(m, s, ws);
      st.step_seconds +=
          std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
      ++st.steps;
      std::fill(s.v.begin(), s.v.end(), Vec3::Zero());
      compute_forces(m, s, ws);
      f = reaction(m, s, ws);
      *rel = o.settle == Settle::kOutOfBalance
                 ? out_of_balance(m, ws) / std::max(std::abs(f), 1e-30)
                 : std::abs(f - last) / std::max(std::abs(f), 1e-30);
      if (*rel <= o.tolerance) return true;
      last = f;
      best.push_back(std::min(*rel, best.empty() ? *rel : best.back()));
      if (it >= kStall && !(best[it] < 0.99 * best[it - kStall])) return stalled = true, false;
    }
    return false;
  };
  Curve out(o.samples + 1);
  std::vector<Vec3> prev = s.x, delta(m.num_nodes(), Vec3::Zero());
  double u_prev = 0;
  for (int j = 1; j <= o.samples; ++j) {
    const double u = travel * j / o.samples;
    const State saved = s;
    // Predictor: the last increment's displacement again.
    for (int i = 0; i < m.num_nodes(); ++i) s.x[i] += delta[i].cwiseProduct(m.free_axes[i]);
    double rel = std::numeric_limits<double>::infinity();
    bool settled = settle_at(u, &rel);
    // The attempt at the full travel u that ended nearest balance, kept when none settles (a
    // split that stops unsettled in an earlier part ends short of u).
    State nearest;
    double nearest_rel = rel, nearest_f = f;
    if (!settled) nearest = s;
    // Smaller parts while they help: a split that stalls no nearer balance than half the last
    // attempt's value (a body at a bifurcation, not a step too large for Newton) is the last.
    bool at_u = true;
    for (int parts = 2; !settled && parts <= o.max_parts; parts *= 2) {
      const double before = rel;
      s = saved;
      settled = true;
      // A part that stops near balance (within kQuasiStaticFailure) does not end the split: the
      // next part starts from it, so the attempt still reaches u.
      int k = 1;
      bool near = true;
      for (; k <= parts && near; ++k) {
        settled = settle_at(k == parts ? u : u_prev + (u - u_prev) * k / parts, &rel) && settled;
        near = rel <= kQuasiStaticFailure;
      }
      at_u = k > parts;
      if (!settled && at_u && rel < nearest_rel) {
        nearest = s;
        nearest_rel = rel;
        nearest_f = f;
      }
      if (!settled && stalled && !(rel < 0.5 * before)) break;
    }
    if (!settled && (!at_u || nearest_rel < rel)) {
      s = nearest;
      rel = nearest_rel;
      f = nearest_f;
    }
    if (!settled) ++st.unconverged;
    if (!settled && !(rel <= kQuasiStaticFailure) && st.failed_at < 0) st.failed_at = u;
    st.worst_residual = std::max(st.worst_residual, rel);
    out[j].displacement = u;
    out[j].force = f;
    if (increment) increment(m, s);
    for (int i = 0; i < m.num_nodes(); ++i) {
      delta[i] = s.x[i] - prev[i];
      prev[i] = s.x[i];
    }
    u_prev = u;
    st.increments = j;
    if (o.progress) o.progress(j, u, rel, settled, st.steps);
    if (o.stop_at_failure && st.failed_at >= 0) {
      out.resize(j + 1);
      break;
    }
    if (stop && stop()) break;
  }
  st.rollbacks = s.counters.rollbacks;
  st.hard_stops = s.counters.hard_stops;
  st.positions = s.x;
  if (stats) *stats = std::move(st);
  return out;
}

std::string bond_compression_plates(BodySpec* spec) {
  ensure_top_plate(spec);
  PlaneSpec& p = spec->planes.at(0);
  if (!(p.normal.norm() > 0)) return "plate 0: normal must be nonzero";
  const Vec3 n = p.normal.normalized();
  double lo = std::numeric_limits<double>::infinity(), hi = -lo;
  Vec3 bmin = Vec3::Constant(lo), bmax = -bmin;
  for (const Vec3& x : spec->mesh.nodes) {
    lo = std::min(lo, n.dot(x));
    hi = std::max(hi, n.dot(x));
    bmin = bmin.cwiseMin(x);
    bmax = bmax.cwiseMax(x);
  }
  if (spec->mesh.nodes.empty()) return "the body has no nodes";
  const double tol = 1e-6 * (bmax - bmin).norm();
  p.normal = n;
  p.offset = lo;  // on the face it bonds
  p.bonded = true;
  p.bond_tolerance = tol;
  FixedSelector base;
  base.kind = FixedSelector::Kind::kPlane;
  base.normal = n;
  base.offset = hi;
  base.tolerance = tol;
  base.axes = 7;
  spec->fixed.push_back(base);
  return {};
}

LoadFn plate_load(const Model& model) {
  const double start = model.planes.at(0).offset;
  return [start](const Model&, State& s, double u) { s.planes[0].offset = start + u; };
}

ReactionFn plate_reaction() {
  return [](const Model& m, const State& s, const Workspace&) {
    return -m.planes[0].normal.dot(s.planes[0].force);
  };
}

std::string add_flat_punch(BodySpec* spec, double radius, bool punch_bonded, bool base_bonded,
                           std::vector<int>* punch, double* area, PunchRule rule) {
  const auto& nodes = spec->mesh.nodes;
  if (nodes.empty()) return "the body has no nodes";
  if (!(radius > 0) || !std::isfinite(radius)) return "punch radius must be > 0 m";
  Vec3 lo = nodes[0], hi = lo;
  for (const Vec3& x : nodes) {
    lo = lo.cwiseMin(x);
    hi = hi.cwiseMax(x);
  }
  const double tol = 1e-6 * (hi - lo).norm();
  // The top face's bounding box centre in x, y.
  Vec3 tlo = Vec3::Constant(std::numeric_limits<double>::infinity()), thi = -tlo;
  for (const Vec3& x : nodes)
    if (x.z() >= hi.z() - tol) {
      tlo = tlo.cwiseMin(x);
      thi = thi.cwiseMax(x);
    }
  const Vec3 c = 0.5 * (tlo + thi);
  // Whole element faces on the top plane whose centre lies within the radius: the punch drives
  // every node of each, as the continuum reference drives its quadratic faces (fem_reference.h).
  // PunchRule::kNodes: the top nodes within the radius, the area that of the faces they drive
  // whole.
  auto within = [&](const Vec3& x) {
    return std::hypot(x.x() - c.x(), x.y() - c.y()) <= radius + tol;
  };
  std::vector<char> under(nodes.size(), 0);
  if (rule == PunchRule::kNodes)
    for (size_t i = 0; i < nodes.size(); ++i)
      under[i] = nodes[i].z() >= hi.z() - tol && within(nodes[i]);
  double covered = 0;
  auto face = [&](const int* f, int n) {
    Vec3 m = Vec3::Zero();
    bool all = true;
    for (int a = 0; a < n; ++a) {
      if (nodes[f[a]].z() < hi.z() - tol) return;
      m += nodes[f[a]];
      all = all && under[f[a]];
    }
    m /= n;
    if (rule == PunchRule::kNodes ? !all : !within(m)) return;
    const Vec3 &p0 = nodes[f[0]], &p1 = nodes[f[1]], &p2 = nodes[f[2]];
    covered += n == 3 ? 0.5 * (p1 - p0).cross(p2 - p0).norm()
                      : 0.5 * (p2 - p0).cross(nodes[f[3]] - p1).norm();
    for (int a = 0; a < n; ++a) under[f[a]] = 1;
  };
  for (const auto& h : spec->mesh.hexahedra)
    for (const auto& f : kHexFaces) {
      const int q[4] = {h[f[0]], h[f[1]], h[f[2]], h[f[3]]};
      face(q, 4);
    }
  for (const auto& t : spec->mesh.tetrahedra)
    for (const auto& f : kTetFaces) {
      const int q[3] = {t[f[0]], t[f[1]], t[f[2]]};
      face(q, 3);
    }
  punch->clear();
  for (int i = 0; i < static_cast<int>(nodes.size()); ++i)
    if (under[i]) punch->push_back(i);
  if (area) *area = covered;
  if (punch->empty())
    return rule == PunchRule::kNodes
               ? "no node of the top face lies under the punch (radius too small)"
               : "no face of the top lies under the punch (its centre farther than the radius "
                 "from the axis: radius smaller than half a cell?)";
  FixedSelector p;
  p.kind = FixedSelector::Kind::kNodes;
  p.nodes = *punch;
  p.axes = punch_bonded ? 7 : 4;
  spec->fixed.push_back(p);
  FixedSelector base;
  base.kind = FixedSelector::Kind::kPlane;
  base.normal = Vec3::UnitZ();
  base.offset = lo.z();
  base.tolerance = tol;
  base.axes = base_bonded ? 7 : 4;
  spec->fixed.push_back(base);
  if (!base_bonded) {
    // Against rigid motion in the base plane: the base node nearest the centre held in x and y,
    // the one nearest a point beside it in y.
    const Vec3 bc(c.x(), c.y(), lo.z());
    const Vec3 side = bc + Vec3(0.25 * (hi.x() - lo.x()), 0, 0);
    int a = -1, b = -1;
    double da = std::numeric_limits<double>::infinity(), db = da;
    for (int i = 0; i < static_cast<int>(nodes.size()); ++i) {
      if (nodes[i].z() > lo.z() + tol) continue;
      if ((nodes[i] - bc).norm() < da) {
        da = (nodes[i] - bc).norm();
        a = i;
      }
      if ((nodes[i] - side).norm() < db) {
        db = (nodes[i] - side).norm();
        b = i;
      }
    }
    FixedSelector pa, pb;
    pa.kind = pb.kind = FixedSelector::Kind::kNodes;
    pa.nodes = {a};
    pa.axes = 3;
    pb.nodes = {b};
    pb.axes = 2;
    spec->fixed.push_back(pa);
    if (b != a) spec->fixed.push_back(pb);
  }
  return {};
}

LoadFn punch_load(const std::vector<int>& punch) {
  return [punch](const Model& m, State& s, double u) {
    for (int i : punch) {
      s.x[i].z() = m.rest[i].z() - u;
      if (m.fixed[i] == 7) {
        s.x[i].x() = m.rest[i].x();
        s.x[i].y() = m.rest[i].y();
      }
    }
  };
}

ReactionFn punch_reaction(const std::vector<int>& punch) {
  return [punch](const Model&, const State&, const Workspace& ws) {
    double f = 0;
    for (int i : punch) f += ws.force[i].z();
    return f;
  };
}

std::string press_flat_punch(BodySpec spec, double radius, double depth, PunchRule rule,
                             PunchPress* out) {
  std::vector<int> punch;
  if (std::string e = add_flat_punch(&spec, radius, false, true, &punch, &out->area, rule);
      !e.empty())
    return e;
  Model m;
  if (std::string e = build_model(spec, &m); !e.empty()) return e;
  QuasiStaticOptions o;
  o.samples = 1;
  o.tolerance = 1e-6;
  QuasiStaticStats st;
  const Curve c = quasi_static_curve(m, punch_load(punch), punch_reaction(punch), depth, o, &st);
  if (st.unconverged) return "indentation did not converge";
  out->force = c.back().force;
  out->rest = m.rest;
  out->x = st.positions;
  return "";
}

}  // namespace conica::lab
