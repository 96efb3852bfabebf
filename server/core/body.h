// Building a Model from geometry: lattices, springs on mesh edges, lumped masses, spring groups,
// fixed-node selectors and the card-to-spring mapping. Runs once at scene load (allocates).
#pragma once

#include <string>
#include <vector>

#include "core/mesh.h"
#include "core/model.h"

namespace conica {

// Spring families of a hexahedral cell (bit mask). Tetrahedral edges count as kEdge.
enum SpringFamily : int {
  kEdge = 1,          // 12 cell edges
  kFaceDiagonal = 2,  // 12 face diagonals
  kBodyDiagonal = 4,  // 4 body diagonals
  kAllFamilies = 7,
};

// Which springs a group takes. A spring goes to the first group whose selection matches.
struct SpringGroupSpec {
  std::string name;
  SpringCard card;
  int families = kAllFamilies;       // lattice families
  std::vector<std::string> regions;  // empty: any; else the spring's element must be in one
  Vec3 axis = Vec3::Zero();          // nonzero: only springs within max_angle of this axis
  double max_angle_deg = 10;         // degrees
};

struct FixedSelector {
  enum class Kind { kPlane, kBox, kRegion, kNodes } kind = Kind::kPlane;
  Vec3 normal = Vec3::UnitZ();  // kPlane: nodes with |normal.x - offset| <= tolerance
  double offset = 0;            // m
  double tolerance = 1e-9;      // m
  Vec3 box_min = Vec3::Zero(), box_max = Vec3::Zero();  // kBox, m
  std::string region;                                   // kRegion
  std::vector<int> nodes;                               // kNodes, 0-based
  int axes = 7;  // which axes are fixed: bit 0 x, 1 y, 2 z (7: all, a clamp)
  // A prescribed path (empty: the nodes stay at rest): waypoints time (s, ascending) and
  // displacement from rest (m) on the fixed axes (a NodeMotion of the model, core/boundary.h).
  std::vector<double> path_time;
  std::vector<Vec3> path_displacement;
};

struct BodySpec {
  Mesh mesh;              // metres
  double density = 1000;  // kg/m^3
  std::vector<SpringGroupSpec> groups;
  std::vector<FixedSelector> fixed;
  Mapping mapping = Mapping::kStrain;
  double bulk_modulus = 0;      // Pa, volume stiffness of every element (core/volume.h); 0: none
  double spread_modulus = 0;    // Pa, hexahedra's Gauss-point spread stiffness (model.h); 0: none
  double shear_modulus = 0;     // Pa, isochoric neo-Hookean shear stiffness (volume.h); 0: none
  double shear_stiffening = 0;  // dimensionless beta >= 0: the shear term stiffens (Yeoh, volume.h)
  SolverOptions options;
  std::vector<ProbeSpec> probes;
  std::vector<PlaneSpec> planes;
};

// A box of size (m) split into cells[0] x cells[1] x cells[2] hexahedra, min corner at origin.
// Nodes: (cells+1) product. The paper's 320-node cube is cells {7, 7, 4}.
Mesh make_box_lattice(const Vec3& size, const std::array<int, 3>& cells);

// A cylinder along z (radius m, height m), base centred on the origin: a square lattice of
// cells_across x cells_across cells mapped onto the disc (x = u sqrt(1 - v^2/2),
// y = v sqrt(1 - u^2/2) for u, v in [-1, 1]), cells_high layers. Hexahedra, no jagged boundary.
Mesh make_cylinder_lattice(double radius, double height, int cells_across, int cells_high);

// Signed volumes (m^3): a tetrahedron's is positive for positive orientation; a hexahedron's is
// the sum of its decomposition into six tetrahedra.
double tet_volume(const Vec3& a, const Vec3& b, const Vec3& c, const Vec3& d);
double hex_volume(const Mesh& mesh, const std::array<int, 8>& h);
double hex_volume(const std::vector<Vec3>& nodes, const std::array<int, 8>& h);

// Rest volume of a model's elements (m^3): the sum of |volume| over tetrahedra and hexahedra.
double body_volume(const Model& model);

// The mesh graph of a model: for every node the nodes it shares a spring or an element with,
// itself included, sorted. The nonzero 3 x 3 blocks of the body's stiffness (allocates; load
// time and checks).
std::vector<std::vector<int>> node_neighbours(const Model& model);

// Two nodes on the z axis joined by one spring of `card` (raw mapping): node 0 fixed at the
// origin, node 1 at z = l0 (m) free along z only, each of `mass` kg. For single-spring experiments
// against analytic values. Precondition: a valid card.
Model make_spring_pair(const SpringCard& card, double l0, double mass,
                       const SolverOptions& options);

// Builds the model. Returns an empty string on success, otherwise what is wrong (negative
// density, invalid card in group "x": ..., group "y" matches no spring, N springs match no
// group, zero-length spring, fixed selector matches no node, ...).
std::string build_model(const BodySpec& spec, Model* model);

}  // namespace conica
