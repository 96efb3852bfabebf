// conica-soak: the server under churn for a long time. A server at --rate-hz on loopback ports
// picked by the OS; --clients churning clients each loop: connect, a seeded random number of
// probe round trips along a moving path, now and then a malformed message (garbage, wrong
// version, NaN, unknown probe, wrong type) that must be answered with an error, now and then a
// control GET_STATS, disconnect. A subscriber reads state frames.
//
// By default every client and the subscriber is a process of its own (this program run again
// with the hidden --client-only / --subscriber-only options; started before the server's loop,
// they get the endpoints on stdin when it runs), so that the server process's
// resident memory, CPU time and missed ticks are the server's alone: with --realtime,
// mlockall(MCL_FUTURE) would otherwise make every client thread's stack and socket buffers
// resident in the measured process. The children end with the run, on SIGINT/SIGTERM to this
// program (they are sent SIGTERM, then SIGKILL after 3 s, and reaped), and with this program
// (PR_SET_PDEATHSIG). --in-process runs the clients as threads of the server's process instead.
//
// Prints missed ticks, errors by kind, resident memory (VmRSS) and a per-minute profile (missed
// ticks, lateness, CPU use of the server, the clients and everything else), and ends with
//   missed_ticks=A ticks=B errors=C rss_start_kib=D rss_end_kib=E
// errors counts what should not happen: unanswered requests, wrong replies, server-side errors
// beyond the malformed messages sent on purpose, client processes that failed. rss_start is taken
// after a warm-up (--warmup seconds; by default the first 10 % of the run, at most 30 s); the
// value at launch is printed too.
// Exit status 1 when errors > 0, missed ticks exceed --max-missed-fraction of the ticks, or
// memory grew by more than --max-rss-growth-kib; 128 + signal number when interrupted.
#include <fcntl.h>
#include <malloc.h>
#include <poll.h>
#include <signal.h>
#include <spdlog/spdlog.h>
#include <sys/prctl.h>
#include <sys/wait.h>
#include <unistd.h>

#include <CLI/CLI.hpp>
#include <algorithm>
#include <atomic>
#include <cerrno>
#include <chrono>
#include <cinttypes>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <fstream>
#include <iostream>
#include <limits>
#include <map>
#include <optional>
#include <random>
#include <sstream>
#include <string>
#include <thread>
#include <vector>
#include <zmq.hpp>

#include "io/scene.h"
#include "net/builtin_scenes.h"
#include "net/server.h"

namespace {

using Clock = std::chrono::steady_clock;
using conica::Vec3;
namespace v1 = conica::v1;

long rss_kib() {
  std::ifstream f("/proc/self/status");
  std::string key;
  long value = -1;
  while (f >> key) {
    if (key == "VmRSS:") {
      f >> value;
      return value;
    }
    f.ignore(std::numeric_limits<std::streamsize>::max(), '\n');
  }
  return value;
}

// The C heap of this process (every malloc arena and mmapped chunk), KiB: what the program has
// allocated now, and what the allocator holds from the system (in use + free, kept for reuse).
struct Heap {
  long in_use_kib = 0, held_kib = 0;
};

Heap heap_kib() {
  const struct mallinfo2 mi = mallinfo2();
  return {static_cast<long>((mi.uordblks + mi.hblkhd) / 1024),
          static_cast<long>((mi.arena + mi.hblkhd) / 1024)};
}

// CPU time (user + system) of a process, s; -1 when it cannot be read.
double cpu_seconds(pid_t pid) {
  std::ifstream f(pid == 0 ? std::string("/proc/self/stat")
                           : "/proc/" + std::to_string(pid) + "/stat");
  std::string line;
  if (!std::getline(f, line)) return -1;
  const auto close = line.rfind(')');
  if (close == std::string::npos) return -1;
  std::istringstream in(line.substr(close + 2));  // from field 3 (state) on
  std::string field;
  unsigned long long utime = 0, stime = 0;
  for (int k = 3; k <= 15 && in >> field; ++k) {
    if (k == 14) utime = std::stoull(field);
    if (k == 15) stime = std::stoull(field);
  }
  return static_cast<double>(utime + stime) / static_cast<double>(sysconf(_SC_CLK_TCK));
}

// Whole machine: busy, kernel (system, irq, softirq) and total CPU time over all cores, s;
// runnable threads now; 1-min load.
struct MachineSample {
  double busy_s = 0, kernel_s = 0, total_s = 0, load1 = 0;
  int procs_running = 0;
};

MachineSample machine_sample() {
  MachineSample m;
  std::ifstream f("/proc/stat");
  std::string key;
  while (f >> key) {
    if (key == "cpu") {
      unsigned long long v[10] = {};
      for (auto& x : v) f >> x;
      unsigned long long total = 0;
      for (int k = 0; k < 8; ++k) total += v[k];  // guest time is inside user already
      const double hz = static_cast<double>(sysconf(_SC_CLK_TCK));
      m.total_s = static_cast<double>(total) / hz;
      m.busy_s = static_cast<double>(total - v[3] - v[4]) / hz;  // minus idle and iowait
      m.kernel_s = static_cast<double>(v[2] + v[5] + v[6]) / hz;
    } else if (key == "procs_running") {
      f >> m.procs_running;
    }
    f.ignore(std::numeric_limits<std::streamsize>::max(), '\n');
  }
  std::ifstream l("/proc/loadavg");
  l >> m.load1;
  return m;
}

struct Tally {
  std::atomic<std::uint64_t> sessions{0}, probes{0}, replies{0}, malformed_sent{0},
      malformed_answered{0}, controls{0}, timeouts{0}, wrong_replies{0}, frames{0};
};

// "key=value ..." for the child's report line, and back.
std::string tally_line(const Tally& t) {
  char buf[512];
  std::snprintf(buf, sizeof buf,
                "tally sessions=%" PRIu64 " probes=%" PRIu64 " replies=%" PRIu64
                " malformed_sent=%" PRIu64 " malformed_answered=%" PRIu64 " controls=%" PRIu64
                " timeouts=%" PRIu64 " wrong_replies=%" PRIu64 " frames=%" PRIu64 "\n",
                t.sessions.load(), t.probes.load(), t.replies.load(), t.malformed_sent.load(),
                t.malformed_answered.load(), t.controls.load(), t.timeouts.load(),
                t.wrong_replies.load(), t.frames.load());
  return buf;
}

// Adds a child's report to `t`; false when the line is not a complete report.
bool add_tally_line(const std::string& text, Tally* t) {
  std::istringstream in(text);
  std::string word;
  if (!(in >> word) || word != "tally") return false;
  std::map<std::string, std::uint64_t> kv;
  while (in >> word) {
    const auto eq = word.find('=');
    if (eq == std::string::npos) return false;
    kv[word.substr(0, eq)] = std::stoull(word.substr(eq + 1));
  }
  const std::pair<const char*, std::atomic<std::uint64_t>*> fields[] = {
      {"sessions", &t->sessions},
      {"probes", &t->probes},
      {"replies", &t->replies},
      {"malformed_sent", &t->malformed_sent},
      {"malformed_answered", &t->malformed_answered},
      {"controls", &t->controls},
      {"timeouts", &t->timeouts},
      {"wrong_replies", &t->wrong_replies},
      {"frames", &t->frames}};
  for (const auto& [name, counter] : fields)
    if (kv.count(name) == 0) return false;
  for (const auto& [name, counter] : fields) *counter += kv[name];
  return true;
}

std::string probe_bytes(std::uint64_t seq, const Vec3& c, std::uint32_t probe_id = 0) {
  v1::ClientMessage m;
  m.set_protocol_version(1);
  auto* p = m.mutable_probe();
  p->set_client_id(7);
  p->set_probe_id(probe_id);
  p->set_sequence(seq);
  p->mutable_position()->set_x(c.x());
  p->mutable_position()->set_y(c.y());
  p->mutable_position()->set_z(c.z());
  return m.SerializeAsString();
}

std::optional<v1::ServerMessage> recv_one(zmq::socket_t& s, int timeout_ms) {
  zmq::pollitem_t item{s.handle(), 0, ZMQ_POLLIN, 0};
  if (zmq::poll(&item, 1, std::chrono::milliseconds(timeout_ms)) == 0) return std::nullopt;
  zmq::message_t msg;
  if (!s.recv(msg, zmq::recv_flags::dontwait)) return std::nullopt;
  v1::ServerMessage out;
  if (!out.ParseFromArray(msg.data(), static_cast<int>(msg.size()))) return v1::ServerMessage{};
  return out;
}

// A probe id no scene of the soak has (more than --clients allows).
constexpr std::uint32_t kUnknownProbe = 100000;

// One churning client: sessions until `end` or `stop`, moving probe `probe_id`.
void churn(zmq::context_t& ctx, const conica::net::Endpoints& ep, Vec3 lo, Vec3 hi, int id,
           std::uint32_t probe_id, Clock::time_point end, const std::atomic<bool>& stop, Tally& t) {
  std::mt19937_64 rng(1234 + id);
  std::uniform_real_distribution<double> u(0, 1);
  std::uint64_t seq = 0;
  const double nan = std::numeric_limits<double>::quiet_NaN();
  const auto going = [&] { return Clock::now() < end && !stop.load(std::memory_order_relaxed); };
  while (going()) {
    ++t.sessions;
    zmq::socket_t s(ctx, zmq::socket_type::dealer);
    s.set(zmq::sockopt::linger, 0);
    s.connect(ep.probe);
    const int n = 1 + static_cast<int>(u(rng) * 50);
    const Vec3 c0 = lo + (hi - lo).cwiseProduct(Vec3(u(rng), u(rng), 1.0));
    for (int k = 0; k < n && going(); ++k) {
      ++seq;
      const int kind = static_cast<int>(u(rng) * 20);  // 1 in 20: malformed
      std::string bytes;
      bool bad = true;
      switch (kind) {
        case 0: {
          const int r = static_cast<int>(u(rng) * 5);
          if (r == 0) bytes = std::string("\xff\x01garbage", 9);
          if (r == 1) {
            v1::ClientMessage m;
            m.ParseFromString(probe_bytes(seq, c0, probe_id));
            m.set_protocol_version(99);
            bytes = m.SerializeAsString();
          }
          if (r == 2) bytes = probe_bytes(seq, Vec3(nan, 0, 0), probe_id);
          if (r == 3) bytes = probe_bytes(seq, c0, kUnknownProbe);
          if (r == 4) {
            v1::ClientMessage m;
            m.set_protocol_version(1);
            m.mutable_control()->set_kind(v1::ControlRequest::GET_STATS);
            bytes = m.SerializeAsString();
          }
          break;
        }
        default: {
          // Down into the body and back along a slow sine, 2 mm deep at most.
          const double depth = 2e-3 * std::sin(0.3 * static_cast<double>(k));
          bytes = probe_bytes(seq, c0 + Vec3(0, 0, 5e-3 - depth), probe_id);
          bad = false;
        }
      }
      if (!s.send(zmq::buffer(bytes), zmq::send_flags::dontwait)) {
        ++t.timeouts;
        continue;
      }
      bad ? ++t.malformed_sent : ++t.probes;
      auto r = recv_one(s, 1000);
      if (!r) {
        if (stop.load()) break;  // interrupted while waiting: not the server's fault
        ++t.timeouts;
        break;  // this connection is suspect: start a new session
      }
      if (bad && r->body_case() == v1::ServerMessage::kError)
        ++t.malformed_answered;
      else if (!bad && r->body_case() == v1::ServerMessage::kForce && r->force().sequence() == seq)
        ++t.replies;
      else
        ++t.wrong_replies;
    }
    if (going() && u(rng) < 0.1) {  // now and then the control socket
      zmq::socket_t c(ctx, zmq::socket_type::dealer);
      c.set(zmq::sockopt::linger, 0);
      c.connect(ep.control);
      v1::ClientMessage m;
      m.set_protocol_version(1);
      m.mutable_control()->set_kind(v1::ControlRequest::GET_STATS);
      m.mutable_control()->set_sequence(++seq);
      c.send(zmq::buffer(m.SerializeAsString()), zmq::send_flags::none);
      auto r = recv_one(c, 1000);
      if (!r) {
        if (!stop.load()) ++t.timeouts;
      } else if (r->body_case() != v1::ServerMessage::kControlReply) {
        ++t.wrong_replies;
      } else {
        ++t.controls;
      }
    }
    std::this_thread::sleep_for(std::chrono::microseconds(static_cast<int>(u(rng) * 2000)));
  }
}

// The subscriber: counts complete state messages until `end` or `stop`.
void subscribe(zmq::context_t& ctx, const std::string& endpoint, Clock::time_point end,
               const std::atomic<bool>& stop, Tally& t) {
  zmq::socket_t sub(ctx, zmq::socket_type::sub);
  sub.set(zmq::sockopt::linger, 0);
  sub.set(zmq::sockopt::subscribe, "");
  sub.connect(endpoint);
  zmq::message_t m;
  while (Clock::now() < end && !stop.load(std::memory_order_relaxed)) {
    zmq::pollitem_t item{sub.handle(), 0, ZMQ_POLLIN, 0};
    if (zmq::poll(&item, 1, std::chrono::milliseconds(100)) > 0)
      while (sub.recv(m, zmq::recv_flags::dontwait))
        if (!m.more()) ++t.frames;
  }
}

// --client-only K / --subscriber-only: one client in this process. Says "ready" on stdout, reads
// "probe-endpoint state-endpoint control-endpoint box" from stdin (box: min x,y,z,max x,y,z in m,
// comma-separated), runs for `seconds` from then and reports its tally on stdout. SIGINT/SIGTERM
// end it early (a watcher thread takes them; the others keep them blocked, so that no ZeroMQ call
// is interrupted).
int run_child(int client_index, double seconds, std::uint32_t probe_id) {
  sigset_t stop_signals;
  sigemptyset(&stop_signals);
  sigaddset(&stop_signals, SIGINT);
  sigaddset(&stop_signals, SIGTERM);
  pthread_sigmask(SIG_BLOCK, &stop_signals, nullptr);
  std::atomic<bool> stop{false}, done{false};
  std::thread watcher([&] {
    const timespec ts{0, 100000000};
    while (!done.load())
      if (sigtimedwait(&stop_signals, nullptr, &ts) > 0) stop = true;
  });
  const auto fail = [&](const std::string& why) {
    std::fprintf(stderr, "conica-soak client process: %s\n", why.c_str());
    done = true;
    watcher.join();
    return 2;
  };
  Tally tally;
  {
    zmq::context_t ctx(1);
    std::fputs("ready\n", stdout);
    std::fflush(stdout);
    std::string line;
    if (!std::getline(std::cin, line)) return fail("no endpoints on stdin (the soak ended first)");
    std::istringstream in(line);
    conica::net::Endpoints ep;
    std::string box;
    double b[6] = {};
    if (!(in >> ep.probe >> ep.state >> ep.control >> box) ||
        std::sscanf(box.c_str(), "%lf,%lf,%lf,%lf,%lf,%lf", &b[0], &b[1], &b[2], &b[3], &b[4],
                    &b[5]) != 6)
      return fail("expected 'probe state control x,y,z,x,y,z' on stdin, got '" + line + "'");
    const auto end = Clock::now() + std::chrono::duration_cast<Clock::duration>(
                                        std::chrono::duration<double>(seconds));
    if (client_index >= 0)
      churn(ctx, ep, Vec3(b[0], b[1], b[2]), Vec3(b[3], b[4], b[5]), client_index, probe_id, end,
            stop, tally);
    else
      subscribe(ctx, ep.state, end, stop, tally);
  }
  done = true;
  watcher.join();
  const std::string line = tally_line(tally);
  std::fwrite(line.data(), 1, line.size(), stdout);
  std::fflush(stdout);
  return 0;
}

struct Child {
  pid_t pid = -1;
  int in_fd = -1;   // write end of the child's stdin
  int out_fd = -1;  // read end of the child's stdout
  int status = 0;
  bool reaped = false;
};

// Starts this program again with `args`; its stdin and stdout are pipes. Everything the child
// does between fork and exec is async-signal-safe (the parent may have threads).
Child spawn_self(const std::vector<std::string>& args) {
  std::vector<char*> argv;
  static char self[] = "/proc/self/exe";
  argv.push_back(self);
  for (const auto& a : args) argv.push_back(const_cast<char*>(a.c_str()));
  argv.push_back(nullptr);
  int fds[2], in[2];
  Child c;
  if (pipe2(fds, O_CLOEXEC) != 0) return c;
  if (pipe2(in, O_CLOEXEC) != 0) {
    close(fds[0]);
    close(fds[1]);
    return c;
  }
  const pid_t parent = getpid();
  const pid_t pid = fork();
  if (pid == 0) {
    prctl(PR_SET_PDEATHSIG, SIGKILL);
    if (getppid() != parent) _exit(126);  // the parent is already gone
    dup2(fds[1], STDOUT_FILENO);          // dup2 clears close-on-exec on the copy
    dup2(in[0], STDIN_FILENO);
    sigset_t none;
    sigemptyset(&none);
    sigprocmask(SIG_SETMASK, &none, nullptr);  // the parent blocked SIGINT/SIGTERM
    execv(self, argv.data());
    _exit(127);
  }
  close(fds[1]);
  close(in[0]);
  if (pid < 0) {
    close(fds[0]);
    close(in[1]);
    return c;
  }
  c.pid = pid;
  c.out_fd = fds[0];
  c.in_fd = in[1];
  return c;
}

// Reads the child's "ready" line; false after `timeout_ms` or when the child is gone.
bool wait_ready(const Child& c, int timeout_ms) {
  std::string got;
  const auto deadline = Clock::now() + std::chrono::milliseconds(timeout_ms);
  while (got.find('\n') == std::string::npos) {
    const auto left =
        std::chrono::duration_cast<std::chrono::milliseconds>(deadline - Clock::now());
    if (left.count() <= 0) return false;
    pollfd p{c.out_fd, POLLIN, 0};
    if (poll(&p, 1, static_cast<int>(left.count())) <= 0) continue;
    char ch;
    if (read(c.out_fd, &ch, 1) != 1) return false;
    got += ch;
  }
  return got == "ready\n";
}

// Reaps the children that have exited; true when all have.
bool reap(std::vector<Child>& children) {
  bool all = true;
  for (auto& c : children) {
    if (c.reaped || c.pid < 0) continue;
    const pid_t r = waitpid(c.pid, &c.status, WNOHANG);
    if (r == c.pid || (r < 0 && errno == ECHILD))
      c.reaped = true;
    else
      all = false;
  }
  return all;
}

// Waits until `deadline` for the children to end; then SIGTERM, 3 s, SIGKILL. Always reaps all.
void end_children(std::vector<Child>& children, Clock::time_point deadline) {
  const auto wait_until = [&](Clock::time_point t) {
    while (!reap(children) && Clock::now() < t)
      std::this_thread::sleep_for(std::chrono::milliseconds(10));
    return reap(children);
  };
  if (wait_until(deadline)) return;
  for (auto& c : children)
    if (!c.reaped && c.pid > 0) kill(c.pid, SIGTERM);
  if (wait_until(Clock::now() + std::chrono::seconds(3))) return;
  for (auto& c : children)
    if (!c.reaped && c.pid > 0) kill(c.pid, SIGKILL);
  for (auto& c : children)
    if (!c.reaped && c.pid > 0) {
      waitpid(c.pid, &c.status, 0);
      c.reaped = true;
    }
}

std::string read_all(int fd) {
  std::string s;
  char buf[1024];
  for (;;) {
    const ssize_t n = read(fd, buf, sizeof buf);
    if (n > 0) {
      s.append(buf, static_cast<std::size_t>(n));
    } else if (n < 0 && errno == EINTR) {
      continue;
    } else {
      return s;
    }
  }
}

// One sample per second of the server's statistics and of the machine.
struct Sample {
  double t_s = 0;
  std::uint64_t ticks = 0, missed = 0;
  double lat_p50_us = 0, lat_p99_us = 0, lat_max_us = 0;  // the server's last 2048 ticks
  double busy_cores = 0, kernel_cores = 0, server_cores = 0, clients_cores = 0, load1 = 0;
  int procs_running = 0;
  std::uint64_t ref_missed = 0;  // --reference-timer
  double ref_max_us = 0;
  long rss_kib = 0;
  Heap heap;
};

// --reference-timer: a thread of the server's process that does nothing but sleep to the
// loop's absolute deadlines (clock_nanosleep, timer slack 1 ns, SCHED_FIFO one priority below the
// loop with --realtime) and counts missed deadlines by the loop's rule. Its lateness is what the
// kernel and the machine give any thread; what the loop loses beyond it is the server's.
class ReferenceTimer {
 public:
  ReferenceTimer(double rate_hz, bool realtime)
      : period_ns_(std::llround(1e9 / rate_hz)), histogram_(kBins + 1, 0) {
    thread_ = std::thread([this, realtime] { run(realtime); });
  }
  ~ReferenceTimer() { stop(); }
  void stop() {
    stop_ = true;
    if (thread_.joinable()) thread_.join();
  }
  std::uint64_t ticks() const { return ticks_.load(); }
  std::uint64_t missed() const { return missed_.load(); }
  bool fifo() const { return fifo_.load(); }
  // Largest lateness since the last call, us.
  double take_max_us() { return 1e-3 * static_cast<double>(max_ns_.exchange(0)); }
  // Percentile of the lateness over the whole run, us (histogram bins of 10 us; after stop()).
  double percentile_us(double q) const {
    std::uint64_t n = 0;
    for (auto c : histogram_) n += c;
    std::uint64_t seen = 0;
    for (std::size_t k = 0; k < histogram_.size(); ++k) {
      seen += histogram_[k];
      if (static_cast<double>(seen) >= q * static_cast<double>(n))
        return 10.0 * static_cast<double>(k + 1);
    }
    return 0;
  }
  double run_max_us() const { return 1e-3 * static_cast<double>(run_max_ns_); }

 private:
  static constexpr std::size_t kBins = 10000;  // 10 us each, up to 100 ms; the last bin: beyond

  static std::int64_t now_ns() {
    timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return static_cast<std::int64_t>(ts.tv_sec) * 1000000000 + ts.tv_nsec;
  }

  void run(bool realtime) {
    prctl(PR_SET_TIMERSLACK, 1UL, 0, 0, 0);
    if (realtime) {
      sched_param sp{};
      sp.sched_priority = std::min(80, sched_get_priority_max(SCHED_FIFO)) - 1;
      fifo_ = pthread_setschedparam(pthread_self(), SCHED_FIFO, &sp) == 0;
    }
    std::int64_t next = now_ns() + period_ns_;
    while (!stop_.load(std::memory_order_relaxed)) {
      const timespec ts{static_cast<time_t>(next / 1000000000),
                        static_cast<long>(next % 1000000000)};
      while (clock_nanosleep(CLOCK_MONOTONIC, TIMER_ABSTIME, &ts, nullptr) == EINTR) {
      }
      const std::int64_t t = now_ns(), late = std::max<std::int64_t>(0, t - next);
      ++histogram_[std::min<std::size_t>(kBins, static_cast<std::size_t>(late / 10000))];
      run_max_ns_ = std::max(run_max_ns_, late);
      std::int64_t m = max_ns_.load(std::memory_order_relaxed);
      while (late > m && !max_ns_.compare_exchange_weak(m, late)) {
      }
      ++ticks_;
      next += period_ns_;
      if (t > next + period_ns_) {
        const std::int64_t missed = (t - next) / period_ns_;
        next += missed * period_ns_;
        missed_ += static_cast<std::uint64_t>(missed);
      }
    }
  }

  const std::int64_t period_ns_;
  std::vector<std::uint64_t> histogram_;  // allocated and written before the run: resident
  std::int64_t run_max_ns_ = 0;
  std::atomic<std::int64_t> max_ns_{0};
  std::atomic<std::uint64_t> ticks_{0}, missed_{0};
  std::atomic<bool> stop_{false}, fifo_{false};
  std::thread thread_;
};

double median(std::vector<double> v) {
  if (v.empty()) return 0;
  std::nth_element(v.begin(), v.begin() + static_cast<long>(v.size() / 2), v.end());
  return v[v.size() / 2];
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{
      "conica-soak: the server under client churn; no crash, few missed ticks, flat memory"};
  double seconds = 60, rate_hz = 1000, max_missed = 0.001, warmup = -1;
  int clients = 4;
  long max_growth_kib = 1024;
  std::string builtin = "cube", scene_file, profile_csv, contact = "surface";
  bool realtime = false, in_process = false, reference_timer = false, probe_per_client = false;
  int client_only = -1, probe_id = 0;
  bool subscriber_only = false;
  app.add_option("--seconds", seconds, "run time, s")->check(CLI::Range(1.0, 1e6));
  app.add_option("--clients", clients, "churning clients")->check(CLI::Range(1, 256));
  app.add_option("--rate-hz", rate_hz, "server loop rate, Hz")->check(CLI::Range(1.0, 20000.0));
  CLI::Option* builtin_opt = app.add_option("--builtin", builtin, "built-in scene")
                                 ->check(CLI::IsMember(conica::net::builtin_scene_names()));
  app.add_option("--scene", scene_file, "scene file (.pbtxt) instead of a built-in scene")
      ->excludes(builtin_opt);
  CLI::Option* contact_opt =
      app.add_option(
             "--contact", contact,
             "the scene's probe contact: surface (the default, a proxy against the surface) "
             "or nodes (the node penalty)")
          ->check(CLI::IsMember({"surface", "nodes"}));
  app.add_option("--max-missed-fraction", max_missed, "goal: missed ticks / ticks (default 0.001)");
  app.add_option("--max-rss-growth-kib", max_growth_kib, "goal: VmRSS growth, KiB (default 1024)");
  app.add_option("--warmup", warmup,
                 "s, the warm-up before memory and missed ticks are counted, taken at the first "
                 "once-a-second sample past it (default: 10 % of the run, at most 30 s; a large "
                 "multi-rate body's factors and local models take longer to reach their working "
                 "size under churn, docs/reliability.md)")
      ->check(CLI::Range(0.0, 1e6));
  app.add_flag("--probe-per-client", probe_per_client,
               "give each client a probe of its own (probe id = client index; the scene's probe "
               "copied), as devices have, instead of all of them moving probe 0");
  app.add_flag("--realtime", realtime, "let the loop try SCHED_FIFO and mlockall");
  app.add_flag("--in-process", in_process,
               "run the clients as threads of the server's process (their memory and CPU then "
               "count as the server's)");
  app.add_flag("--reference-timer", reference_timer,
               "also run a thread that only sleeps to the loop's deadlines (same scheduling "
               "policy, one priority below) and report its missed deadlines and lateness");
  app.add_option("--profile-csv", profile_csv,
                 "write one row per second: ticks, missed ticks, lateness, CPU use, load, RSS");
  // Hidden: the child processes' modes.
  app.add_option("--client-only", client_only, "run one churning client (index)")->group("");
  app.add_flag("--subscriber-only", subscriber_only, "run the state subscriber")->group("");
  app.add_option("--probe-id", probe_id, "the client's probe")->group("");
  CLI11_PARSE(app, argc, argv);
  if (warmup >= seconds) {
    std::fprintf(stderr, "conica-soak: --warmup %g s must be shorter than --seconds %g s\n", warmup,
                 seconds);
    return 2;
  }
  if (client_only >= 0 || subscriber_only)
    return run_child(subscriber_only ? -1 : client_only, seconds,
                     static_cast<std::uint32_t>(std::max(0, probe_id)));
  spdlog::set_level(spdlog::level::warn);

  // SIGINT/SIGTERM are taken by the main thread (sigtimedwait) so that the children can be ended
  // and reaped; blocked before any thread starts, so every thread inherits the mask.
  sigset_t stop_signals;
  sigemptyset(&stop_signals);
  sigaddset(&stop_signals, SIGINT);
  sigaddset(&stop_signals, SIGTERM);
  pthread_sigmask(SIG_BLOCK, &stop_signals, nullptr);
  signal(SIGPIPE, SIG_IGN);  // a client process that died makes a write fail, not this one

  std::FILE* csv = nullptr;
  if (!profile_csv.empty()) {
    csv = std::fopen(profile_csv.c_str(), "w");
    if (csv == nullptr) {
      std::fprintf(stderr, "conica-soak: cannot write --profile-csv %s: %s\n", profile_csv.c_str(),
                   std::strerror(errno));
      return 2;
    }
    std::fprintf(
        csv,
        "t_s,ticks,missed_ticks,lateness_p50_us,lateness_p99_us,lateness_max_us,"
        "busy_cores,kernel_cores,server_cores,clients_cores,other_cores,procs_running,"
        "load1,rss_kib,heap_in_use_kib,heap_held_kib,ref_missed_ticks,ref_lateness_max_us\n");
  }

  const long rss_launch = rss_kib();
  std::optional<ReferenceTimer> reference;
  if (reference_timer) reference.emplace(rate_hz, realtime);
  zmq::context_t ctx(2);
  conica::net::ServerOptions opt;
  opt.probe_endpoint = opt.state_endpoint = opt.control_endpoint = "tcp://127.0.0.1:*";
  opt.rate_hz = rate_hz;
  opt.log_period_s = 0;
  opt.realtime = realtime;
  opt.refuse_slow_scene = false;
  conica::net::Server server(ctx, opt);
  conica::BodySpec spec;
  std::string err = scene_file.empty() ? conica::net::builtin_scene(builtin, 1.0 / rate_hz, &spec)
                                       : conica::io::load_scene(scene_file, &spec);
  // A built-in scene's probes take --contact (surface unless given); a scene file's keep what it
  // says unless --contact is given.
  if (scene_file.empty() || contact_opt->count() > 0)
    for (conica::ProbeSpec& p : spec.probes)
      p.contact =
          contact == "nodes" ? conica::ContactModel::kNodes : conica::ContactModel::kSurface;
  if (probe_per_client && err.empty()) spec.probes.resize(clients, spec.probes.front());
  if (err.empty()) err = server.load(spec);
  // The client processes start (exec, libraries, ZeroMQ context) before the loop does, so that
  // their start-up costs no ticks; each says "ready" and waits for the endpoints on its stdin.
  std::vector<Child> children;
  if (err.empty() && !in_process) {
    char secs[64];
    std::snprintf(secs, sizeof secs, "%.17g", seconds);
    for (int k = -1; k < clients && err.empty(); ++k) {
      std::vector<std::string> args = {"--seconds", secs};
      if (k < 0) {
        args.push_back("--subscriber-only");
      } else {
        args.push_back("--client-only");
        args.push_back(std::to_string(k));
        args.push_back("--probe-id");
        args.push_back(std::to_string(probe_per_client ? k : 0));
      }
      children.push_back(spawn_self(args));
      if (children.back().pid < 0)
        err = std::string("cannot start a client process: ") + std::strerror(errno);
    }
    for (const auto& c : children)
      if (err.empty() && c.pid > 0 && !wait_ready(c, 30000))
        err = "client process " + std::to_string(c.pid) + " did not get ready within 30 s";
  }
  if (err.empty()) err = server.start();
  if (!err.empty()) {
    std::fprintf(stderr, "conica-soak: %s\n", err.c_str());
    for (auto& c : children)
      if (c.in_fd >= 0) close(c.in_fd);  // EOF: the children end
    end_children(children, Clock::now() + std::chrono::seconds(3));
    return 2;
  }
  const conica::net::Endpoints ep = server.endpoints();
  conica::net::ProbeLimits lim;
  conica::net::body_box(server.model(), 0, &lim);
  const Vec3 lo = lim.box_min, hi = lim.box_max;

  const auto t0 = Clock::now();
  const auto end =
      t0 + std::chrono::duration_cast<Clock::duration>(std::chrono::duration<double>(seconds));
  const auto warm = t0 + std::chrono::duration_cast<Clock::duration>(std::chrono::duration<double>(
                             warmup >= 0 ? warmup : std::min(30.0, 0.1 * seconds)));
  Tally tally;
  std::atomic<bool> stop{false};
  std::vector<std::thread> threads;
  if (in_process) {
    for (int k = 0; k < clients; ++k)
      threads.emplace_back(
          [&, k] { churn(ctx, ep, lo, hi, k, probe_per_client ? k : 0, end, stop, tally); });
    threads.emplace_back([&] { subscribe(ctx, ep.state, end, stop, tally); });
  } else {
    char line[1024];
    std::snprintf(line, sizeof line, "%s %s %s %.17g,%.17g,%.17g,%.17g,%.17g,%.17g\n",
                  ep.probe.c_str(), ep.state.c_str(), ep.control.c_str(), lo.x(), lo.y(), lo.z(),
                  hi.x(), hi.y(), hi.z());
    for (auto& c : children) {
      const std::size_t n = std::strlen(line);
      (void)!write(c.in_fd, line, n);  // a child that cannot take it ends and is counted as failed
      close(c.in_fd);
      c.in_fd = -1;
    }
  }
  const auto clients_cpu = [&] {
    double s = 0;
    for (const auto& c : children)
      if (!c.reaped && c.pid > 0) s += std::max(0.0, cpu_seconds(c.pid));
    return s;
  };

  // Sample once per second until the end (or a signal); a progress line every 60 s.
  int signal_number = 0;
  long rss_start = -1;
  double warm_at = 0;  // s since the run began, when the warm-up's sample was taken
  Heap heap_start;
  long heap_peak_in_use = 0;
  conica::net::LoopStatsData s_start;
  // The sample the run's growth and missed ticks are counted from, taken at time t.
  auto take_warm_sample = [&](Clock::time_point t) {
    warm_at = std::chrono::duration<double>(t - t0).count();
    rss_start = rss_kib();
    heap_start = heap_kib();
    s_start = server.stats();
  };
  std::vector<Sample> samples;
  MachineSample m_prev = machine_sample();
  double server_cpu_prev = cpu_seconds(0), clients_cpu_prev = clients_cpu();
  auto t_prev = Clock::now();
  Sample minute_start;
  double minute_lat_max = 0, minute_p99_worst = 0, minute_ref_max = 0;
  for (auto next = t0 + std::chrono::seconds(1); !stop && Clock::now() < end;
       next += std::chrono::seconds(1)) {
    const auto wake = std::min(next, end);
    for (;;) {  // sleep until `wake`, unless a stop signal comes
      const auto left = wake - Clock::now();
      if (left <= Clock::duration::zero()) break;
      const auto ns = std::chrono::duration_cast<std::chrono::nanoseconds>(left).count();
      const timespec ts{static_cast<time_t>(ns / 1000000000), static_cast<long>(ns % 1000000000)};
      const int sig = sigtimedwait(&stop_signals, nullptr, &ts);
      if (sig > 0) {
        signal_number = sig;
        break;
      }
    }
    if (signal_number != 0) break;
    const auto t = Clock::now();
    if (rss_start < 0 && t >= warm) take_warm_sample(t);
    const auto st = server.stats();
    const MachineSample m = machine_sample();
    const double server_cpu = cpu_seconds(0), client_cpu = clients_cpu();
    const double dt = std::chrono::duration<double>(t - t_prev).count();
    Sample x;
    x.t_s = std::chrono::duration<double>(t - t0).count();
    x.ticks = st.ticks;
    x.missed = st.missed_ticks;
    x.lat_p50_us = st.lateness_p50_us;
    x.lat_p99_us = st.lateness_p99_us;
    x.lat_max_us = st.lateness_max_us;
    x.busy_cores = (m.busy_s - m_prev.busy_s) / dt;
    x.kernel_cores = (m.kernel_s - m_prev.kernel_s) / dt;
    x.server_cores = (server_cpu - server_cpu_prev) / dt;
    x.clients_cores = std::max(0.0, client_cpu - clients_cpu_prev) / dt;
    x.load1 = m.load1;
    x.procs_running = m.procs_running;
    x.rss_kib = rss_kib();
    x.heap = heap_kib();
    heap_peak_in_use = std::max(heap_peak_in_use, x.heap.in_use_kib);
    if (reference) {
      x.ref_missed = reference->missed();
      x.ref_max_us = reference->take_max_us();
    }
    samples.push_back(x);
    if (csv != nullptr) {
      std::fprintf(
          csv,
          "%.1f,%" PRIu64 ",%" PRIu64
          ",%.0f,%.0f,%.0f,%.3f,%.3f,%.3f,%.3f,%.3f,%d,%.2f,%ld,%ld,%ld,%" PRIu64 ",%.0f\n",
          x.t_s, x.ticks, x.missed, x.lat_p50_us, x.lat_p99_us, x.lat_max_us, x.busy_cores,
          x.kernel_cores, x.server_cores, x.clients_cores,
          std::max(0.0, x.busy_cores - x.server_cores - x.clients_cores), x.procs_running, x.load1,
          x.rss_kib, x.heap.in_use_kib, x.heap.held_kib, x.ref_missed, x.ref_max_us);
      std::fflush(csv);
    }
    minute_lat_max = std::max(minute_lat_max, x.lat_max_us);
    minute_p99_worst = std::max(minute_p99_worst, x.lat_p99_us);
    minute_ref_max = std::max(minute_ref_max, x.ref_max_us);
    if (samples.size() % 60 == 0) {
      const double span = x.t_s - minute_start.t_s;
      double busy = 0, kern = 0, srv = 0, cli = 0;
      for (std::size_t k = samples.size() - 60; k < samples.size(); ++k) {
        busy += samples[k].busy_cores / 60;
        kern += samples[k].kernel_cores / 60;
        srv += samples[k].server_cores / 60;
        cli += samples[k].clients_cores / 60;
      }
      const std::uint64_t dticks = x.ticks - minute_start.ticks,
                          dmissed = x.missed - minute_start.missed;
      std::printf(
          "t=%.0f s ticks=%" PRIu64 " missed=%" PRIu64 " | last %.0f s: missed %" PRIu64
          " (%.3f %%), lateness max %.0f us, worst 2-s p99 %.0f us; cores busy %.2f "
          "(server %.2f, clients %.2f, other %.2f; in the kernel %.2f); load %.2f; rss_kib=%ld",
          x.t_s, x.ticks, x.missed, span, dmissed,
          100.0 * static_cast<double>(dmissed) /
              static_cast<double>(std::max<std::uint64_t>(1, dticks)),
          minute_lat_max, minute_p99_worst, busy, srv, cli, std::max(0.0, busy - srv - cli), kern,
          x.load1, x.rss_kib);
      if (reference)
        std::printf("; reference timer missed %" PRIu64 ", lateness max %.0f us",
                    x.ref_missed - minute_start.ref_missed, minute_ref_max);
      std::printf("\n");
      std::fflush(stdout);
      minute_start = x;
      minute_lat_max = minute_p99_worst = minute_ref_max = 0;
    }
    m_prev = m;
    server_cpu_prev = server_cpu;
    clients_cpu_prev = client_cpu;
    t_prev = t;
  }
  if (csv != nullptr) std::fclose(csv);

  // Clients end by themselves at `end` (within about a second: the reply timeout); the children
  // are ended and reaped in every case.
  if (signal_number != 0 || stop) stop = true;
  for (auto& th : threads) th.join();
  end_children(children, stop ? Clock::now() : end + std::chrono::seconds(10));
  std::uint64_t failed_children = 0;
  for (auto& c : children) {
    const std::string text = c.out_fd >= 0 ? read_all(c.out_fd) : std::string();
    if (c.out_fd >= 0) close(c.out_fd);
    const bool exited_ok = c.pid > 0 && WIFEXITED(c.status) && WEXITSTATUS(c.status) == 0;
    if (!add_tally_line(text, &tally) || !exited_ok) {
      ++failed_children;
      if (signal_number == 0)
        std::fprintf(stderr, "conica-soak: client process %d %s\n", static_cast<int>(c.pid),
                     c.pid < 0               ? "did not start"
                     : WIFSIGNALED(c.status) ? strsignal(WTERMSIG(c.status))
                     : !exited_ok            ? "exited with an error"
                                             : "gave no report");
    }
  }
  if (rss_start < 0) take_warm_sample(Clock::now());  // interrupted before the warm-up ended
  const long rss_end = rss_kib();
  const Heap heap_end = heap_kib();
  server.stop();
  if (reference) reference->stop();
  const conica::net::LoopStatsData s = server.stats();

  if (signal_number != 0)
    std::printf("interrupted by %s after %.0f s; client processes ended and reaped\n",
                strsignal(signal_number), std::chrono::duration<double>(Clock::now() - t0).count());
  std::printf("clients %d (%s), %.0f s at %.0f Hz (%s)%s: %" PRIu64 " sessions, %" PRIu64
              " probes, %" PRIu64 " replies, %" PRIu64 " control requests, %" PRIu64
              " state frames\n",
              clients, in_process ? "threads of the server's process" : "separate processes",
              seconds, rate_hz, scene_file.empty() ? builtin.c_str() : scene_file.c_str(),
              realtime ? ", --realtime" : "", tally.sessions.load(), tally.probes.load(),
              tally.replies.load(), tally.controls.load(), tally.frames.load());
  std::printf("malformed sent %" PRIu64 ", answered with an error %" PRIu64 "\n",
              tally.malformed_sent.load(), tally.malformed_answered.load());
  std::printf("server errors by kind:");
  for (int c = 1; c < conica::net::kNumErrorCodes; ++c)
    std::printf(" %s=%" PRIu64,
                conica::net::error_kind_name(static_cast<conica::net::ErrorKind>(c)),
                s.errors_by_code[c]);
  std::vector<double> p50s, p99s;
  double lat_max = s.lateness_max_us;
  for (const auto& x : samples) {
    p50s.push_back(x.lat_p50_us);
    p99s.push_back(x.lat_p99_us);
    lat_max = std::max(lat_max, x.lat_max_us);
  }
  const double p99_worst =
      p99s.empty() ? s.lateness_p99_us : *std::max_element(p99s.begin(), p99s.end());
  std::printf("\nserver: probes %" PRIu64 ", replies sent %" PRIu64 ", dropped %" PRIu64
              ", held %" PRIu64
              " (past the reply budget); step p50 %.0f us, p99 %.0f us; input "
              "stage p50 %.0f us, p99 %.0f us\n",
              s.probes_received, s.replies_sent, s.replies_dropped, s.replies_held, s.step_p50_us,
              s.step_p99_us, s.input_p50_us, s.input_p99_us);
  // The server keeps percentiles of its last 2048 ticks; sampled every second, these windows
  // cover every tick, so the maximum is the run's and the p50/p99 are medians over the windows.
  std::printf(
      "lateness: run max %.0f us; 2048-tick windows sampled each second: median p50 %.0f us, "
      "median p99 %.0f us, worst p99 %.0f us\n",
      lat_max, median(p50s), median(p99s), p99_worst);
  const std::uint64_t server_unexpected =
      s.errors > tally.malformed_sent.load() ? s.errors - tally.malformed_sent.load() : 0;
  const std::uint64_t unanswered =
      tally.malformed_sent.load() -
      std::min(tally.malformed_sent.load(), tally.malformed_answered.load());
  const std::uint64_t errors = tally.timeouts + tally.wrong_replies + unanswered +
                               server_unexpected + (signal_number != 0 ? 0 : failed_children);
  std::printf("errors: timeouts=%" PRIu64 " wrong_replies=%" PRIu64 " unanswered_malformed=%" PRIu64
              " server_unexpected=%" PRIu64 " failed_client_processes=%" PRIu64 "\n",
              tally.timeouts.load(), tally.wrong_replies.load(), unanswered, server_unexpected,
              signal_number != 0 ? 0 : failed_children);
  if (reference)
    std::printf("reference timer (%s): missed %" PRIu64 " of %" PRIu64
                " deadlines; lateness p50/p99/max %.0f/%.0f/%.0f us (10-us bins)\n",
                reference->fifo() ? "SCHED_FIFO" : "normal priority", reference->missed(),
                reference->ticks() + reference->missed(), reference->percentile_us(0.5),
                reference->percentile_us(0.99), reference->run_max_us());
  std::printf("rss: launch %ld KiB, after warm-up %ld KiB (tick %" PRIu64
              ", %.1f s into the run), end %ld KiB\n",
              rss_launch, rss_start, s_start.ticks, warm_at, rss_end);
  std::printf(
      "heap (malloc): in use %ld KiB after warm-up, %ld KiB at the end, %ld KiB at most "
      "(sampled each second); held from the system %ld -> %ld KiB\n",
      heap_start.in_use_kib, heap_end.in_use_kib, heap_peak_in_use, heap_start.held_kib,
      heap_end.held_kib);
  std::printf("missed ticks: %" PRIu64 " during the warm-up (first %" PRIu64 " ticks), %" PRIu64
              " of the %" PRIu64 " ticks after it (%.3f %%)\n",
              s_start.missed_ticks, s_start.ticks, s.missed_ticks - s_start.missed_ticks,
              s.ticks - s_start.ticks,
              100.0 * static_cast<double>(s.missed_ticks - s_start.missed_ticks) /
                  static_cast<double>(std::max<std::uint64_t>(1, s.ticks - s_start.ticks)));
  std::printf("missed_ticks=%" PRIu64 " ticks=%" PRIu64 " errors=%" PRIu64
              " rss_start_kib=%ld rss_end_kib=%ld\n",
              s.missed_ticks, s.ticks, errors, rss_start, rss_end);
  std::fflush(stdout);
  if (signal_number != 0) return 128 + signal_number;
  const bool ok =
      errors == 0 &&
      static_cast<double>(s.missed_ticks) <= max_missed * static_cast<double>(s.ticks) &&
      rss_end - rss_start <= max_growth_kib;
  return ok ? 0 : 1;
}
