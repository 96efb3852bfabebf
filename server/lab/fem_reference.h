// A continuum reference for a scene's test, computed with CalculiX (ccx): the body as quadratic
// hexahedra (C3D20R) on the scene's own geometry, a hyperelastic law fitted to the same uniaxial
// data the card was fitted to, and the boundary conditions of `conica-lab compress` (frictionless
// or bonded plates) and `conica-lab indent` (a flat punch on a sliding or bonded base). What is
// here builds the deck and reads ccx's printed reactions; running ccx is the CLI's (conica-lab
// fem-reference). No I/O, no logging.
//
// The law: Yeoh (CalculiX *HYPERELASTIC, YEOH), W = C10 (I1 - 3) + C20 (I1 - 3)^2 + C30 (I1 - 3)^3
// + (J - 1)^2 / D1, with I1 the isochoric first invariant. Its incompressible uniaxial nominal
// stress is P = 2 (lambda - lambda^-2) (C10 + 2 C20 (I1 - 3) + 3 C30 (I1 - 3)^2),
// I1 = lambda^2 + 2 / lambda: linear in C10, C20, C30, fitted by least squares on the relative
// error. D1 = 2 / K with K from the small-strain shear modulus 2 C10 and the Poisson ratio asked.
#pragma once

#include <array>
#include <string>
#include <vector>

#include "core/mesh.h"

namespace conica::lab {

// 20-node hexahedra in CalculiX order (corners as VTK, then the midside nodes of edges 1-2, 2-3,
// 3-4, 4-1, 5-6, 6-7, 7-8, 8-5, 1-5, 2-6, 3-7, 4-8), 0-based node indices.
struct FemMesh {
  std::vector<Vec3> nodes;  // m
  std::vector<std::array<int, 20>> elements;
  bool quarter = false;        // only x >= centre.x, y >= centre.y: symmetry planes there
  Vec3 centre = Vec3::Zero();  // m, of the top face's bounding box (the symmetry axis)
};

// Every hexahedron of `mesh` split into refine^3 by its trilinear map, each a 20-node element on
// the same map, coincident nodes merged. quarter: keep only the elements in x >= cx, y >= cy (the
// centre of the bounding box) when the mesh is mirror-symmetric about both planes; *quarter is
// set to whether it was. Precondition: refine >= 1, the mesh has hexahedra.
FemMesh make_c3d20_mesh(const Mesh& mesh, int refine, bool quarter);

// A box lattice (every cell of a tensor grid present, axis-aligned) with its grid planes thinned
// out away from a punch: the planes within `keep` of the vertical axis through (axis.x, axis.y)
// and of the top face are kept; beyond, each cell is at most twice as wide as its neighbour
// nearer the punch, the outer faces kept. The same box, fewer cells: for a continuum reference
// whose solve would otherwise be too slow. Returns the error (not a full box lattice), empty on
// success.
std::string coarsen_box_lattice(const Mesh& mesh, const Vec3& axis, double keep, Mesh* out);

struct YeohLaw {
  double c10 = 0, c20 = 0, c30 = 0;  // Pa
  double d1 = 0;                     // 1/Pa
};
// Incompressible uniaxial nominal stress (Pa, compression positive) at compressive engineering
// strain e (0 <= e < 1).
double yeoh_uniaxial_stress(const YeohLaw& law, double e);
// Least-squares fit on relative error over the points with strain >= min_strain (compression
// positive, stress Pa); D1 from `poisson` (< 1/2). Empty error on success; fails when fewer than
// three points remain or the fit is not stable in compression (stress not increasing with
// strain over the fitted range).
std::string fit_yeoh(const std::vector<double>& strain, const std::vector<double>& stress,
                     double poisson, double min_strain, YeohLaw* law);

struct FemCase {
  enum class Test { kCompress, kIndent } test = Test::kCompress;
  double travel = 0;              // m: plate or punch travel at the end of the step
  bool bonded = false;            // compress: both plates bonded; indent: base clamped
  double punch_radius = 0;        // m, indent
  bool punch_bonded = false;      // indent: punch nodes held in x and y
  int increments = 20;            // at least this many (largest increment 1 / increments)
  bool full_integration = false;  // C3D20 (27 Gauss points) instead of C3D20R (8)
};

// The CalculiX input deck of `c` on `mesh` with `law`. Nodes of the driven set: the top face
// (compress), or all 8 nodes of every top-face element face whose centre lies within the punch
// radius of the centre axis (indent: whole quadratic faces, so no face is driven at some of its
// nodes only); the base is the lowest face. Increments: compress starts at and is capped by
// 1 / increments; indent starts at a quarter of that (the first increment carries the punch's
// edge singularity from an unstrained body) and grows automatically up to it. Returns the
// error (no face under the punch), empty on success.
std::string write_calculix_deck(const FemMesh& mesh, const YeohLaw& law, const FemCase& c,
                                const std::string& title, std::string* deck,
                                int* driven_nodes = nullptr);

struct FemPoint {
  double displacement = 0;  // m
  double force = 0;         // N, on the driven set against the travel (whole body)
};
// The driven set's total reaction at every increment of ccx's .dat output (*NODE PRINT TOTALS
// of set NDRIVE), scaled by 4 for a quarter model, with the point (0, 0) first. Returns the
// error (no totals found), empty on success.
std::string read_calculix_totals(const std::string& dat, const FemCase& c, bool quarter,
                                 std::vector<FemPoint>* curve);

}  // namespace conica::lab
