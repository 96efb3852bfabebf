// Optional ZeroMQ CURVE security for the server's sockets: encryption plus authentication of
// clients by their long-term public key (libzmq built with libsodium; see curve_available()).
//
// Keys are Z85 text (40 characters for 32 bytes). Key files are text, one key per line,
// '#' comments allowed:
//   NAME.key   "public <z85>" and "secret <z85>"  (mode 0600; the secret never leaves it)
//   NAME.pub   "public <z85>"                      (what the other side is given)
// The server reads its NAME.key (--curve-server-key) and a folder with one .pub file per
// authorised client (--curve-clients). A client needs the server's .pub and its own .key.
//
// Authentication runs in a ZAP handler (RFC 27): a REP socket bound on
// inproc://zeromq.zap.01 in the server's context, answered by a thread of its own. It accepts a
// CURVE handshake only when the client's public key is listed; every refusal is counted and
// logged (at most once per second, with the count since the last report). One ZAP handler per
// context: a second CURVE server in the same context cannot start.
#pragma once

#include <atomic>
#include <cstdint>
#include <string>
#include <thread>
#include <unordered_set>
#include <vector>
#include <zmq.hpp>

namespace conica::net {

// zmq_has("curve"): this libzmq can encrypt.
bool curve_available();

struct CurveKeyPair {
  std::string public_key;  // z85, 40 characters
  std::string secret_key;  // z85, 40 characters
};

// A fresh key pair; returns an error message or "".
std::string generate_keypair(CurveKeyPair* out);
// Writes DIR/NAME.key (0600) and DIR/NAME.pub; refuses to overwrite. Error message or "".
std::string write_keypair(const std::string& dir, const std::string& name, const CurveKeyPair& kp);
// Reads a key file; fills what it holds (a .pub has no secret). Error message or "".
std::string read_key_file(const std::string& path, CurveKeyPair* out);
// The public keys of every *.pub file in `dir` (at least one). Error message or "".
std::string read_client_keys(const std::string& dir, std::vector<std::string>* public_keys);
// Is `key` 40 characters of valid Z85 that decode to 32 bytes?
bool valid_z85_key(const std::string& key);

// Client side: make `socket` a CURVE client of the server with public key `server_public`.
void set_curve_client(zmq::socket_t& socket, const std::string& server_public,
                      const CurveKeyPair& client);
// Server side: make `socket` a CURVE server with `secret` and the ZAP domain "conica".
void set_curve_server(zmq::socket_t& socket, const std::string& secret);

class ZapHandler {
 public:
  // `allowed`: z85 public keys of the authorised clients.
  ZapHandler(zmq::context_t& context, std::vector<std::string> allowed);
  ~ZapHandler();
  ZapHandler(const ZapHandler&) = delete;
  ZapHandler& operator=(const ZapHandler&) = delete;

  // Binds inproc://zeromq.zap.01 and starts the thread. Error message or "".
  std::string start();
  void stop();

  std::uint64_t accepted() const { return accepted_.load(); }
  std::uint64_t refused() const { return refused_.load(); }

 private:
  void run();
  void handle(zmq::socket_t& rep);

  zmq::context_t& context_;
  std::unordered_set<std::string> allowed_;  // 32-byte binary keys
  std::thread thread_;
  std::atomic<bool> stop_{false};
  std::atomic<std::uint64_t> accepted_{0}, refused_{0};
  std::uint64_t refused_unlogged_ = 0;
  std::uint64_t last_log_ns_ = 0;
  zmq::socket_t socket_;
};

}  // namespace conica::net
