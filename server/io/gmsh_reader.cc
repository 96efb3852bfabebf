// Gmsh text readers: legacy v1 ($NOD/$ELM), 2.2 ($Nodes/$Elements/$PhysicalNames) and 4.1
// (entity blocks, physical tags on $Entities), ASCII; binary 2.2 and 4.1 files (file-type 1)
// go to gmsh_binary_reader.cc. Format reference: gmsh.info/doc/texinfo, "MSH file format" and
// its "Legacy formats" appendix.
#include <cstdint>

#include "io/binary_reader.h"
#include "io/gmsh_detail.h"
#include "io/readers.h"

namespace conica::io::detail {

// Gmsh element types (same numbers in all versions): the linear ones and the higher-order
// types meshio writes. A binary element block needs the node count of its type.
ElementType element_type(std::int64_t type) {
  switch (type) {
    case 1:
      return {2, "line"};
    case 2:
      return {3, "triangle"};
    case 3:
      return {4, "quadrangle"};
    case 4:
      return {4, "tetrahedron"};
    case 5:
      return {8, "hexahedron"};
    case 6:
      return {6, "prism"};
    case 7:
      return {5, "pyramid"};
    case 8:
      return {3, "line3"};
    case 9:
      return {6, "triangle6"};
    case 10:
      return {9, "quadrangle9"};
    case 11:
      return {10, "tetrahedron10"};
    case 12:
      return {27, "hexahedron27"};
    case 13:
      return {18, "prism18"};
    case 14:
      return {14, "pyramid14"};
    case 15:
      return {1, "point"};
    case 16:
      return {8, "quadrangle8"};
    case 17:
      return {20, "hexahedron20"};
    case 18:
      return {15, "prism15"};
    case 19:
      return {13, "pyramid13"};
    case 21:
      return {10, "triangle10"};
    case 23:
      return {15, "triangle15"};
    case 25:
      return {21, "triangle21"};
    case 26:
      return {4, "line4"};
    case 27:
      return {5, "line5"};
    case 28:
      return {6, "line6"};
    case 29:
      return {20, "tetrahedron20"};
    case 30:
      return {35, "tetrahedron35"};
    case 31:
      return {56, "tetrahedron56"};
    case 36:
      return {16, "quadrangle16"};
    case 37:
      return {25, "quadrangle25"};
    case 38:
      return {36, "quadrangle36"};
    case 42:
      return {28, "triangle28"};
    case 43:
      return {36, "triangle36"};
    case 44:
      return {45, "triangle45"};
    case 45:
      return {55, "triangle55"};
    case 46:
      return {66, "triangle66"};
    case 47:
      return {49, "quadrangle49"};
    case 48:
      return {64, "quadrangle64"};
    case 49:
      return {81, "quadrangle81"};
    case 50:
      return {100, "quadrangle100"};
    case 51:
      return {121, "quadrangle121"};
    case 62:
      return {7, "line7"};
    case 63:
      return {8, "line8"};
    case 64:
      return {9, "line9"};
    case 65:
      return {10, "line10"};
    case 66:
      return {11, "line11"};
    case 71:
      return {84, "tetrahedron84"};
    case 72:
      return {120, "tetrahedron120"};
    case 73:
      return {165, "tetrahedron165"};
    case 74:
      return {220, "tetrahedron220"};
    case 75:
      return {286, "tetrahedron286"};
    case 90:
      return {40, "prism40"};
    case 91:
      return {75, "prism75"};
    case 92:
      return {64, "hexahedron64"};
    case 93:
      return {125, "hexahedron125"};
    case 94:
      return {216, "hexahedron216"};
    case 95:
      return {343, "hexahedron343"};
    case 96:
      return {512, "hexahedron512"};
    case 97:
      return {729, "hexahedron729"};
    case 98:
      return {1000, "hexahedron1000"};
    case 106:
      return {126, "prism126"};
    case 107:
      return {196, "prism196"};
    case 108:
      return {288, "prism288"};
    case 109:
      return {405, "prism405"};
    case 110:
      return {550, "prism550"};
    default:
      return {};
  }
}

std::string type_name(std::int64_t type) {
  const ElementType t = element_type(type);
  return t.num_nodes > 0 ? t.name : "gmsh type " + std::to_string(type);
}

namespace {

std::int64_t bound(const LineReader& in, std::int64_t bytes_per_record) {
  return static_cast<std::int64_t>(in.remaining_bytes()) / bytes_per_record + 1;
}

bool is_section_start(std::string_view line) {
  const std::string_view s = Fields(line).rest();
  return !s.empty() && s.front() == '$';
}

// The next line must be `end` (e.g. "$EndNodes").
void expect_end(LineReader& in, std::string_view end, std::string_view after) {
  std::string_view line;
  if (!in.next_nonblank(&line)) {
    in.fail("unexpected end of file, missing " + std::string(end) + " after " + std::string(after));
  }
  if (Fields(line).rest() != end) {
    in.fail("expected " + std::string(end) + " after " + std::string(after) + ", found '" +
            std::string(Fields(line).rest().substr(0, 40)) + "'");
  }
}

// The next line of a counted section; fails on end of file or on a '$' line (count mismatch).
std::string_view record_line(LineReader& in, std::string_view section, std::string_view what,
                             std::int64_t i, std::int64_t count) {
  std::string_view line;
  const std::string progress =
      std::to_string(i) + " of " + std::to_string(count) + " " + std::string(what);
  if (!in.next_nonblank(&line)) {
    in.fail("unexpected end of file in " + std::string(section) + " after " + progress);
  }
  if (is_section_start(line)) {
    in.fail("found '" + std::string(Fields(line).rest().substr(0, 40)) + "' after " + progress +
            ": the count does not match");
  }
  return line;
}

void no_more_fields(const LineReader& in, Fields* f, std::string_view what) {
  std::string_view extra;
  if (f->next(&extra)) {
    in.fail("unexpected field '" + std::string(extra) + "' at the end of " + std::string(what));
  }
}

// Skips a section up to and including its $End line.
void skip_section(LineReader& in, std::string_view start) {
  const std::string end = "$End" + std::string(start.substr(1));
  const int first = in.line_number();
  std::string_view line;
  while (in.next(&line)) {
    if (Fields(line).rest() == end) return;
  }
  in.fail_at(first, "section " + std::string(start) + " has no " + end);
}

// "$PhysicalNames": dim tag "name". Keeps the names of 3-D groups (regions are volumes).
void read_physical_names(LineReader& in, std::map<int, std::string>* names) {
  const std::int64_t n = to_count(in, Fields(in.expect_line("physical name count")).rest(),
                                  "physical name count", bound(in, kMinNodeBytes));
  for (std::int64_t i = 0; i < n; ++i) {
    Fields f(record_line(in, "$PhysicalNames", "names", i, n));
    const std::int64_t dim = int_field(in, &f, "physical dimension");
    const int tag = tag_value(in, int_field(in, &f, "physical tag"), "physical tag");
    std::string_view name = f.rest();
    if (name.size() >= 2 && name.front() == '"' && name.back() == '"') {
      name = name.substr(1, name.size() - 2);
    } else if (name.empty() || name.front() == '"') {
      in.fail("physical name must be a quoted string");
    }
    if (dim == 3) (*names)[tag] = std::string(name);
  }
  expect_end(in, "$EndPhysicalNames", "the physical names");
}

Vec3 read_xyz(const LineReader& in, Fields* f) {
  Vec3 p;
  p.x() = double_field(in, f, "x coordinate");
  p.y() = double_field(in, f, "y coordinate");
  p.z() = double_field(in, f, "z coordinate");
  return p;
}

// ---- v1 -------------------------------------------------------------------------------------

void read_v1_nodes(LineReader& in, NodeTable* nodes) {
  const std::int64_t n = to_count(in, Fields(in.expect_line("node count")).rest(), "node count",
                                  bound(in, kMinNodeBytes));
  for (std::int64_t i = 0; i < n; ++i) {
    Fields f(record_line(in, "$NOD", "nodes", i, n));
    const std::int64_t id = int_field(in, &f, "node id");
    const Vec3 p = read_xyz(in, &f);
    no_more_fields(in, &f, "a node line");
    nodes->add(in, id, p);
  }
  expect_end(in, "$ENDNOD", std::to_string(n) + " nodes");
}

// elm-number elm-type reg-phys reg-elem number-of-nodes node-list
void read_v1_elements(LineReader& in, const NodeTable& nodes, MeshAssembler* out) {
  const std::int64_t n = to_count(in, Fields(in.expect_line("element count")).rest(),
                                  "element count", bound(in, kMinElementBytes));
  std::vector<std::int64_t> ids;
  for (std::int64_t i = 0; i < n; ++i) {
    Fields f(record_line(in, "$ELM", "elements", i, n));
    const std::int64_t id = int_field(in, &f, "element number");
    const std::int64_t type = int_field(in, &f, "element type");
    const int phys = tag_value(in, int_field(in, &f, "physical region"), "physical region");
    int_field(in, &f, "elementary region");
    const std::int64_t nn = int_field(in, &f, "number of nodes");
    if (nn < 1 || nn > 1000) in.fail("element " + std::to_string(id) + ": bad number of nodes");
    ids.clear();
    for (std::int64_t k = 0; k < nn; ++k) ids.push_back(int_field(in, &f, "node number"));
    no_more_fields(in, &f, "element " + std::to_string(id));
    add_element(in, nodes, out, id, type, ids, {phys});
  }
  expect_end(in, "$ENDELM", std::to_string(n) + " elements");
}

// ---- 2.2 ------------------------------------------------------------------------------------

void read_v2_nodes(LineReader& in, NodeTable* nodes) {
  const std::int64_t n = to_count(in, Fields(in.expect_line("node count")).rest(), "node count",
                                  bound(in, kMinNodeBytes));
  for (std::int64_t i = 0; i < n; ++i) {
    Fields f(record_line(in, "$Nodes", "nodes", i, n));
    const std::int64_t id = int_field(in, &f, "node id");
    const Vec3 p = read_xyz(in, &f);
    no_more_fields(in, &f, "a node line");
    nodes->add(in, id, p);
  }
  expect_end(in, "$EndNodes", std::to_string(n) + " nodes");
}

// elm-number elm-type number-of-tags <tags> node-number-list; tag 0 is the physical group.
void read_v2_elements(LineReader& in, const NodeTable& nodes, MeshAssembler* out) {
  const std::int64_t n = to_count(in, Fields(in.expect_line("element count")).rest(),
                                  "element count", bound(in, kMinElementBytes));
  std::vector<std::int64_t> ids;
  for (std::int64_t i = 0; i < n; ++i) {
    Fields f(record_line(in, "$Elements", "elements", i, n));
    const std::int64_t id = int_field(in, &f, "element number");
    const std::int64_t type = int_field(in, &f, "element type");
    const std::int64_t ntags = int_field(in, &f, "number of tags");
    if (ntags < 0 || ntags > 100) in.fail("element " + std::to_string(id) + ": bad tag count");
    int phys = 0;
    for (std::int64_t k = 0; k < ntags; ++k) {
      const std::int64_t tag = int_field(in, &f, "element tag");
      if (k == 0) phys = tag_value(in, tag, "physical tag");
    }
    ids.clear();
    std::string_view token;
    while (f.next(&token)) ids.push_back(to_int(in, token, "node number"));
    add_element(in, nodes, out, id, type, ids, {phys});
  }
  expect_end(in, "$EndElements", std::to_string(n) + " elements");
}

// ---- 4.1 ------------------------------------------------------------------------------------

// numPoints numCurves numSurfaces numVolumes, then one line per entity:
//   point:  tag x y z numPhysicalTags physicalTag...
//   others: tag minX minY minZ maxX maxY maxZ numPhysicalTags physicalTag... (bounding list)
void read_v4_entities(LineReader& in, std::map<EntityKey, std::vector<int>>* physicals) {
  Fields head(in.expect_line("entity counts"));
  std::int64_t counts[4];
  const char* what[4] = {"point count", "curve count", "surface count", "volume count"};
  for (int d = 0; d < 4; ++d) {
    std::string_view token;
    if (!head.next(&token)) in.fail(std::string("missing ") + what[d]);
    counts[d] = to_count(in, token, what[d], bound(in, kMinNodeBytes));
  }
  for (int d = 0; d < 4; ++d) {
    for (std::int64_t i = 0; i < counts[d]; ++i) {
      Fields f(record_line(in, "$Entities", "entities", i, counts[d]));
      const int tag = tag_value(in, int_field(in, &f, "entity tag"), "entity tag");
      for (int k = 0; k < (d == 0 ? 3 : 6); ++k) double_field(in, &f, "entity coordinate");
      const std::int64_t nphys = int_field(in, &f, "number of physical tags");
      if (nphys < 0 || nphys > 1000) in.fail("bad number of physical tags");
      std::vector<int>& tags = (*physicals)[{d, tag}];
      for (std::int64_t k = 0; k < nphys; ++k) {
        tags.push_back(tag_value(in, int_field(in, &f, "physical tag"), "physical tag"));
      }
    }
  }
  expect_end(in, "$EndEntities", "the entities");
}

// numEntityBlocks numNodes minNodeTag maxNodeTag, then per block
// entityDim entityTag parametric numNodesInBlock, the block's tags, then its coordinates.
void read_v4_nodes(LineReader& in, NodeTable* nodes) {
  Fields head(in.expect_line("node block header"));
  const int header_line = in.line_number();
  const std::int64_t blocks = count_field(in, &head, "block count", bound(in, kMinNodeBytes));
  const std::int64_t total = count_field(in, &head, "node count", bound(in, kMinNodeBytes));
  std::int64_t read = 0;
  std::vector<std::int64_t> ids;
  for (std::int64_t b = 0; b < blocks; ++b) {
    Fields f(record_line(in, "$Nodes", "node blocks", b, blocks));
    int_field(in, &f, "entity dimension");
    int_field(in, &f, "entity tag");
    const std::int64_t parametric = int_field(in, &f, "parametric flag");
    if (parametric != 0 && parametric != 1) in.fail("parametric flag must be 0 or 1");
    std::string_view token;
    if (!f.next(&token)) in.fail("missing number of nodes in block");
    const std::int64_t n =
        to_count(in, token, "number of nodes in block", bound(in, kMinNodeBytes));
    if (read + n > total) {
      in.fail("node blocks hold more than the " + std::to_string(total) + " nodes announced");
    }
    ids.clear();
    for (std::int64_t i = 0; i < n; ++i) {
      Fields t(record_line(in, "$Nodes", "node tags of the block", i, n));
      ids.push_back(int_field(in, &t, "node tag"));
      no_more_fields(in, &t, "a node tag line");
    }
    for (std::int64_t i = 0; i < n; ++i) {
      Fields c(record_line(in, "$Nodes", "node coordinates of the block", i, n));
      nodes->add(in, ids[i], read_xyz(in, &c));  // parametric u, v after x y z are ignored
    }
    read += n;
  }
  if (read != total) {
    in.fail_at(header_line, "node blocks hold " + std::to_string(read) +
                                " nodes, header announced " + std::to_string(total));
  }
  expect_end(in, "$EndNodes", std::to_string(blocks) + " node blocks");
}

// numEntityBlocks numElements minElementTag maxElementTag, then per block
// entityDim entityTag elementType numElementsInBlock and one line per element: tag nodes...
void read_v4_elements(LineReader& in, const NodeTable& nodes,
                      const std::map<EntityKey, std::vector<int>>& physicals, MeshAssembler* out) {
  Fields head(in.expect_line("element block header"));
  const int header_line = in.line_number();
  const std::int64_t blocks = count_field(in, &head, "block count", bound(in, kMinElementBytes));
  const std::int64_t total = count_field(in, &head, "element count", bound(in, kMinLineBytes));
  std::int64_t read = 0;
  std::vector<std::int64_t> ids;
  const std::vector<int> no_tags;
  for (std::int64_t b = 0; b < blocks; ++b) {
    Fields f(record_line(in, "$Elements", "element blocks", b, blocks));
    const int dim = tag_value(in, int_field(in, &f, "entity dimension"), "entity dimension");
    const int tag = tag_value(in, int_field(in, &f, "entity tag"), "entity tag");
    const std::int64_t type = int_field(in, &f, "element type");
    std::string_view token;
    if (!f.next(&token)) in.fail("missing number of elements in block");
    const std::int64_t n =
        to_count(in, token, "number of elements in block", bound(in, kMinLineBytes));
    if (read + n > total) {
      in.fail("element blocks hold more than the " + std::to_string(total) + " elements announced");
    }
    const auto phys = physicals.find({dim, tag});
    const std::vector<int>& tags = phys != physicals.end() ? phys->second : no_tags;
    for (std::int64_t i = 0; i < n; ++i) {
      Fields e(record_line(in, "$Elements", "elements of the block", i, n));
      const std::int64_t id = int_field(in, &e, "element tag");
      ids.clear();
      while (e.next(&token)) ids.push_back(to_int(in, token, "node tag"));
      add_element(in, nodes, out, id, type, ids, tags);
    }
    read += n;
  }
  if (read != total) {
    in.fail_at(header_line, "element blocks hold " + std::to_string(read) +
                                " elements, header announced " + std::to_string(total));
  }
  expect_end(in, "$EndElements", std::to_string(blocks) + " element blocks");
}

}  // namespace

MeshFile read_gmsh1(LineReader& in) {
  MeshAssembler out;
  NodeTable nodes(&out.file().mesh);
  out.file().format = "gmsh 1";
  read_v1_nodes(in, &nodes);
  std::string_view line;
  if (!in.next_nonblank(&line)) in.fail("unexpected end of file, expected $ELM");
  if (Fields(line).rest() != "$ELM") {
    in.fail("expected $ELM, found '" + std::string(Fields(line).rest().substr(0, 40)) + "'");
  }
  read_v1_elements(in, nodes, &out);
  return out.finish({});
}

MeshFile read_gmsh(LineReader& in, std::string_view text) {
  // $MeshFormat: version file-type data-size
  Fields f(in.expect_line("the mesh format line"));
  std::string_view version;
  if (!f.next(&version)) in.fail("missing Gmsh version");
  const std::int64_t file_type = int_field(in, &f, "file type");
  const int format_line = in.line_number();
  const bool v2 = version == "2" || version == "2.0" || version == "2.1" || version == "2.2";
  const bool v4 = version == "4.1";
  if (!v2 && !v4) {
    in.fail("unsupported Gmsh version " + std::string(version) +
            " (supported: 1, 2.2 and 4.1, ASCII and binary)");
  }
  if (file_type != 0 && file_type != 1) {
    in.fail("file type " + std::to_string(file_type) + " is neither 0 (ASCII) nor 1 (binary)");
  }
  if (file_type == 1) {
    const std::int64_t data_size = int_field(in, &f, "data size");
    if (data_size != 8) {
      in.fail("data size " + std::to_string(data_size) +
              ": binary files need 8 (double coordinates" + (v4 ? ", 8-byte size_t" : "") + ")");
    }
    ByteReader bytes(text, text.size() - in.remaining_bytes(), in.name());
    return read_gmsh_binary(bytes, v2);
  }
  expect_end(in, "$EndMeshFormat", "the mesh format");

  MeshAssembler out;
  NodeTable nodes(&out.file().mesh);
  out.file().format = "gmsh " + std::string(v2 ? "2.2" : "4.1");
  std::map<int, std::string> names;
  std::map<EntityKey, std::vector<int>> physicals;
  bool have_nodes = false;
  std::string_view line;
  while (in.next_nonblank(&line)) {
    const std::string_view s = Fields(line).rest();
    if (s.front() != '$')
      in.fail("expected a section ($Nodes, $Elements...), found '" + std::string(s.substr(0, 40)) +
              "'");
    if (s == "$PhysicalNames") {
      read_physical_names(in, &names);
    } else if (s == "$Entities" && v4) {
      read_v4_entities(in, &physicals);
    } else if (s == "$Nodes") {
      if (have_nodes) in.fail("second $Nodes section");
      have_nodes = true;
      v2 ? read_v2_nodes(in, &nodes) : read_v4_nodes(in, &nodes);
    } else if (s == "$Elements") {
      if (!have_nodes) in.fail("$Elements before $Nodes");
      v2 ? read_v2_elements(in, nodes, &out) : read_v4_elements(in, nodes, physicals, &out);
    } else if (s.rfind("$End", 0) == 0) {
      in.fail("'" + std::string(s) + "' closes no open section");
    } else {
      skip_section(in, s);
    }
  }
  if (!have_nodes) in.fail_at(format_line, "no $Nodes section");
  return out.finish(names);
}

}  // namespace conica::io::detail
