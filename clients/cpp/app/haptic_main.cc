// conica-haptic: the 1 kHz servo loop for a haptic device. Each tick: read the device, take the
// server's replies, render (haptics/renderer.h: clamps, virtual coupling, interpolation with the
// reply's stiffness, passivity controller), command the force, send the simulated probe's
// position. Deadlines are absolute (CLOCK_MONOTONIC); an overrun skips ticks and counts them.
#include <sys/prctl.h>

#include <CLI/CLI.hpp>
#include <algorithm>
#include <csignal>
#include <cstdio>
#include <fstream>
#include <iostream>
#include <memory>
#include <string>

#include "client/connection.h"
#include "haptics/device.h"
#include "haptics/servo.h"

using namespace conica::client;
using namespace conica::haptics;

namespace {

volatile std::sig_atomic_t g_stop = 0;
void on_signal(int) { g_stop = 1; }

// The server over ZeroMQ: one update per tick, replies taken as they come.
class ZmqLink : public ForceLink {
 public:
  ZmqLink(zmq::context_t& ctx, const std::string& endpoint, std::uint32_t probe, double radius,
          const CurveClient& curve)
      : conn_(ctx, endpoint, 11, curve), probe_(probe), radius_(radius) {}
  void send(double, const Vec3& p) override {
    if (!conn_.send(probe_, seq_++, static_cast<std::uint64_t>(now_ns()), p, radius_))
      ++send_failures;
  }
  bool poll(double t, LocalModel* out) override {
    for (;;) {
      bool got = false;
      const ReplyKind k = conn_.receive(0, &f_, &error_, &got);
      if (!got) return false;
      if (k == ReplyKind::kError || k == ReplyKind::kMalformed) {
        ++errors;
        last_error = error_;
        continue;
      }
      if (k != ReplyKind::kForce || f_.probe_id != probe_) continue;
      out->t = t;
      out->x0 = f_.position;
      out->f0 = f_.force;
      out->k = f_.stiffness;
      out->contact = f_.contact;
      ++replies;
      return true;
    }
  }
  std::uint64_t replies = 0, errors = 0, send_failures = 0;
  std::string last_error;

 private:
  ProbeConnection conn_;
  std::uint32_t probe_;
  double radius_;
  std::uint64_t seq_ = 0;
  ForceSample f_;
  std::string error_;
};

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{"conica-haptic: 1 kHz haptic servo loop against conica-server"};
  std::string device_name = "virtual", profile_name = "touch", endpoint = "tcp://127.0.0.1:5555";
  std::string offset = "0.02,0.02,0.045", log_path, hand_start = "0.02,0.02,0.05", hand_axis = "-z";
  double seconds = 10, scale = 1, rate_hz = 1000, radius = 0;
  double hand_depth = 0.012, hand_period = 2.0, hand_k = 300, hand_b = 2;
  double wall_k = 0;
  std::uint32_t probe = 0;
  std::string curve_server_pub, curve_key;
  bool list = false, no_pc = false, no_coupling = false, no_interp = false;
  RendererOptions ro;
  app.add_flag("--list-devices", list, "list device backends and how to enable the missing ones");
  app.add_option("--device", device_name, "virtual, openhaptics, dhd or nifalcon");
  app.add_option("--profile", profile_name,
                 "touch, omni, falcon or omega (force and stiffness limits)");
  app.add_option("--endpoint", endpoint, "probe ROUTER of the server");
  app.add_option("--probe", probe, "probe index in the scene");
  app.add_option("--radius", radius, "m, probe radius (0: the scene's)");
  app.add_option("--seconds", seconds, "run time (0: until Ctrl-C)");
  app.add_option("--rate-hz", rate_hz, "servo rate")->check(CLI::Range(100.0, 10000.0));
  app.add_option("--offset", offset, "m, scene point of the device origin (hardware devices)");
  app.add_option("--scale", scale, "workspace scale, scene m per device m (hardware devices)");
  app.add_option("--coupling-stiffness", ro.coupling_stiffness, "N/m (0: the profile's max)");
  app.add_option("--coupling-damping", ro.coupling_damping, "N s/m");
  app.add_option("--reply-timeout", ro.reply_timeout, "s without replies before the force fades");
  app.add_flag("--no-passivity", no_pc, "disable the passivity observer/controller");
  app.add_flag("--no-coupling", no_coupling, "render the local model at the device position");
  app.add_flag("--no-interpolate", no_interp, "hold the last reply's force between replies");
  app.add_option("--hand-start", hand_start, "virtual: m, where the scripted hand starts");
  app.add_option("--hand-axis", hand_axis, "virtual: direction the hand presses");
  app.add_option("--hand-depth", hand_depth, "virtual: m the hand moves along the axis and back");
  app.add_option("--hand-period", hand_period, "virtual: s per press");
  app.add_option("--hand-stiffness", hand_k, "virtual: N/m, hand impedance");
  app.add_option("--hand-damping", hand_b, "virtual: N s/m, hand impedance");
  app.add_option("--offline-wall", wall_k,
                 "N/m: no server; a wall through --offset, normal +z, answers 2 ticks late");
  app.add_option("--log", log_path, "CSV per tick: t,x,y,z,px,py,pz,fx,fy,fz");
  app.add_option("--curve-server-pub", curve_server_pub,
                 "CURVE: the server's public certificate (its NAME.key, not NAME.key_secret)");
  app.add_option("--curve-key", curve_key,
                 "CURVE: this client's secret certificate NAME.key_secret (the server lists "
                 "its NAME.key)");
  CLI11_PARSE(app, argc, argv);

  if (list) {
    std::printf("device backends:\n");
    for (const auto& b : device_backends()) {
      std::printf("  %-12s %s  %s [%s]\n", b.name.c_str(),
                  b.available ? "available  " : "not built  ", b.devices.c_str(), b.units.c_str());
      if (!b.available) std::printf("               to enable: %s\n", b.enable.c_str());
    }
    std::printf("profiles:\n");
    for (const auto& p : device_profiles())
      std::printf("  %-8s max force %.1f N, max stiffness %.0f N/m, slew %.0f N/s\n",
                  p.name.c_str(), p.max_force, p.max_stiffness, p.max_force_rate);
    return 0;
  }
  auto fail = [](const std::string& m) {
    std::cerr << "conica-haptic: " << m << "\n";
    return 1;
  };
  const auto prof = find_profile(profile_name);
  if (!prof) return fail("unknown profile \"" + profile_name + "\" (touch, omni, falcon, omega)");
  const auto off = parse_vec3(offset), hs = parse_vec3(hand_start);
  const auto ha = parse_axis(hand_axis);
  if (!off || !hs || !ha) return fail("--offset / --hand-start must be x,y,z, --hand-axis an axis");
  ro.dt = 1.0 / rate_hz;
  ro.passivity = !no_pc;
  ro.coupling = !no_coupling;
  ro.interpolate = !no_interp;

  std::unique_ptr<Device> device;
  VirtualDevice* virt = nullptr;
  if (device_name == "virtual") {
    VirtualDeviceOptions vo;
    vo.mass = prof->mass;
    vo.hand_stiffness = hand_k;
    vo.hand_damping = hand_b;
    vo.dt = ro.dt;
    vo.hand = hand_press(*hs, *ha, hand_depth, hand_period);
    auto v = std::make_unique<VirtualDevice>(vo);
    virt = v.get();
    device = std::move(v);
  } else {
    DeviceFrame frame = device_name == "openhaptics" ? openhaptics_frame() : si_frame();
    if (device_name == "nifalcon") frame.rotation = openhaptics_frame().rotation;  // Y up, m
    frame.offset = *off;
    frame.scale = scale;
    std::string error;
    device = open_hardware(device_name, frame, &error);
    if (!device) return fail(error);
  }

  CurveClient curve;
  if (std::string e = load_curve_client(curve_server_pub, curve_key, &curve); !e.empty())
    return fail(e);

  zmq::context_t ctx(1);
  std::unique_ptr<ForceLink> link;
  ZmqLink* zl = nullptr;
  if (wall_k > 0) {
    link = std::make_unique<WallLink>(*off, Vec3(0, 0, 1), wall_k, 2, ro.dt);
  } else {
    auto z = std::make_unique<ZmqLink>(ctx, endpoint, probe, radius, curve);
    zl = z.get();
    link = std::move(z);
  }
  Renderer renderer(*prof, ro);

  std::ofstream log;
  if (!log_path.empty()) {
    log.open(log_path);
    if (!log) return fail("cannot write " + log_path);
    log << "t,x,y,z,px,py,pz,fx,fy,fz\n";
  }
  std::signal(SIGINT, on_signal);
  std::signal(SIGTERM, on_signal);
  prctl(PR_SET_TIMERSLACK, 1UL, 0, 0, 0);

  const std::int64_t period = static_cast<std::int64_t>(1e9 / rate_hz + 0.5);
  const std::int64_t t0 = now_ns() + 50'000'000;
  const std::int64_t ticks = seconds > 0 ? static_cast<std::int64_t>(seconds * rate_hz) : INT64_MAX;
  std::int64_t k = 0, missed = 0, done = 0;
  double peak = 0;
  while (k < ticks && !g_stop) {
    sleep_until_ns(t0 + k * period);
    const double t = k * ro.dt;
    const ServoTick s = servo_tick(t, *device, renderer, *link);
    peak = std::max(peak, s.force.norm());
    ++done;
    if (log.is_open()) {
      char line[256];
      std::snprintf(line, sizeof line, "%.4f,%.7g,%.7g,%.7g,%.7g,%.7g,%.7g,%.6g,%.6g,%.6g\n", t,
                    s.device.position.x(), s.device.position.y(), s.device.position.z(),
                    s.probe.x(), s.probe.y(), s.probe.z(), s.force.x(), s.force.y(), s.force.z());
      log << line;
    }
    // Next deadline; skip the ones already past (no catch-up burst).
    const std::int64_t next = (now_ns() - t0) / period + 1;
    missed += std::max<std::int64_t>(0, next - (k + 1));
    k = std::max(k + 1, next);
  }
  device->close();

  const RendererStats& st = renderer.stats();
  std::printf("conica-haptic: %s device, %s profile, %lld ticks, %lld missed\n",
              device->name().c_str(), prof->name.c_str(), static_cast<long long>(done),
              static_cast<long long>(missed));
  std::printf("  replies %llu (rejected %llu), stale ticks %llu, peak force %.3f N\n",
              static_cast<unsigned long long>(st.replies),
              static_cast<unsigned long long>(st.rejected_replies),
              static_cast<unsigned long long>(st.stale_ticks), peak);
  std::printf(
      "  clamped: force %llu ticks, rate %llu ticks, stiffness %llu replies; passivity "
      "controller active %llu ticks\n",
      static_cast<unsigned long long>(st.force_clamped),
      static_cast<unsigned long long>(st.rate_clamped),
      static_cast<unsigned long long>(st.stiffness_clamped),
      static_cast<unsigned long long>(st.pc_active_ticks));
  std::printf("  work done on the device by the rendered force: %.6f J", st.device_work);
  if (virt) std::printf(" (virtual device's own account: %.6f J)", virt->work_received());
  std::printf("\n");
  if (zl && zl->errors)
    std::printf("  server errors %llu, last: %s\n", static_cast<unsigned long long>(zl->errors),
                zl->last_error.c_str());
  if (zl && zl->replies == 0)
    return fail("no replies from " + endpoint + "; is conica-server running?");
  return 0;
}
