// Mesh files -> conica::Mesh. The format is chosen by the file's first line, not its name:
//   "$NOD"                        Gmsh legacy v1 ($NOD/$ELM)
//   "$MeshFormat" 2.x / 4.1 ASCII Gmsh 2.2 ($Nodes/$Elements) and 4.1 (entity blocks)
//   "# vtk DataFile Version"      legacy VTK unstructured grid, ASCII (cell types 10, 12, 5;
//                                 also the 5.1 OFFSETS/CONNECTIVITY layout)
// Gmsh node ids are arbitrary and are mapped to 0-based indices in file order. Tetrahedra,
// hexahedra and triangles are kept; every other element type is skipped and counted.
// Physical groups (Gmsh) or an integer CELL_DATA scalar (VTK) become Regions of the
// tetrahedra and hexahedra, named by $PhysicalNames or "region_<id>".
// Coordinates are in file units. Orientation is as in the file: run repair() to fix it.
#pragma once

#include <map>
#include <string>
#include <string_view>

#include "core/mesh.h"
#include "io/result.h"

namespace conica::io {

struct MeshFile {
  Mesh mesh;
  std::string format;                        // "gmsh 1", "gmsh 2.2", "gmsh 4.1", "vtk 3.0", ...
  int skipped_elements = 0;                  // elements of other types
  std::map<std::string, int> skipped_types;  // e.g. {"line": 71}
};

// Reads and parses a file. Errors name the file, the line and what is wrong.
Result<MeshFile> read_mesh(const std::string& path);

// Parses the text of a mesh file; `name` is used in error messages.
Result<MeshFile> parse_mesh(std::string_view text, const std::string& name);

}  // namespace conica::io
