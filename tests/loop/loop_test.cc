// The fixed-rate loop in-process, without any wire: a ManualClock (time moves only when the loop
// sleeps or the test advances it) and a MemoryTransport. Every expectation is computed
// independently: deadlines from the period, forces and positions by running the core on a twin
// model, missed ticks from the overrun rule.
#include <gtest/gtest.h>

#include <atomic>
#include <chrono>
#include <cmath>
#include <cstdlib>
#include <new>
#include <string>
#include <thread>
#include <vector>

#include "core/body.h"
#include "core/step.h"
#include "loop/clock.h"
#include "loop/fixed_rate_loop.h"
#include "loop/memory_transport.h"
#include "loop/scene.h"

// Counts operator new on this thread (the tick path must allocate nothing).
#include "../counting_new.h"

namespace conica::loop {
namespace {

constexpr double kRate = 1000;       // Hz
constexpr TimeNs kPeriod = 1000000;  // ns, 1 / kRate
constexpr TimeNs kStart = 5'000'000'000;
constexpr double kRadius = 3e-3;  // m

// A w x w x h (m) lattice of cells^3-ish hexahedra, bottom clamped, one probe, tissue-like card.
BodySpec Lattice(const Vec3& size, const std::array<int, 3>& cells) {
  BodySpec b;
  b.mesh = make_box_lattice(size, cells);
  b.density = 1000;
  SpringCard card;
  card.law = LawKind::kConical;
  card.conical = ConicalCard{2e9, 1e-3, 2e-3, 8e-3, 10e-3, 3};
  card.stiffness_cap = 20;
  b.groups.push_back({"tissue", card, kAllFamilies, {}, Vec3::Zero(), 10});
  FixedSelector bottom;
  bottom.tolerance = 1e-9;
  b.fixed.push_back(bottom);
  b.options.dt = 1 / kRate;
  b.options.mass_damping = 5;
  b.probes.push_back(ProbeSpec{kRadius, 0, ContactModel::kNodes});
  return b;
}
BodySpec Small() { return Lattice(Vec3(0.02, 0.02, 0.01), {4, 4, 2}); }  // 75 nodes
BodySpec Large() { return Lattice(Vec3(0.03, 0.02, 0.01), {6, 4, 2}); }  // 105 nodes

std::string LoadByName(const std::string& name, BodySpec* spec) {
  if (name == "small")
    *spec = Small();
  else if (name == "large")
    *spec = Large();
  else
    return "no scene called " + name;
  return {};
}

// A twin of what the loop runs: the same spec built again, stepped by the core directly.
struct Twin {
  explicit Twin(const BodySpec& spec) {
    EXPECT_EQ(build_model(spec, &model), "");
    state = make_state(model);
    ws = std::make_unique<Workspace>(model);
  }
  void steps(int n) {
    for (int k = 0; k < n; ++k) step(model, state, *ws);
  }
  ProbeState press(const Vec3& at) {
    set_probe(state, 0, at, true);
    ProbeState ps = state.probes[0];
    conica::probe_contact(model, state.x, 0, at, ps.radius, &ps);
    state.probes[0] = ps;
    return ps;
  }
  Model model;
  State state;
  std::unique_ptr<Workspace> ws;
};

// Pressed `depth` (m) into the top face (z = top) above the node column at (x, y).
Vec3 Pressed(double x, double y, double top, double depth) {
  return Vec3(x, y, top + kRadius - depth);
}

ProbeUpdate Probe(std::uint64_t seq, const Vec3& at, int probe_id = 0) {
  ProbeUpdate u;
  u.client_id = 3;
  u.probe_id = probe_id;
  u.sequence = seq;
  u.position = at;
  return u;
}

class LoopTest : public ::testing::Test {
 protected:
  void Start(LoopOptions opt = {}, const BodySpec& spec = Small()) {
    opt.rate_hz = kRate;
    opt.prepare.refuse_slow_scene = false;  // a loaded machine must not refuse the scene
    loop_ = std::make_unique<FixedRateLoop>(std::move(opt));
    auto scene = std::make_unique<Scene>();
    ASSERT_EQ(prepare_scene(spec, loop_->prepare_options(), scene.get()), "");
    loop_->install(std::move(scene));
    loop_->begin(clock_, transport_);
    ASSERT_EQ(loop_->next_deadline_ns(), kStart + kPeriod);
  }
  // Runs until the loop has ticked `n` times in all.
  void TickTo(std::uint64_t n) {
    while (loop_->stats().ticks < n) ASSERT_TRUE(loop_->tick());
  }
  static TimeNs At(double periods) { return kStart + static_cast<TimeNs>(periods * kPeriod); }

  std::vector<const MemoryTransport::Frame*> ForceFrames() const {
    std::vector<const MemoryTransport::Frame*> out;
    for (const auto& f : transport_.frames())
      if (!f.with_positions) out.push_back(&f);
    return out;
  }
  template <class T>
  std::vector<std::pair<TimeNs, const T*>> Sent() const {
    std::vector<std::pair<TimeNs, const T*>> out;
    for (const auto& s : transport_.sent())
      if (const T* t = std::get_if<T>(&s.what)) out.push_back({s.at_ns, t});
    return out;
  }

  ManualClock clock_{kStart};
  MemoryTransport transport_{clock_};
  std::unique_ptr<FixedRateLoop> loop_;
};

TEST_F(LoopTest, TicksAtTheFixedRateOnAbsoluteDeadlines) {
  LoopOptions opt;
  opt.positions_hz = 100;  // every 10th tick
  Start(opt);
  TickTo(50);
  const auto frames = ForceFrames();
  ASSERT_EQ(frames.size(), 50u);
  for (std::size_t k = 0; k < frames.size(); ++k) {
    EXPECT_EQ(frames[k]->at_ns, At(k + 1.0)) << k;         // tick k+1 runs at its deadline exactly
    EXPECT_EQ(frames[k]->tick, k + 1);                     // one core step per tick
    EXPECT_NEAR(frames[k]->time, (k + 1) / kRate, 1e-12);  // s, summed dt
  }
  int positions = 0;
  for (const auto& f : transport_.frames())
    if (f.with_positions) {
      ++positions;
      EXPECT_EQ(f.tick % 10, 0u);
      EXPECT_EQ(f.positions.size(), 75u);
    }
  EXPECT_EQ(positions, 5);
  loop_->end();
  EXPECT_EQ(loop_->stats().ticks, 50u);
  EXPECT_EQ(loop_->stats().missed_ticks, 0u);
  EXPECT_EQ(loop_->stats().lateness_max_us, 0);
  EXPECT_EQ(loop_->stats().rate_hz, kRate);
  EXPECT_EQ(loop_->stats().body.steps, 0u);
}

// A multi-rate scene's statistics carry the body thread's counters (zero for a body stepped every
// tick, as above): its steps, factorisations and last step's cost, with the probe pressed in.
TEST_F(LoopTest, MultiRateStatisticsCarryTheBodyThread) {
  BodySpec spec = Small();
  spec.options.integrator = Integrator::kImplicitEuler;
  spec.options.linear_solver = LinearSolver::kFactorCG;
  spec.options.body_rate_hz = kRate / 10;
  Start({}, spec);
  EXPECT_EQ(loop_->stats().body.steps, 0u);
  transport_.send_probe(At(0.5), 3, Probe(1, Pressed(0.01, 0.01, 0.01, 1e-3)));
  for (int k = 0; k < 100; ++k) {
    ASSERT_TRUE(loop_->tick());
    std::this_thread::sleep_for(std::chrono::microseconds(500));  // the body thread's turn
  }
  loop_->end();
  const LoopStats& st = loop_->stats();
  EXPECT_GE(st.body.steps, 3u);
  EXPECT_LE(st.body.steps, 10u);  // one per 10 ticks at most
  EXPECT_GE(st.body.factorizations, 1u);
  EXPECT_GT(st.body.step_us, 0);
}

TEST_F(LoopTest, ProbeUpdateIsAnsweredAtOnceWithTheCoreForceAndStepsTheBody) {
  LoopOptions opt;
  opt.positions_hz = 100;
  Start(opt);
  const Vec3 at = Pressed(0.01, 0.01, 0.01, 1.5e-3);
  transport_.send_probe(At(10.5), 3, Probe(41, at));
  TickTo(20);

  // The twin: 10 ticks with no probe, then the probe placed and its contact evaluated.
  Twin twin(Small());
  twin.steps(10);
  const ProbeState expected = twin.press(at);
  ASSERT_GT(expected.contacts, 0);
  ASSERT_GT(expected.force.z(), 0);  // pushed up, out of the body

  const auto replies = Sent<ForceReply>();
  ASSERT_EQ(replies.size(), 1u);
  const ForceReply& r = *replies[0].second;
  EXPECT_EQ(replies[0].first, At(10.5));  // answered when it arrived, between ticks 10 and 11
  EXPECT_EQ(r.recv_ns, At(10.5));
  EXPECT_EQ(r.tick, 10u);
  EXPECT_EQ(r.update.sequence, 41u);
  EXPECT_EQ(r.probe.force, expected.force);
  EXPECT_EQ(r.probe.stiffness, expected.stiffness);
  EXPECT_EQ(r.probe.contacts, expected.contacts);

  // Ticks 11..20 integrate with the probe in place: the same positions and probe force.
  twin.steps(10);
  const MemoryTransport::Frame& last = transport_.frames().back();
  ASSERT_TRUE(last.with_positions);
  ASSERT_EQ(last.tick, 20u);
  for (int i = 0; i < twin.model.num_nodes(); ++i) ASSERT_EQ(last.positions[i], twin.state.x[i]);
  EXPECT_EQ(last.probes[0].force, twin.state.probes[0].force);
  EXPECT_EQ(loop_->stats().probes_received, 1u);
  EXPECT_EQ(loop_->stats().replies_sent, 1u);
}

// A contact stage that takes a fifth of a period on the loop's clock and answers a force that
// names the position it was solved at (x component, in N per mm).
ManualClock* slow_contact_clock = nullptr;
void SlowContact(const Model&, const State&, int, const Vec3& center, double, ProbeState* probe) {
  slow_contact_clock->advance(kPeriod / 5);
  probe->force = Vec3(1e3 * center.x(), 0, 1);
  probe->contacts = 1;
}

TEST_F(LoopTest, RepliesPastTheBudgetAreHeldWithTheLastSolvedContact) {
  // Budget a quarter period: the first two solves (0.2 + 0.2 periods) are made, the third update
  // between the same ticks is answered with the second's force and position, and becomes the
  // target of the next tick's step; after that tick the budget is whole again.
  LoopOptions opt;
  opt.reply_budget = 0.25;
  opt.contact = &SlowContact;
  slow_contact_clock = &clock_;
  Start(opt);
  const Vec3 a = Pressed(0.004, 0.01, 0.01, 1e-3), b = Pressed(0.006, 0.01, 0.01, 1e-3),
             c = Pressed(0.008, 0.01, 0.01, 1e-3), d = Pressed(0.012, 0.01, 0.01, 1e-3);
  transport_.send_probe(At(10.1), 3, Probe(1, a));
  transport_.send_probe(At(10.2), 3, Probe(2, b));
  transport_.send_probe(At(10.3), 3, Probe(3, c));
  transport_.send_probe(At(11.2), 3, Probe(4, d));
  TickTo(12);
  const auto replies = Sent<ForceReply>();
  ASSERT_EQ(replies.size(), 4u);
  const auto force_x = [&](int k) { return replies[k].second->probe.force.x(); };
  EXPECT_DOUBLE_EQ(force_x(0), 1e3 * a.x());
  EXPECT_DOUBLE_EQ(force_x(1), 1e3 * b.x());
  EXPECT_DOUBLE_EQ(force_x(2), 1e3 * b.x());      // held: the second's contact
  EXPECT_EQ(replies[2].second->probe.center, b);  // ... at the position it belongs to
  EXPECT_EQ(replies[2].second->update.sequence, 3u);
  EXPECT_DOUBLE_EQ(force_x(3), 1e3 * d.x());  // the next tick's budget
  EXPECT_EQ(replies[3].second->probe.center, d);
  EXPECT_EQ(loop_->stats().replies_held, 1u);
  EXPECT_EQ(loop_->stats().replies_sent, 4u);
  // The held update's position was the target of tick 11.
  Twin twin(Small());
  twin.steps(10);
  set_probe(twin.state, 0, c, true);
  twin.steps(1);
  set_probe(twin.state, 0, d, true);
  twin.steps(1);
  const MemoryTransport::Frame& last = *ForceFrames().back();
  ASSERT_EQ(last.tick, 12u);
  ASSERT_GT(twin.state.probes[0].force.z(), 0);
  EXPECT_EQ(last.probes[0].force, twin.state.probes[0].force);
}

TEST_F(LoopTest, CommandsAreAppliedBetweenTicks) {
  LoopOptions opt;
  opt.positions_hz = 100;
  Start(opt);
  transport_.send_control(At(5.5), 8, 1, SetParameter{Parameter::kGravityZ, -9.81});
  transport_.send_control(At(12.5), 8, 2, Pause{});
  transport_.send_control(At(15.5), 8, 3, Resume{});
  transport_.send_control(At(16.5), 8, 4, SetParameter{Parameter::kDamping, -1});
  transport_.send_control(At(16.5), 8, 5, SetParameter{Parameter::kUnknown, 1});
  TickTo(20);

  const auto results = Sent<ControlResult>();
  ASSERT_EQ(results.size(), 5u);
  const TimeNs when[] = {At(5.5), At(12.5), At(15.5), At(16.5), At(16.5)};
  for (int k = 0; k < 5; ++k) {
    EXPECT_EQ(results[k].first, when[k]) << k;  // answered as it arrived
    EXPECT_EQ(results[k].second->sequence, k + 1u);
    EXPECT_EQ(results[k].second->num_nodes, 75u);
  }
  EXPECT_TRUE(results[0].second->ok);
  EXPECT_EQ(results[0].second->message, "gravity_z set");
  EXPECT_TRUE(results[1].second->stats.paused);
  EXPECT_EQ(results[1].second->stats.ticks, 12u);
  EXPECT_FALSE(results[3].second->ok);  // negative damping
  EXPECT_FALSE(results[4].second->ok);  // unknown parameter
  EXPECT_EQ(loop_->scene()->model->options.gravity.z(), -9.81);
  EXPECT_EQ(loop_->scene()->model->options.mass_damping, 5);  // unchanged by the refused set

  // Twin: gravity from tick 6 on; paused over ticks 13..15 (no step), stepping again from 16.
  Twin twin(Small());
  twin.steps(5);
  twin.model.options.gravity.z() = -9.81;
  twin.steps(7);  // ticks 6..12
  twin.steps(5);  // ticks 16..20
  const auto frames = ForceFrames();
  ASSERT_EQ(frames.size(), 20u);
  for (int k = 12; k < 15; ++k) EXPECT_EQ(frames[k]->tick, 12u) << "paused at tick " << k + 1;
  EXPECT_EQ(frames[19]->tick, 17u);
  const MemoryTransport::Frame& last = transport_.frames().back();
  ASSERT_TRUE(last.with_positions);
  for (int i = 0; i < twin.model.num_nodes(); ++i) ASSERT_EQ(last.positions[i], twin.state.x[i]);
  EXPECT_LT(twin.state.x[twin.model.num_nodes() - 1].z(), 0.01);  // it did sag
}

TEST_F(LoopTest, DampingSetBetweenTicksRebuildsWhatTheStepDerivedFromIt) {
  // Multi-rate active region: the far field's interval and inertia come from the damping.
  BodySpec spec = Large();
  spec.options.active_region = true;
  spec.options.active_far_every = 0;
  Start({}, spec);
  const double gamma_before = loop_->scene()->workspace->bounds.far_gamma;
  transport_.send_control(At(3.5), 8, 1, SetParameter{Parameter::kDamping, 400});
  TickTo(6);
  const Scene& scene = *loop_->scene();
  ASSERT_EQ(scene.model->options.mass_damping, 400);
  const Workspace fresh(*scene.model);  // what a scene loaded with this damping would step with
  EXPECT_EQ(scene.workspace->bounds.far_gamma, fresh.bounds.far_gamma);
  EXPECT_EQ(scene.workspace->bounds.far_every, fresh.bounds.far_every);
  EXPECT_EQ(scene.workspace->bounds.far_raise, fresh.bounds.far_raise);
  EXPECT_EQ(scene.workspace->bounds.measured_every, fresh.bounds.measured_every);
  EXPECT_GT(fresh.bounds.far_gamma, gamma_before + 300)
      << "the far field's damping bound must follow";
  EXPECT_LT(scene.state.region.far_phase, std::max(1, fresh.bounds.far_every));
}

TEST_F(LoopTest, BadMessagesAreAnsweredCountedAndChangeNothing) {
  Start();
  const Vec3 good = Pressed(0.01, 0.01, 0.01, 1e-3);
  transport_.send_probe(At(2.5), 3, Probe(1, good));
  transport_.send_undecodable(At(3.5), 3, Channel::kProbe, {ErrorKind::kMalformed, "garbage", 0});
  transport_.send_probe(At(3.5), 3, Probe(2, Vec3(0.01, 0.01, 2.0)));  // outside the box
  transport_.send_probe(At(3.5), 3, Probe(3, good, 1));                // no probe 1
  transport_.send_probe(At(3.5), 3, Probe(4, Vec3(0.01, std::nan(""), 0.01)));
  transport_.send_control(At(3.5), 8, 9, Pause{});
  transport_.send_probe(At(4.5), 3, Probe(5, good));
  TickTo(6);
  const auto errors = Sent<Rejection>();
  ASSERT_EQ(errors.size(), 4u);
  EXPECT_EQ(errors[0].second->kind, ErrorKind::kMalformed);
  EXPECT_EQ(errors[1].second->kind, ErrorKind::kBadValue);
  EXPECT_EQ(errors[2].second->kind, ErrorKind::kUnknownProbe);
  EXPECT_EQ(errors[3].second->kind, ErrorKind::kBadValue);
  EXPECT_EQ(errors[1].second->sequence, 2u);
  const LoopStats& s = loop_->stats();
  EXPECT_EQ(s.errors, 4u);
  EXPECT_EQ(s.errors_by_code[static_cast<int>(ErrorKind::kBadValue)], 2u);
  EXPECT_EQ(s.errors_by_code[static_cast<int>(ErrorKind::kMalformed)], 1u);
  EXPECT_EQ(s.errors_by_code[static_cast<int>(ErrorKind::kUnknownProbe)], 1u);
  EXPECT_EQ(s.probes_received, 2u);
  // The second good probe, after the bad ones, sees what the twin sees at tick 3 (paused since).
  Twin twin(Small());
  twin.steps(2);
  twin.press(good);
  twin.steps(1);
  const ProbeState expected = twin.press(good);
  const auto replies = Sent<ForceReply>();
  ASSERT_EQ(replies.size(), 2u);
  EXPECT_EQ(replies[1].second->tick, 3u);
  EXPECT_EQ(replies[1].second->probe.force, expected.force);
}

TEST_F(LoopTest, SceneIsPreparedOffTheLoopAndSwappedAtATickBoundaryWithoutAMissedReply) {
  // The loader waits for the test's word, so the preparation provably spans ticks.
  std::atomic<bool> go{false};
  LoopOptions opt;
  opt.scene_loader = [&go](const std::string& name, BodySpec* spec) {
    while (!go.load()) std::this_thread::sleep_for(std::chrono::milliseconds(1));
    return LoadByName(name, spec);
  };
  Start(opt);
  // A client presses every period, half-way between ticks.
  const Vec3 at = Pressed(0.01, 0.01, 0.01, 1e-3);
  for (int k = 1; k <= 11; ++k) transport_.send_probe(At(k + 0.5), 3, Probe(k, at));
  transport_.send_control(At(3.5), 8, 21, LoadScene{"large"});
  transport_.send_control(At(3.6), 8, 22, LoadScene{"small"});  // one at a time
  TickTo(6);
  EXPECT_TRUE(loop_->scene_pending());  // ticks 4..6 ran while it was loading
  go = true;
  // The worker builds and times the scene in real time; the loop's clock stands still meanwhile.
  const auto give_up = std::chrono::steady_clock::now() + std::chrono::seconds(60);
  while (!loop_->scene_ready() && std::chrono::steady_clock::now() < give_up)
    std::this_thread::sleep_for(std::chrono::milliseconds(1));
  ASSERT_TRUE(loop_->scene_ready());
  TickTo(12);

  const auto results = Sent<ControlResult>();
  ASSERT_EQ(results.size(), 2u);
  EXPECT_EQ(results[0].second->sequence, 22u);  // refused at once: another is preparing
  EXPECT_FALSE(results[0].second->ok);
  EXPECT_EQ(results[0].first, At(3.6));
  const ControlResult& loaded = *results[1].second;
  EXPECT_EQ(loaded.sequence, 21u);
  EXPECT_TRUE(loaded.ok) << loaded.message;
  EXPECT_EQ(loaded.num_nodes, 105u);
  EXPECT_EQ(results[1].first, At(7));  // at the deadline of tick 7: a tick boundary
  EXPECT_EQ(loop_->scene()->model->num_nodes(), 105);

  // Ticks 1..6 ran the small body, 7.. the large one.
  const auto frames = ForceFrames();
  ASSERT_EQ(frames.size(), 12u);
  for (int k = 0; k < 12; ++k) EXPECT_EQ(frames[k]->num_nodes, k < 6 ? 75 : 105) << k;
  // Every probe answered once, in order, when it arrived; the ones after the swap against the
  // new body.
  const auto replies = Sent<ForceReply>();
  ASSERT_EQ(replies.size(), 11u);
  for (int k = 0; k < 11; ++k) {
    EXPECT_EQ(replies[k].second->update.sequence, k + 1u);
    EXPECT_EQ(replies[k].first, At(k + 1.5));
  }
  Twin twin(Large());  // at rest at the swap, stepped in tick 7 (before the probe at 7.5)
  twin.steps(1);
  const ProbeState expected = twin.press(at);
  EXPECT_EQ(replies[6].second->tick, 1u);
  EXPECT_EQ(replies[6].second->probe.force, expected.force);
  EXPECT_EQ(loop_->stats().missed_ticks, 0u);
  EXPECT_EQ(loop_->stats().replies_sent, 11u);
}

TEST_F(LoopTest, RefusedSceneKeepsTheBody) {
  std::atomic<bool> go{false};
  LoopOptions opt;
  opt.scene_loader = [&go](const std::string& name, BodySpec* spec) {
    while (!go.load()) std::this_thread::sleep_for(std::chrono::milliseconds(1));
    return LoadByName(name, spec);
  };
  Start(opt);
  transport_.send_control(At(1.5), 8, 5, LoadScene{"kidney"});
  TickTo(2);
  EXPECT_TRUE(loop_->scene_pending());
  go = true;
  const auto give_up = std::chrono::steady_clock::now() + std::chrono::seconds(60);
  while (!loop_->scene_ready() && std::chrono::steady_clock::now() < give_up)
    std::this_thread::sleep_for(std::chrono::milliseconds(1));
  ASSERT_TRUE(loop_->scene_ready());
  TickTo(3);
  const auto results = Sent<ControlResult>();
  ASSERT_EQ(results.size(), 1u);
  EXPECT_FALSE(results[0].second->ok);
  EXPECT_EQ(results[0].second->message, "no scene called kidney");
  EXPECT_EQ(results[0].second->num_nodes, 75u);
  EXPECT_EQ(results[0].first, At(3));  // at the next tick boundary
  EXPECT_EQ(loop_->scene()->model->num_nodes(), 75);
  EXPECT_FALSE(loop_->scene_pending());
}

TEST_F(LoopTest, LoadSceneWithoutALoaderIsRefusedAtOnce) {
  Start();
  transport_.send_control(At(1.5), 8, 6, LoadScene{"small"});
  TickTo(2);
  const auto results = Sent<ControlResult>();
  ASSERT_EQ(results.size(), 1u);
  EXPECT_FALSE(results[0].second->ok);
  EXPECT_EQ(results[0].first, At(1.5));
  EXPECT_FALSE(loop_->scene_pending());
}

TEST_F(LoopTest, AnOverrunSkipsTheMissedDeadlinesAndCountsThem) {
  Start();
  // Tick 5's publish "takes" 3.5 periods.
  const TimeNs overrun = 3 * kPeriod + kPeriod / 2;
  transport_.on_publish = [&](const StateFrame& f) {
    if (f.state->tick == 5 && !f.with_positions) clock_.advance(overrun);
  };
  TickTo(10);
  loop_->end();
  // The rule: the next deadline D6 = D5 + P; once the clock is past D6 + P, the deadlines up to
  // the clock are skipped: missed = (t - D6) / P, and the next tick runs at once if it is late.
  const TimeNs d5 = At(5), d6 = d5 + kPeriod, t = d5 + overrun;
  const std::uint64_t missed = (t - d6) / kPeriod;
  const TimeNs next = d6 + missed * kPeriod;
  ASSERT_EQ(missed, 2u);
  const auto frames = ForceFrames();
  ASSERT_EQ(frames.size(), 10u);
  EXPECT_EQ(frames[4]->at_ns, d5);
  EXPECT_EQ(frames[5]->at_ns, t);  // late: at once
  for (int k = 6; k < 10; ++k) EXPECT_EQ(frames[k]->at_ns, next + (k - 5) * kPeriod) << k;
  EXPECT_EQ(loop_->stats().missed_ticks, missed);
  EXPECT_DOUBLE_EQ(loop_->stats().lateness_max_us, (t - next) * 1e-3);
  EXPECT_EQ(frames[9]->tick, 10u);  // dt stays fixed: one step per tick that ran
}

// A transport that answers nothing and hands over one probe update per period: what a steady
// client looks like to the loop, with no recording (which would allocate).
class SteadyClient final : public Transport {
 public:
  SteadyClient(Clock& clock, Vec3 at) : clock_(clock), at_(at) {}
  bool poll(TimeNs deadline, Incoming* in) override {
    const TimeNs t = clock_.now_ns();
    if (t >= next_) {
      next_ = t + kPeriod;
      in->route = Route{};
      in->message = Probe(++seq_, at_);
      return true;
    }
    clock_.sleep_until(std::min(deadline, next_));
    return false;
  }
  bool reply(const Route&, const ForceReply& r) override { return r.probe.contacts > 0; }
  bool reply(const Route&, const ControlResult&) override { return true; }
  bool reply(const Route&, const Rejection&) override { return false; }
  void publish(const StateFrame&) override {}

 private:
  Clock& clock_;
  Vec3 at_;
  TimeNs next_ = kStart + kPeriod / 2;
  std::uint64_t seq_ = 0;
};

// The loop's own work per tick and per probe reply: serving, input, step, publish, statistics.
// The contact stage is stubbed (a unit force) so the count is the loop's; the core's stages have
// their own allocation test (tests/core/alloc_test.cc).
void UnitContact(const Model&, const State&, int, const Vec3&, double, ProbeState* probe) {
  probe->force = Vec3::UnitZ();
  probe->contacts = 1;
}

TEST(LoopAllocationTest, TicksAndProbeRepliesAllocateNothing) {
  ManualClock clock(kStart);
  SteadyClient client(clock, Pressed(0.01, 0.01, 0.01, 1e-3));
  LoopOptions opt;
  opt.rate_hz = kRate;
  opt.contact = &UnitContact;
  opt.prepare.refuse_slow_scene = false;
  FixedRateLoop loop(opt);
  auto scene = std::make_unique<Scene>();
  ASSERT_EQ(prepare_scene(Small(), loop.prepare_options(), scene.get()), "");
  loop.install(std::move(scene));
  loop.begin(clock, client);
  for (int k = 0; k < 10; ++k) ASSERT_TRUE(loop.tick());  // warm up
  EXPECT_EQ(counting_new::during([&] {
              for (int k = 0; k < 1000; ++k) loop.tick();
            }),
            0);
  EXPECT_EQ(loop.stats().ticks, 1010u);
  EXPECT_GE(loop.stats().probes_received, 1000u);
  EXPECT_EQ(loop.stats().replies_sent, loop.stats().probes_received);
  loop.end();
}

// A surface sphere small against the surface's node spacing (5 mm here) is told at load that it
// will feel the nodes as it slides (docs/contact.md: the drag ripple is within 5 % from 1.6
// spacings); one of two spacings is not, nor is a node-law probe.
TEST(SceneNotesTest, ASphereSmallAgainstTheSurfaceSpacingIsToldItWillFeelTheNodes) {
  auto ripple_notes = [](double radius, ContactModel contact) {
    BodySpec spec = Small();
    spec.probes[0].radius = radius;
    spec.probes[0].contact = contact;
    PrepareOptions opt;
    opt.refuse_slow_scene = false;
    opt.benchmark_steps = 2;
    Scene scene;
    EXPECT_EQ(prepare_scene(spec, opt, &scene), "");
    std::vector<std::string> out;
    for (const Note& n : scene.notes)
      if (n.text.find("ripples with the nodes") != std::string::npos) out.push_back(n.text);
    return out;
  };
  const std::vector<std::string> small = ripple_notes(5e-3, ContactModel::kSurface);
  ASSERT_EQ(small.size(), 1u);
  EXPECT_NE(small[0].find("5 mm node spacing (R = 1.00 h)"), std::string::npos) << small[0];
  EXPECT_TRUE(ripple_notes(10e-3, ContactModel::kSurface).empty());
  EXPECT_TRUE(ripple_notes(5e-3, ContactModel::kNodes).empty());
}

}  // namespace
}  // namespace conica::loop
