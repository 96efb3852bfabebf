// Gmsh readers: legacy v1 ($NOD/$ELM), 2.2 ($Nodes/$Elements/$PhysicalNames) and 4.1 (entity
// blocks, physical tags on $Entities), ASCII and, for 2.2 and 4.1, binary (file-type 1: the
// integer 1 after the format line gives the byte order, $Nodes/$Elements/$Entities hold raw
// numbers: int and double in 2.2, int, size_t and double in 4.1). Format reference:
// gmsh.info/doc/texinfo, "MSH file format" and its "Legacy formats" appendix.
#include <cstdint>
#include <cstdio>
#include <unordered_map>
#include <utility>

#include "io/binary_reader.h"
#include "io/readers.h"

namespace conica::io::detail {

namespace {

// Smallest number of bytes one record can take; bounds counts by what the file can hold.
constexpr std::int64_t kMinNodeBytes = 8;     // "1 0 0 0\n"
constexpr std::int64_t kMinElementBytes = 6;  // "1 15 1\n" (4.1: "1 1\n" + header share)
constexpr std::int64_t kMinLineBytes = 2;     // any non-empty line

std::int64_t bound(const LineReader& in, std::int64_t bytes_per_record) {
  return static_cast<std::int64_t>(in.remaining_bytes()) / bytes_per_record + 1;
}

struct ElementType {
  int num_nodes = -1;  // -1: unknown type
  const char* name = "";
};

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

// Node ids -> 0-based indices.
class NodeTable {
 public:
  explicit NodeTable(Mesh* mesh) : mesh_(mesh) {}

  // `in`: anything with fail(what), the LineReader or an offset in a binary file.
  template <class Reader>
  void add(const Reader& in, std::int64_t id, const Vec3& p) {
    const auto [it, inserted] = index_.emplace(id, static_cast<int>(mesh_->nodes.size()));
    if (!inserted) in.fail("node " + std::to_string(id) + " is defined twice");
    mesh_->nodes.push_back(p);
  }

  template <class Reader>
  int index(const Reader& in, std::int64_t element, std::int64_t id) const {
    const auto it = index_.find(id);
    if (it == index_.end()) {
      in.fail("element " + std::to_string(element) + " references unknown node " +
              std::to_string(id));
    }
    return it->second;
  }

 private:
  Mesh* mesh_;
  std::unordered_map<std::int64_t, int> index_;
};

// Files one element given its Gmsh type and node ids; validates every node reference.
template <class Reader>
void add_element(const Reader& in, const NodeTable& nodes, MeshAssembler* out, std::int64_t id,
                 std::int64_t type, const std::vector<std::int64_t>& node_ids,
                 const std::vector<int>& tags) {
  const ElementType t = element_type(type);
  if (t.num_nodes > 0 && static_cast<int>(node_ids.size()) != t.num_nodes) {
    in.fail("element " + std::to_string(id) + " (" + t.name + ") has " +
            std::to_string(node_ids.size()) + " nodes, expected " + std::to_string(t.num_nodes));
  }
  if (node_ids.empty()) in.fail("element " + std::to_string(id) + " has no nodes");
  std::vector<int> idx(node_ids.size());
  for (std::size_t i = 0; i < node_ids.size(); ++i) idx[i] = nodes.index(in, id, node_ids[i]);
  switch (type) {
    case 2:
      out->add_triangle({idx[0], idx[1], idx[2]});
      break;
    case 4:
      out->add_tetrahedron({idx[0], idx[1], idx[2], idx[3]}, tags);
      break;
    case 5:
      out->add_hexahedron({idx[0], idx[1], idx[2], idx[3], idx[4], idx[5], idx[6], idx[7]}, tags);
      break;
    default:
      out->skip(type_name(type));
  }
}

template <class Reader>
int tag_value(const Reader& in, std::int64_t v, std::string_view what) {
  if (v < INT32_MIN || v > INT32_MAX) in.fail(std::string(what) + " out of range");
  return static_cast<int>(v);
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

using EntityKey = std::pair<int, int>;  // (dimension, tag)

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

// ---- binary 2.2 and 4.1 ---------------------------------------------------------------------
// The format line is ASCII; then come the endianness marker and sections whose names, counts
// (2.2) and $PhysicalNames are text lines, and whose records are raw numbers. Errors give the
// byte offset of the record or line at fault.

// A place in a binary file, for NodeTable and add_element: errors point at a record's start.
struct At {
  const ByteReader& in;
  std::size_t offset;
  [[noreturn]] void fail(std::string_view what) const { in.fail_at(offset, what); }
};

// What a line found where text was expected looks like, for messages.
std::string describe(std::string_view line) {
  const std::string_view s = Fields(line).rest();
  for (const char c : s.substr(0, 40)) {
    const auto u = static_cast<unsigned char>(c);
    if (u < 0x20 && c != '\t') return "binary data";
    if (u >= 0x7f) return "binary data";
  }
  return "'" + std::string(s.substr(0, 40)) + "'";
}

// After a binary block: its closing "\n", then `end` (e.g. "$EndNodes"). Other bytes mean the
// counts do not match the data.
void expect_binary_end(ByteReader& in, std::string_view end, std::string_view after) {
  const std::size_t at = in.offset();
  std::string_view line;
  if (!in.next_nonblank_line(&line)) {
    in.fail_at(
        at, "unexpected end of file, missing " + std::string(end) + " after " + std::string(after));
  }
  if (Fields(line).rest() != end) {
    in.fail_at(at, "expected " + std::string(end) + " after " + std::string(after) + ", found " +
                       describe(line) + ": the counts do not match the data");
  }
}

// An integer on a text line of a binary file.
std::int64_t line_int(const ByteReader& in, std::size_t at, Fields* f, std::string_view what) {
  std::string_view token;
  if (!f->next(&token)) in.fail_at(at, "missing " + std::string(what));
  std::int64_t v = 0;
  if (!parse_int(token, &v)) {
    in.fail_at(
        at, std::string(what) + ": '" + std::string(token.substr(0, 40)) + "' is not an integer");
  }
  return v;
}

// A count line ("12" after "$Nodes" in 2.2): a non-negative integer whose records, at least
// `record_bytes` each, fit in the rest of the file.
std::int64_t count_line(ByteReader& in, std::string_view what, std::int64_t record_bytes) {
  std::size_t at = 0;
  Fields f(in.expect_line(what, &at));
  const std::int64_t n = line_int(in, at, &f, what);
  if (n < 0) in.fail_at(at, std::string(what) + " is negative (" + std::to_string(n) + ")");
  std::string_view extra;
  if (f.next(&extra))
    in.fail_at(at, "unexpected field '" + std::string(extra.substr(0, 40)) + "' after the " +
                       std::string(what));
  in.need(static_cast<std::uint64_t>(n), static_cast<std::uint64_t>(record_bytes), what, at);
  return n;
}

// A size_t count of 4.1 that fits the rest of the file, as a signed number.
std::int64_t size_count(ByteReader& in, std::string_view what, std::int64_t record_bytes) {
  const std::size_t at = in.offset();
  const std::uint64_t n = in.u64(what);
  if (n > static_cast<std::uint64_t>(INT64_MAX)) {
    in.fail_at(at, std::string(what) + " " + std::to_string(n) + " is out of range");
  }
  in.need(n, static_cast<std::uint64_t>(record_bytes), what, at);
  return static_cast<std::int64_t>(n);
}

// A size_t tag of 4.1 (node or element tag) as a signed number.
std::int64_t size_tag(ByteReader& in, std::string_view what) {
  const std::size_t at = in.offset();
  const std::uint64_t v = in.u64(what);
  if (v > static_cast<std::uint64_t>(INT64_MAX)) {
    in.fail_at(at, std::string(what) + " " + std::to_string(v) + " is out of range");
  }
  return static_cast<std::int64_t>(v);
}

ElementType known_type(const ByteReader& in, std::size_t at, std::int64_t type) {
  const ElementType t = element_type(type);
  if (t.num_nodes < 0) {
    in.fail_at(at, "unknown element type " + std::to_string(type) +
                       ": its record size is unknown, the rest of $Elements cannot be read");
  }
  return t;
}

// "$PhysicalNames" of a binary file: text, as in ASCII files.
void read_binary_physical_names(ByteReader& in, std::map<int, std::string>* names) {
  const std::int64_t n = count_line(in, "physical name count", kMinNodeBytes);
  for (std::int64_t i = 0; i < n; ++i) {
    std::size_t at = 0;
    std::string_view line;
    if (!in.next_nonblank_line(&line, &at)) {
      in.fail("unexpected end of file in $PhysicalNames after " + std::to_string(i) + " of " +
              std::to_string(n) + " names");
    }
    Fields f(line);
    const std::int64_t dim = line_int(in, at, &f, "physical dimension");
    const int tag = tag_value(At{in, at}, line_int(in, at, &f, "physical tag"), "physical tag");
    std::string_view name = f.rest();
    if (name.size() >= 2 && name.front() == '"' && name.back() == '"') {
      name = name.substr(1, name.size() - 2);
    } else {
      in.fail_at(at, "physical name must be a quoted string");
    }
    if (dim == 3) (*names)[tag] = std::string(name);
  }
  expect_binary_end(in, "$EndPhysicalNames", "the physical names");
}

// Skips a section up to and including its $End line.
void skip_binary_section(ByteReader& in, std::string_view start, std::size_t start_at) {
  const std::string end = "$End" + std::string(start.substr(1));
  std::string_view line;
  while (in.next_line(&line)) {
    if (Fields(line).rest() == end) return;
  }
  in.fail_at(start_at,
             "section " + std::string(start.substr(0, 40)) + " has no " + end.substr(0, 44));
}

// 2.2: number-of-nodes (text line), then per node: int id, double x y z.
void read_b2_nodes(ByteReader& in, NodeTable* nodes) {
  const std::int64_t n = count_line(in, "node count", 4 + 3 * 8);
  for (std::int64_t i = 0; i < n; ++i) {
    const std::size_t at = in.offset();
    const std::int64_t id = in.i32("node id");
    Vec3 p;
    p.x() = in.finite_f64("x coordinate of node " + std::to_string(id));
    p.y() = in.finite_f64("y coordinate of node " + std::to_string(id));
    p.z() = in.finite_f64("z coordinate of node " + std::to_string(id));
    nodes->add(At{in, at}, id, p);
  }
  expect_binary_end(in, "$EndNodes", std::to_string(n) + " nodes");
}

// 2.2: number-of-elements (text line), then blocks of one type: int type, int count, int
// number-of-tags, then per element: int id, int tags..., int nodes...; tag 0 is physical.
void read_b2_elements(ByteReader& in, const NodeTable& nodes, MeshAssembler* out) {
  const std::int64_t total = count_line(in, "element count", 4 * 2);
  std::int64_t read = 0;
  std::vector<std::int64_t> ids;
  while (read < total) {
    const std::size_t header_at = in.offset();
    const std::int64_t type = in.i32("element type of an element block header");
    const std::int64_t n = in.i32("element count of an element block header");
    const std::int64_t ntags = in.i32("tag count of an element block header");
    const ElementType t = known_type(in, header_at, type);
    if (n < 1 || n > total - read) {
      in.fail_at(header_at, "element block of " + std::to_string(n) + " " + t.name +
                                " elements: expected 1 to " + std::to_string(total - read) + " (" +
                                std::to_string(read) + " of " + std::to_string(total) +
                                " elements read)");
    }
    if (ntags < 0 || ntags > 100) {
      in.fail_at(header_at, "element block: bad tag count " + std::to_string(ntags));
    }
    in.need(static_cast<std::uint64_t>(n), 4 * static_cast<std::uint64_t>(1 + ntags + t.num_nodes),
            "element block of " + std::string(t.name) + " elements: element count");
    for (std::int64_t i = 0; i < n; ++i) {
      const std::size_t at = in.offset();
      const std::int64_t id = in.i32("element number");
      int phys = 0;
      for (std::int64_t k = 0; k < ntags; ++k) {
        const std::int64_t tag = in.i32("element tag");
        if (k == 0) phys = static_cast<int>(tag);
      }
      ids.clear();
      for (int k = 0; k < t.num_nodes; ++k) ids.push_back(in.i32("node number"));
      add_element(At{in, at}, nodes, out, id, type, ids, {phys});
    }
    read += n;
  }
  expect_binary_end(in, "$EndElements", std::to_string(total) + " elements");
}

// 4.1: size_t numPoints numCurves numSurfaces numVolumes, then per entity
//   point:  int tag, double x y z, size_t numPhysicalTags, int physicalTag...
//   others: int tag, double min/max x y z, size_t numPhysicalTags, int physicalTag...,
//           size_t numBounding, int boundingTag...
void read_b4_entities(ByteReader& in, std::map<EntityKey, std::vector<int>>* physicals) {
  std::int64_t counts[4];
  const char* what[4] = {"point count", "curve count", "surface count", "volume count"};
  for (int d = 0; d < 4; ++d)
    counts[d] = size_count(in, what[d], d == 0 ? 4 + 24 + 8 : 4 + 48 + 16);
  for (int d = 0; d < 4; ++d) {
    for (std::int64_t i = 0; i < counts[d]; ++i) {
      const int tag = in.i32("entity tag");
      in.skip((d == 0 ? 3 : 6) * 8, "entity coordinates");
      const std::int64_t nphys = size_count(in, "number of physical tags", 4);
      std::vector<int>& tags = (*physicals)[{d, tag}];
      for (std::int64_t k = 0; k < nphys; ++k) tags.push_back(in.i32("physical tag"));
      if (d > 0) {
        const std::int64_t nbound = size_count(in, "number of bounding entities", 4);
        in.skip(static_cast<std::size_t>(nbound) * 4, "bounding entity tags");
      }
    }
  }
  expect_binary_end(in, "$EndEntities", "the entities");
}

// 4.1: size_t numEntityBlocks numNodes minNodeTag maxNodeTag, then per block
// int entityDim entityTag parametric, size_t numNodesInBlock, size_t tags..., then
// double x y z (and u, v, w up to entityDim when parametric) per node.
void read_b4_nodes(ByteReader& in, NodeTable* nodes) {
  const std::size_t header_at = in.offset();
  const std::int64_t blocks = size_count(in, "node block count", 3 * 4 + 8);
  const std::int64_t total = size_count(in, "node count", 8 + 3 * 8);
  in.u64("minimum node tag");
  in.u64("maximum node tag");
  std::int64_t read = 0;
  std::vector<std::int64_t> ids;
  for (std::int64_t b = 0; b < blocks; ++b) {
    const std::size_t block_at = in.offset();
    const std::int64_t dim = in.i32("entity dimension of a node block");
    in.i32("entity tag of a node block");
    const std::int64_t parametric = in.i32("parametric flag of a node block");
    if (dim < 0 || dim > 3) {
      in.fail_at(block_at, "node block " + std::to_string(b + 1) + ": entity dimension " +
                               std::to_string(dim) + " is not 0 to 3");
    }
    if (parametric != 0 && parametric != 1) {
      in.fail_at(block_at, "node block " + std::to_string(b + 1) + ": parametric flag " +
                               std::to_string(parametric) + " is not 0 or 1");
    }
    const int values = 3 + (parametric ? static_cast<int>(dim) : 0);
    const std::int64_t n = size_count(in, "number of nodes in block", 8 + 8 * values);
    if (n > total - read) {
      in.fail_at(block_at,
                 "node blocks hold more than the " + std::to_string(total) + " nodes announced");
    }
    ids.clear();
    for (std::int64_t i = 0; i < n; ++i) ids.push_back(size_tag(in, "node tag"));
    for (std::int64_t i = 0; i < n; ++i) {
      const std::size_t at = in.offset();
      const std::string node = " of node " + std::to_string(ids[i]);
      Vec3 p;
      p.x() = in.finite_f64("x coordinate" + node);
      p.y() = in.finite_f64("y coordinate" + node);
      p.z() = in.finite_f64("z coordinate" + node);
      in.skip(8 * (values - 3), "parametric coordinates" + node);
      nodes->add(At{in, at}, ids[i], p);
    }
    read += n;
  }
  if (read != total) {
    in.fail_at(header_at, "node blocks hold " + std::to_string(read) + " nodes, header announced " +
                              std::to_string(total));
  }
  expect_binary_end(in, "$EndNodes", std::to_string(blocks) + " node blocks");
}

// 4.1: size_t numEntityBlocks numElements minElementTag maxElementTag, then per block
// int entityDim entityTag elementType, size_t numElementsInBlock, then per element
// size_t tag, size_t nodeTag....
void read_b4_elements(ByteReader& in, const NodeTable& nodes,
                      const std::map<EntityKey, std::vector<int>>& physicals, MeshAssembler* out) {
  const std::size_t header_at = in.offset();
  const std::int64_t blocks = size_count(in, "element block count", 3 * 4 + 8);
  const std::int64_t total = size_count(in, "element count", 2 * 8);
  in.u64("minimum element tag");
  in.u64("maximum element tag");
  std::int64_t read = 0;
  std::vector<std::int64_t> ids;
  const std::vector<int> no_tags;
  for (std::int64_t b = 0; b < blocks; ++b) {
    const std::size_t block_at = in.offset();
    const int dim = in.i32("entity dimension of an element block");
    const int tag = in.i32("entity tag of an element block");
    const std::int64_t type = in.i32("element type of an element block");
    const ElementType t = known_type(in, block_at, type);
    const std::int64_t n = size_count(in, "number of elements in block", 8 * (1 + t.num_nodes));
    if (n > total - read) {
      in.fail_at(block_at, "element blocks hold more than the " + std::to_string(total) +
                               " elements announced");
    }
    const auto phys = physicals.find({dim, tag});
    const std::vector<int>& tags = phys != physicals.end() ? phys->second : no_tags;
    for (std::int64_t i = 0; i < n; ++i) {
      const std::size_t at = in.offset();
      const std::int64_t id = size_tag(in, "element tag");
      ids.clear();
      for (int k = 0; k < t.num_nodes; ++k) ids.push_back(size_tag(in, "node tag"));
      add_element(At{in, at}, nodes, out, id, type, ids, tags);
    }
    read += n;
  }
  if (read != total) {
    in.fail_at(header_at, "element blocks hold " + std::to_string(read) +
                              " elements, header announced " + std::to_string(total));
  }
  expect_binary_end(in, "$EndElements", std::to_string(blocks) + " element blocks");
}

// After the format line of a binary file: the marker, $EndMeshFormat, then the sections.
MeshFile read_gmsh_binary(ByteReader& in, bool v2) {
  const std::size_t marker_at = in.offset();
  const std::string_view m =
      in.bytes(4, "the endianness marker (the integer 1 after the format line)");
  const auto byte = [&m](int i) { return static_cast<unsigned>(static_cast<unsigned char>(m[i])); };
  if (byte(0) == 1 && byte(1) == 0 && byte(2) == 0 && byte(3) == 0) {
    in.set_big_endian(false);
  } else if (byte(0) == 0 && byte(1) == 0 && byte(2) == 0 && byte(3) == 1) {
    in.set_big_endian(true);
  } else {
    char hex[32];
    std::snprintf(hex, sizeof hex, "%02x %02x %02x %02x", byte(0), byte(1), byte(2), byte(3));
    in.fail_at(marker_at, std::string("endianness marker: expected the integer 1 in binary "
                                      "(01 00 00 00 or 00 00 00 01), found bytes ") +
                              hex + " (file-type 1 says binary: is this an ASCII file?)");
  }
  expect_binary_end(in, "$EndMeshFormat", "the endianness marker");

  MeshAssembler out;
  NodeTable nodes(&out.file().mesh);
  out.file().format = std::string("gmsh ") + (v2 ? "2.2" : "4.1") + " binary";
  std::map<int, std::string> names;
  std::map<EntityKey, std::vector<int>> physicals;
  bool have_nodes = false;
  std::string_view line;
  std::size_t at = 0;
  while (in.next_nonblank_line(&line, &at)) {
    const std::string_view s = Fields(line).rest();
    if (s.front() != '$') {
      in.fail_at(at, "expected a section ($Nodes, $Elements...), found " + describe(s));
    }
    if (s == "$PhysicalNames") {
      read_binary_physical_names(in, &names);
    } else if (s == "$Entities" && !v2) {
      read_b4_entities(in, &physicals);
    } else if (s == "$Nodes") {
      if (have_nodes) in.fail_at(at, "second $Nodes section");
      have_nodes = true;
      v2 ? read_b2_nodes(in, &nodes) : read_b4_nodes(in, &nodes);
    } else if (s == "$Elements") {
      if (!have_nodes) in.fail_at(at, "$Elements before $Nodes");
      v2 ? read_b2_elements(in, nodes, &out) : read_b4_elements(in, nodes, physicals, &out);
    } else if (s.rfind("$End", 0) == 0) {
      in.fail_at(at, describe(s) + " closes no open section");
    } else {
      skip_binary_section(in, s, at);
    }
  }
  if (!have_nodes) in.fail_at(marker_at, "no $Nodes section");
  return out.finish(names);
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
