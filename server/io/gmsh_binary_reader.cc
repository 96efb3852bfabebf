// Gmsh binary readers, 2.2 and 4.1 (file-type 1: the integer 1 after the format line gives the
// byte order, $Nodes/$Elements/$Entities hold raw numbers: int and double in 2.2, int, size_t
// and double in 4.1). Format reference: gmsh.info/doc/texinfo, "MSH file format".
#include <cstdint>
#include <cstdio>

#include "io/binary_reader.h"
#include "io/gmsh_detail.h"
#include "io/readers.h"

namespace conica::io::detail {

namespace {

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
  std::string quoted = "'";
  quoted += s.substr(0, 40);
  quoted += '\'';
  return quoted;
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

}  // namespace

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

}  // namespace conica::io::detail
