#include "net/curve.h"

#include <spdlog/spdlog.h>
#include <sys/stat.h>
#include <time.h>
#include <zmq.h>

#include <algorithm>
#include <array>
#include <cctype>
#include <ctime>
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

namespace {

namespace fs = std::filesystem;

constexpr const char* kConvertHint = "conica-keygen --convert ";

std::string read_text(const std::string& path, std::string* text) {
  std::ifstream f(path, std::ios::binary);
  if (!f) return path + ": cannot open key file";
  std::ostringstream s;
  s << f.rdbuf();
  if (f.bad()) return path + ": read error";
  *text = s.str();
  if (text->size() > 64 * 1024) return path + ": not a key file (larger than 64 KiB)";
  return {};
}

std::vector<std::string> split_lines(const std::string& text) {
  std::vector<std::string> lines;
  std::istringstream is(text);
  std::string line;
  while (std::getline(is, line)) {
    if (!line.empty() && line.back() == '\r') line.pop_back();
    lines.push_back(line);
  }
  return lines;
}

bool blank_or_comment(const std::string& line) {
  const std::size_t i = line.find_first_not_of(" \t");
  return i == std::string::npos || line[i] == '#';
}

// The old conica format: every meaningful line is "public <z85>" or "secret <z85>".
bool old_format(const std::string& text) {
  bool any = false;
  for (const std::string& line : split_lines(text)) {
    if (blank_or_comment(line)) continue;
    std::istringstream is(line);
    std::string word, key, extra;
    if (!(is >> word >> key) || (is >> extra)) return false;
    if ((word != "public" && word != "secret") || !valid_z85_key(key)) return false;
    any = true;
  }
  return any;
}

std::string old_format_message(const std::string& path) {
  return path +
         ": an old conica key file ('public <z85>' / 'secret <z85>' lines, in which NAME.key "
         "was the SECRET file and NAME.pub the public one); conica now reads ZeroMQ "
         "certificates as pyzmq and czmq write them (NAME.key public, NAME.key_secret "
         "secret): convert it with `" +
         kConvertHint + path + "`";
}

bool name_char(char c) {
  return std::isalnum(static_cast<unsigned char>(c)) || c == '$' || c == '-' || c == '_' ||
         c == '@' || c == '.' || c == '&' || c == '+' || c == '/';
}

// A ZeroMQ certificate (ZPL, ZeroMQ RFC 4: four spaces per level, "name = value", values
// quoted or bare, '#' comments): the keys under "curve". Error message or "".
std::string parse_certificate(const std::string& path, const std::string& text, CurveKeyPair* kp) {
  std::vector<std::string> stack;
  int n = 0;
  std::string public_line, secret_line;
  for (const std::string& raw : split_lines(text)) {
    ++n;
    const std::string where = path + ":" + std::to_string(n) + ": ";
    if (blank_or_comment(raw)) continue;
    std::size_t indent = 0;
    while (indent < raw.size() && raw[indent] == ' ') ++indent;
    if (indent < raw.size() && raw[indent] == '\t') {
      return where + "a tab in the indentation (ZPL indents by four spaces)";
    }
    if (indent % 4 != 0) {
      return where + "indented by " + std::to_string(indent) +
             " spaces (ZPL indents by four spaces per level)";
    }
    const std::size_t depth = indent / 4;
    if (depth > stack.size()) return where + "indented deeper than the section it belongs to";
    std::size_t i = indent;
    while (i < raw.size() && name_char(raw[i])) ++i;
    const std::string name = raw.substr(indent, i - indent);
    if (name.empty()) {
      return where + "expected a name (a section, or 'name = value'), found '" +
             raw.substr(indent, 40) + "'";
    }
    while (i < raw.size() && (raw[i] == ' ' || raw[i] == '\t')) ++i;
    std::string value;
    bool has_value = false;
    if (i < raw.size() && raw[i] == '=') {
      has_value = true;
      ++i;
      while (i < raw.size() && (raw[i] == ' ' || raw[i] == '\t')) ++i;
      if (i < raw.size() && (raw[i] == '"' || raw[i] == '\'')) {
        const char q = raw[i];
        const std::size_t close = raw.find(q, i + 1);
        if (close == std::string::npos) return where + "value of " + name + " has no closing quote";
        value = raw.substr(i + 1, close - i - 1);
        i = close + 1;
      } else {
        const std::size_t stop = raw.find_first_of(" \t#", i);
        value = raw.substr(i, stop == std::string::npos ? std::string::npos : stop - i);
        i = stop == std::string::npos ? raw.size() : stop;
      }
      while (i < raw.size() && (raw[i] == ' ' || raw[i] == '\t')) ++i;
    }
    if (i < raw.size() && raw[i] != '#') {
      return where + "unexpected '" + raw.substr(i, 40) + "' after " + name +
             " (expected 'name = \"value\"' or a section name)";
    }
    stack.resize(depth);
    stack.push_back(name);
    const bool in_curve = depth == 1 && stack[0] == "curve";
    if (in_curve && (name == "public-key" || name == "secret-key")) {
      if (!has_value) return where + name + " has no value (expected " + name + " = \"<z85>\")";
      if (!valid_z85_key(value)) {
        return where + name + " is not a z85 CURVE key (40 characters of Z85 for 32 bytes)";
      }
      std::string& slot = name == "public-key" ? kp->public_key : kp->secret_key;
      std::string& line = name == "public-key" ? public_line : secret_line;
      if (!slot.empty()) return where + "second " + name + " (first on line " + line + ")";
      slot = value;
      line = std::to_string(n);
    }
  }
  if (kp->public_key.empty()) {
    return path +
           ": no curve/public-key in the file (a ZeroMQ certificate has a 'curve' section "
           "with public-key = \"<z85>\")";
  }
  return {};
}

std::string write_file(const fs::path& p, const std::string& text, bool secret) {
  // A secret file is private from its creation on, not only after it is written.
  const mode_t old = umask(secret ? 077 : 022);
  std::ofstream f(p, std::ios::binary);
  umask(old);
  if (!f) return "cannot write " + p.string();
  f << text;
  f.close();
  if (!f) return "cannot write " + p.string();
  if (secret) {
    std::error_code ec;
    fs::permissions(p, fs::perms::owner_read | fs::perms::owner_write, ec);
    if (ec) return "cannot make " + p.string() + " private: " + ec.message();
  }
  return {};
}

// "2026-12-02 01:10:00" local time, as pyzmq's banner has it.
std::string now_text() {
  const std::time_t t = std::time(nullptr);
  std::tm tm{};
  localtime_r(&t, &tm);
  char buf[32];
  std::strftime(buf, sizeof buf, "%Y-%m-%d %H:%M:%S", &tm);
  return buf;
}

}  // namespace

std::string certificate_text(const CurveKeyPair& kp, bool with_secret) {
  std::string t = "#   ****  Generated on " + now_text() + " by conica  ****\n";
  if (with_secret) {
    t += "#   ZeroMQ CURVE **Secret** Certificate\n"
         "#   DO NOT PROVIDE THIS FILE TO OTHER USERS nor change its permissions.\n";
  } else {
    t += "#   ZeroMQ CURVE Public Certificate\n"
         "#   Exchange securely, or use a secure mechanism to verify the contents\n"
         "#   of this file after exchange. Store public certificates in your home\n"
         "#   directory, in the .curve subdirectory.\n";
  }
  t += "\nmetadata\ncurve\n    public-key = \"" + kp.public_key + "\"\n";
  if (with_secret) t += "    secret-key = \"" + kp.secret_key + "\"\n";
  return t;
}

std::string write_keypair(const std::string& dir, const std::string& name, const CurveKeyPair& kp) {
  std::error_code ec;
  fs::create_directories(dir, ec);
  if (ec) return "cannot create " + dir + ": " + ec.message();
  const fs::path pub = fs::path(dir) / (name + ".key"),
                 secret = fs::path(dir) / (name + ".key_secret");
  for (const fs::path& p : {pub, secret})
    if (fs::exists(p)) return p.string() + " exists: not overwritten";
  if (std::string e = write_file(secret, certificate_text(kp, true), true); !e.empty()) return e;
  return write_file(pub, certificate_text(kp, false), false);
}

bool is_old_key_file(const std::string& path) {
  std::string text;
  return read_text(path, &text).empty() && old_format(text);
}

std::string read_key_file(const std::string& path, CurveKeyPair* out) {
  std::string text;
  if (std::string e = read_text(path, &text); !e.empty()) return e;
  if (old_format(text)) return old_format_message(path);
  if (text.find('\0') != std::string::npos) return path + ": not a key file (binary data)";
  CurveKeyPair kp;
  if (std::string e = parse_certificate(path, text, &kp); !e.empty()) return e;
  if (!kp.secret_key.empty()) {
    // The public key follows from the secret one; a mismatch is a damaged file.
    char pub[41] = {};
    if (zmq_curve_public(pub, kp.secret_key.c_str()) != 0) return path + ": bad secret key";
    if (kp.public_key != pub) return path + ": public and secret keys do not match";
  }
  *out = kp;
  return {};
}

std::string read_client_keys(const std::string& dir, std::vector<std::string>* keys) {
  std::error_code ec;
  std::vector<fs::path> files, old;
  for (const auto& e : fs::directory_iterator(dir, ec)) {
    if (!e.is_regular_file()) continue;
    if (e.path().extension() == ".key") files.push_back(e.path());
    if (e.path().extension() == ".pub" && is_old_key_file(e.path().string()))
      old.push_back(e.path());
  }
  if (ec) return dir + ": cannot list client keys: " + ec.message();
  std::sort(old.begin(), old.end());
  if (!old.empty()) return old_format_message(old.front().string());
  if (files.empty()) return dir + ": no client public certificates (NAME.key)";
  std::sort(files.begin(), files.end());
  keys->clear();
  for (const auto& p : files) {
    CurveKeyPair kp;
    if (std::string e = read_key_file(p.string(), &kp); !e.empty()) return e;
    if (!kp.secret_key.empty())
      return p.string() +
             ": holds a secret key; the clients folder takes public certificates (NAME.key) only";
    keys->push_back(kp.public_key);
  }
  return {};
}

std::string convert_old_key_file(const std::string& path, std::vector<std::string>* done) {
  std::string text;
  if (std::string e = read_text(path, &text); !e.empty()) return e;
  if (!old_format(text)) {
    return path + ": not an old conica key file (no 'public <z85>' / 'secret <z85>' lines)";
  }
  CurveKeyPair kp;
  for (const std::string& line : split_lines(text)) {
    if (blank_or_comment(line)) continue;
    std::istringstream is(line);
    std::string word, key;
    is >> word >> key;
    (word == "public" ? kp.public_key : kp.secret_key) = key;
  }
  if (!kp.secret_key.empty()) {
    char pub[41] = {};
    if (zmq_curve_public(pub, kp.secret_key.c_str()) != 0) return path + ": bad secret key";
    if (!kp.public_key.empty() && kp.public_key != pub)
      return path + ": public and secret keys do not match";
    kp.public_key = pub;
  }
  const fs::path old(path);
  const fs::path base = old.parent_path() / old.stem();
  const fs::path pub = base.string() + ".key", secret = base.string() + ".key_secret";
  // An existing certificate is kept only when it holds the same keys.
  auto same = [&kp](const fs::path& p, bool want_secret, std::string* why) {
    CurveKeyPair have;
    if (std::string e = read_key_file(p.string(), &have); !e.empty()) {
      *why = e;
      return false;
    }
    if (have.public_key != kp.public_key || (want_secret && have.secret_key != kp.secret_key) ||
        (!want_secret && !have.secret_key.empty())) {
      *why = p.string() + " exists and holds other keys: not overwritten";
      return false;
    }
    return true;
  };
  std::string why;
  if (!kp.secret_key.empty()) {
    if (fs::exists(secret)) {
      if (!same(secret, true, &why)) return why;
    } else {
      if (std::string e = write_file(secret, certificate_text(kp, true), true); !e.empty())
        return e;
      done->push_back("wrote " + secret.string() + " (secret certificate, mode 0600)");
    }
  }
  if (fs::exists(pub) && !fs::equivalent(pub, old)) {
    if (is_old_key_file(pub.string())) {
      // The old pair's other half (NAME.key beside NAME.pub): convert it first.
      if (std::string e = convert_old_key_file(pub.string(), done); !e.empty()) return e;
    }
    if (!same(pub, false, &why)) return why;
  } else {
    // Write beside, then rename over the old file, so a failure leaves the old file whole.
    const fs::path tmp = pub.string() + ".new";
    if (std::string e = write_file(tmp, certificate_text(kp, false), false); !e.empty()) return e;
    std::error_code ec;
    fs::rename(tmp, pub, ec);
    if (ec) return "cannot replace " + pub.string() + ": " + ec.message();
    done->push_back("wrote " + pub.string() + " (public certificate" +
                    (fs::equivalent(pub, old, ec) ? ", replacing the old key pair file)" : ")"));
  }
  if (!fs::equivalent(pub, old)) {
    std::error_code ec;
    fs::remove(old, ec);
    if (ec) return "cannot remove " + old.string() + ": " + ec.message();
    done->push_back("removed " + old.string() + " (old public key file)");
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
