// Internal to conica_io: what the Gmsh text readers (gmsh_reader.cc) and the binary reader
// (gmsh_binary_reader.cc) share: element types, the node table and the filing of elements.
#pragma once

#include <cstdint>
#include <map>
#include <string>
#include <string_view>
#include <unordered_map>
#include <utility>
#include <vector>

#include "io/binary_reader.h"
#include "io/readers.h"

namespace conica::io::detail {

// Smallest number of bytes one record can take; bounds counts by what the file can hold.
constexpr std::int64_t kMinNodeBytes = 8;     // "1 0 0 0\n"
constexpr std::int64_t kMinElementBytes = 6;  // "1 15 1\n" (4.1: "1 1\n" + header share)
constexpr std::int64_t kMinLineBytes = 2;     // any non-empty line

struct ElementType {
  int num_nodes = -1;  // -1: unknown type
  const char* name = "";
};

// A Gmsh element type's node count and name (gmsh_reader.cc); type_name() also names the
// unknown ones.
ElementType element_type(std::int64_t type);
std::string type_name(std::int64_t type);

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

using EntityKey = std::pair<int, int>;  // (dimension, tag)

// A binary file (file-type 1; 2.2 when `v2`, else 4.1) from after its format line
// (gmsh_binary_reader.cc).
MeshFile read_gmsh_binary(ByteReader& in, bool v2);

}  // namespace conica::io::detail
