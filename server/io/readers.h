// Internal to conica_io: the format readers behind parse_mesh() and what they share.
#pragma once

#include <array>
#include <map>
#include <string>
#include <string_view>
#include <vector>

#include "io/mesh_reader.h"
#include "io/text_reader.h"

namespace conica::io::detail {

// Collects elements into a MeshFile: keeps tetrahedra, hexahedra and triangles, counts the
// rest, and files volume elements under their physical tags (0 means none).
class MeshAssembler {
 public:
  MeshAssembler();
  MeshFile& file() { return file_; }

  void add_tetrahedron(const std::array<int, 4>& nodes, const std::vector<int>& tags);
  void add_hexahedron(const std::array<int, 8>& nodes, const std::vector<int>& tags);
  void add_triangle(const std::array<int, 3>& nodes) { file_.mesh.triangles.push_back(nodes); }
  void skip(const std::string& type_name);

  // Moves regions into the mesh in ascending tag order; `names` maps tag -> name, others get
  // "region_<tag>".
  MeshFile finish(const std::map<int, std::string>& names);

  // Gmsh tag 0 means "no physical group"; a VTK cell-data value 0 is a region like any other.
  bool zero_is_region = false;

 private:
  Region& region(int tag);
  MeshFile file_;
  std::map<int, Region> regions_;
};

// Each reader is handed the reader positioned after the first (header) line, and throws
// ParseError on a malformed file. `text` is the whole file: a binary file is read from the
// reader's position on with a ByteReader (io/binary_reader.h).
MeshFile read_gmsh1(LineReader& in);
// After "$MeshFormat": versions 2.x and 4.1, ASCII and binary.
MeshFile read_gmsh(LineReader& in, std::string_view text);
// After "# vtk DataFile Version x.y": ASCII and BINARY.
MeshFile read_vtk(LineReader& in, std::string_view header, std::string_view text);

}  // namespace conica::io::detail
