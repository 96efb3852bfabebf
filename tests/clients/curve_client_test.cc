// The clients' CURVE options (clients/cpp/client/connection.h): the certificates
// conica-server --generate-keys writes (NAME.key public, NAME.key_secret secret) are read with
// errors naming the file and the problem; a client
// whose key the server lists gets physically sensible force replies from an in-process CURVE
// server, a client with an unknown key gets nothing within a bounded wait.
#include <gtest/gtest.h>
#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <filesystem>
#include <fstream>
#include <thread>

#include "client/connection.h"
#include "net/builtin_scenes.h"
#include "net/curve.h"
#include "net/server.h"

namespace conica::client {
namespace {

namespace fs = std::filesystem;

constexpr double kTop = 0.04;           // m, top face of the built-in cube
constexpr double kNode = 3 * 0.04 / 7;  // m, x and y of a lattice column
constexpr double kRadius = 5e-3;        // m, the cube's probe radius

class CurveClientTest : public ::testing::Test {
 protected:
  void SetUp() override {
    if (!net::curve_available()) GTEST_SKIP() << "libzmq without CURVE";
    dir_ = fs::temp_directory_path() /
           ("conica-curve-client-" + std::to_string(::getpid()) + "-" +
            ::testing::UnitTest::GetInstance()->current_test_info()->name());
    fs::remove_all(dir_);
    net::CurveKeyPair server, alice, mallory;
    for (auto* k : {&server, &alice, &mallory}) ASSERT_EQ(net::generate_keypair(k), "");
    ASSERT_EQ(net::write_keypair(dir_.string(), "server", server), "");
    ASSERT_EQ(net::write_keypair((dir_ / "clients").string(), "alice", alice), "");
    ASSERT_EQ(net::write_keypair((dir_ / "other").string(), "mallory", mallory), "");
    server_secret_ = server.secret_key;
  }
  void TearDown() override {
    if (server_) server_->stop();
    fs::remove_all(dir_);
  }

  std::string File(const std::string& name) const { return (dir_ / name).string(); }

  void StartServer() {
    net::ServerOptions opt;
    opt.probe_endpoint = opt.state_endpoint = opt.control_endpoint = "tcp://127.0.0.1:*";
    opt.log_period_s = 0;
    opt.refuse_slow_scene = false;
    opt.curve_secret_key = server_secret_;
    ASSERT_EQ(net::read_client_keys(File("clients"), &opt.curve_client_keys), "");
    server_ = std::make_unique<net::Server>(ctx_, opt);
    conica::BodySpec spec;
    ASSERT_EQ(net::builtin_scene("cube", 1e-3, &spec), "");
    ASSERT_EQ(server_->load(spec), "");
    ASSERT_EQ(server_->start(), "");
  }

  // Sends one update and waits up to timeout_s for the reply with its sequence.
  bool Probe(ProbeConnection& c, std::uint64_t seq, const Vec3& x, double timeout_s,
             ForceSample* f) {
    EXPECT_TRUE(c.send(0, seq, static_cast<std::uint64_t>(now_ns()), x));
    const std::int64_t deadline = now_ns() + static_cast<std::int64_t>(timeout_s * 1e9);
    std::string error;
    while (now_ns() < deadline) {
      bool got = false;
      const ReplyKind k = c.receive(deadline, f, &error, &got);
      EXPECT_NE(k, ReplyKind::kError) << error;
      if (got && k == ReplyKind::kForce && f->sequence == seq) return true;
    }
    return false;
  }

  fs::path dir_;
  std::string server_secret_;
  zmq::context_t ctx_;
  std::unique_ptr<net::Server> server_;
};

TEST_F(CurveClientTest, KeyFileErrorsNameTheFileAndTheProblem) {
  CurveClient c;
  EXPECT_EQ(load_curve_client("", "", &c), "");
  EXPECT_FALSE(c.enabled());
  EXPECT_NE(load_curve_client(File("server.key"), "", &c).find("needs --curve-key"),
            std::string::npos);
  EXPECT_NE(
      load_curve_client("", File("clients/alice.key_secret"), &c).find("needs --curve-server-pub"),
      std::string::npos);
  EXPECT_EQ(load_curve_client(File("missing.key"), File("clients/alice.key_secret"), &c),
            File("missing.key") +
                ": cannot open key file (--curve-server-pub: the server's public certificate "
                "NAME.key)");
  EXPECT_EQ(load_curve_client(File("server.key"), File("missing.key_secret"), &c),
            File("missing.key_secret") +
                ": cannot open key file (--curve-key: this client's secret certificate "
                "NAME.key_secret)");
  // The server's secret certificate given to a client.
  EXPECT_EQ(load_curve_client(File("server.key_secret"), File("clients/alice.key_secret"), &c),
            File("server.key_secret") +
                ": holds the server's secret key; give the client the server's public "
                "certificate (NAME.key, not NAME.key_secret)");
  // The client's public certificate instead of its secret one.
  EXPECT_EQ(load_curve_client(File("server.key"), File("clients/alice.key"), &c),
            File("clients/alice.key") +
                ": a public certificate (no secret key); give this client's secret certificate "
                "(NAME.key_secret), not its NAME.key");
  // A damaged certificate: the line is named.
  std::ofstream(File("damaged.key_secret")) << "# mine\ncurve\n    secret-key = \"0123456789\"\n";
  EXPECT_EQ(load_curve_client(File("server.key"), File("damaged.key_secret"), &c),
            File("damaged.key_secret") +
                ":3: secret-key is not a z85 CURVE key (40 characters of Z85 for 32 bytes) "
                "(--curve-key: this client's secret certificate NAME.key_secret)");
  std::ofstream(File("empty.key")) << "# nothing here\n";
  EXPECT_EQ(load_curve_client(File("empty.key"), File("clients/alice.key_secret"), &c),
            File("empty.key") +
                ": no curve/public-key in the file (a ZeroMQ certificate has a 'curve' section "
                "with public-key = \"<z85>\") (--curve-server-pub: the server's public "
                "certificate NAME.key)");
  // An old conica key pair file: what it is and the command that converts it.
  net::CurveKeyPair pair;
  ASSERT_EQ(net::generate_keypair(&pair), "");
  std::ofstream(File("old.key")) << "# conica CURVE key pair: keep this file private\npublic "
                                 << pair.public_key << "\nsecret " << pair.secret_key << "\n";
  const std::string old = load_curve_client(File("server.key"), File("old.key"), &c);
  EXPECT_NE(old.find(File("old.key") + ": an old conica key file"), std::string::npos) << old;
  EXPECT_NE(old.find("`conica-keygen --convert " + File("old.key") + "`"), std::string::npos)
      << old;
  EXPECT_FALSE(c.enabled());
  ASSERT_EQ(load_curve_client(File("server.key"), File("clients/alice.key_secret"), &c), "");
  EXPECT_TRUE(c.enabled());
  EXPECT_TRUE(net::valid_z85_key(c.server_public));
  EXPECT_TRUE(net::valid_z85_key(c.keys.secret_key));
}

TEST_F(CurveClientTest, AuthorisedClientGetsForcesUnknownClientGetsNothing) {
  StartServer();
  const net::Endpoints ep = server_->endpoints();
  CurveClient alice;
  ASSERT_EQ(load_curve_client(File("server.key"), File("clients/alice.key_secret"), &alice), "");

  ProbeConnection conn(ctx_, ep.probe, 5, alice);
  ForceSample f;
  // Out of contact: exactly no force.
  ASSERT_TRUE(Probe(conn, 1, Vec3(kNode, kNode, kTop + kRadius + 0.01), 5, &f))
      << "an authorised CURVE client got no reply";
  EXPECT_FALSE(f.contact);
  EXPECT_EQ(f.force, Vec3::Zero());
  // Pressing 0.5, 1 and 2 mm into the top face over a lattice column: the body pushes the probe
  // up (+z), harder the deeper it goes, with no sizeable sideways force, and the reported
  // stiffness says the same (dFz/dz < 0).
  // Each depth reached as a device would, 0.05 mm per update a millisecond apart, then held for
  // 0.2 s (a probe placed millimetres deep at once is followed by its proxy over some ticks and
  // knocks the body into a transient).
  double last = 0, at = 0;
  std::uint64_t seq = 1;
  for (double depth : {0.5e-3, 1e-3, 2e-3}) {
    for (int k = 0; k < 400; ++k) {
      at = std::min(depth, at + 5e-5);
      ASSERT_TRUE(Probe(conn, ++seq, Vec3(kNode, kNode, kTop + kRadius - at), 5, &f)) << depth;
      if (at == depth && k >= 200) break;
      std::this_thread::sleep_for(std::chrono::milliseconds(1));
    }
    EXPECT_TRUE(f.contact) << depth;
    EXPECT_GT(f.force.z(), last) << depth;
    EXPECT_LT(f.force.head<2>().norm(), 0.05 * f.force.z()) << depth;
    ASSERT_TRUE(f.has_stiffness);
    EXPECT_LT(f.stiffness(2, 2), 0) << depth;
    EXPECT_NEAR(f.position.z(), kTop + kRadius - depth, 1e-12);
    last = f.force.z();
  }
  v1::ControlReply reply;
  std::string error;
  EXPECT_TRUE(
      control_request(ctx_, ep.control, v1::ControlRequest::GET_STATS, 5000, &reply, &error, alice))
      << error;
  EXPECT_EQ(reply.num_nodes(), 320u);

  // A valid key pair that the server does not list: no reply, and the wait ends on time.
  CurveClient mallory;
  ASSERT_EQ(load_curve_client(File("server.key"), File("other/mallory.key_secret"), &mallory), "");
  ProbeConnection stranger(ctx_, ep.probe, 6, mallory);
  const std::int64_t t0 = now_ns();
  EXPECT_FALSE(Probe(stranger, 1, Vec3(kNode, kNode, kTop + kRadius - 1e-3), 1.5, &f))
      << "a client with an unknown key was served";
  EXPECT_LT((now_ns() - t0) * 1e-9, 3.0);
  EXPECT_FALSE(control_request(ctx_, ep.control, v1::ControlRequest::GET_STATS, 1000, &reply,
                               &error, mallory));
  EXPECT_NE(error.find("no control reply"), std::string::npos) << error;
  EXPECT_GE(server_->curve_refused(), 1u);
  // The authorised client is still served.
  EXPECT_TRUE(Probe(conn, ++seq, Vec3(kNode, kNode, kTop + kRadius - 1e-3), 5, &f));
}

}  // namespace
}  // namespace conica::client
