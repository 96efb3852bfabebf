// Mesh readers on arbitrary bytes: the format is chosen by the first line (Gmsh v1, 2.2, 4.1,
// legacy VTK, each ASCII or binary), so one target reaches every reader. Seeds: fuzz/corpus/mesh,
// the binary ones written by meshio (fuzz/CMakeLists.txt says how). A mesh that parses is then
// repaired, as a scene with a mesh does; element indices must be in range whenever parsing
// succeeds.
#include <cstddef>
#include <cstdint>
#include <cstdlib>
#include <string_view>

#include "io/mesh_reader.h"
#include "io/mesh_repair.h"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const std::string_view text(reinterpret_cast<const char*>(data), size);
  auto r = conica::io::parse_mesh(text, "fuzz.msh");
  if (!r) return 0;
  conica::Mesh& m = r.value().mesh;
  const auto n = m.nodes.size();
  for (const auto& t : m.tetrahedra)
    for (auto i : t)
      if (static_cast<std::size_t>(i) >= n) std::abort();
  for (const auto& h : m.hexahedra)
    for (auto i : h)
      if (static_cast<std::size_t>(i) >= n) std::abort();
  for (const auto& t : m.triangles)
    for (auto i : t)
      if (static_cast<std::size_t>(i) >= n) std::abort();
  conica::io::repair(m);
  return 0;
}
