#include "net/curve.h"

#include <spdlog/spdlog.h>
#include <sys/stat.h>
#include <time.h>
#include <zmq.h>

#include <algorithm>
#include <array>
#include <filesystem>
#include <fstream>
#include <sstream>

namespace conica::net {
namespace {

constexpr const char* kZapEndpoint = "inproc://zeromq.zap.01";
constexpr const char* kDomain = "conica";

std::uint64_t mono_ns() {
  timespec ts;
  clock_gettime(CLOCK_MONOTONIC, &ts);
  return static_cast<std::uint64_t>(ts.tv_sec) * 1000000000ull +
         static_cast<std::uint64_t>(ts.tv_nsec);
}

// 32 binary bytes of a z85 key ("" when invalid).
std::string decode_key(const std::string& z85) {
  if (z85.size() != 40) return {};
  std::array<std::uint8_t, 32> bin{};
  if (zmq_z85_decode(bin.data(), z85.c_str()) == nullptr) return {};
  return std::string(reinterpret_cast<const char*>(bin.data()), bin.size());
}

std::string encode_key(const std::string& bin) {
  char z85[41] = {};
  zmq_z85_encode(z85, reinterpret_cast<const std::uint8_t*>(bin.data()), bin.size());
  return z85;
}

}  // namespace

bool curve_available() { return zmq_has("curve") != 0; }

bool valid_z85_key(const std::string& key) { return !decode_key(key).empty(); }

std::string generate_keypair(CurveKeyPair* out) {
  if (!curve_available()) return "this libzmq has no CURVE support (built without libsodium)";
  char pub[41] = {}, sec[41] = {};
  if (zmq_curve_keypair(pub, sec) != 0)
    return std::string("zmq_curve_keypair: ") + zmq_strerror(zmq_errno());
  out->public_key = pub;
  out->secret_key = sec;
  return {};
}

std::string write_keypair(const std::string& dir, const std::string& name, const CurveKeyPair& kp) {
  namespace fs = std::filesystem;
  std::error_code ec;
  fs::create_directories(dir, ec);
  if (ec) return "cannot create " + dir + ": " + ec.message();
  const fs::path key = fs::path(dir) / (name + ".key"), pub = fs::path(dir) / (name + ".pub");
  for (const fs::path& p : {key, pub})
    if (fs::exists(p)) return p.string() + " exists: not overwritten";
  {
    // Create the secret file private before writing anything into it.
    const mode_t old = umask(077);
    std::ofstream f(key);
    umask(old);
    if (!f) return "cannot write " + key.string();
    f << "# conica CURVE key pair: keep this file private\npublic " << kp.public_key << "\nsecret "
      << kp.secret_key << "\n";
    if (!f) return "cannot write " + key.string();
  }
  fs::permissions(key, fs::perms::owner_read | fs::perms::owner_write, ec);
  std::ofstream f(pub);
  f << "# conica CURVE public key\npublic " << kp.public_key << "\n";
  if (!f) return "cannot write " + pub.string();
  return {};
}

std::string read_key_file(const std::string& path, CurveKeyPair* out) {
  std::ifstream f(path);
  if (!f) return path + ": cannot open key file";
  std::string line;
  CurveKeyPair kp;
  int n = 0;
  while (std::getline(f, line) && ++n <= 100) {
    std::istringstream is(line);
    std::string word, key;
    if (!(is >> word) || word[0] == '#') continue;
    if (!(is >> key) || (word != "public" && word != "secret") || !valid_z85_key(key))
      return path + ":" + std::to_string(n) + ": expected 'public <z85 key>' or 'secret <z85 key>'";
    (word == "public" ? kp.public_key : kp.secret_key) = key;
  }
  if (kp.public_key.empty() && kp.secret_key.empty()) return path + ": no key in the file";
  if (!kp.secret_key.empty()) {
    // The public key follows from the secret one; a mismatch is a damaged file.
    char pub[41] = {};
    if (zmq_curve_public(pub, kp.secret_key.c_str()) != 0) return path + ": bad secret key";
    if (kp.public_key.empty()) kp.public_key = pub;
    if (kp.public_key != pub) return path + ": public and secret keys do not match";
  }
  *out = kp;
  return {};
}

std::string read_client_keys(const std::string& dir, std::vector<std::string>* keys) {
  namespace fs = std::filesystem;
  std::error_code ec;
  std::vector<fs::path> files;
  for (const auto& e : fs::directory_iterator(dir, ec))
    if (e.is_regular_file() && e.path().extension() == ".pub") files.push_back(e.path());
  if (ec) return dir + ": cannot list client keys: " + ec.message();
  if (files.empty()) return dir + ": no client public keys (*.pub)";
  std::sort(files.begin(), files.end());
  keys->clear();
  for (const auto& p : files) {
    CurveKeyPair kp;
    if (std::string e = read_key_file(p.string(), &kp); !e.empty()) return e;
    if (!kp.secret_key.empty())
      return p.string() + ": holds a secret key; give the server .pub files only";
    keys->push_back(kp.public_key);
  }
  return {};
}

void set_curve_client(zmq::socket_t& s, const std::string& server_public, const CurveKeyPair& c) {
  s.set(zmq::sockopt::curve_serverkey, zmq::const_buffer(decode_key(server_public).data(), 32));
  s.set(zmq::sockopt::curve_publickey, zmq::const_buffer(decode_key(c.public_key).data(), 32));
  s.set(zmq::sockopt::curve_secretkey, zmq::const_buffer(decode_key(c.secret_key).data(), 32));
}

void set_curve_server(zmq::socket_t& s, const std::string& secret) {
  s.set(zmq::sockopt::curve_server, true);
  s.set(zmq::sockopt::curve_secretkey, zmq::const_buffer(decode_key(secret).data(), 32));
  // libzmq 4.3 accepts every CURVE client when no ZAP handler is bound (ZAP_ENFORCE_DOMAIN is
  // a draft option): the Server binds its ZapHandler before these sockets and closes it after.
  s.set(zmq::sockopt::zap_domain, kDomain);
}

ZapHandler::ZapHandler(zmq::context_t& context, std::vector<std::string> allowed)
    : context_(context) {
  for (const std::string& k : allowed)
    if (std::string b = decode_key(k); !b.empty()) allowed_.insert(std::move(b));
}

ZapHandler::~ZapHandler() { stop(); }

std::string ZapHandler::start() {
  if (thread_.joinable()) return {};
  try {
    socket_ = zmq::socket_t(context_, zmq::socket_type::rep);
    socket_.set(zmq::sockopt::linger, 0);
    socket_.bind(kZapEndpoint);
  } catch (const zmq::error_t& e) {
    if (socket_.handle() != nullptr) socket_.close();
    return std::string("ZAP handler: cannot bind ") + kZapEndpoint + ": " + e.what();
  }
  stop_.store(false);
  thread_ = std::thread([this] { run(); });
  return {};
}

void ZapHandler::stop() {
  if (!thread_.joinable()) return;
  stop_.store(true);
  thread_.join();
  socket_.close();
  if (refused_unlogged_)
    spdlog::warn("CURVE: {} more connections refused since the last report", refused_unlogged_);
  refused_unlogged_ = 0;
}

void ZapHandler::run() {
  while (!stop_.load()) {
    zmq::pollitem_t item{socket_.handle(), 0, ZMQ_POLLIN, 0};
    try {
      if (zmq::poll(&item, 1, std::chrono::milliseconds(50)) > 0) handle(socket_);
    } catch (const zmq::error_t& e) {
      if (e.num() == ETERM) return;
      spdlog::warn("ZAP handler: {}", e.what());
    }
  }
}

// RFC 27 request: version, request id, domain, address, identity, mechanism, credentials...
// Reply: version, request id, status code, status text, user id, metadata.
void ZapHandler::handle(zmq::socket_t& rep) {
  std::vector<zmq::message_t> parts;
  do {
    parts.emplace_back();
    if (!rep.recv(parts.back(), zmq::recv_flags::none)) return;
  } while (parts.back().more() && parts.size() < 16);
  while (parts.back().more()) {  // drain an oversized request
    zmq::message_t extra;
    (void)rep.recv(extra, zmq::recv_flags::none);
    if (!extra.more()) break;
  }
  const auto str = [&](std::size_t k) {
    return k < parts.size() ? parts[k].to_string() : std::string();
  };
  const std::string version = str(0), id = str(1), domain = str(2), address = str(3),
                    mechanism = str(5), credential = str(6);
  bool ok = version == "1.0" && mechanism == "CURVE" && credential.size() == 32 &&
            allowed_.count(credential) > 0;
  const std::string user = ok ? encode_key(credential) : std::string();
  if (ok) {
    ++accepted_;
    spdlog::debug("CURVE: accepted client {} from {}", user, address);
  } else {
    ++refused_;
    const std::uint64_t t = mono_ns();
    if (last_log_ns_ == 0 || t - last_log_ns_ >= 1000000000ull) {
      spdlog::warn("CURVE: refused {} client {} from {}{}", mechanism.empty() ? "?" : mechanism,
                   credential.size() == 32 ? encode_key(credential) : std::string("(no key)"),
                   address,
                   refused_unlogged_
                       ? fmt::format("; {} more refused since the last report", refused_unlogged_)
                       : std::string());
      last_log_ns_ = t;
      refused_unlogged_ = 0;
    } else {
      ++refused_unlogged_;
    }
  }
  const std::string code = ok ? "200" : "400", text = ok ? "OK" : "unknown client key";
  rep.send(zmq::buffer(version.empty() ? std::string("1.0") : version), zmq::send_flags::sndmore);
  rep.send(zmq::buffer(id), zmq::send_flags::sndmore);
  rep.send(zmq::buffer(code), zmq::send_flags::sndmore);
  rep.send(zmq::buffer(text), zmq::send_flags::sndmore);
  rep.send(zmq::buffer(user), zmq::send_flags::sndmore);
  rep.send(zmq::const_buffer(nullptr, 0), zmq::send_flags::none);
}

}  // namespace conica::net
