#include "io/probe_script.h"

#include <charconv>
#include <cmath>
#include <fstream>
#include <sstream>

namespace conica::io {
namespace {

std::string_view trim(std::string_view s) {
  while (!s.empty() && (s.front() == ' ' || s.front() == '\t')) s.remove_prefix(1);
  while (!s.empty() && (s.back() == ' ' || s.back() == '\t' || s.back() == '\r')) s.remove_suffix(1);
  return s;
}

bool to_double(std::string_view s, double* v) {
  s = trim(s);
  if (s.empty()) return false;
  const auto r = std::from_chars(s.data(), s.data() + s.size(), *v);
  return r.ec == std::errc() && r.ptr == s.data() + s.size() && std::isfinite(*v);
}

}  // namespace

bool ProbeScript::position(int probe, double t, Vec3* x) const {
  if (probe < 0 || probe >= static_cast<int>(probes.size())) return false;
  const auto& k = probes[probe];
  if (k.empty() || t < k.front().t) return false;
  if (t >= k.back().t) {
    *x = k.back().x;
    return true;
  }
  size_t i = 1;
  while (k[i].t <= t) ++i;
  const double w = (t - k[i - 1].t) / (k[i].t - k[i - 1].t);
  *x = (1 - w) * k[i - 1].x + w * k[i].x;
  return true;
}

double ProbeScript::end_time() const {
  double t = 0;
  for (const auto& k : probes)
    if (!k.empty()) t = std::max(t, k.back().t);
  return t;
}

Result<ProbeScript> parse_probe_script(std::string_view text, const std::string& name) {
  ProbeScript script;
  int line_no = 0;
  bool header = false;
  size_t pos = 0;
  while (pos <= text.size()) {
    const size_t end = std::min(text.find('\n', pos), text.size());
    std::string_view line = trim(text.substr(pos, end - pos));
    pos = end + 1;
    ++line_no;
    if (line.empty() || line.front() == '#') {
      if (end == text.size()) break;
      continue;
    }
    auto where = [&](const std::string& what) {
      return Error{name + ":" + std::to_string(line_no) + ": " + what};
    };
    std::vector<std::string_view> f;
    size_t a = 0;
    while (true) {
      const size_t b = line.find(',', a);
      f.push_back(line.substr(a, b == std::string_view::npos ? std::string_view::npos : b - a));
      if (b == std::string_view::npos) break;
      a = b + 1;
    }
    if (!header) {
      if (f.size() != 5 || trim(f[0]) != "t" || trim(f[1]) != "probe" || trim(f[2]) != "x" ||
          trim(f[3]) != "y" || trim(f[4]) != "z")
        return where("expected the header t,probe,x,y,z");
      header = true;
      continue;
    }
    if (f.size() != 5) return where("expected 5 fields t,probe,x,y,z, got " + std::to_string(f.size()));
    double v[5];
    static const char* kNames[5] = {"t", "probe", "x", "y", "z"};
    for (int k = 0; k < 5; ++k)
      if (!to_double(f[k], &v[k])) return where("field " + std::string(kNames[k]) + " is not a finite number: '" + std::string(trim(f[k])) + "'");
    if (v[0] < 0) return where("t must be >= 0 s");
    if (v[1] < 0 || v[1] > 63 || v[1] != std::floor(v[1]))
      return where("probe must be an integer in 0..63");
    const int p = static_cast<int>(v[1]);
    if (static_cast<int>(script.probes.size()) <= p) script.probes.resize(p + 1);
    auto& k = script.probes[p];
    if (!k.empty() && v[0] <= k.back().t)
      return where("t must increase for each probe (probe " + std::to_string(p) + ")");
    k.push_back({v[0], Vec3(v[2], v[3], v[4])});
    if (end == text.size()) break;
  }
  if (!header) return Error{name + ": empty probe script (expected the header t,probe,x,y,z)"};
  return script;
}

Result<ProbeScript> read_probe_script(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  if (!in) return Error{path + ": cannot open probe script"};
  std::ostringstream s;
  s << in.rdbuf();
  return parse_probe_script(s.str(), path);
}

void make_absolute(ProbeScript& script, const Vec3& lo, const Vec3& hi) {
  for (auto& k : script.probes)
    for (auto& f : k) f.x = lo + f.x.cwiseProduct(hi - lo);
}

}  // namespace conica::io
