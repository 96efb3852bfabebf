// Scenes that need no file, so the server runs out of the box:
//   cube   the paper's 320-node lattice: 7 x 7 x 4 cells over 4 x 4 x 4 cm
//   block  a 8 x 4 x 2 cm slab, 16 x 8 x 4 cells (765 nodes)
//   liver  a flattened, lopsided dome of about 14 x 10 x 5 cm on 5 mm-ish cells
// All: one tissue-like conical card (strain mapping; K0 about 490 N/m per 1 cm column, stiffness
// cap 20 K0), density 1000 kg/m^3, light mass damping, bottom face (z = 0) clamped, one probe of
// radius 5 mm, symplectic Euler at dt.
#pragma once

#include <string>
#include <vector>

#include "core/body.h"

namespace conica::net {

std::vector<std::string> builtin_scene_names();

// Fills `spec` with the named scene at time step dt (s). Returns an empty string on success,
// otherwise what is wrong.
std::string builtin_scene(const std::string& name, double dt, BodySpec* spec);

}  // namespace conica::net
