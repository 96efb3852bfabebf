// Legacy VTK unstructured grids, ASCII and BINARY (formats 2.0 to 5.1; see "VTK File Formats"
// in the VTK user's guide). Cells 10 (tetra), 12 (hexahedron) and 5 (triangle) are kept, others
// counted. The first one-component integer CELL_DATA scalar names the regions of volume cells.
// This file reads ASCII files; BINARY ones go to vtk_binary_reader.cc.
#include <cmath>
#include <cstdint>
#include <optional>

#include "io/binary_reader.h"
#include "io/readers.h"
#include "io/vtk_detail.h"

namespace conica::io::detail {

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

namespace {

constexpr std::int64_t kMinValueBytes = 2;  // "0 "

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
