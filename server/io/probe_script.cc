#include "io/probe_script.h"

#include <algorithm>
#include <charconv>
#include <cmath>
#include <fstream>
#include <sstream>

namespace conica::io {
namespace {

bool blank(char c) { return c == ' ' || c == '\t' || c == '\r'; }

// A field of a line: its text without surrounding blanks and its 1-based column.
struct Field {
  std::string_view text;
  int column = 1;
};

// Splits `line` on ','; columns count from the start of the raw line.
std::vector<Field> split(std::string_view line) {
  std::vector<Field> out;
  std::size_t a = 0;
  for (;;) {
    const std::size_t b = std::min(line.find(',', a), line.size());
    std::size_t s = a, e = b;
    while (s < e && blank(line[s])) ++s;
    while (e > s && blank(line[e - 1])) --e;
    out.push_back({line.substr(s, e - s), static_cast<int>((s < b ? s : a) + 1)});
    if (b == line.size()) break;
    a = b + 1;
  }
  return out;
}

bool to_double(std::string_view s, double* v) {
  if (s.empty()) return false;
  const auto r = std::from_chars(s.data(), s.data() + s.size(), *v);
  return r.ec == std::errc() && r.ptr == s.data() + s.size() && std::isfinite(*v);
}

std::string number(double v) {
  std::ostringstream s;
  s << v;
  return s.str();
}

constexpr const char* kHeader = "t,probe,x,y,z";

}  // namespace

ProbeScriptFormat client_trajectory_format() {
  ProbeScriptFormat f;
  f.header_required = false;
  f.strictly_increasing = false;
  f.max_probe = 1000000;
  f.max_abs_position_m = 100;
  return f;
}

Result<std::vector<ProbeScriptRow>> parse_probe_rows(std::string_view text, const std::string& name,
                                                     const ProbeScriptFormat& format) {
  static const char* kNames[5] = {"t", "probe", "x", "y", "z"};
  std::vector<ProbeScriptRow> rows;
  std::vector<double> last_t;  // per probe; NaN before its first row
  int line_no = 0;
  bool first = true;  // no header or data line seen yet
  std::size_t pos = 0;
  while (pos < text.size()) {
    const std::size_t end = std::min(text.find('\n', pos), text.size());
    const std::string_view line = text.substr(pos, end - pos);
    pos = end + 1;
    ++line_no;
    std::size_t lead = 0;
    while (lead < line.size() && blank(line[lead])) ++lead;
    if (lead == line.size() || line[lead] == '#') continue;
    auto at = [&](int column, const std::string& what) {
      return Error{name + ":" + std::to_string(line_no) + ":" + std::to_string(column) + ": " +
                   what};
    };
    const std::vector<Field> f = split(line);
    if (first) {
      first = false;
      const bool is_header = f.size() == 5 && f[0].text == "t" && f[1].text == "probe" &&
                             f[2].text == "x" && f[3].text == "y" && f[4].text == "z";
      if (format.header_required) {
        if (!is_header)
          return at(static_cast<int>(lead) + 1, std::string("expected the header ") + kHeader);
        continue;
      }
      if (line[lead] == 't') continue;  // an optional header ("t,probe,x,y,z", "time,...")
    }
    if (f.size() != 5) {
      const int column = f.size() > 5 ? f[5].column : static_cast<int>(line.size()) + 1;
      return at(column, "expected 5 fields (t,probe,x,y,z), got " + std::to_string(f.size()));
    }
    double v[5];
    for (int k = 0; k < 5; ++k)
      if (!to_double(f[k].text, &v[k]))
        return at(f[k].column, "field " + std::string(kNames[k]) + ": \"" + std::string(f[k].text) +
                                   "\" is not a finite number");
    if (v[0] < 0) return at(f[0].column, "time must be >= 0 s, got " + std::string(f[0].text));
    if (v[1] < 0 || v[1] > format.max_probe || v[1] != std::floor(v[1]))
      return at(f[1].column, "probe must be an integer in 0.." + std::to_string(format.max_probe) +
                                 ", got " + std::string(f[1].text));
    for (int k = 2; k < 5; ++k)
      if (std::abs(v[k]) > format.max_abs_position_m)
        return at(f[k].column, "position more than " + number(format.max_abs_position_m) +
                                   " m from the origin (the file must be in metres)");
    const int p = static_cast<int>(v[1]);
    if (static_cast<int>(last_t.size()) <= p) last_t.resize(p + 1, std::nan(""));
    const double prev = last_t[p];
    if (!std::isnan(prev) && v[0] < prev)
      return at(f[0].column, "time goes backwards for probe " + std::to_string(p) + " (" +
                                 number(v[0]) + " s after " + number(prev) + " s)");
    if (!std::isnan(prev) && v[0] == prev && format.strictly_increasing)
      return at(f[0].column, "time must increase for probe " + std::to_string(p) + " (" +
                                 number(v[0]) + " s twice)");
    last_t[p] = v[0];
    rows.push_back({v[0], p, Vec3(v[2], v[3], v[4]), line_no});
  }
  if (first && format.header_required)
    return Error{name + ": empty probe script (expected the header " + kHeader + ")"};
  if (rows.empty()) return Error{name + ": no samples (expected lines " + kHeader + ")"};
  return rows;
}

Result<std::vector<ProbeScriptRow>> read_probe_rows(const std::string& path,
                                                    const ProbeScriptFormat& format) {
  std::ifstream in(path, std::ios::binary);
  if (!in) return Error{path + ": cannot open probe script"};
  std::ostringstream s;
  s << in.rdbuf();
  return parse_probe_rows(s.str(), path, format);
}

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

namespace {

Result<ProbeScript> to_script(Result<std::vector<ProbeScriptRow>> rows) {
  if (!rows) return Error{rows.error()};
  ProbeScript script;
  for (const ProbeScriptRow& r : rows.value()) {
    if (static_cast<int>(script.probes.size()) <= r.probe) script.probes.resize(r.probe + 1);
    script.probes[r.probe].push_back({r.t, r.x});
  }
  return script;
}

}  // namespace

Result<ProbeScript> parse_probe_script(std::string_view text, const std::string& name) {
  return to_script(parse_probe_rows(text, name));
}

Result<ProbeScript> read_probe_script(const std::string& path) {
  return to_script(read_probe_rows(path));
}

void make_absolute(ProbeScript& script, const Vec3& lo, const Vec3& hi) {
  for (auto& k : script.probes)
    for (auto& f : k) f.x = lo + f.x.cwiseProduct(hi - lo);
}

}  // namespace conica::io
