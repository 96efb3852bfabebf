// Runs the built conica-lab (CONICA_LAB_BIN) as a user would, for the tests that drive it.
#pragma once

#include <sys/wait.h>

#include <array>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>
#include <vector>

namespace conica::testing {

struct LabRun {
  int status = -1;     // exit status
  std::string output;  // stdout and stderr
};

inline LabRun run_lab(const std::string& args) {
  LabRun r;
  const std::string cmd = std::string("'") + CONICA_LAB_BIN + "' " + args + " 2>&1";
  FILE* p = popen(cmd.c_str(), "r");
  if (!p) return r;
  std::array<char, 4096> buf;
  std::size_t n;
  while ((n = std::fread(buf.data(), 1, buf.size(), p)) > 0) r.output.append(buf.data(), n);
  const int w = pclose(p);
  r.status = WIFEXITED(w) ? WEXITSTATUS(w) : -1;
  return r;
}

// The whole file at `path` ("" when it cannot be read).
inline std::string slurp(const std::filesystem::path& path) {
  std::ifstream in(path, std::ios::binary);
  std::ostringstream s;
  s << in.rdbuf();
  return s.str();
}

// Removes the files a test wrote when it ends, pass or fail.
struct RemovedAtEnd {
  std::vector<std::string> paths;
  ~RemovedAtEnd() {
    for (const std::string& p : paths) std::filesystem::remove(p);
  }
};

}  // namespace conica::testing
