// Optional ZeroMQ CURVE security for the server's sockets: encryption plus authentication of
// clients by their long-term public key (libzmq built with libsodium; see curve_available()).
//
// Keys are Z85 text (40 characters for 32 bytes), kept in ZeroMQ certificates: the ZPL text
// files czmq's zcert writes and pyzmq's zmq.auth reads (create_certificates,
// load_certificate), with their naming:
//   NAME.key         the PUBLIC certificate: what the other side is given
//                      metadata
//                      curve
//                          public-key = "<z85>"
//   NAME.key_secret  the SECRET certificate (mode 0600; never handed out): the same plus
//                          secret-key = "<z85>"
// The server reads its NAME.key_secret (--curve-server-key) and a folder of public
// certificates, one NAME.key per authorised client (--curve-clients; NAME.key_secret files
// there are ignored, as zmq.auth.load_certificates does). A client needs the server's NAME.key
// and its own NAME.key_secret. Certificates made by pyzmq or czmq work as they are.
//
// Key files of conica before the certificates ("public <z85>" / "secret <z85>" lines, with
// NAME.key the SECRET file and NAME.pub the public one) are refused with a message saying so
// and the command that converts them (conica-keygen --convert FILE, convert_old_key_file()).
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
// Writes the certificates DIR/NAME.key (public) and DIR/NAME.key_secret (public and secret,
// 0600); refuses to overwrite either. Error message or "".
std::string write_keypair(const std::string& dir, const std::string& name, const CurveKeyPair& kp);
// Reads a certificate; fills what it holds (a public certificate has no secret). Errors name
// the file, the line where there is one, and the problem; an old conica key file is refused
// with what it is and how to convert it. Error message or "".
std::string read_key_file(const std::string& path, CurveKeyPair* out);
// The public keys of every NAME.key certificate in `dir` (at least one; NAME.key_secret files
// are skipped, a certificate holding a secret key or an old NAME.pub is refused). Error message
// or "".
std::string read_client_keys(const std::string& dir, std::vector<std::string>* public_keys);
// The text of a certificate: public only, or public and secret when `with_secret`.
std::string certificate_text(const CurveKeyPair& kp, bool with_secret);
// Does `path` hold an old conica key file ("public <z85>" / "secret <z85>" lines)?
bool is_old_key_file(const std::string& path);
// Converts an old conica key file: from a key pair (old NAME.key) writes NAME.key_secret and
// replaces NAME.key with the public certificate; from an old NAME.pub writes the public
// certificate NAME.key and removes NAME.pub. `done` gets one line per file written or removed.
// Refuses to overwrite a certificate that holds a different key. Error message or "".
std::string convert_old_key_file(const std::string& path, std::vector<std::string>* done);
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
