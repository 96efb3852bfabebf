#include "loop/scene.h"

#include <algorithm>
#include <cmath>
#include <cstdarg>
#include <cstdio>

#include "core/contact.h"
#include "loop/clock.h"

namespace conica::loop {
namespace {

std::string format(const char* fmt, ...) {
  char buf[512];
  va_list args;
  va_start(args, fmt);
  std::vsnprintf(buf, sizeof(buf), fmt, args);
  va_end(args);
  return buf;
}

}  // namespace

std::string prepare_scene(const BodySpec& spec, const PrepareOptions& opt, Scene* scene) {
  scene->notes.clear();
  auto note = [&](bool warning, std::string text) {
    scene->notes.push_back({warning, std::move(text)});
  };
  auto m = std::make_unique<Model>();
  if (std::string e = build_model(spec, m.get()); !e.empty()) return e;
  const double period_s = 1.0 / opt.rate_hz;
  if (std::abs(m->options.dt - period_s) > 1e-9 * period_s)
    note(true, format("scene dt %g s differs from the loop period %g s: simulated time runs at "
                      "%.2fx",
                      m->options.dt, period_s, m->options.dt / period_s));
  if (m->probes.empty()) note(true, "scene has no probe: every probe update will be refused");
  // A sphere small against the surface's node spacing feels the lattice as it slides: dragged at
  // 0.2 R depth, the normal force ripples 27-30 % at R = h and within 5 % only from R = 1.6 h
  // (docs/contact.md, "Drag ripple against the lattice spacing").
  const double h = surface_spacing(*m);
  for (size_t k = 0; k < m->probes.size(); ++k) {
    const ProbeSpec& p = m->probes[k];
    if (p.contact == ContactModel::kSurface && p.shape == ToolShape::kSphere && h > 0 &&
        p.radius < 1.6 * h)
      note(false, format("probe %zu: a %.3g mm sphere on a surface of %.3g mm node spacing "
                         "(R = %.2f h): slid along the surface its force ripples with the nodes "
                         "(27-30 %% at R = h, within 5 %% from R = 1.6 h, at 0.2 R depth)",
                         k, 1e3 * p.radius, 1e3 * h, p.radius / h));
  }

  // Step cost on a copy of the rest state.
  int n = std::max(1, opt.benchmark_steps);
  double budget_s = period_s;
  if (m->options.body_rate_hz > 0) {
    // Multi-rate: the body's step and local model at its own step, against its own period.
    const Model b = body_model(*m);
    const int every = ticks_per_body_step(*m);
    budget_s = period_s * every;
    // As the body thread runs them (loop/body_worker.cc, Factoring::kBackground): the first step
    // factors for the first time (its CG block-Jacobi preconditioned: no factor in hand yet),
    // then a factorisation is begun every refactor_every steps (every step when refactor_every
    // is 0: how often CG asks for one is not known at rest) and run on the factor thread (here
    // timed apart), and the step after it finished hands it over (and solves W anew). The body
    // thread's cost is the mean of the steps after the first, with their local models.
    const int per = std::max(1, m->options.refactor_every);
    n = 2 * per + 1;
    SteadyClock clock;
    State s = make_state(b);
    Workspace ws(b);
    LocalModelBuilder builder(b);
    prime_workspace(ws);
    LocalModel lm;
    std::vector<double> cost(n);
    double factoring = 0;
    int since = 0;
    for (int k = 0; k < n; ++k) {
      const TimeNs t0 = clock.now_ns();
      step_body(b, m->options, s, ws, builder, &since, true);
      const TimeNs t1 = clock.now_ns();
      if (builder.pending()) builder.factor_pending();
      const TimeNs t2 = clock.now_ns();
      if (k > 0 && t2 > t1) factoring = static_cast<double>(t2 - t1) * 1e-3;
      if (!b.probes.empty()) builder.build(b, s, ws, 0, 0, &lm);
      cost[k] = static_cast<double>((t1 - t0) + (clock.now_ns() - t2)) * 1e-3;
    }
    double mean = 0;
    for (int k = 1; k < n; ++k) mean += cost[k] / (n - 1);
    scene->step_us = mean;
    note(false, format("multi-rate: the body steps every %d ticks (%g Hz), its step and local "
                       "model %.0f us at rest, and its factorisation (one per %d steps, on a "
                       "thread of its own) %.0f us; the ticks answer the probes from its "
                       "compliance",
                       every, 1.0 / budget_s, scene->step_us, per, factoring));
    if (factoring > 1e6 * budget_s * per)
      note(true, format("a factorisation costs %.0f us, more than the %d body periods between "
                        "two (%.0f us): the body's factor ages beyond refactor_every",
                        factoring, per, 1e6 * budget_s * per));
  } else {
    SteadyClock clock;
    State s = make_state(*m);
    Workspace ws(*m);
    std::vector<double> cost(n);
    for (int k = 0; k < n; ++k) {
      const TimeNs t0 = clock.now_ns();
      step(*m, s, ws);
      cost[k] = static_cast<double>(clock.now_ns() - t0) * 1e-3;
    }
    std::nth_element(cost.begin(), cost.begin() + n / 2, cost.end());
    scene->step_us = cost[n / 2];
    if (m->options.active_region) {
      if (m->options.integrator == Integrator::kImplicitEuler)
        note(true, "active region ignored: the implicit integrator steps every node");
      else if (ws.bounds.far_every > 0)
        note(false, format("active region: tolerance %g m; far field one step every %d ticks "
                           "(measured stability bound %d, far inertia x %.3f); the step below is "
                           "measured at rest",
                           m->options.active_tolerance, ws.bounds.far_every,
                           ws.bounds.measured_every, ws.bounds.far_raise));
      else
        note(false, format("active region: tolerance %g m; far field frozen",
                           m->options.active_tolerance));
    }
  }
  const double median = scene->step_us, period_us = 1e6 * budget_s;
  if (median > period_us && opt.refuse_slow_scene)
    return format(
        "the step costs %.0f us (%s of %d at rest%s), more than the %.0f us period at %g Hz: "
        "lower the rate%s or simplify the scene",
        median, m->options.body_rate_hz > 0 ? "mean" : "median",
        m->options.body_rate_hz > 0 ? n - 1 : n,
        m->options.body_rate_hz > 0 ? ", factorisations included" : "", period_us, 1.0 / budget_s,
        m->options.body_rate_hz > 0 ? " (body_rate_hz)" : "");
  if (median > 0.5 * period_us)
    note(true, format("the step costs %.0f us of the %.0f us period: ticks may be missed", median,
                      period_us));
  body_box(*m, opt.box_margin, &scene->limits);
  scene->model = std::move(m);
  reset_scene(scene);
  return {};
}

namespace {
void start_factor_worker(Scene* scene) {
  if (scene->workspace->factor)
    scene->factor_worker = std::make_unique<FactorWorker>(scene->workspace->factor.get());
}

void start_body_worker(Scene* scene) {
  if (scene->model->options.body_rate_hz > 0)
    scene->body_worker = std::make_unique<BodyWorker>(*scene->model, scene->state);
}
}  // namespace

void reset_scene(Scene* scene) {
  scene->body_worker.reset();
  scene->factor_worker.reset();
  scene->state = make_state(*scene->model);
  scene->workspace = std::make_unique<Workspace>(*scene->model);
  start_factor_worker(scene);
  start_body_worker(scene);
}

void scene_options_changed(Scene* scene) {
  scene->body_worker.reset();  // its copy of the model has the old options
  scene->factor_worker.reset();
  options_changed(*scene->model, scene->state, *scene->workspace);
  start_factor_worker(scene);
  start_body_worker(scene);
}

void ScenePreparer::start(std::string source, SceneLoader loader, PrepareOptions options,
                          std::unique_ptr<Scene> retired) {
  wait();
  done_.store(false, std::memory_order_relaxed);
  result_ = Result{};
  result_.source = std::move(source);
  worker_ = std::thread(
      [this, loader = std::move(loader), options, retired = std::move(retired)]() mutable {
        retired.reset();
        BodySpec spec;
        std::string e = loader ? loader(result_.source, &spec) : "no scene loader";
        if (e.empty()) {
          auto scene = std::make_unique<Scene>();
          e = prepare_scene(spec, options, scene.get());
          result_.notes = std::move(scene->notes);
          if (e.empty()) result_.scene = std::move(scene);
        }
        result_.error = std::move(e);
        done_.store(true, std::memory_order_release);
      });
}

ScenePreparer::Result ScenePreparer::take() {
  if (worker_.joinable()) worker_.join();
  done_.store(false, std::memory_order_relaxed);
  return std::move(result_);
}

void ScenePreparer::wait() {
  if (worker_.joinable()) worker_.join();
  done_.store(false, std::memory_order_relaxed);
  result_ = Result{};
}

}  // namespace conica::loop
