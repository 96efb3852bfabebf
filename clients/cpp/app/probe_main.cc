// conica-probe: drives probes through a built-in script or a CSV trajectory and records the
// server's replies to CSV (t,probe,seq,x,y,z,fx,fy,fz,contact,rtt_us).
//
// By default each probe has one request outstanding and the script clock advances one sample
// per reply (as fast as the server answers); --realtime sends every sample at its script time
// (absolute deadlines on CLOCK_MONOTONIC) and records whatever comes back.
#include <CLI/CLI.hpp>
#include <algorithm>
#include <cstdio>
#include <fstream>
#include <iostream>
#include <map>
#include <memory>
#include <sstream>
#include <string>
#include <vector>

#include "client/connection.h"
#include "common/latency_stats.h"
#include "common/trajectory.h"

using namespace conica::client;

namespace {

struct ProbeRun {
  int id = 0;
  std::unique_ptr<ProbeSource> source;
  bool done = false;
  int outstanding = 0;
  Feedback feedback;
  bool have_feedback = false;
  Sample next;
  bool have_next = false;
};

struct Request {
  int run = -1;   // index into runs
  double t = 0;   // script time, s
  Vec3 position;  // m
  std::int64_t sent_ns = 0;
  bool answered = false;
};

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{"conica-probe: scripted probes against conica-server, replies recorded to CSV"};
  std::string endpoint = "tcp://127.0.0.1:5555", script = "press", trajectory, out_path = "-";
  std::string at = "0.02,0.02,0.045", axis = "-z", sweep_dir = "x", spacing = "0.01,0,0";
  std::vector<int> probes{0};
  ScriptParams p;
  double rate_hz = 1000, radius = 0, timeout_s = 2;
  bool realtime = false;
  std::uint32_t client_id = 1;
  std::string curve_server_pub, curve_key;
  app.add_option("--endpoint", endpoint, "probe ROUTER of the server");
  app.add_option("--script", script, "press, ramp, sine, sweep or creep");
  app.add_option("--trajectory", trajectory, "CSV file t,probe,x,y,z (s, m) instead of a script");
  app.add_option("--probes", probes, "probe indices the script drives (e.g. 0,1)")->delimiter(',');
  app.add_option("--spacing", spacing, "m, offset x,y,z added per further probe of a script");
  app.add_option("--at", at, "m, probe centre x,y,z at depth 0 (default: top of the builtin cube)");
  app.add_option("--axis", axis, "pressing direction: x, -z, ... or x,y,z");
  app.add_option("--depth", p.depth, "m, press depth (creep: the most it may go)");
  app.add_option("--approach", p.approach, "m, start this far outside the contact point");
  app.add_option("--speed", p.speed, "m/s, approach and pressing speed");
  app.add_option("--hold", p.hold, "s, hold time (press, creep)");
  app.add_option("--freq", p.freq, "Hz (sine)");
  app.add_option("--cycles", p.cycles, "cycles (sine)");
  app.add_option("--length", p.length, "m, sweep length (sweep)");
  app.add_option("--sweep-dir", sweep_dir, "sweep direction (sweep)");
  app.add_option("--force", p.target_force, "N, target normal force (creep)");
  app.add_option("--gain", p.gain, "m/(N s), force controller gain (creep)");
  app.add_option("--rate-hz", rate_hz, "script sample rate, Hz")->check(CLI::Range(1.0, 100000.0));
  app.add_option("--radius", radius, "m, probe radius (0: the scene's)");
  app.add_option("--client-id", client_id, "client id sent with every update");
  app.add_option("--timeout", timeout_s, "s to wait for a reply before giving up");
  app.add_option("-o,--out", out_path, "CSV output file ('-': stdout)");
  app.add_flag("--realtime", realtime, "pace by the script clock instead of as fast as possible");
  app.add_option("--curve-server-pub", curve_server_pub,
                 "CURVE: the server's public certificate (its NAME.key, not NAME.key_secret)");
  app.add_option("--curve-key", curve_key,
                 "CURVE: this client's secret certificate NAME.key_secret (the server lists "
                 "its NAME.key)");
  CLI11_PARSE(app, argc, argv);

  auto fail = [](const std::string& m) {
    std::cerr << "conica-probe: " << m << "\n";
    return 1;
  };
  const auto at_v = parse_vec3(at);
  const auto axis_v = parse_axis(axis);
  const auto sweep_v = parse_axis(sweep_dir);
  const auto spacing_v = parse_vec3(spacing);
  if (!at_v) return fail("--at must be x,y,z in metres, got \"" + at + "\"");
  if (!axis_v) return fail("--axis must be x, -z, ... or a non-zero x,y,z, got \"" + axis + "\"");
  if (!sweep_v) return fail("--sweep-dir must be an axis, got \"" + sweep_dir + "\"");
  if (!spacing_v) return fail("--spacing must be x,y,z in metres, got \"" + spacing + "\"");
  p.axis = *axis_v;
  p.sweep_dir = *sweep_v;
  p.dt = 1.0 / rate_hz;

  CurveClient curve;
  if (std::string e = load_curve_client(curve_server_pub, curve_key, &curve); !e.empty())
    return fail(e);

  std::vector<ProbeRun> runs;
  std::string error;
  if (!trajectory.empty()) {
    std::vector<TrajectoryRow> rows;
    if (!load_trajectory(trajectory, &rows, &error)) return fail(error);
    std::map<int, std::vector<TrajectoryRow>> by_probe;
    for (const auto& r : rows) by_probe[r.probe].push_back(r);
    for (auto& [id, list] : by_probe) {
      ProbeRun run;
      run.id = id;
      run.source = make_replay(std::move(list), p.dt);
      runs.push_back(std::move(run));
    }
  } else {
    for (std::size_t i = 0; i < probes.size(); ++i) {
      if (probes[i] < 0) return fail("probe indices must be >= 0");
      ScriptParams pi = p;
      pi.at = *at_v + static_cast<double>(i) * *spacing_v;
      ProbeRun run;
      run.id = probes[i];
      run.source = make_script(script, pi, &error);
      if (!run.source) return fail(error);
      runs.push_back(std::move(run));
    }
  }

  std::ofstream file;
  std::ostream* out = &std::cout;
  if (out_path != "-") {
    file.open(out_path);
    if (!file) return fail("cannot write " + out_path);
    out = &file;
  }
  *out << "t,probe,seq,x,y,z,fx,fy,fz,contact,rtt_us\n";

  zmq::context_t context(1);
  ProbeConnection conn(context, endpoint, client_id, curve);
  std::vector<Request> requests;
  requests.reserve(1 << 16);
  std::vector<double> rtts;
  double max_force = 0;
  const std::int64_t timeout_ns = static_cast<std::int64_t>(timeout_s * 1e9);
  const std::int64_t t0 = now_ns() + 20'000'000;  // realtime: start 20 ms from now
  std::int64_t last_progress = now_ns();

  auto send = [&](int r, const Sample& s, std::int64_t stamp_ns) {
    const std::uint64_t seq = requests.size();
    requests.push_back({r, s.t, s.position, stamp_ns, false});
    if (!conn.send(static_cast<std::uint32_t>(runs[r].id), seq,
                   static_cast<std::uint64_t>(stamp_ns), s.position, radius))
      return false;
    ++runs[r].outstanding;
    return true;
  };
  // Handles one message if one arrives by deadline_ns. Returns false on a fatal error.
  auto receive = [&](std::int64_t deadline_ns) {
    ForceSample f;
    bool got = false;
    const ReplyKind kind = conn.receive(deadline_ns, &f, &error, &got);
    if (!got) return true;
    const std::int64_t now = now_ns();
    if (kind == ReplyKind::kError || kind == ReplyKind::kMalformed) return false;
    if (kind != ReplyKind::kForce || f.sequence >= requests.size()) return true;
    Request& q = requests[f.sequence];
    if (q.answered || f.client_id != client_id) return true;
    q.answered = true;
    ProbeRun& run = runs[q.run];
    --run.outstanding;
    run.feedback = {q.t, f.force, f.contact};
    run.have_feedback = true;
    const double rtt_us = (now - q.sent_ns) * 1e-3;
    rtts.push_back(rtt_us);
    max_force = std::max(max_force, f.force.norm());
    char line[320];
    std::snprintf(line, sizeof line, "%.6f,%d,%llu,%.9g,%.9g,%.9g,%.9g,%.9g,%.9g,%d,%.1f\n", q.t,
                  run.id, static_cast<unsigned long long>(f.sequence), q.position.x(),
                  q.position.y(), q.position.z(), f.force.x(), f.force.y(), f.force.z(),
                  f.contact ? 1 : 0, rtt_us);
    *out << line;
    last_progress = now;
    return true;
  };
  auto fetch = [&](ProbeRun& run) {
    if (run.done || run.have_next) return;
    run.have_next = run.source->next(run.have_feedback ? &run.feedback : nullptr, &run.next);
    if (!run.have_next) run.done = true;
  };

  for (;;) {
    for (auto& run : runs)
      if (realtime || run.outstanding == 0) fetch(run);
    bool pending = false, outstanding = false;
    for (auto& run : runs) {
      pending |= run.have_next;
      outstanding |= run.outstanding > 0;
    }
    if (!pending && !outstanding) break;
    if (!realtime) {
      for (std::size_t r = 0; r < runs.size(); ++r) {
        ProbeRun& run = runs[r];
        if (run.have_next && run.outstanding == 0) {
          if (!send(static_cast<int>(r), run.next, now_ns()))
            return fail("cannot queue a probe update");
          run.have_next = false;
        }
      }
      if (!receive(now_ns() + timeout_ns)) return fail(error);
    } else {
      // Earliest sample due; replies are handled while waiting for it.
      int due = -1;
      for (std::size_t r = 0; r < runs.size(); ++r)
        if (runs[r].have_next && (due < 0 || runs[r].next.t < runs[due].next.t))
          due = static_cast<int>(r);
      if (due >= 0) {
        const std::int64_t at_ns = t0 + static_cast<std::int64_t>(runs[due].next.t * 1e9);
        while (now_ns() < at_ns)
          if (!receive(at_ns)) return fail(error);
        if (!send(due, runs[due].next, at_ns)) return fail("cannot queue a probe update");
        runs[due].have_next = false;
      } else if (!receive(now_ns() + 10'000'000)) {
        return fail(error);
      }
    }
    if (now_ns() - last_progress > timeout_ns && (!realtime || !pending))
      return fail("no reply from " + endpoint + " within " + std::to_string(timeout_s) +
                  " s; is conica-server running there?");
  }
  out->flush();
  const LatencySummary s = summarize(rtts);
  std::fprintf(stderr,
               "conica-probe: %zu replies from %zu probe(s), max |F| %.3f N, round trip p50 %.0f "
               "us p99 %.0f us\n",
               s.count, runs.size(), max_force, s.p50, s.p99);
  return 0;
}
