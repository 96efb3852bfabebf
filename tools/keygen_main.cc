// conica-keygen: CURVE certificates for conica-server and its clients, in the ZeroMQ
// certificate format pyzmq and czmq use (server/net/curve.h).
//   conica-keygen keys server             keys/server.key (public), keys/server.key_secret
//   conica-keygen keys/clients alice      a client's pair; the server lists keys/clients
//   conica-keygen --convert keys/server.key keys/clients
//                                         old conica key files (NAME.key secret, NAME.pub
//                                         public) to certificates; a folder converts every old
//                                         key file in it
#include <CLI/CLI.hpp>
#include <algorithm>
#include <cstdio>
#include <filesystem>
#include <string>
#include <vector>

#include "net/curve.h"

namespace {

int convert(const std::vector<std::string>& paths) {
  namespace fs = std::filesystem;
  std::vector<std::string> files;
  for (const std::string& p : paths) {
    if (!fs::is_directory(p)) {
      files.push_back(p);
      continue;
    }
    // Key pairs first, so that NAME.pub meets an already converted NAME.key.
    std::vector<std::string> pairs, pubs;
    for (const auto& e : fs::directory_iterator(p)) {
      if (!e.is_regular_file() || !conica::net::is_old_key_file(e.path().string())) continue;
      (e.path().extension() == ".pub" ? pubs : pairs).push_back(e.path().string());
    }
    std::sort(pairs.begin(), pairs.end());
    std::sort(pubs.begin(), pubs.end());
    if (pairs.empty() && pubs.empty()) std::printf("%s: no old key files\n", p.c_str());
    files.insert(files.end(), pairs.begin(), pairs.end());
    files.insert(files.end(), pubs.begin(), pubs.end());
  }
  int status = 0;
  for (const std::string& f : files) {
    // A pair converted on the way (NAME.key beside NAME.pub) is no longer old: skip it.
    if (!fs::exists(f)) continue;
    std::vector<std::string> done;
    const std::string e = conica::net::convert_old_key_file(f, &done);
    for (const std::string& d : done) std::printf("%s\n", d.c_str());
    if (!e.empty()) {
      std::fprintf(stderr, "conica-keygen: %s\n", e.c_str());
      status = 1;
    }
  }
  return status;
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{
      "CURVE certificates for conica: DIR/NAME.key (public: give it to the other side) and "
      "DIR/NAME.key_secret (secret, mode 0600), the ZeroMQ certificate format of pyzmq's "
      "zmq.auth and czmq's zcert"};
  std::string dir, name;
  std::vector<std::string> old;
  app.add_option("dir", dir, "folder to write into (created if missing)");
  app.add_option("name", name, "certificate name: DIR/NAME.key and DIR/NAME.key_secret");
  app.add_option("--convert", old,
                 "convert old conica key files (or every one in a folder) to certificates: "
                 "NAME.key (old key pair) becomes NAME.key_secret plus the public NAME.key, "
                 "NAME.pub becomes NAME.key")
      ->excludes("dir");
  CLI11_PARSE(app, argc, argv);
  if (!conica::net::curve_available()) {
    std::fprintf(stderr, "conica-keygen: this libzmq has no CURVE support\n");
    return 1;
  }
  if (!old.empty()) return convert(old);
  if (dir.empty() || name.empty()) {
    std::fprintf(stderr, "conica-keygen: give DIR and NAME, or --convert FILE (see --help)\n");
    return 2;
  }
  conica::net::CurveKeyPair kp;
  std::string e = conica::net::generate_keypair(&kp);
  if (e.empty()) e = conica::net::write_keypair(dir, name, kp);
  if (!e.empty()) {
    std::fprintf(stderr, "conica-keygen: %s\n", e.c_str());
    return 1;
  }
  std::printf(
      "%s/%s.key_secret (secret certificate: keep private)\n%s/%s.key (public certificate: hand "
      "out) public-key %s\n",
      dir.c_str(), name.c_str(), dir.c_str(), name.c_str(), kp.public_key.c_str());
  return 0;
}
