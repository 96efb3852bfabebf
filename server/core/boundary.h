// Boundary conditions beyond fixed axes and penalty plates: node sets moved along prescribed
// paths (NodeMotion) and plates that bond the nodes they touch (PlaneSpec::bonded).
//
// Both are kinematic: the nodes concerned are fixed on the prescribed axes (inv_mass and
// free_axes as for any fixed node), and at the start of each step their positions are set to
// where the boundary puts them at the end of it. A bonded plate's nodes sit at
// rest + (offset_now - offset_rest) n, so moving the plate (State::planes[k].offset) carries them
// with it; the plate's force then adds their reactions, the force the body exerts on each of them
// (the net of its springs, elements and contacts at those nodes), to the penalty force of the
// nodes that meet it without being bonded.
//
// No allocation, I/O or logging in apply_boundary_motion or add_bonded_reactions.
#pragma once

#include <string>
#include <vector>

#include "core/model.h"

namespace conica {

struct Workspace;

// The displacement (m) of `motion` at time t (s): piecewise linear between its waypoints, held
// at the ends.
Vec3 motion_displacement(const NodeMotion& motion, double t);

// Fills `motion`'s path from waypoints (time s ascending, displacement m; as many of each, at
// least one) and its axes (1..7). Returns what is wrong, empty on success.
std::string make_motion(const std::vector<double>& time, const std::vector<Vec3>& displacement,
                        int axes, NodeMotion* motion);

// Build time (build_model): for every bonded plane of `model`, the nodes (rest positions `rest`)
// within its bond tolerance of its face are listed in bonded_nodes and fixed on all axes (the
// caller derives inv_mass and free_axes from model->fixed afterwards). Returns what is wrong
// (a bonded plate that touches no node), empty on success.
std::string bond_plates(const std::vector<Vec3>& rest, Model* model);

// True when the model has a motion or a bonded plate.
bool has_boundary_motion(const Model& model);

// Puts the nodes of every motion at their prescribed positions at time t (s) and those of every
// bonded plate where its current offset carries them; their velocities on the prescribed axes are
// zeroed (the step does not move fixed axes).
void apply_boundary_motion(const Model& model, State& state, double t);

// Adds the reactions of every bonded plate's nodes (ws.force, the body's force on them) to its
// PlaneState::force, after the force pass.
void add_bonded_reactions(const Model& model, State& state, const Workspace& ws);

}  // namespace conica
