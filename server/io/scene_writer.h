// Scenes back to text: a SceneFile as the conica.v1.Scene message (proto/conica/v1/scene.proto),
// printed by protobuf's text format, so that read_scene / parse_scene read back the same
// SceneFile (numbers are printed to round-trip exactly).
#pragma once

#include <string>

#include "core/body.h"
#include "io/scene.h"

namespace conica::io {

// The whole scene. The mesh path is written relative to `dir`, the folder the text is saved in.
std::string scene_text(const SceneFile& scene, const std::string& dir = ".");

// The material of `body` alone: bulk_modulus, spread_modulus, shear_modulus (when not 0) and its
// groups; no geometry. Text to paste into a scene (the lines of calibrated cards).
std::string material_text(const BodySpec& body);

// Writes `text` to `path`; returns the error ("path: cannot write"), empty on success.
std::string write_text_file(const std::string& path, const std::string& text);

}  // namespace conica::io
