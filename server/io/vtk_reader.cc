// Legacy VTK unstructured grids, ASCII and BINARY (formats 2.0 to 5.1; see "VTK File Formats"
// in the VTK user's guide). Cells 10 (tetra), 12 (hexahedron) and 5 (triangle) are kept, others
// counted. The first one-component integer CELL_DATA scalar names the regions of volume cells.
// BINARY files keep the keywords as text lines and write the numbers after each keyword line
// raw and big-endian (cells as int, or from 5.1 OFFSETS/CONNECTIVITY of the type they name).
#include <cmath>
#include <cstdint>
#include <optional>

#include "io/binary_reader.h"
#include "io/readers.h"

namespace conica::io::detail {

namespace {

constexpr std::int64_t kMinValueBytes = 2;  // "0 "

std::string cell_type_name(std::int64_t type) {
  switch (type) {
    case 1:
      return "vertex";
    case 2:
      return "polyvertex";
    case 3:
      return "line";
    case 4:
      return "polyline";
    case 5:
      return "triangle";
    case 6:
      return "triangle strip";
    case 7:
      return "polygon";
    case 8:
      return "pixel";
    case 9:
      return "quad";
    case 10:
      return "tetra";
    case 11:
      return "voxel";
    case 12:
      return "hexahedron";
    case 13:
      return "wedge";
    case 14:
      return "pyramid";
    case 24:
      return "quadratic tetra";
    case 25:
      return "quadratic hexahedron";
    default:
      return "vtk cell type " + std::to_string(type);
  }
}

// Tokens with one token of look-ahead.
class Tokens {
 public:
  explicit Tokens(LineReader* in) : t_(in) {}
  bool next(std::string_view* token) {
    if (pending_) {
      *token = *pending_;
      pending_.reset();
      return true;
    }
    return t_.next(token);
  }
  std::string_view expect(std::string_view what) {
    std::string_view token;
    if (!next(&token)) t_.lines().fail("unexpected end of file, expected " + std::string(what));
    return token;
  }
  void push_back(std::string_view token) { pending_ = token; }
  std::int64_t integer(std::string_view what) { return to_int(t_.lines(), expect(what), what); }
  std::int64_t count(std::string_view what, std::int64_t bytes_per_item) {
    const std::int64_t max =
        static_cast<std::int64_t>(t_.lines().remaining_bytes()) / bytes_per_item + 1;
    return to_count(t_.lines(), expect(what), what, max);
  }
  void skip_line() { t_.skip_line(); }
  LineReader& lines() { return t_.lines(); }

 private:
  TokenReader t_;
  std::optional<std::string_view> pending_;
};

struct Cells {
  std::vector<std::int64_t> offsets{0};  // (num_cells + 1)
  std::vector<std::int64_t> connectivity;
  std::vector<std::int64_t> lines;  // (num_cells) line (ASCII) or byte offset (BINARY) of
                                    // each cell, for messages
  std::vector<std::int64_t> types;  // (num_cells)
  int types_line = 0;
  std::int64_t count() const { return static_cast<std::int64_t>(offsets.size()) - 1; }
};

// CELLS n size: n lines "k i0 .. ik-1" (legacy), or, from 5.1, "OFFSETS type" with n offsets
// then "CONNECTIVITY type" with size indices.
void read_cells(Tokens& t, std::int64_t num_points, Cells* cells) {
  LineReader& in = t.lines();
  const std::int64_t n = t.count("cell count", kMinValueBytes);
  const std::int64_t size = t.count("cell list size", kMinValueBytes);
  auto check_index = [&](std::int64_t cell, std::int64_t index) {
    if (index < 0 || index >= num_points) {
      in.fail("cell " + std::to_string(cell) + " references unknown point " +
              std::to_string(index) + " (the file has " + std::to_string(num_points) + " points)");
    }
  };
  std::string_view token = t.expect("cell data");
  if (token == "OFFSETS") {
    t.expect("offset type");
    if (n < 1) in.fail("OFFSETS needs at least one offset");
    for (std::int64_t i = 0; i < n; ++i) {
      const std::int64_t o = t.integer("offset");
      if (i == 0 ? o != 0 : o < cells->offsets.back()) {
        in.fail("offsets must start at 0 and not decrease");
      }
      if (i > 0) {
        cells->offsets.push_back(o);
        cells->lines.push_back(in.line_number());
      }
    }
    if (t.expect("CONNECTIVITY") != "CONNECTIVITY") in.fail("expected CONNECTIVITY");
    t.expect("connectivity type");
    if (cells->offsets.back() != size) {
      in.fail("last offset " + std::to_string(cells->offsets.back()) +
              " differs from the connectivity size " + std::to_string(size));
    }
    std::int64_t cell = 0;
    for (std::int64_t i = 0; i < size; ++i) {
      while (cells->offsets[cell + 1] <= i) ++cell;
      const std::int64_t index = t.integer("point index");
      check_index(cell, index);
      cells->connectivity.push_back(index);
    }
    return;
  }
  t.push_back(token);
  std::int64_t used = 0;
  for (std::int64_t c = 0; c < n; ++c) {
    const std::int64_t k = t.integer("number of cell points");
    cells->lines.push_back(in.line_number());
    if (k < 1 || k > size - used - 1) {
      in.fail("cell " + std::to_string(c) + " with " + std::to_string(k) +
              " points overflows the cell list size " + std::to_string(size));
    }
    for (std::int64_t i = 0; i < k; ++i) {
      const std::int64_t index = t.integer("point index");
      check_index(c, index);
      cells->connectivity.push_back(index);
    }
    used += 1 + k;
    cells->offsets.push_back(static_cast<std::int64_t>(cells->connectivity.size()));
  }
  if (used != size) {
    in.fail("cells use " + std::to_string(used) + " values, header announced " +
            std::to_string(size));
  }
}

// Skips `n` values.
void skip_values(Tokens& t, std::int64_t n) {
  for (std::int64_t i = 0; i < n; ++i) t.expect("data value");
}

// Reads one dataset attribute starting at `keyword`; keeps a one-component integer cell
// scalar in *regions if none was kept yet.
void read_attribute(Tokens& t, std::string_view keyword, std::int64_t n, bool cell_data,
                    std::vector<std::int64_t>* regions, bool* have_regions) {
  LineReader& in = t.lines();
  if (keyword == "SCALARS") {
    t.expect("scalar name");
    t.expect("scalar type");
    std::int64_t components = 1;
    std::string_view token = t.expect("LOOKUP_TABLE");
    if (token != "LOOKUP_TABLE") {
      components = to_int(in, token, "number of components");
      if (components < 1 || components > 4) in.fail("scalars need 1 to 4 components");
      token = t.expect("LOOKUP_TABLE");
    }
    if (token != "LOOKUP_TABLE")
      in.fail("expected LOOKUP_TABLE, found '" + std::string(token) + "'");
    t.expect("lookup table name");
    const bool keep = cell_data && components == 1 && !*have_regions;
    std::vector<std::int64_t> values;
    bool integral = true;
    for (std::int64_t i = 0; i < n * components; ++i) {
      const std::string_view v = t.expect("scalar value");
      if (!keep || !integral) continue;
      double x = 0;
      if (!parse_double(v, &x)) in.fail("scalar value '" + std::string(v) + "' is not a number");
      integral = x == std::floor(x) && std::abs(x) < 2e9;
      if (integral) values.push_back(static_cast<std::int64_t>(x));  // 1e99 -> int64 is UB
    }
    if (keep && integral) {
      *regions = std::move(values);
      *have_regions = true;
    }
  } else if (keyword == "VECTORS" || keyword == "NORMALS") {
    t.expect("name");
    t.expect("type");
    skip_values(t, 3 * n);
  } else if (keyword == "TENSORS") {
    t.expect("name");
    t.expect("type");
    skip_values(t, 9 * n);
  } else if (keyword == "TEXTURE_COORDINATES") {
    t.expect("name");
    const std::int64_t dim = t.integer("dimension");
    if (dim < 1 || dim > 3) in.fail("texture coordinates need dimension 1 to 3");
    t.expect("type");
    skip_values(t, dim * n);
  } else if (keyword == "COLOR_SCALARS") {
    t.expect("name");
    const std::int64_t m = t.integer("number of values");
    if (m < 1 || m > 4) in.fail("color scalars need 1 to 4 values");
    skip_values(t, m * n);
  } else if (keyword == "LOOKUP_TABLE") {
    t.expect("name");
    skip_values(t, 4 * t.count("table size", 4 * kMinValueBytes));
  } else if (keyword == "FIELD") {
    t.expect("field name");
    const std::int64_t arrays = t.count("array count", kMinValueBytes);
    for (std::int64_t a = 0; a < arrays; ++a) {
      t.expect("array name");
      const std::int64_t components = t.count("component count", kMinValueBytes);
      const std::int64_t tuples = t.count("tuple count", kMinValueBytes);
      t.expect("array type");
      if (components > 0 &&
          tuples > static_cast<std::int64_t>(in.remaining_bytes()) / components + 1) {
        in.fail("field array larger than the rest of the file");
      }
      skip_values(t, components * tuples);
    }
  } else if (keyword == "METADATA") {
    // Ends at the next blank line.
    t.skip_line();
    std::string_view line;
    while (in.next(&line) && !Fields(line).rest().empty()) {
    }
  } else {
    in.fail("unknown VTK keyword '" + std::string(keyword.substr(0, 40)) + "'");
  }
}

// Files the cells into `out`; `fail(where, what)` reports a cell of the wrong size at its line
// or byte offset.
template <class Fail>
void assemble(const Cells& cells, const std::vector<std::int64_t>& regions, bool have_regions,
              MeshAssembler* out, Fail fail) {
  const std::vector<int> no_tags;
  for (std::int64_t c = 0; c < cells.count(); ++c) {
    const std::int64_t* p = cells.connectivity.data() + cells.offsets[c];
    const std::int64_t k = cells.offsets[c + 1] - cells.offsets[c];
    const std::int64_t type = cells.types[c];
    const int expected = type == 10 ? 4 : type == 12 ? 8 : type == 5 ? 3 : -1;
    if (expected > 0 && k != expected) {
      fail(cells.lines[c], "cell " + std::to_string(c) + " (" + cell_type_name(type) + ") has " +
                               std::to_string(k) + " points, expected " + std::to_string(expected));
    }
    const bool tagged = have_regions && static_cast<std::int64_t>(regions.size()) == cells.count();
    const std::vector<int> tags = tagged ? std::vector<int>{static_cast<int>(regions[c])} : no_tags;
    auto at = [&](int i) { return static_cast<int>(p[i]); };
    if (type == 10) {
      out->add_tetrahedron({at(0), at(1), at(2), at(3)}, tags);
    } else if (type == 12) {
      out->add_hexahedron({at(0), at(1), at(2), at(3), at(4), at(5), at(6), at(7)}, tags);
    } else if (type == 5) {
      out->add_triangle({at(0), at(1), at(2)});
    } else {
      out->skip(cell_type_name(type));
    }
  }
}

// ---- BINARY ---------------------------------------------------------------------------------

// A VTK data type: its size and whether it is a signed or unsigned integer or a float.
struct VtkType {
  int size = 0;   // 0: unknown
  char kind = 0;  // 'i', 'u', 'f'
};

std::string lower(std::string_view s) {
  std::string out(s);
  for (char& c : out) c = (c >= 'A' && c <= 'Z') ? static_cast<char>(c - 'A' + 'a') : c;
  return out;
}

VtkType vtk_type(std::string_view name) {
  const std::string n = lower(name);
  if (n == "unsigned_char" || n == "vtktypeuint8") return {1, 'u'};
  if (n == "char" || n == "vtktypeint8") return {1, 'i'};
  if (n == "unsigned_short" || n == "vtktypeuint16") return {2, 'u'};
  if (n == "short" || n == "vtktypeint16") return {2, 'i'};
  if (n == "unsigned_int" || n == "vtktypeuint32") return {4, 'u'};
  if (n == "int" || n == "vtktypeint32") return {4, 'i'};
  if (n == "unsigned_long" || n == "vtktypeuint64") return {8, 'u'};
  if (n == "long" || n == "vtktypeint64") return {8, 'i'};
  if (n == "float" || n == "vtktypefloat32") return {4, 'f'};
  if (n == "double" || n == "vtktypefloat64") return {8, 'f'};
  return {};
}

// Keyword lines of a BINARY file, split into fields, with the offset of the line for messages.
class KeywordLines {
 public:
  explicit KeywordLines(ByteReader* in) : in_(in) {}
  // The next non-blank line; false at end of file.
  bool next() {
    std::string_view line;
    if (!in_->next_nonblank_line(&line, &at_)) return false;
    line_ = line;
    f_ = Fields(line);
    return true;
  }
  void expect(std::string_view what) {
    if (!next()) in_->fail("unexpected end of file, expected " + std::string(what));
  }
  std::string_view word(std::string_view what) {
    std::string_view w;
    if (!f_.next(&w)) in_->fail_at(at_, "missing " + std::string(what) + " on the line");
    return w;
  }
  bool more(std::string_view* w) { return f_.next(w); }
  std::int64_t integer(std::string_view what) {
    const std::string_view w = word(what);
    std::int64_t v = 0;
    if (!parse_int(w, &v)) {
      in_->fail_at(
          at_, std::string(what) + ": '" + std::string(w.substr(0, 40)) + "' is not an integer");
    }
    return v;
  }
  // A count whose values, `bytes` each, fit in the rest of the file.
  std::int64_t count(std::string_view what, std::int64_t bytes) {
    const std::int64_t n = integer(what);
    if (n < 0) in_->fail_at(at_, std::string(what) + " is negative (" + std::to_string(n) + ")");
    in_->need(static_cast<std::uint64_t>(n), static_cast<std::uint64_t>(bytes), what, at_);
    return n;
  }
  VtkType type(std::string_view what) {
    const std::string_view w = word(what);
    const VtkType t = vtk_type(w);
    if (t.size == 0) {
      in_->fail_at(at_, std::string(what) + " '" + std::string(w.substr(0, 40)) +
                            "' is not a VTK data type this reader knows (char ... double, "
                            "vtktypeint64)");
    }
    return t;
  }
  std::size_t at() const { return at_; }
  std::string_view line() const { return line_; }

 private:
  ByteReader* in_;
  std::string_view line_;
  Fields f_{{}};
  std::size_t at_ = 0;
};

// One big-endian value as a double (floats must be finite).
double read_number(ByteReader& in, const VtkType& t, std::string_view what) {
  switch (t.kind == 'f' ? t.size : -t.size) {
    case 4:
      return in.finite_f32(what);
    case 8:
      return in.finite_f64(what);
    default:
      break;
  }
  const std::string_view b = in.bytes(static_cast<std::size_t>(t.size), what);
  std::uint64_t u = 0;
  for (const char c : b) u = (u << 8) | static_cast<unsigned char>(c);
  if (t.kind == 'u') return static_cast<double>(u);
  const int bits = 8 * t.size;
  const std::int64_t v = bits == 64 ? static_cast<std::int64_t>(u)
                                    : static_cast<std::int64_t>(u << (64 - bits)) >> (64 - bits);
  return static_cast<double>(v);
}

// One big-endian integer value (cells, offsets, types).
std::int64_t read_integer(ByteReader& in, const VtkType& t, std::string_view what) {
  const std::size_t at = in.offset();
  if (t.kind == 'f') in.fail_at(at, std::string(what) + ": a float type holds no indices");
  const std::string_view b = in.bytes(static_cast<std::size_t>(t.size), what);
  std::uint64_t u = 0;
  for (const char c : b) u = (u << 8) | static_cast<unsigned char>(c);
  const int bits = 8 * t.size;
  if (t.kind == 'u') {
    if (u > static_cast<std::uint64_t>(INT64_MAX)) {
      in.fail_at(at, std::string(what) + " " + std::to_string(u) + " is out of range");
    }
    return static_cast<std::int64_t>(u);
  }
  return bits == 64 ? static_cast<std::int64_t>(u)
                    : static_cast<std::int64_t>(u << (64 - bits)) >> (64 - bits);
}

const VtkType kInt{4, 'i'};

// CELLS n size: n cells "k i0 .. ik-1" as int (legacy), or, from 5.1, "OFFSETS type" with n
// offsets then "CONNECTIVITY type" with size indices.
void read_binary_cells(ByteReader& in, KeywordLines& k, std::int64_t num_points, Cells* cells) {
  const std::size_t cells_at = k.at();
  const std::int64_t n = k.count("cell count", 0);
  const std::int64_t size = k.count("cell list size", 0);
  auto check_index = [&](std::size_t at, std::int64_t cell, std::int64_t index) {
    if (index < 0 || index >= num_points) {
      in.fail_at(at, "cell " + std::to_string(cell) + " references unknown point " +
                         std::to_string(index) + " (the file has " + std::to_string(num_points) +
                         " points)");
    }
  };
  if (in.starts_with("OFFSETS")) {
    k.expect("OFFSETS");
    k.word("OFFSETS");
    const VtkType ot = k.type("offset type");
    if (n < 1) in.fail_at(k.at(), "OFFSETS needs at least one offset");
    in.need(static_cast<std::uint64_t>(n), static_cast<std::uint64_t>(ot.size), "offset count",
            cells_at);
    for (std::int64_t i = 0; i < n; ++i) {
      const std::size_t at = in.offset();
      const std::int64_t o = read_integer(in, ot, "offset");
      if (i == 0 ? o != 0 : o < cells->offsets.back()) {
        in.fail_at(at, "offsets must start at 0 and not decrease (offset " + std::to_string(i) +
                           " is " + std::to_string(o) + ")");
      }
      if (i > 0) {
        cells->offsets.push_back(o);
        cells->lines.push_back(static_cast<std::int64_t>(at));
      }
    }
    k.expect("CONNECTIVITY");
    if (k.word("CONNECTIVITY") != "CONNECTIVITY") {
      in.fail_at(k.at(), "expected CONNECTIVITY, found " + std::string(k.line().substr(0, 40)));
    }
    const VtkType ct = k.type("connectivity type");
    in.need(static_cast<std::uint64_t>(size), static_cast<std::uint64_t>(ct.size),
            "connectivity size", cells_at);
    if (cells->offsets.back() != size) {
      in.fail_at(k.at(), "last offset " + std::to_string(cells->offsets.back()) +
                             " differs from the connectivity size " + std::to_string(size));
    }
    std::int64_t cell = 0;
    for (std::int64_t i = 0; i < size; ++i) {
      while (cells->offsets[cell + 1] <= i) ++cell;
      const std::size_t at = in.offset();
      const std::int64_t index = read_integer(in, ct, "point index");
      check_index(at, cell, index);
      cells->connectivity.push_back(index);
    }
    return;
  }
  in.need(static_cast<std::uint64_t>(size), 4, "cell list size", cells_at);
  std::int64_t used = 0;
  for (std::int64_t c = 0; c < n; ++c) {
    const std::size_t at = in.offset();
    const std::int64_t points = read_integer(in, kInt, "number of cell points");
    cells->lines.push_back(static_cast<std::int64_t>(at));
    if (points < 1 || points > size - used - 1) {
      in.fail_at(at, "cell " + std::to_string(c) + " with " + std::to_string(points) +
                         " points overflows the cell list size " + std::to_string(size));
    }
    for (std::int64_t i = 0; i < points; ++i) {
      const std::size_t index_at = in.offset();
      const std::int64_t index = read_integer(in, kInt, "point index");
      check_index(index_at, c, index);
      cells->connectivity.push_back(index);
    }
    used += 1 + points;
    cells->offsets.push_back(static_cast<std::int64_t>(cells->connectivity.size()));
  }
  if (used != size) {
    in.fail_at(cells_at, "cells use " + std::to_string(used) + " values, header announced " +
                             std::to_string(size));
  }
}

// Skips `n` values of `t` (checked to fit first).
void skip_binary_values(ByteReader& in, std::int64_t n, int size, std::string_view what,
                        std::size_t at) {
  in.need(static_cast<std::uint64_t>(n), static_cast<std::uint64_t>(size), what, at);
  in.skip(static_cast<std::size_t>(n) * static_cast<std::size_t>(size), what);
}

// `a * b` values, both non-negative and bounded by the file size: no overflow below 2^62.
std::int64_t product(const ByteReader& in, std::size_t at, std::int64_t a, std::int64_t b) {
  if (a > 0 && b > INT64_MAX / 16 / a) in.fail_at(at, "value count larger than the file");
  return a * b;
}

// One dataset attribute of a BINARY file starting at keyword line `k`; keeps a one-component
// integer cell scalar in *regions if none was kept yet.
void read_binary_attribute(ByteReader& in, KeywordLines& k, std::string_view keyword,
                           std::int64_t n, bool cell_data, std::vector<std::int64_t>* regions,
                           bool* have_regions) {
  const std::size_t at = k.at();
  if (keyword == "SCALARS") {
    k.word("scalar name");
    const VtkType t = k.type("scalar type");
    std::int64_t components = 1;
    std::string_view w;
    if (k.more(&w)) {
      if (!parse_int(w, &components) || components < 1 || components > 4) {
        in.fail_at(at,
                   "scalars need 1 to 4 components, found '" + std::string(w.substr(0, 40)) + "'");
      }
    }
    k.expect("LOOKUP_TABLE");
    if (k.word("LOOKUP_TABLE") != "LOOKUP_TABLE") {
      in.fail_at(k.at(), "expected LOOKUP_TABLE, found " + std::string(k.line().substr(0, 40)));
    }
    k.word("lookup table name");
    const std::int64_t values = product(in, at, n, components);
    in.need(static_cast<std::uint64_t>(values), static_cast<std::uint64_t>(t.size),
            "scalar value count", at);
    const bool keep = cell_data && components == 1 && !*have_regions;
    std::vector<std::int64_t> kept;
    bool integral = true;
    for (std::int64_t i = 0; i < values; ++i) {
      const double x = read_number(in, t, "scalar value");
      if (!keep || !integral) continue;
      integral = x == std::floor(x) && std::abs(x) < 2e9;
      if (integral) kept.push_back(static_cast<std::int64_t>(x));
    }
    if (keep && integral) {
      *regions = std::move(kept);
      *have_regions = true;
    }
  } else if (keyword == "VECTORS" || keyword == "NORMALS" || keyword == "TENSORS") {
    k.word("name");
    const VtkType t = k.type("type");
    skip_binary_values(in, product(in, at, n, keyword == "TENSORS" ? 9 : 3), t.size, "values", at);
  } else if (keyword == "TEXTURE_COORDINATES") {
    k.word("name");
    const std::int64_t dim = k.integer("dimension");
    if (dim < 1 || dim > 3) in.fail_at(at, "texture coordinates need dimension 1 to 3");
    const VtkType t = k.type("type");
    skip_binary_values(in, product(in, at, n, dim), t.size, "texture coordinates", at);
  } else if (keyword == "COLOR_SCALARS") {
    k.word("name");
    const std::int64_t m = k.integer("number of values");
    if (m < 1 || m > 4) in.fail_at(at, "color scalars need 1 to 4 values");
    skip_binary_values(in, product(in, at, n, m), 1, "color scalars", at);  // unsigned char
  } else if (keyword == "LOOKUP_TABLE") {
    k.word("name");
    const std::int64_t size = k.count("table size", 4);
    skip_binary_values(in, size, 4, "lookup table", at);  // RGBA unsigned char
  } else if (keyword == "FIELD") {
    k.word("field name");
    const std::int64_t arrays = k.count("array count", 1);
    for (std::int64_t a = 0; a < arrays; ++a) {
      k.expect("a field array");
      k.word("array name");
      const std::int64_t components = k.count("component count", 0);
      const std::int64_t tuples = k.count("tuple count", 0);
      const VtkType t = k.type("array type");
      skip_binary_values(in, product(in, k.at(), components, tuples), t.size, "field array",
                         k.at());
    }
  } else if (keyword == "METADATA") {
    // Text up to the next blank line.
    std::string_view line;
    while (in.next_line(&line) && !Fields(line).rest().empty()) {
    }
  } else {
    in.fail_at(at, "unknown VTK keyword '" + std::string(keyword.substr(0, 40)) + "'");
  }
}

// After the BINARY line.
MeshFile read_vtk_binary(ByteReader& in, std::string_view version) {
  in.set_big_endian(true);
  KeywordLines k(&in);
  k.expect("DATASET");
  if (k.word("DATASET") != "DATASET") in.fail_at(k.at(), "expected DATASET");
  const std::string_view dataset = k.word("dataset type");
  if (dataset != "UNSTRUCTURED_GRID") {
    in.fail_at(k.at(), "unsupported VTK dataset " + std::string(dataset.substr(0, 40)) +
                           " (only UNSTRUCTURED_GRID)");
  }

  MeshAssembler out;
  out.zero_is_region = true;
  out.file().format = "vtk " + std::string(version) + " binary";
  Mesh& mesh = out.file().mesh;
  bool have_points = false;
  Cells cells;
  bool have_cells = false;
  std::int64_t attribute_count = 0;
  bool cell_data = false;
  bool in_data = false;
  std::vector<std::int64_t> regions;
  bool have_regions = false;
  std::size_t cell_types_at = 0;

  while (k.next()) {
    const std::size_t at = k.at();
    const std::string_view token = k.word("keyword");
    if (token == "POINTS") {
      if (have_points) in.fail_at(at, "second POINTS section");
      const std::int64_t n = k.count("point count", 0);
      const VtkType t = k.type("point type");
      in.need(static_cast<std::uint64_t>(n), 3 * static_cast<std::uint64_t>(t.size), "point count",
              at);
      mesh.nodes.reserve(static_cast<std::size_t>(n));
      for (std::int64_t i = 0; i < n; ++i) {
        Vec3 p;
        for (int c = 0; c < 3; ++c)
          p[c] = read_number(in, t, "coordinate of point " + std::to_string(i));
        mesh.nodes.push_back(p);
      }
      have_points = true;
    } else if (token == "CELLS") {
      if (!have_points) in.fail_at(at, "CELLS before POINTS");
      if (have_cells) in.fail_at(at, "second CELLS section");
      read_binary_cells(in, k, static_cast<std::int64_t>(mesh.nodes.size()), &cells);
      have_cells = true;
    } else if (token == "CELL_TYPES") {
      if (!have_cells) in.fail_at(at, "CELL_TYPES before CELLS");
      const std::int64_t n = k.count("cell type count", 4);
      if (n != cells.count()) {
        in.fail_at(at, "CELL_TYPES has " + std::to_string(n) + " entries for " +
                           std::to_string(cells.count()) + " cells");
      }
      cell_types_at = at;
      for (std::int64_t i = 0; i < n; ++i)
        cells.types.push_back(read_integer(in, kInt, "cell type"));
    } else if (token == "CELL_DATA" || token == "POINT_DATA") {
      cell_data = token == "CELL_DATA";
      attribute_count = k.count("data count", 1);
      in_data = true;
      if (cell_data) {
        if (attribute_count != cells.count()) {
          in.fail_at(at, "CELL_DATA has " + std::to_string(attribute_count) + " values for " +
                             std::to_string(cells.count()) + " cells");
        }
      } else if (attribute_count != static_cast<std::int64_t>(mesh.nodes.size())) {
        in.fail_at(at, "POINT_DATA has " + std::to_string(attribute_count) + " values for " +
                           std::to_string(mesh.nodes.size()) + " points");
      }
    } else if ((token == "FIELD" || token == "METADATA") && !in_data) {
      read_binary_attribute(in, k, token, 0, false, &regions, &have_regions);
    } else if (in_data) {
      read_binary_attribute(in, k, token, attribute_count, cell_data, &regions, &have_regions);
    } else {
      in.fail_at(at,
                 "unexpected " +
                     (Fields(token).rest().empty() ? std::string("line")
                                                   : "'" + std::string(token.substr(0, 40)) + "'") +
                     " in the dataset");
    }
  }
  (void)cell_types_at;
  if (have_cells && cells.types.empty() && cells.count() > 0) {
    in.fail("unexpected end of file, missing CELL_TYPES");
  }
  assemble(cells, regions, have_regions, &out, [&in](std::int64_t at, const std::string& what) {
    in.fail_at(static_cast<std::size_t>(at), what);
  });
  return out.finish({});
}
}  // namespace

MeshFile read_vtk(LineReader& in, std::string_view header, std::string_view text) {
  // "# vtk DataFile Version x.y", a title line, then ASCII or BINARY.
  const std::string_view version = Fields(header.substr(22)).rest();
  if (version != "1.0" && version != "2.0" && version != "3.0" && version != "4.0" &&
      version != "4.1" && version != "4.2" && version != "5.1") {
    in.fail("unsupported VTK version '" + std::string(version) + "'");
  }
  std::string_view line;
  if (!in.next(&line)) in.fail("unexpected end of file, expected the title line");
  const std::string_view encoding = Fields(in.expect_line("ASCII or BINARY")).rest();
  if (encoding == "BINARY") {
    ByteReader bytes(text, text.size() - in.remaining_bytes(), in.name());
    return read_vtk_binary(bytes, version);
  }
  if (encoding != "ASCII") {
    in.fail("expected ASCII or BINARY, found '" + std::string(encoding.substr(0, 40)) + "'");
  }

  Tokens t(&in);
  if (t.expect("DATASET") != "DATASET") in.fail("expected DATASET");
  const std::string_view dataset = t.expect("dataset type");
  if (dataset != "UNSTRUCTURED_GRID") {
    in.fail("unsupported VTK dataset " + std::string(dataset) + " (only UNSTRUCTURED_GRID)");
  }

  MeshAssembler out;
  out.zero_is_region = true;
  out.file().format = "vtk " + std::string(version);
  Mesh& mesh = out.file().mesh;
  bool have_points = false;
  Cells cells;
  bool have_cells = false;
  std::int64_t attribute_count = 0;  // values per component in the current *_DATA block
  bool cell_data = false;
  bool in_data = false;
  std::vector<std::int64_t> regions;
  bool have_regions = false;

  std::string_view token;
  while (t.next(&token)) {
    if (token == "POINTS") {
      if (have_points) in.fail("second POINTS section");
      const std::int64_t n = t.count("point count", 3 * kMinValueBytes);
      t.expect("point type");
      for (std::int64_t i = 0; i < n; ++i) {
        Vec3 p;
        for (int k = 0; k < 3; ++k) p[k] = to_double(in, t.expect("coordinate"), "coordinate");
        mesh.nodes.push_back(p);
      }
      have_points = true;
    } else if (token == "CELLS") {
      if (!have_points) in.fail("CELLS before POINTS");
      if (have_cells) in.fail("second CELLS section");
      read_cells(t, static_cast<std::int64_t>(mesh.nodes.size()), &cells);
      have_cells = true;
    } else if (token == "CELL_TYPES") {
      if (!have_cells) in.fail("CELL_TYPES before CELLS");
      const std::int64_t n = t.count("cell type count", kMinValueBytes);
      if (n != cells.count()) {
        in.fail("CELL_TYPES has " + std::to_string(n) + " entries for " +
                std::to_string(cells.count()) + " cells");
      }
      cells.types_line = in.line_number();
      for (std::int64_t i = 0; i < n; ++i) cells.types.push_back(t.integer("cell type"));
    } else if (token == "CELL_DATA" || token == "POINT_DATA") {
      cell_data = token == "CELL_DATA";
      attribute_count = t.count("data count", kMinValueBytes);
      in_data = true;
      if (cell_data) {
        if (attribute_count != cells.count()) {
          in.fail("CELL_DATA has " + std::to_string(attribute_count) + " values for " +
                  std::to_string(cells.count()) + " cells");
        }
      } else if (attribute_count != static_cast<std::int64_t>(mesh.nodes.size())) {
        in.fail("POINT_DATA has " + std::to_string(attribute_count) + " values for " +
                std::to_string(mesh.nodes.size()) + " points");
      }
    } else if ((token == "FIELD" || token == "METADATA") && !in_data) {
      read_attribute(t, token, 0, false, &regions, &have_regions);  // dataset-level field data
    } else if (in_data) {
      read_attribute(t, token, attribute_count, cell_data, &regions, &have_regions);
    } else {
      in.fail("unexpected '" + std::string(token.substr(0, 40)) + "' in the dataset");
    }
  }
  if (have_cells && cells.types.empty() && cells.count() > 0) {
    in.fail("unexpected end of file, missing CELL_TYPES");
  }
  assemble(cells, regions, have_regions, &out, [&in](std::int64_t line, const std::string& what) {
    in.fail_at(static_cast<int>(line), what);
  });
  return out.finish({});
}

}  // namespace conica::io::detail
