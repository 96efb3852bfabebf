// Mesh files -> conica::Mesh. The format is chosen by the file's first line, not its name:
//   "$NOD"                        Gmsh legacy v1 ($NOD/$ELM)
//   "$MeshFormat" 2.x / 4.1       Gmsh 2.2 ($Nodes/$Elements) and 4.1 (entity blocks), ASCII
//                                 (file-type 0) or binary (file-type 1, either byte order)
//   "# vtk DataFile Version"      legacy VTK unstructured grid, ASCII or BINARY (big-endian;
//                                 cell types 10, 12, 5; also the 5.1 OFFSETS/CONNECTIVITY layout)
// Anything else (VTK XML .vtu, STL, Abaqus, Exodus...) is refused with the meshio command
// that converts it to Gmsh (convert_command()).
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
  std::string format;  // "gmsh 1", "gmsh 2.2", "gmsh 4.1 binary", "vtk 3.0", "vtk 5.1 binary"...
  int skipped_elements = 0;                  // elements of other types
  std::map<std::string, int> skipped_types;  // e.g. {"line": 71}
};

// Reads and parses a file. Errors name the file, the line (text) or byte offset (binary data)
// and what is wrong: "liver.msh:412: ..." or "liver.msh: byte 5120: ...".
Result<MeshFile> read_mesh(const std::string& path);

// Parses the bytes of a mesh file; `name` is used in error messages.
Result<MeshFile> parse_mesh(std::string_view text, const std::string& name);

// The command that converts a mesh file of another format to one conica reads:
// "meshio convert --output-format gmsh22 in.vtu in.msh" (python3-meshio; Gmsh 2.2 binary, which
// takes any mix of cell types; without the option meshio writes .msh as ANSYS).
std::string convert_command(const std::string& path);

}  // namespace conica::io
