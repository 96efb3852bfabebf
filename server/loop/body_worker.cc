#include "loop/body_worker.h"

#include <pthread.h>
#include <sched.h>

#include <algorithm>
#include <chrono>
#include <cmath>

namespace conica::loop {
BodyWorker::BodyWorker(const Model& served, const State& rest, Factoring factoring)
    : body_(body_model(served)),
      body_state_(rest),
      ws_(body_),
      builder_(body_),
      every_(ticks_per_body_step(served)),
      served_options_(served.options),
      surface_(served) {
  double r = 0;
  for (const ProbeSpec& p : served.probes) r = std::max(r, p.radius);
  reach_ = served.options.body_reach > 0 ? served.options.body_reach : 0.5 * r;
  for (Snapshot& s : snap_) {
    s.local.assign(served.probes.size(), LocalModel());
    s.x = rest.x;
  }
  input_ = rest.probes;
  estimates_.resize(served.probes.size());
  near_.reserve(std::max(served.num_nodes(), 3 * static_cast<int>(served.surface.size())));
  const double share = tissue_share_stiffness(served);
  for (const ProbeSpec& p : served.probes)
    share_.push_back(p.contact == ContactModel::kSurface ? share : 0.1 * p.stiffness);
  prime_workspace(ws_);
  factoring_ = factoring;
  if (factoring_ != Factoring::kInline) factor_thread_ = std::thread([this] { run_factor(); });
  thread_ = std::thread([this] { run(); });
}

BodyWorker::~BodyWorker() {
  state_.store(kStop, std::memory_order_release);
  state_.notify_all();
  thread_.join();
  if (factor_thread_.joinable()) {
    factor_job_.store(2, std::memory_order_release);
    factor_job_.notify_all();
    factor_thread_.join();
  }
}

void BodyWorker::run_factor() {
  sched_param p{};
  p.sched_priority = 0;
  pthread_setschedparam(pthread_self(), SCHED_OTHER, &p);  // not the loop's real-time policy
  for (;;) {
    const int v = factor_job_.load(std::memory_order_acquire);
    if (v == 2) return;
    if (v == 0) {
      factor_job_.wait(0, std::memory_order_acquire);
      continue;
    }
    builder_.factor_pending();
    int expected = 1;
    if (!factor_job_.compare_exchange_strong(expected, 0, std::memory_order_acq_rel)) return;
    factor_job_.notify_all();
  }
}

void BodyWorker::run() {
  sched_param p{};
  p.sched_priority = 0;
  pthread_setschedparam(pthread_self(), SCHED_OTHER, &p);  // not the loop's real-time policy
  for (;;) {
    const int v = state_.load(std::memory_order_acquire);
    if (v == kStop) return;
    if (v != kRun) {
      state_.wait(v, std::memory_order_acquire);
      continue;
    }
    const auto t0 = std::chrono::steady_clock::now();
    for (size_t k = 0; k < input_.size(); ++k) {
      if (body_.probes[k].contact == ContactModel::kSurface) {
        body_state_.probes[k] = input_[k];  // the tick's proxy, carried by the body's surface
        continue;
      }
      body_state_.probes[k].radius = input_[k].radius;
      set_probe(body_state_, static_cast<int>(k), input_[k].center, input_[k].active);
    }
    if (factoring_ == Factoring::kWaited)
      for (int v; (v = factor_job_.load(std::memory_order_acquire)) == 1;)
        factor_job_.wait(v, std::memory_order_acquire);
    step_body(body_, served_options_, body_state_, ws_, builder_, &since_factor_,
              factoring_ != Factoring::kInline);
    if (factoring_ != Factoring::kInline && builder_.pending()) {
      factor_job_.store(1, std::memory_order_release);
      factor_job_.notify_one();
    }
    Snapshot& out = snap_[back_];
    for (size_t k = 0; k < input_.size(); ++k) {
      LocalModel& lm = out.local[k];
      if (!input_[k].active ||
          !builder_.build(body_, body_state_, ws_, static_cast<int>(k), reach_, &lm)) {
        lm.valid = false;
        lm.num = 0;
      }
    }
    std::copy(body_state_.x.begin(), body_state_.x.end(), out.x.begin());
    factorizations_.store(builder_.factorizations(), std::memory_order_relaxed);
    region_solves_.store(builder_.region_solves(), std::memory_order_relaxed);
    rollbacks_.store(body_state_.counters.rollbacks, std::memory_order_relaxed);
    newton_.store(body_state_.counters.newton_iterations, std::memory_order_relaxed);
    cg_.store(body_state_.counters.cg_iterations, std::memory_order_relaxed);
    body_ns_.store(
        std::chrono::duration_cast<std::chrono::nanoseconds>(std::chrono::steady_clock::now() - t0)
            .count(),
        std::memory_order_relaxed);
    int expected = kRun;
    state_.compare_exchange_strong(expected, kDone, std::memory_order_acq_rel);
  }
}

void BodyWorker::answer(const Model& served, const std::vector<Vec3>& x, int k, const Vec3& center,
                        double radius, ProbeState* probe, std::vector<Vec3>* x_out) {
  LocalModel& lm = snap_[front_].local[k];
  const double R = radius > 0 ? radius : probe->radius;
  if (lm.valid && (center - lm.center0).norm() <= reach_) {
    haptic_contact(served, lm, k, center, R, probe, x_out, &surface_);
    evaluations_ = lm.layer_evaluations;
    proxy_fallbacks_ += lm.proxy_fallback;
  } else {
    const bool surface = served.probes[k].contact == ContactModel::kSurface;
    const Vec3 at = surface && probe->proxy_placed ? probe->proxy : center;
    Estimate& e = estimates_[k];
    if (e.model.num == 0 || e.body_step != body_steps_ || e.radius != R ||
        (at - e.model.center0).norm() > reach_) {
      estimate_local_model(served, x, k, at, R, reach_, share_[k], &near_, &e.model);
      e.body_step = body_steps_;
      e.radius = R;
    }
    haptic_contact(served, e.model, k, center, R, probe, x_out, &surface_);
    evaluations_ = e.model.layer_evaluations;
    ++frozen_;
  }
}

BodyStats BodyWorker::stats() const {
  BodyStats b;
  b.steps = body_steps();
  b.late_ticks = late_ticks();
  b.estimates = frozen_answers();
  b.factorizations = factorizations();
  b.rollbacks = rollbacks();
  b.step_us = 1e-3 * static_cast<double>(last_body_ns());
  b.proxy_fallbacks = proxy_fallbacks();
  return b;
}

void BodyWorker::tick(const Model& served, State& s) {
  if (state_.load(std::memory_order_acquire) == kDone && since_ >= latency_) {
    // The handed-over state is the body's at its kick-off plus one body step. A step that came
    // late hands over an older state, whose free motion is not carried on (LocalModel::ticks
    // negative): extrapolated from its age, the phantom's per-tick force in real time went from
    // 1.74 to 3.38 % RMS against the converged body (docs/performance.md).
    const bool late = since_ > every_;
    for (LocalModel& lm : snap_[back_].local) lm.ticks = late ? -(1 << 30) : 0;
    // A fresh model's region starts where the last tick served it (the nodes the last model held
    // too; the others at the body's state): the body's state is in equilibrium with the proxy
    // its step held at kick-off, a body step or more behind the probe, and its first solve from
    // there, against a proxy up to a millimetre deeper, ran out of its evaluations on the fine
    // liver in real time with the region thrown 7.8 mm, the tool free and 0 N served.
    for (size_t k = 0; k < snap_[back_].local.size(); ++k)
      warm_start(snap_[front_].local[k], s.x, &snap_[back_].local[k]);
    std::swap(front_, back_);
    std::copy(snap_[front_].x.begin(), snap_[front_].x.end(), s.x.begin());
    ++body_steps_;
    state_.store(kIdle, std::memory_order_release);
  }
  if (++since_ >= every_) {
    if (state_.load(std::memory_order_acquire) == kIdle) {
      std::copy(s.probes.begin(), s.probes.end(), input_.begin());
      since_ = 0;
      state_.store(kRun, std::memory_order_release);
      state_.notify_one();
    } else {
      ++late_ticks_;
    }
  }
  for (size_t k = 0; k < s.probes.size(); ++k) {
    ProbeState& p = s.probes[k];
    if (!p.active) {
      p.force.setZero();
      p.stiffness.setZero();
      p.contacts = 0;
      continue;
    }
    answer(served, snap_[front_].x, static_cast<int>(k), p.center, p.radius, &p, &s.x);
  }
  ++s.tick;
  s.time += served.options.dt;
}

void BodyWorker::contact(const Model& served, const State& s, int k, const Vec3& center,
                         double radius, ProbeState* probe) {
  if (served.probes[k].contact != ContactModel::kSurface) {
    answer(served, snap_[front_].x, k, center, radius, probe, nullptr);
    return;
  }
  // Surface contact: as a single-rate reply, the proxy moves toward the pose against the served
  // positions (the last tick's answer) with the nodes held; the next tick solves the region.
  probe->center = center;
  probe->active = true;
  if (radius > 0) probe->radius = radius;
  update_proxy(served, k, s.x, &surface_.candidates[k], probe, kReplyMaxEvaluations);
}

}  // namespace conica::loop
