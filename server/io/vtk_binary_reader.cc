// Legacy VTK BINARY unstructured grids (what is kept: see vtk_reader.cc). BINARY files keep the
// keywords as text lines and write the numbers after each keyword line raw and big-endian
// (cells as int, or from 5.1 OFFSETS/CONNECTIVITY of the type they name).
#include <cmath>
#include <cstdint>

#include "io/binary_reader.h"
#include "io/readers.h"
#include "io/vtk_detail.h"

namespace conica::io::detail {

namespace {

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

}  // namespace

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

}  // namespace conica::io::detail
