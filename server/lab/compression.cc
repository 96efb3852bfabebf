#include "lab/compression.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <limits>
#include <map>
#include <memory>

#include "core/multirate.h"
#include "core/stability.h"
#include "core/step.h"
#include "lab/quasi_static.h"

namespace conica::lab {
namespace {

// Spread of n.x over the rest nodes: {min, max}.
std::pair<double, double> extent(const Model& m, const Vec3& n) {
  double lo = std::numeric_limits<double>::infinity(), hi = -lo;
  for (const Vec3& x : m.rest) {
    lo = std::min(lo, n.dot(x));
    hi = std::max(hi, n.dot(x));
  }
  return {lo, hi};
}

// Linear interpolation of y(x) at xq on ascending x; clamped at the ends.
double interpolate(const std::vector<double>& x, const std::vector<double>& y, double xq) {
  if (xq <= x.front()) return y.front();
  if (xq >= x.back()) return y.back();
  const auto it = std::upper_bound(x.begin(), x.end(), xq);
  const size_t j = static_cast<size_t>(it - x.begin());
  const double t = (xq - x[j - 1]) / (x[j] - x[j - 1]);
  return y[j - 1] + t * (y[j] - y[j - 1]);
}

}  // namespace

void cut_at_failure(Curve* curve, double failed_at) {
  if (failed_at < 0) return;
  while (curve->size() > 1 && curve->back().displacement >= failed_at) curve->pop_back();
}

bool ensure_top_plate(BodySpec* spec) {
  if (!spec->planes.empty()) return false;
  double top = -std::numeric_limits<double>::infinity();
  for (const Vec3& x : spec->mesh.nodes) top = std::max(top, x.z());
  PlaneSpec p;
  p.normal = -Vec3::UnitZ();
  p.offset = -top;  // {-z >= -top}: below the top
  spec->planes.push_back(p);
  return true;
}

double plate_height(const Model& model) {
  const auto [lo, hi] = extent(model, model.planes.at(0).normal);
  return hi - lo;
}

double rigid_plate_stiffness(const Model& m, bool with_maxwell) {
  double k_mean = 0;
  for (const SpringGroup& g : m.groups) {
    const double k0 = g.card.k0() + (with_maxwell ? g.card.maxwell_k : 0.0);
    for (int k = g.begin; k < g.end; ++k) k_mean += m.force_scale[k] * m.deflection_scale[k] * k0;
  }
  k_mean /= std::max(1, m.num_springs());
  double k_plate = 1e4 * k_mean;
  if (m.options.integrator != Integrator::kImplicitEuler) {
    // Explicit steps: the penalty must keep omega h <= 1 on the lightest node it touches.
    double m_min = std::numeric_limits<double>::infinity();
    for (int i = 0; i < m.num_nodes(); ++i)
      if (m.mass[i] > 0) m_min = std::min(m_min, m.mass[i]);
    const double h = m.options.dt / m.options.substeps;
    k_plate = std::min(k_plate, m_min / (h * h));
  }
  return k_plate;
}

double cross_section(const Model& model) { return body_volume(model) / plate_height(model); }

namespace {
// Rest centroid and the projector onto the plane normal to plane 0 (its axis through it).
struct Axis {
  Vec3 centroid = Vec3::Zero();
  Mat3 lateral = Mat3::Identity();
};
Axis body_axis(const Model& model) {
  Axis a;
  for (int i = 0; i < model.num_nodes(); ++i) a.centroid += model.rest[i];
  a.centroid /= std::max(1, model.num_nodes());
  const Vec3 n = model.planes.at(0).normal;
  a.lateral -= n * n.transpose();
  return a;
}
}  // namespace

double layer_spread(const Model& model, const std::vector<Vec3>& x) {
  const Axis a = body_axis(model);
  const Vec3 n = model.planes.at(0).normal;
  std::map<long, double> outer;  // rest height (um) -> largest distance from the axis
  for (int i = 0; i < model.num_nodes(); ++i) {
    double& r = outer[std::lround(n.dot(model.rest[i]) * 1e6)];
    r = std::max(r, (a.lateral * (x[i] - a.centroid)).norm());
  }
  double lo = std::numeric_limits<double>::infinity(), hi = 0;
  for (const auto& [h, r] : outer) {
    lo = std::min(lo, r);
    hi = std::max(hi, r);
  }
  return outer.empty() ? 0.0 : hi - lo;
}

namespace {

// What a compression run reports of itself (CompressionStats) from its final state.
void fill_stats(const Model& m, const std::vector<Vec3>& x, const Counters& counters,
                double plate_stiffness, double dt, double max_pen, long steps, double step_time,
                CompressionStats* stats) {
  stats->steps = steps;
  stats->dt = dt;
  stats->plate_stiffness = plate_stiffness;
  stats->max_penetration = max_pen;
  stats->rollbacks = counters.rollbacks;
  stats->hard_stops = counters.hard_stops;
  stats->step_seconds = steps ? step_time / static_cast<double>(steps) : 0;
  stats->positions = x;
  stats->layer_spread = layer_spread(m, x);
  const Axis a = body_axis(m);
  stats->half_width = 0;
  for (const Vec3& r : m.rest)
    stats->half_width = std::max(stats->half_width, (a.lateral * (r - a.centroid)).norm());
}

}  // namespace

Curve compression_curve(const Model& model, double rate, double to_strain, int samples,
                        CompressionStats* stats, bool served) {
  const bool multirate = served && model.options.body_rate_hz > 0;
  Model m = multirate ? body_model(model) : model;
  PlaneSpec& plate = m.planes.at(0);
  const Vec3 n = plate.normal;
  const auto [lo, hi] = extent(m, n);
  const double travel = to_strain * (hi - lo);

  // A rigid plate: penalty well above the springs' axial stiffness.
  plate.stiffness = std::max(plate.stiffness, rigid_plate_stiffness(m, false));

  State s = make_state(m);
  s.planes[0].offset = lo;  // touching the body's top
  Workspace ws(m);
  std::unique_ptr<LocalModelBuilder> builder;
  int since_factor = 0;
  if (multirate) {
    builder = std::make_unique<LocalModelBuilder>(m);
    prime_workspace(ws);
  }
  const double dt = m.options.dt;
  const long steps = std::max(1L, static_cast<long>(std::ceil(travel / (rate * dt) - 1e-9)));
  std::vector<double> u(steps + 1, 0.0), f(steps + 1, 0.0);
  double max_pen = 0, step_time = 0, failed = -1;
  for (long k = 1; k <= steps; ++k) {
    s.planes[0].offset = lo + std::min(travel, rate * dt * static_cast<double>(k));
    const auto t0 = std::chrono::steady_clock::now();
    if (multirate)
      step_body(m, model.options, s, ws, *builder, &since_factor);
    else
      step(m, s, ws);
    step_time += std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
    compute_forces(m, s, ws);  // the reaction at the end-of-step positions
    u[k] = s.planes[0].offset - lo;
    f[k] = -n.dot(s.planes[0].force);
    double pen = 0;
    for (const Vec3& x : s.x) pen = std::max(pen, s.planes[0].offset - n.dot(x));
    max_pen = std::max(max_pen, pen);
    if (failed < 0 && (s.counters.rollbacks > 0 || pen > kBlowUpPenetration * (hi - lo)))
      failed = u[k];
  }
  Curve out(samples + 1);
  for (int i = 0; i <= samples; ++i) {
    out[i].displacement = travel * i / samples;
    out[i].force = interpolate(u, f, out[i].displacement);
  }
  if (stats) {
    fill_stats(m, s.x, s.counters, plate.stiffness, dt, max_pen, steps, step_time, stats);
    stats->failed_at = failed;
  }
  return out;
}

namespace {

// The static compression's set-up, shared by static_compression_curve and
// compression_equilibria: plane 0 of *m made a rigid plate at first contact (returns the body's
// height along it, m), and the quasi-static settings: each increment's equilibrium to a steady
// reaction (`tolerance`) by inexact Newton steps, at most max_steps steps of dt_s.
double rigid_plate_at_contact(Model* m) {
  PlaneSpec& plate = m->planes.at(0);
  const auto [lo, hi] = extent(*m, plate.normal);
  plate.stiffness = std::max(plate.stiffness, rigid_plate_stiffness(*m, false));
  plate.offset = lo;  // first contact
  return hi - lo;
}

QuasiStaticOptions static_options(const Model& m, int samples, double tolerance, int max_steps,
                                  double dt_s) {
  QuasiStaticOptions o;
  o.samples = samples;
  o.settle = Settle::kReactionSteady;
  o.tolerance = tolerance;
  o.max_iterations = max_steps;
  o.dt = dt_s;
  // Inexact Newton: each solve is repeated until the force settles, so a step need not be exact.
  o.newton_iterations = 2;
  o.cg_iterations = std::max(m.options.cg_iterations, 100);
  o.cg_tolerance = std::max(m.options.cg_tolerance, 1e-4);
  return o;
}

}  // namespace

Curve static_compression_curve(const Model& model, double to_strain, int samples,
                               CompressionStats* stats, double tolerance, int max_steps,
                               double dt_s) {
  Model m = model;
  const double height = rigid_plate_at_contact(&m);
  const QuasiStaticOptions o = static_options(m, samples, tolerance, max_steps, dt_s);
  double max_pen = 0;
  QuasiStaticStats qs;
  const Curve out = quasi_static_curve(
      m, plate_load(m), plate_reaction(), to_strain * height, o, &qs,
      [&max_pen](const Model& mm, const State& s) {
        for (const Vec3& x : s.x)
          max_pen = std::max(max_pen, s.planes[0].offset - mm.planes[0].normal.dot(x));
      });
  if (stats) {
    Counters c;
    c.rollbacks = qs.rollbacks;
    c.hard_stops = qs.hard_stops;
    fill_stats(m, qs.positions, c, m.planes[0].stiffness, dt_s, max_pen, qs.steps, qs.step_seconds,
               stats);
  }
  return out;
}

CompressionEquilibria compression_equilibria(const Model& model, double to_strain, int samples) {
  Model m = model;
  const double height = rigid_plate_at_contact(&m);
  // The static compression's settings (a steady reaction to 1e-5, at most 15 steps of 1 s): close
  // enough for the sign of the stiffness's eigenvalues at the onset's resolution (one increment),
  // and minutes faster than balancing every node to 1e-4 on a body near its limit.
  const QuasiStaticOptions o = static_options(m, samples, 1e-5, 15, 1.0);
  CompressionEquilibria out;
  int increment = 0;
  quasi_static_curve(
      m, plate_load(m), plate_reaction(), to_strain * height, o, nullptr,
      [&](const Model& mm, const State& s) {
        const double strain = to_strain * ++increment / samples;
        const EquilibriumStability e = equilibrium_stability(mm, s);
        ++out.checked;
        out.factored = out.factored && e.factored;
        if (e.factored && e.negative > 0) {
          out.unstable_at = strain;
          out.modes = e.negative;
        } else if (e.factored) {
          out.stable_to = strain;
        }
      },
      [&out] { return out.unstable_at >= 0; });  // the first onset is the answer
  return out;
}

std::string make_uniaxial_cell(const std::vector<SpringGroupSpec>& groups, Mapping mapping,
                               double side, Model* cell, double bulk_modulus, double shear_modulus,
                               double shear_stiffening) {
  BodySpec spec;
  spec.mesh = make_box_lattice(Vec3(side, side, side), {1, 1, 1});
  spec.density = 1000;
  spec.groups = groups;
  for (auto& g : spec.groups) {
    if (!g.regions.empty()) return "spring group \"" + g.name + "\" selects regions: no cell model";
    g.card.damping = 0;  // quasi-static: no rate effects
    g.card.maxwell_k = 0;
    g.card.maxwell_tau = 0;
  }
  spec.mapping = mapping;
  spec.bulk_modulus = bulk_modulus;
  spec.shear_modulus = shear_modulus;
  spec.shear_stiffening = shear_stiffening;
  SolverOptions& o = spec.options;
  o.integrator = Integrator::kImplicitEuler;
  o.dt = 1.0;  // long step: each implicit step is a Newton step on the static equilibrium
  o.newton_iterations = 1;
  o.cg_iterations = 100;
  o.cg_tolerance = 1e-13;
  o.mass_damping = 0;
  o.max_speed = 1e9;
  FixedSelector base, top, pin, pin2;
  base.kind = top.kind = FixedSelector::Kind::kPlane;
  base.offset = 0;
  top.offset = side;
  base.tolerance = top.tolerance = 1e-9 * side;
  base.axes = top.axes = 4;  // z
  // Nodes 0 (0,0,0), 4 (0,0,s) held in x, y; 1 (s,0,0), 5 (s,0,s) in y: no rigid motion, and the
  // plates neither slide nor turn against each other.
  pin.kind = pin2.kind = FixedSelector::Kind::kNodes;
  pin.nodes = {0, 4};
  pin.axes = 3;
  pin2.nodes = {1, 5};
  pin2.axes = 2;
  spec.fixed = {base, top, pin, pin2};
  return build_model(spec, cell);
}

std::vector<double> cell_stress_curve(const Model& cell, const std::vector<double>& strains) {
  State s = make_state(cell);
  Workspace ws(cell);
  Vec3 lo = cell.rest[0], hi = cell.rest[0];
  for (const Vec3& x : cell.rest) {
    lo = lo.cwiseMin(x);
    hi = hi.cwiseMax(x);
  }
  const Vec3 size = hi - lo;
  std::vector<int> top, right;
  for (int i = 0; i < cell.num_nodes(); ++i) {
    if (cell.rest[i].z() > hi.z() - 1e-9 * size.z()) top.push_back(i);
    if (cell.rest[i].x() > hi.x() - 1e-9 * size.x()) right.push_back(i);
  }
  // Affine map diag(lambda, lambda, 1 - e) about the min corner: the face forces are the
  // tractions. Returns the x-force on the right face and the z-force on the top face.
  auto faces = [&](double lambda, double e, double* fx, double* fz) {
    for (int i = 0; i < cell.num_nodes(); ++i) {
      const Vec3 X = cell.rest[i] - lo;
      s.x[i] = lo + Vec3(lambda * X.x(), lambda * X.y(), (1 - e) * X.z());
    }
    compute_forces(cell, s, ws);
    *fx = 0;
    *fz = 0;
    for (int i : right) *fx += ws.force[i].x();
    for (int i : top) *fz += ws.force[i].z();
  };
  std::vector<double> out;
  out.reserve(strains.size());
  double lambda = 1;
  for (double e : strains) {
    // Lateral stretch with zero lateral traction: secant iterations from the last solution.
    double l0 = lambda, l1 = lambda * (1 + 1e-4), fz = 0, g0, g1;
    faces(l0, e, &g0, &fz);
    for (int it = 0; it < 60 && g0 != 0; ++it) {
      faces(l1, e, &g1, &fz);
      if (g1 == g0) break;
      const double l2 = std::clamp(l1 - g1 * (l1 - l0) / (g1 - g0), 0.5 * l1, 2 * l1);
      l0 = l1;
      g0 = g1;
      l1 = l2;
      if (std::abs(l1 - l0) <= 1e-13 * l1) break;
    }
    lambda = l1;
    double gx;
    faces(lambda, e, &gx, &fz);
    out.push_back(fz / (size.x() * size.y()));
  }
  return out;
}

}  // namespace conica::lab
