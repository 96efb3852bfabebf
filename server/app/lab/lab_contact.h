// conica-lab contact: what the command (lab_contact.cc) and its experiments share: options,
// scenes, the top surface (lab_contact_common.cc) and runs of one driven tool.
#pragma once

#include <cstdint>
#include <functional>
#include <string>
#include <vector>

#include "core/body.h"
#include "core/model.h"

namespace conica::lab::contact {

constexpr const char* kCmd = "conica-lab contact";

// The command's options (lab_contact.cc).
struct Opts {
  std::vector<std::string> scenes;
  bool suite = false;
  std::vector<std::string> experiments;
  std::string out_dir;
  // press
  double speed_mm_s = 5;
  std::vector<double> radius_factors = {0.25, 0.5, 1, 2};
  std::vector<std::string> positions = {"node", "face"};
  double max_depth_fraction = 0.5;
  double hold_s = 1;
  // hertz
  std::vector<double> size_mm = {60, 60, 30};
  std::vector<double> spacings_mm = {5, 2.5};
  std::vector<int> cells;
  bool hertz_on_scene = false;
  double sphere_radius_mm = 10;
  double punch_radius_mm = 5;
  int hertz_steps = 20;
  int hertz_settle = 5;
  double hertz_dt_ms = 1000;
  int hertz_newton = 4;
  int hertz_cg = 200;
  double compression_strain = 0.01;
  // drag
  std::vector<double> drag_factors = {0.25, 1};
  std::vector<double> drag_depths = {0.2, 1};
  double drag_spacings = 5;
  // hold
  double hold_radius_mm = 10;
  double hold_depth_mm = 4;
  double hold_press_s = 0.8;
  double hold_hold_s = 2;
  // speed check
  bool speed_check = false;
};

// A scene file as loaded.
struct Scene {
  std::string path, name;
  BodySpec spec;
};

// ---------------------------------------------------------------- geometry of the top surface

struct Top {
  std::vector<int> tris;     // surface triangles of the top face
  double spacing = 0;        // m, median of their two shorter edges
  double cx = 0, cy = 0;     // m, centre of the top's (x, y) bounding box
  Vec3 node = Vec3::Zero();  // the top node nearest the centre
  Vec3 face = Vec3::Zero();  // the face point near the centre (quad centre or triangle centroid)
  bool quad = false;         // face is the centre of a quad of two triangles
};

Top find_top(const Model& m);

// The rest surface's highest and lowest z on the vertical line through (x, y).
bool surface_span(const Model& m, double x, double y, double* ztop, double* zbot);

// ---------------------------------------------------------------- runs

struct Sample {
  long tick = 0;
  double t = 0, tool_depth = 0, proxy_depth = 0, penetration = 0, target_x = 0;
  Vec3 f = Vec3::Zero();
  int contacts = 0;
};

struct Run {
  std::vector<Sample> s;
  std::uint64_t rollbacks = 0;
  double seconds = 0;  // wall time
  double max_penetration = 0;
};

// Builds spec with one surface-contact tool (replacing the scene's probes).
std::string with_tool(BodySpec spec, double radius, ToolShape shape, Model* m,
                      ContactModel contact = ContactModel::kSurface);

// Steps `ticks` ticks with the device target target(k) (k = 0..ticks-1). Depths are ref - z.
Run drive(const Model& m, long ticks, double ref, const std::function<Vec3(long)>& target);

// One CSV per case in --out-dir (nothing without it); false, with a message, if it cannot be
// written.
bool write_csv(const Opts& o, const std::string& name, const Run& r);

// `v` printed with the printf format `f`.
std::string fmt(const char* f, double v);

// Mean and standard deviation / |mean| of `v` (0 for an empty `v` or a zero mean).
void mean_sd(const std::vector<double>& v, double* mean, double* rel_sd);

// The experiments: each prints its table on stdout and returns the exit status.
// lab_contact_press.cc: presses, drags, holds and the quasi-static check on the scenes.
int run_press(const Opts& o, const std::vector<Scene>& scenes);
int run_drag(const Opts& o, const std::vector<Scene>& scenes);
int run_hold(const Opts& o, const std::vector<Scene>& scenes);
int run_speed_check(const Opts& o, const std::vector<Scene>& scenes);
// lab_contact_hertz.cc: Hertz and Sneddon on blocks (or the first scene's body).
int run_hertz(const Opts& o, const std::vector<Scene>& scenes);

}  // namespace conica::lab::contact
