#include "io/curve_reader.h"

#include <algorithm>
#include <cctype>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <limits>
#include <sstream>

#include "io/text_reader.h"

namespace conica::io {
namespace {

using detail::LineReader;
using detail::parse_double;

std::string num(double v) {
  char buf[32];
  std::snprintf(buf, sizeof buf, "%.6g", v);
  return buf;
}

// The cells of a CSV row: blanks around a cell, and a trailing ';' or CR, dropped.
std::vector<std::string> cells_of(std::string_view line) {
  std::vector<std::string> out;
  size_t a = 0;
  while (true) {
    const size_t b = line.find(',', a);
    out.emplace_back(line.substr(a, b == std::string_view::npos ? std::string_view::npos : b - a));
    if (b == std::string_view::npos) break;
    a = b + 1;
  }
  for (auto& s : out) {
    while (!s.empty() && (s.back() == '\r' || s.back() == ' ' || s.back() == ';')) s.pop_back();
    while (!s.empty() && s.front() == ' ') s.erase(s.begin());
  }
  return out;
}

// "Compression (mm)" -> name "Compression", unit "mm"; no parentheses: unit empty.
void split_header(const std::string& cell, std::string* name, std::string* unit) {
  const size_t open = cell.rfind('(');
  if (open == std::string::npos || cell.back() != ')') {
    *name = cell;
    unit->clear();
    return;
  }
  size_t end = open;
  while (end > 0 && cell[end - 1] == ' ') --end;
  *name = cell.substr(0, end);
  *unit = cell.substr(open + 1, cell.size() - open - 2);
}

// A metadata line "... Height: 30mm;" -> 0.03 (m); 0 when the line says no height.
double height_of(std::string_view line) {
  std::string lower(line);
  std::transform(lower.begin(), lower.end(), lower.begin(),
                 [](unsigned char c) { return std::tolower(c); });
  const size_t at = lower.find("height:");
  if (at == std::string::npos) return 0;
  std::string rest = lower.substr(at + 7);
  while (!rest.empty() && (rest.back() == ';' || rest.back() == ' ' || rest.back() == '\r'))
    rest.pop_back();
  size_t i = rest.find_first_not_of(' ');
  if (i == std::string::npos) return 0;
  size_t j = i;
  while (j < rest.size() && (std::isdigit(static_cast<unsigned char>(rest[j])) || rest[j] == '.'))
    ++j;
  double v = 0;
  if (!parse_double(std::string_view(rest).substr(i, j - i), &v) || !(v > 0)) return 0;
  std::string unit = rest.substr(j);
  unit.erase(0, unit.find_first_not_of(' '));
  if (unit == "mm") return v * 1e-3;
  if (unit == "m") return v;
  return 0;
}

struct Column {
  int index = -1;     // 0-based cell
  std::string label;  // the header cell, e.g. "Load (N)"
  double scale = 1;   // to SI
  std::string unit;
  // "column 3 (Load (N))"
  std::string where() const { return "column " + std::to_string(index + 1) + " (" + label + ")"; }
};

}  // namespace

Result<ForceCurve> parse_curve(std::string_view text, const std::string& name,
                               const CurveRequest& request) {
  ForceCurve out;
  LineReader in(text, name);
  Column u, f;
  int header_line = 0;
  std::string_view line;
  // Metadata, then the header row.
  while (in.next(&line)) {
    if (line.find_first_not_of(" \r\t") == std::string_view::npos) continue;
    const std::vector<std::string> cells = cells_of(line);
    bool has_u = false;
    for (size_t c = 0; c < cells.size(); ++c) {
      std::string n, unit;
      split_header(cells[c], &n, &unit);
      if (n == request.displacement_column && !unit.empty() && u.index < 0) {
        u = {static_cast<int>(c), cells[c], 1, unit};
        has_u = true;
      }
      if (n == request.force_column && !unit.empty() && f.index < 0)
        f = {static_cast<int>(c), cells[c], 1, unit};
    }
    if (!has_u) {
      if (const double h = height_of(line); h > 0 && out.file_height == 0) out.file_height = h;
      f = {};
      continue;
    }
    header_line = in.line_number();
    if (f.index < 0) {
      std::string list;
      for (const std::string& c : cells) list += (list.empty() ? "" : ", ") + c;
      return Error{
          in.message("no column \"" + request.force_column + " (N)\" (columns: " + list + ")")};
    }
    break;
  }
  if (header_line == 0)
    return Error{name + ": no header row naming the columns \"" + request.displacement_column +
                 " (mm)\" and \"" + request.force_column + " (N)\""};
  if (u.unit == "mm")
    u.scale = 1e-3;
  else if (u.unit != "m")
    return Error{in.message(u.where() + ": unit '" + u.unit + "' is not mm or m")};
  if (f.unit == "kN")
    f.scale = 1e3;
  else if (f.unit != "N")
    return Error{in.message(f.where() + ": unit '" + f.unit + "' is not N or kN")};
  out.displacement_unit = u.unit;
  out.force_unit = f.unit;

  // Rows: the loading branch is kept, up to the first row of the largest compression.
  double max_u = -std::numeric_limits<double>::infinity();
  size_t max_at = 0;
  int max_line = 0;
  while (in.next(&line)) {
    if (line.find_first_not_of(" \r\t") == std::string_view::npos) continue;
    const std::vector<std::string> cells = cells_of(line);
    double value[2];
    const Column* cols[2] = {&u, &f};
    for (int k = 0; k < 2; ++k) {
      const Column& c = *cols[k];
      if (static_cast<int>(cells.size()) <= c.index)
        return Error{in.message(c.where() + " missing: the row has " +
                                std::to_string(cells.size()) + " columns")};
      if (!parse_double(cells[c.index], &value[k]))
        return Error{in.message(c.where() + ": '" + cells[c.index] + "' is not a finite number")};
    }
    ++out.rows;
    out.samples.push_back({u.scale == 1 ? value[0] : value[0] * u.scale,
                           f.scale == 1 ? value[1] : value[1] * f.scale});
    if (value[0] > max_u) {
      max_u = value[0];
      max_at = out.samples.size();
      max_line = in.line_number();
    }
  }
  if (out.samples.size() < 2)
    return Error{name + ": fewer than two data rows after the header (line " +
                 std::to_string(header_line) + ")"};
  out.samples.resize(max_at);  // the loading branch
  out.last_line = max_line;
  const CurveSample& peak = out.samples.back();
  const std::string at = name + ":" + std::to_string(max_line) + ": ";
  if (!(peak.displacement > 0))
    return Error{at + u.where() + ": the largest compression is " + num(max_u) + " " + u.unit +
                 ": a tension test (this reader takes compression positive)"};
  if (!(peak.force > 0))
    return Error{at + f.where() + ": the load at the largest compression is " +
                 num(peak.force / f.scale) + " " + f.unit +
                 ": a tension curve, or the load's sign is reversed (compression is positive)"};

  // Units and reach against the specimen's height.
  out.height = request.height > 0 ? request.height : out.file_height;
  if (request.height > 0 && out.file_height > 0 &&
      std::abs(out.file_height / request.height - 1) > 0.01)
    out.warnings.push_back(name + ": the file's specimen height " + num(out.file_height * 1e3) +
                           " mm is not the body's " + num(request.height * 1e3) +
                           " mm; strains are the body's");
  const double h = out.height;
  if (h > 0) {
    const std::string height = "the specimen's height of " + num(h / u.scale) + " " + u.unit;
    if (peak.displacement > h)
      return Error{
          at + u.where() + ": reaches " + num(max_u) + " " + u.unit + ", more than " + height +
          (u.unit == "m" && peak.displacement * 1e-3 <= h ? ": the values look like millimetres"
                                                          : "")};
    if (u.unit == "mm" && peak.displacement < 1e-3 * h)
      return Error{at + u.where() + ": ends at " + num(max_u) + " mm, " +
                   num(100 * peak.displacement / h) + " % of " + height +
                   ": the values look like metres"};
    if (request.max_strain > 0 && peak.displacement < request.max_strain * h * (1 - 1e-9))
      return Error{at + u.where() + ": the curve ends at " + num(max_u) + " " + u.unit +
                   " (strain " + num(peak.displacement / h) + " of " + num(h / u.scale) + " " +
                   u.unit + "), before the " + num(request.max_strain * h / u.scale) + " " +
                   u.unit + " asked (strain " + num(request.max_strain) + ")"};
  }
  return out;
}

Result<ForceCurve> read_curve(const std::string& path, const CurveRequest& request) {
  std::ifstream in(path, std::ios::binary);
  if (!in) return Error{path + ": cannot open curve file"};
  std::ostringstream text;
  text << in.rdbuf();
  return parse_curve(text.str(), path, request);
}

}  // namespace conica::io
