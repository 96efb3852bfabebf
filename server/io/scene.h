// Scene files: protobuf text format against proto/conica/v1/scene.proto -> BodySpec -> Model.
// Every error names the file, the line and column where it can, and what is wrong:
//   cube.pbtxt:7:3: Message type "conica.v1.Scene" has no field named "densty".
//   cube.pbtxt:5:1: density must be > 0 kg/m^3 (got -3)
//   cube.pbtxt:9:1: group 1 ("red"): d must be > 0 (got 0)
#pragma once

#include <array>
#include <string>
#include <string_view>

#include "core/body.h"
#include "core/model.h"
#include "io/result.h"

namespace conica::io {

// The geometry as the scene gives it (spec.mesh is what it generates or reads).
struct SceneGeometry {
  enum class Kind { kLattice, kCylinder, kMesh } kind = Kind::kLattice;
  Vec3 size = Vec3::Zero();           // lattice, m
  std::array<int, 3> cells{1, 1, 1};  // lattice
  double radius = 0, height = 0;      // cylinder, m
  int cells_across = 1, cells_high = 1;
  Vec3 origin = Vec3::Zero();     // lattice and cylinder, m
  double scale = 1;               // mesh: metres per file unit
  Vec3 translate = Vec3::Zero();  // mesh, m
  bool repair = true;             // mesh
};

struct SceneFile {
  std::string name;
  std::string description;
  std::string path;       // as given
  std::string mesh_path;  // resolved mesh file, empty for lattices
  SceneGeometry geometry;
  BodySpec spec;              // geometry in metres, cards, selectors, solver options
  std::string material;       // the `material` name, empty when the scene gives its groups
  std::string material_path;  // the card file it was read from
};

// The card file of material `name` for a scene in folder `scene_dir`: scene_dir/materials/
// NAME.card, else the first CONICA_MATERIAL_PATH folder holding NAME.card. Empty with *error
// set when there is none or the name is not a plain file name.
std::string find_material(const std::string& name, const std::string& scene_dir,
                          std::string* error);

// Reads, parses and validates a scene; the mesh path is resolved against the scene's folder.
// Validation includes building the model once, so a scene that loads also builds.
Result<SceneFile> read_scene(const std::string& path);
Result<SceneFile> parse_scene(std::string_view text, const std::string& name,
                              const std::string& base_dir);

// Convenience: the spec of a scene file, or the error message (empty on success).
std::string load_scene(const std::string& path, BodySpec* spec);

// Reads a scene and builds its model.
Result<Model> load_model(const std::string& path);

}  // namespace conica::io
