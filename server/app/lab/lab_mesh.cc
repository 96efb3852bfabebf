// conica-lab mesh FILE: read a mesh, print its summary and what repair() would change.
#include <cstdio>
#include <memory>
#include <string>

#include "app/lab/lab.h"
#include "io/mesh_reader.h"
#include "io/mesh_repair.h"

namespace conica::lab {

namespace {

std::string vec(const Vec3& p) {
  char s[96];
  std::snprintf(s, sizeof s, "[%.6g, %.6g, %.6g]", p.x(), p.y(), p.z());
  return s;
}

int run_mesh(const std::string& path) {
  io::Result<io::MeshFile> read = io::read_mesh(path);
  if (!read) {
    std::fprintf(stderr, "conica-lab mesh: %s\n", read.error().c_str());
    return 1;
  }
  const io::MeshFile& file = read.value();
  const Mesh& mesh = file.mesh;
  const io::BoundingBox box = io::bounding_box(mesh);

  // The file as read.
  std::printf("file: %s\nformat: %s\n", path.c_str(), file.format.c_str());
  std::printf("nodes: %zu\n", mesh.nodes.size());
  std::printf("tetrahedra: %zu\n", mesh.tetrahedra.size());
  std::printf("hexahedra: %zu\n", mesh.hexahedra.size());
  std::printf("triangles: %zu\n", mesh.triangles.size());
  std::string skipped;
  for (const auto& [type, count] : file.skipped_types) {
    skipped += (skipped.empty() ? " (" : ", ") + type + " " + std::to_string(count);
  }
  std::printf("skipped elements: %d%s\n", file.skipped_elements,
              skipped.empty() ? "" : (skipped + ")").c_str());
  std::printf("springs: %zu\n", io::spring_pairs(mesh).size());
  std::printf("bbox: %s .. %s\n", vec(box.min).c_str(), vec(box.max).c_str());
  std::printf("regions: %zu\n", mesh.regions.size());
  for (const Region& r : mesh.regions) {
    std::printf("  %s (id %d): %zu tetrahedra, %zu hexahedra\n", r.name.c_str(), r.id,
                r.tetrahedra.size(), r.hexahedra.size());
  }

  // What repair() changes, and the mesh a body would be built from.
  Mesh repaired = mesh;
  const io::MeshReport report = io::repair(repaired);
  std::string lines = io::to_string(report);
  std::printf("repair:\n");
  for (std::size_t start = 0; start < lines.size();) {
    const std::size_t end = lines.find('\n', start);
    std::printf("  %s\n", lines.substr(start, end - start).c_str());
    start = end + 1;
  }
  std::printf("repaired: nodes %zu, tetrahedra %zu, hexahedra %zu, springs %zu\n",
              repaired.nodes.size(), repaired.tetrahedra.size(), repaired.hexahedra.size(),
              io::spring_pairs(repaired).size());
  std::printf("surface triangles: %zu\n", io::surface_triangles(repaired).size());
  std::printf("volume: %.6g (file units^3)\n", io::total_volume(repaired));
  return 0;
}

}  // namespace

void register_mesh(CLI::App& app, Runner* run) {
  auto path = std::make_shared<std::string>();
  CLI::App* cmd = app.add_subcommand(
      "mesh", "Read a mesh (Gmsh 1/2.2/4.1, legacy VTK) and print its summary and repair report");
  cmd->add_option("file", *path, "mesh file")->required();
  cmd->callback([path, run] { *run = [path] { return run_mesh(*path); }; });
}

}  // namespace conica::lab
