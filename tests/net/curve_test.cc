// CURVE access control (server/net/curve.h): certificates round-trip in the ZeroMQ format
// (pyzmq's and czmq's files read as they are, old conica key files refused and converted), a
// listed client key is served on every socket, an unknown key and a plain (non-CURVE) client
// get nothing and are counted.
#include "net/curve.h"

#include <gtest/gtest.h>

#include <chrono>
#include <filesystem>
#include <fstream>
#include <optional>
#include <sstream>
#include <thread>

#include "net/builtin_scenes.h"
#include "net/server.h"

namespace conica::net {
namespace {

using std::chrono::milliseconds;

std::string ProbeBytes(std::uint64_t seq) {
  v1::ClientMessage m;
  m.set_protocol_version(1);
  m.mutable_probe()->set_sequence(seq);
  m.mutable_probe()->mutable_position()->set_x(0.017);
  m.mutable_probe()->mutable_position()->set_y(0.017);
  m.mutable_probe()->mutable_position()->set_z(0.044);
  return m.SerializeAsString();
}

std::optional<v1::ServerMessage> Ask(zmq::socket_t& s, const std::string& bytes, int timeout_ms) {
  if (!s.send(zmq::buffer(bytes), zmq::send_flags::dontwait)) return std::nullopt;
  zmq::pollitem_t item{s.handle(), 0, ZMQ_POLLIN, 0};
  if (zmq::poll(&item, 1, milliseconds(timeout_ms)) == 0) return std::nullopt;
  zmq::message_t msg;
  if (!s.recv(msg, zmq::recv_flags::dontwait)) return std::nullopt;
  v1::ServerMessage out;
  if (!out.ParseFromArray(msg.data(), static_cast<int>(msg.size()))) return std::nullopt;
  return out;
}

class CurveTest : public ::testing::Test {
 protected:
  void SetUp() override {
    if (!curve_available()) GTEST_SKIP() << "libzmq without CURVE";
    dir_ = std::filesystem::temp_directory_path() /
           ("conica-curve-" + std::to_string(::getpid()) + "-" +
            ::testing::UnitTest::GetInstance()->current_test_info()->name());
    std::filesystem::remove_all(dir_);
    ASSERT_EQ(generate_keypair(&server_), "");
    ASSERT_EQ(generate_keypair(&known_), "");
    ASSERT_EQ(generate_keypair(&unknown_), "");
    ASSERT_EQ(write_keypair(dir_.string(), "server", server_), "");
    ASSERT_EQ(write_keypair((dir_ / "clients").string(), "alice", known_), "");
  }
  void TearDown() override {
    if (server_obj_) server_obj_->stop();
    std::filesystem::remove_all(dir_);
  }

  void StartServer() {
    CurveKeyPair sk;
    ASSERT_EQ(read_key_file((dir_ / "server.key_secret").string(), &sk), "");
    ServerOptions opt;
    opt.probe_endpoint = opt.state_endpoint = opt.control_endpoint = "tcp://127.0.0.1:*";
    opt.log_period_s = 0;
    opt.refuse_slow_scene = false;
    opt.curve_secret_key = sk.secret_key;
    ASSERT_EQ(read_client_keys((dir_ / "clients").string(), &opt.curve_client_keys), "");
    server_obj_ = std::make_unique<Server>(ctx_, opt);
    BodySpec spec;
    ASSERT_EQ(builtin_scene("cube", 1e-3, &spec), "");
    ASSERT_EQ(server_obj_->load(spec), "");
    ASSERT_EQ(server_obj_->start(), "");
  }

  zmq::socket_t Client(const std::string& endpoint, const CurveKeyPair* keys) {
    zmq::socket_t s(ctx_, zmq::socket_type::dealer);
    s.set(zmq::sockopt::linger, 0);
    if (keys) set_curve_client(s, server_.public_key, *keys);
    s.connect(endpoint);
    return s;
  }

  std::filesystem::path dir_;
  CurveKeyPair server_, known_, unknown_;
  zmq::context_t ctx_;
  std::unique_ptr<Server> server_obj_;
};

std::string slurp(const std::filesystem::path& p) {
  std::ifstream f(p);
  std::ostringstream s;
  s << f.rdbuf();
  return s.str();
}

TEST_F(CurveTest, KeyFilesRoundTripAndSecretsStayPrivate) {
  CurveKeyPair k, p;
  // NAME.key_secret holds both keys, NAME.key the public one only (the ZeroMQ naming).
  ASSERT_EQ(read_key_file((dir_ / "server.key_secret").string(), &k), "");
  EXPECT_EQ(k.public_key, server_.public_key);
  EXPECT_EQ(k.secret_key, server_.secret_key);
  ASSERT_EQ(read_key_file((dir_ / "server.key").string(), &p), "");
  EXPECT_EQ(p.public_key, server_.public_key);
  EXPECT_TRUE(p.secret_key.empty());
  EXPECT_EQ(slurp(dir_ / "server.key").find(server_.secret_key), std::string::npos);
  EXPECT_NE(
      slurp(dir_ / "server.key").find("curve\n    public-key = \"" + server_.public_key + "\"\n"),
      std::string::npos);
  EXPECT_NE(
      slurp(dir_ / "server.key_secret").find("    secret-key = \"" + server_.secret_key + "\"\n"),
      std::string::npos);
  const auto perms = std::filesystem::status(dir_ / "server.key_secret").permissions();
  EXPECT_EQ(perms & (std::filesystem::perms::group_all | std::filesystem::perms::others_all),
            std::filesystem::perms::none);
  EXPECT_NE(write_keypair(dir_.string(), "server", server_), "") << "overwrote a key pair";
  // Damaged or mismatched files are refused, saying where.
  std::ofstream(dir_ / "bad.key_secret")
      << "curve\n    public-key = \"" << server_.public_key << "\"\n    secret-key = \""
      << known_.secret_key << "\"\n";
  EXPECT_NE(read_key_file((dir_ / "bad.key_secret").string(), &k).find("do not match"),
            std::string::npos);
  std::ofstream(dir_ / "short.key") << "metadata\ncurve\n    public-key = \"abc\"\n";
  EXPECT_EQ(read_key_file((dir_ / "short.key").string(), &k),
            (dir_ / "short.key").string() +
                ":3: public-key is not a z85 CURVE key (40 characters of Z85 for 32 bytes)");
  std::vector<std::string> keys;
  // The clients folder holds alice.key and alice.key_secret: only the certificate counts.
  ASSERT_TRUE(std::filesystem::exists(dir_ / "clients" / "alice.key_secret"));
  ASSERT_EQ(read_client_keys((dir_ / "clients").string(), &keys), "");
  EXPECT_EQ(keys, std::vector<std::string>{known_.public_key});
  EXPECT_NE(read_client_keys((dir_ / "none").string(), &keys), "");
  // A secret certificate under a public name in the clients folder is refused.
  std::filesystem::copy_file(dir_ / "server.key_secret", dir_ / "clients" / "oops.key");
  EXPECT_NE(read_client_keys((dir_ / "clients").string(), &keys).find("oops.key: holds a secret"),
            std::string::npos);
}

// Certificates as czmq's zcert_save and pyzmq's zmq.auth.create_certificates write them
// (banners, metadata, quoting), and ZPL variations a hand-edited file may have.
TEST_F(CurveTest, CertificatesOfOtherWritersAreRead) {
  const std::string czmq =
      "#   ****  Generated on 2016-01-19 12:38:19 by CZMQ  ****\n"
      "#   ZeroMQ CURVE **Secret** Certificate\n"
      "#   DO NOT PROVIDE THIS FILE TO OTHER USERS nor change its permissions.\n"
      "\n"
      "metadata\n"
      "    name = \"alice\"\n"
      "    email = \"alice@example.org\"\n"
      "curve\n"
      "    public-key = \"" +
      known_.public_key +
      "\"\n"
      "    secret-key = \"" +
      known_.secret_key + "\"\n";
  std::ofstream(dir_ / "czmq.key_secret") << czmq;
  CurveKeyPair k;
  ASSERT_EQ(read_key_file((dir_ / "czmq.key_secret").string(), &k), "");
  EXPECT_EQ(k.public_key, known_.public_key);
  EXPECT_EQ(k.secret_key, known_.secret_key);
  // Single quotes, CRLF, a trailing comment, a section after curve.
  std::ofstream(dir_ / "variant.key") << "curve\r\n    public-key = '" << known_.public_key
                                      << "'   # alice\r\nother\r\n    public-key = \"x\"\r\n";
  ASSERT_EQ(read_key_file((dir_ / "variant.key").string(), &k), "");
  EXPECT_EQ(k.public_key, known_.public_key);
  EXPECT_TRUE(k.secret_key.empty());
  // ZPL mistakes name the line.
  auto error = [&](const std::string& text) {
    std::ofstream(dir_ / "zpl.key") << text;
    CurveKeyPair kp;
    return read_key_file((dir_ / "zpl.key").string(), &kp);
  };
  const std::string f = (dir_ / "zpl.key").string();
  EXPECT_EQ(error("curve\n\tpublic-key = \"" + known_.public_key + "\"\n"),
            f + ":2: a tab in the indentation (ZPL indents by four spaces)");
  EXPECT_EQ(error("curve\n   public-key = \"" + known_.public_key + "\"\n"),
            f + ":2: indented by 3 spaces (ZPL indents by four spaces per level)");
  EXPECT_EQ(error("curve\n    public-key = \"" + known_.public_key + "\n"),
            f + ":2: value of public-key has no closing quote");
  EXPECT_EQ(error("metadata\n    public-key = \"" + known_.public_key + "\"\n"),
            f + ": no curve/public-key in the file (a ZeroMQ certificate has a 'curve' section "
                "with public-key = \"<z85>\")");
  EXPECT_EQ(error("curve\n        public-key = \"" + known_.public_key + "\"\n"),
            f + ":2: indented deeper than the section it belongs to");
}

// Key files of conica before the certificates: NAME.key was the key pair, NAME.pub the public
// key. They are refused saying what they are and how to convert them; the conversion gives
// certificates with the same keys.
TEST_F(CurveTest, OldKeyFilesAreRefusedAndConverted) {
  const std::filesystem::path old = dir_ / "old";
  std::filesystem::create_directories(old / "clients");
  std::ofstream(old / "server.key")
      << "# conica CURVE key pair: keep this file private\npublic " << server_.public_key
      << "\nsecret " << server_.secret_key << "\n";
  std::ofstream(old / "server.pub")
      << "# conica CURVE public key\npublic " << server_.public_key << "\n";
  std::ofstream(old / "clients" / "bob.pub") << "public " << known_.public_key << "\n";
  CurveKeyPair k;
  const std::string key = (old / "server.key").string();
  EXPECT_EQ(read_key_file(key, &k),
            key +
                ": an old conica key file ('public <z85>' / 'secret <z85>' lines, in which "
                "NAME.key was the SECRET file and NAME.pub the public one); conica now reads "
                "ZeroMQ certificates as pyzmq and czmq write them (NAME.key public, "
                "NAME.key_secret secret): convert it with `conica-keygen --convert " +
                key + "`");
  EXPECT_TRUE(is_old_key_file(key));
  std::vector<std::string> keys;
  const std::string bob = (old / "clients" / "bob.pub").string();
  EXPECT_NE(
      read_client_keys((old / "clients").string(), &keys).find(bob + ": an old conica key file"),
      std::string::npos);

  std::vector<std::string> done;
  ASSERT_EQ(convert_old_key_file(key, &done), "");
  EXPECT_EQ(done.size(), 2u);
  ASSERT_EQ(read_key_file((old / "server.key_secret").string(), &k), "");
  EXPECT_EQ(k.public_key, server_.public_key);
  EXPECT_EQ(k.secret_key, server_.secret_key);
  ASSERT_EQ(read_key_file(key, &k), "");
  EXPECT_EQ(k.public_key, server_.public_key);
  EXPECT_TRUE(k.secret_key.empty()) << "the converted NAME.key still holds the secret";
  const auto perms = std::filesystem::status(old / "server.key_secret").permissions();
  EXPECT_EQ(perms & (std::filesystem::perms::group_all | std::filesystem::perms::others_all),
            std::filesystem::perms::none);
  // The old NAME.pub beside it: NAME.key is already its certificate, the .pub goes.
  done.clear();
  ASSERT_EQ(convert_old_key_file((old / "server.pub").string(), &done), "");
  EXPECT_FALSE(std::filesystem::exists(old / "server.pub"));
  // A client's old .pub becomes NAME.key, and the folder serves again.
  ASSERT_EQ(convert_old_key_file(bob, &done), "");
  EXPECT_FALSE(std::filesystem::exists(bob));
  ASSERT_EQ(read_client_keys((old / "clients").string(), &keys), "");
  EXPECT_EQ(keys, std::vector<std::string>{known_.public_key});
  // Converting twice, or over a certificate with other keys, is refused.
  EXPECT_NE(convert_old_key_file(key, &done).find("not an old conica key file"), std::string::npos);
  std::ofstream(old / "clients" / "bob.pub") << "public " << unknown_.public_key << "\n";
  EXPECT_NE(convert_old_key_file(bob, &done).find("holds other keys: not overwritten"),
            std::string::npos);
  // An old .pub left in the clients folder keeps the server from starting, naming it.
  EXPECT_NE(read_client_keys((old / "clients").string(), &keys).find(bob + ": an old conica"),
            std::string::npos);
}

TEST_F(CurveTest, KnownKeyIsServedUnknownKeyAndPlainClientsAreRefused) {
  StartServer();
  const Endpoints ep = server_obj_->endpoints();

  zmq::socket_t alice = Client(ep.probe, &known_);
  auto r = Ask(alice, ProbeBytes(1), 5000);
  ASSERT_TRUE(r.has_value()) << "a listed client key was not served";
  EXPECT_EQ(r->force().sequence(), 1u);
  EXPECT_TRUE(r->force().contact());
  zmq::socket_t alice_control = Client(ep.control, &known_);
  v1::ClientMessage c;
  c.set_protocol_version(1);
  c.mutable_control()->set_kind(v1::ControlRequest::GET_STATS);
  c.mutable_control()->set_sequence(3);
  auto cr = Ask(alice_control, c.SerializeAsString(), 5000);
  ASSERT_TRUE(cr.has_value());
  EXPECT_EQ(cr->control_reply().sequence(), 3u);
  // State frames are encrypted too, and reach a listed subscriber.
  zmq::socket_t sub(ctx_, zmq::socket_type::sub);
  sub.set(zmq::sockopt::linger, 0);
  set_curve_client(sub, server_.public_key, known_);
  sub.set(zmq::sockopt::subscribe, "F");
  sub.connect(ep.state);
  zmq::pollitem_t item{sub.handle(), 0, ZMQ_POLLIN, 0};
  EXPECT_GT(zmq::poll(&item, 1, milliseconds(5000)), 0) << "no state frame for a listed subscriber";
  const std::uint64_t accepted = server_obj_->curve_accepted();
  EXPECT_GE(accepted, 3u);
  EXPECT_EQ(server_obj_->curve_refused(), 0u);

  // A valid CURVE key that is not listed: handshake refused, no reply.
  zmq::socket_t mallory = Client(ep.probe, &unknown_);
  EXPECT_FALSE(Ask(mallory, ProbeBytes(2), 1500).has_value()) << "an unknown key was served";
  EXPECT_GE(server_obj_->curve_refused(), 1u);
  // A plain client: no CURVE handshake, never reaches the ZAP handler or the loop.
  zmq::socket_t plain = Client(ep.probe, nullptr);
  EXPECT_FALSE(Ask(plain, ProbeBytes(3), 1000).has_value()) << "a plain client was served";
  // A client that knows the server's key but claims another client's public key cannot finish
  // the handshake without the matching secret.
  CurveKeyPair forged{known_.public_key, unknown_.secret_key};
  zmq::socket_t forger = Client(ep.probe, &forged);
  EXPECT_FALSE(Ask(forger, ProbeBytes(4), 1000).has_value()) << "a forged key was served";

  // The listed client is still served, and nothing reached the loop from the others.
  auto again = Ask(alice, ProbeBytes(5), 5000);
  ASSERT_TRUE(again.has_value());
  EXPECT_EQ(again->force().sequence(), 5u);
  EXPECT_EQ(server_obj_->stats().errors, 0u);
}

TEST_F(CurveTest, BadKeysAreRefusedAtStart) {
  ServerOptions opt;
  opt.probe_endpoint = opt.state_endpoint = opt.control_endpoint = "tcp://127.0.0.1:*";
  opt.curve_secret_key = server_.secret_key;  // but no client keys
  Server s(ctx_, opt);
  BodySpec spec;
  ASSERT_EQ(builtin_scene("cube", 1e-3, &spec), "");
  opt.refuse_slow_scene = false;
  Server s2(ctx_, [&] {
    auto o = opt;
    o.curve_client_keys = {"not a key"};
    return o;
  }());
  ASSERT_EQ(s.load(spec), "");
  EXPECT_NE(s.start(), "");
  ASSERT_EQ(s2.load(spec), "");
  EXPECT_NE(s2.start().find("z85"), std::string::npos);
}

}  // namespace
}  // namespace conica::net
