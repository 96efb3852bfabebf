// Contact of rigid tools with the deformed surface of a body, through a proxy.
//
// The contact layer. A tool shape (a sphere of radius R around its centre, a flat-ended
// cylinder: a punch of radius R whose end face is centred at its pose and pushes along its axis,
// or a plane: an unbounded face through its pose pushing along its axis, R its length scale)
// overlaps the body's surface triangles at their current positions. A surface point y inside the
// tool at penetration g(y) (sphere: g = R - |y - c|; punch: g = -(y - c).a within radius R of the
// axis) carries the pressure p(g) of a contact layer, pushing it out of the tool (sphere: along
// u = (y - c) / |y - c|; punch: along a). The layer stores the energy
//     E = integral over the surface of psi(g) dA,   psi' = p,
//     p(g) = k g / (1 - g / g_max)   for g <= 0.9 g_max,  then linear in g with the slope at 0.9
//     g_max,
// a penalty of stiffness k (Pa/m) that turns into a barrier at g_max = kContactDepthFraction R, so
// the tool never sinks deeper than that into the deformed surface at any force. The integral is
// taken triangle by triangle, exactly in the geometry: each triangle's overlap with the tool
// (the disc the sphere cuts from its plane, or the punch's footprint) is split into sub-triangles
// from the disc's centre, integrated in polar-like coordinates with the rim as a boundary of the
// domain, so the smooth integrand is resolved by Gauss points whatever the size of the patch
// (a tool a tenth of the node spacing included) and the force is continuous as the tool slides
// across edges and vertices. The force at each Gauss point is spread to the triangle's three
// nodes by its barycentric weights. On a flat surface the total force does not depend on where
// the tool sits relative to the nodes.
//
// Stiffness from the tissue. The default k is kContactStiffnessFactor E* / R, with E* = E / (1 -
// nu^2) the body's contact modulus (the isotropic estimate of its springs and element terms,
// contact_modulus()): the layer's penetration is then a fixed small fraction of the tissue's own
// indentation (about 1 % at a Hertz depth of 0.1 R), the same for every mesh, step and integrator.
//
// The proxy (god object). Each tool has a proxy: the pose the tool takes in the simulation. The
// client moves the device target t; the proxy minimises
//     Phi(x) = k_vc / 2 |x - t|^2 + E(x)        (k_vc: the virtual coupling, N/m)
// with the body's nodes held, by Newton iterations that never let the tool's reference point (the
// sphere's centre, the punch's face centre) cross the deformed surface: every trial move is swept
// from the proxy's last position against the surface triangles and stopped short of the first one
// it would cross, however far the device jumps, and no update takes it more than
// kProxyDepthRate R deeper into the surface than it was (a jump is followed over a few ticks). A
// tool that appears inside the body has its proxy
// placed on the nearest point of the surface. Between ticks the proxy rides on the surface point
// nearest to it, so it is carried along as the surface deforms. The force on the device is the
// coupling force F = k_vc (x - t) and its stiffness dF/dt = k_vc (k_vc I - K)^-1 K, with K =
// dF_contact/dx the layer's stiffness at the proxy (nodes held): a spring in series with the
// layer, never stiffer than k_vc. The body receives the layer's forces at the proxy.
//
// Bonded tools (ProbeSpec::bonded). Every surface node with a share of the surface the tool covers
// is glued to it where it is relative to the proxy the first time, by a spring k A_i (k the
// layer's, A_i the node's share int l_i dA of the covered surface, the largest so far: the
// distribution the layer pushes with), until the probe is deactivated. The proxy's Phi takes the
// bonds' energy with the nodes held, and K the bonds' -sum k A_i I.
//
// The default coupling is kCouplingFactor E* R: stiff against the tissue under the tool (whose
// Hertz stiffness is 2 E* sqrt(R d)), so the proxy lags the device by about 1 % of the force at
// the depths of a press.
//
// No allocation, I/O or logging here: scratch comes from the caller, sized once per model.
#pragma once

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <vector>

#include "core/model.h"

namespace conica {

// The barrier depth as a fraction of the tool radius.
inline constexpr double kContactDepthFraction = 0.25;
// Default layer stiffness k = kContactStiffnessFactor E* / R (Pa/m).
inline constexpr double kContactStiffnessFactor = 100.0;
// Default virtual coupling k_vc = kCouplingFactor E* R (N/m).
inline constexpr double kCouplingFactor = 100.0;
// A proxy update sinks the tool at most this fraction of its radius deeper into the surface.
inline constexpr double kProxyDepthRate = 0.02;
// The candidate triangles' reach: within this multiple of the tool radius of its sweep.
inline constexpr double kCandidateReach = 1.5;
// The candidate list's skin, a fraction of the tool radius (ContactCandidates).
inline constexpr double kCandidateSkin = 0.5;
// A proxy's Newton step of at most this fraction of the tool radius, that keeps the tool
// shallower than the depth limit, is taken without a line search (without evaluating the layer
// again): the proxy follows a device that moves a little per tick at one layer evaluation.
inline constexpr double kProxyTrustStep = 0.005;
// A proxy's Newton solve evaluates the layer at most this many times (iterations and their line
// searches together) and then keeps the best iterate it has: a device that jumps far along the
// surface is followed over some ticks instead of one tick spending hundreds of evaluations on
// steps the depth rate refuses.
inline constexpr int kProxyMaxEvaluations = 24;
// An evaluation costs in proportion to the faces the tool touches (each one's overlap is
// integrated): past its first kProxyMinEvaluations, an update evaluates the layer again only while
// the faces it has integrated, summed over its evaluations, stay under kProxyFaceBudget, and keeps
// its best iterate otherwise. A tool on a few faces keeps the kProxyMaxEvaluations bound; one that
// crushes the surface under it (tens of faces) is followed over some ticks instead of one tick
// integrating hundreds of faces (about 2.5 us each on this project's 2-core machine).
inline constexpr int kProxyFaceBudget = 96;
inline constexpr int kProxyMinEvaluations = 4;
// The virtual coupling is linear up to a stretch of this multiple of the tool radius, and pulls
// with a constant force beyond (Coupling): k_vc R = kCouplingFactor E* R^2, 75 times the force of
// a Hertz press one radius deep, so a press the proxy follows stays far below it.
inline constexpr double kCouplingReach = 1.0;
// A proxy's line search shortens a Newton step at most this many times; a step that still
// fails (it leaves the tool deeper than it may go, however short, or does not lower the energy)
// ends the solve, and the next update goes on from there.
inline constexpr int kProxyLineSearch = 6;
// A reply to a probe update between ticks (probe_contact) moves the proxy with at most this many
// layer evaluations per solve, the tick's proxy stage with kProxyMaxEvaluations: a device that
// moves a little per update needs one or two, and one whose proxy cannot follow (a far jump into
// a dent of a crumpled surface) gets a proxy on its way, which the tick's stage carries on.
inline constexpr int kReplyMaxEvaluations = 6;
// A sphere's proxy that would move farther than this multiple of its radius in one update, to a
// target near the surface, is put down touching the surface over the target (or at the target,
// if free), if the move crosses no surface (update_proxy): a far jump at two layer evaluations.
inline constexpr double kProxyJump = 1.0;

// The surface triangles near one tool, the proxy's broad phase (a Verlet list). A pass over the
// whole surface lists the triangles whose bounding sphere (centroid, largest centroid-vertex
// distance) comes within reach + skin of the tool's sweep (the segment from the proxy's start to
// the device target) and keeps the surface nodes' positions. Later updates filter that list to
// the triangles within reach of their own sweep, with no pass over the surface, while it still
// provably holds all of them: with no surface node moved by more than delta since the pass, a
// bounding sphere's centre moved by at most delta and its radius by at most 2 delta; a sweep
// whose ends moved by at most Delta lies within Delta of the old one; so every triangle left out
// is still farther than reach while 3 delta + Delta < skin. Sized for every triangle and surface
// node of the model: nothing is allocated in the step.
struct ContactCandidates {
  std::vector<int> triangles;  // within reach of the last update's sweep: what tool_contact reads
  std::vector<int> near;       // within reach + skin of the sweep at the last pass
  std::vector<Vec3> x_pass;    // (model.surface_nodes) m, their positions at that pass
  Vec3 start_pass = Vec3::Zero(), target_pass = Vec3::Zero();  // m, that pass's sweep
  double reach_pass = -1;                                      // m (< 0: no pass yet)
  double skin_pass = 0;                                        // m
  const Model* model = nullptr;                                // the model of that pass
  std::uint64_t passes = 0;  // passes over the whole surface so far (diagnostic)

  ContactCandidates() = default;
  explicit ContactCandidates(const Model& model) { reserve(model); }
  // Capacity for every surface triangle and surface node of `model` (allocates when short).
  void reserve(const Model& model);
};

// The contact layer's pressure law.
struct ContactLayer {
  double k = 0;      // Pa/m, small-penetration stiffness
  double g_max = 0;  // m, barrier depth

  // Pressure p (Pa), its slope dp/dg (Pa/m) and the energy density psi (J/m^2) at penetration g.
  void eval(double g, double* p, double* dp, double* psi) const;
};

inline void ContactLayer::eval(double g, double* p, double* dp, double* psi) const {
  if (!(g > 0)) {
    *p = *dp = *psi = 0;
    return;
  }
  const double gc = 0.9 * g_max;
  const double gg = std::min(g, gc);
  const double x = gg / g_max, r = 1 - x, ir = 1 / r;
  // psi = k g_max^2 (-x - log(1 - x)) = k g_max^2 sum_{n >= 2} x^n / n: the series below x = 1/8
  // (12 terms: what is left out is below 3e-12 of the sum), which also keeps the digits
  // that -x - log(1 - x) cancels away at a small penetration (and costs no logarithm).
  double series = 0;
  if (x < 0.125) {
    constexpr double c[12] = {1.0 / 2, 1.0 / 3, 1.0 / 4,  1.0 / 5,  1.0 / 6,  1.0 / 7,
                              1.0 / 8, 1.0 / 9, 1.0 / 10, 1.0 / 11, 1.0 / 12, 1.0 / 13};
    double h = c[11];
    for (int j = 10; j >= 0; --j) h = c[j] + x * h;
    series = x * x * h;
  }
  double pc = k * gg * ir, dpc = k * ir * ir,
         psic = k * g_max * g_max * (x < 0.125 ? series : -x - std::log(r));
  if (g <= gc) {
    *p = pc;
    *dp = dpc;
    *psi = psic;
    return;
  }
  const double dg = g - gc;
  *p = pc + dpc * dg;
  *dp = dpc;
  *psi = psic + pc * dg + 0.5 * dpc * dg * dg;
}

// The layer's pressure p (Pa) and its slope dp/dg (Pa/m) at penetration g, without the energy.
inline void layer_pressure(const ContactLayer& layer, double g, double* p, double* dp) {
  if (!(g > 0)) {
    *p = *dp = 0;
    return;
  }
  const double gc = 0.9 * layer.g_max;
  const double gg = std::min(g, gc);
  const double ir = 1 / (1 - gg / layer.g_max);
  *p = layer.k * gg * ir;
  *dp = layer.k * ir * ir;
  if (g > gc) *p += *dp * (g - gc);
}

// What tool_contact sums for the tool besides its force and depth (the node forces and blocks
// are asked for by their arrays).
enum ToolTerms : unsigned {
  kToolForceOnly = 0,
  kToolEnergy = 1u,     // ToolContact::energy
  kToolStiffness = 2u,  // ToolContact::stiffness, stiffness_psd
  kToolAll = 3u,
  // node_pair's blocks without the curvature term (the pressure term alone: positive
  // semi-definite, what the implicit system takes)
  kToolPairPressureOnly = 4u,
};

// What a tool at a fixed pose feels from the surface with the nodes held.
struct ToolContact {
  double energy = 0;                  // J
  Vec3 force = Vec3::Zero();          // N, on the tool
  Mat3 stiffness = Mat3::Zero();      // N/m, d force / d pose (exact)
  Mat3 stiffness_psd = Mat3::Zero();  // N/m, its positive part: -sum p' n n^T (no curvature term)
  double depth = 0;                   // m, deepest penetration
  int faces = 0;                      // triangles touched
};

// The layer of probe k (its stiffness and barrier for a tool of radius R, m).
ContactLayer contact_layer(const Model& model, int probe, double radius);

// The body's contact modulus E* = E / (1 - nu^2) (Pa) from its springs' isotropic network estimate
// (E = sum(k_ax l0^2) / (6 V), nu = 1/4) and its element terms (bulk and shear moduli).
double contact_modulus(const Model& model);

// The tool of probe k (shape from the model, radius R > 0) posed at `pose` against the surface at
// positions x, over the listed surface triangles (tris, n; tris == nullptr: all of them). Fills
// `out`; when node_force is given adds the layer's force on every node to it, and when
// node_block is given adds each node's lumped stiffness block sum w lambda p' n n^T (a positive
// semi-definite bound on the layer's stiffness at that node, what implicit and semi-implicit
// updates use) to node_block[i]. `terms` (ToolTerms) leaves out what the caller does not read
// (left zero in `out`): the contact stage asks for the node terms only.
// When node_area is given, adds to node_area[i] each node's share int l_i dA of the surface
// inside the tool (m^2).
// When node_pair is given (with tris), adds to node_pair[6 q + j] the pair blocks of the q-th
// listed triangle, K_ab = sum w lambda_a lambda_b (p' n n^T - p kappa (I - n n^T)) for its
// corners (a, b) = (0, 0), (1, 1), (2, 2), (0, 1), (0, 2), (1, 2) (K_ba = K_ab; kappa the tool
// surface's curvature, 1 / r on a sphere, 0 on a punch or plane): minus the derivative of the
// layer's force on corner a with respect to corner b's position, its pressure term (the one the
// lumped blocks sum: node_block is the pressure term's row sum, positive semi-definite) and the
// turning of the push's direction around the sphere; the faces' own turning is left out. Summed
// over every pair they are minus the tool's exact stiffness. For a Newton method on the nodes
// and the proxy together (core/multirate.cc).
void tool_contact(const Model& model, int probe, double radius, const Vec3& pose,
                  const std::vector<Vec3>& x, const int* tris, int n, ToolContact* out,
                  Vec3* node_force = nullptr, Mat3* node_block = nullptr, unsigned terms = kToolAll,
                  double* node_area = nullptr, Mat3* node_pair = nullptr);

// The proxy stage for probe k: moves the proxy of *probe (from its last pose, carried by the
// surface, toward probe->center) and fills probe->force, stiffness, depth, contacts, proxy and
// anchor, with the nodes held at x. `candidates` (reserved for the model, so nothing is
// allocated; one per probe keeps its list between updates) is left holding in
// candidates->triangles the triangles within reach of the tool, what the step's contact stage
// then evaluates; nullptr: every triangle is tested (slower, same result). Each Newton solve of
// the proxy evaluates the layer at most `max_evaluations` times, and the update as a whole within
// kProxyFaceBudget.
void update_proxy(const Model& model, int k, const std::vector<Vec3>& x,
                  ContactCandidates* candidates, ProbeState* probe,
                  int max_evaluations = kProxyMaxEvaluations);

// The surface point the proxy of p rides on until its next update (p->anchor, anchor_bary,
// anchor_offset): the nearest point of the listed triangles (list == nullptr: all `count` of
// them) at positions x when it is within `reach` (m) of the proxy, else p->anchor = -1.
void anchor_proxy(const Model& model, const std::vector<Vec3>& x, const int* list, int count,
                  double reach, ProbeState* p);

// The proxy stage for a proxy held where it is (the multi-rate body, whose proxy the 1 kHz tick
// solved against the body's predicted positions; ProbeSpec::hold_proxy): fills the candidates
// around it, probe->force, stiffness, depth, contacts and the anchor it rides on from here, with
// the proxy unmoved. A proxy not yet placed (or an inactive probe) gets update_proxy.
void hold_proxy(const Model& model, int k, const std::vector<Vec3>& x,
                ContactCandidates* candidates, ProbeState* probe);

// Probe k's tool radius (m): the live one in its state, else the model's.
double probe_radius(const Model& model, int k, const ProbeState& probe);

// The virtual coupling of probe k for a tool of radius R (N/m).
double coupling_stiffness(const Model& model, int probe, double radius);

// The virtual coupling between the device and the proxy, saturated: linear, k (N/m), while it
// is stretched by at most `reach` (m, kCouplingReach R), then pulling with the constant force
// k reach along the stretch. A proxy that cannot follow its device (a jump, a dent the tool
// climbs out of) pushes the tissue with at most that instead of k times the whole lag.
// e = proxy - device (m).
struct Coupling {
  double k = 0, reach = 0;
  double energy(const Vec3& e) const;  // J
  Vec3 force(const Vec3& e) const;     // N, on the device (the energy's gradient in the proxy)
  Mat3 hessian(const Vec3& e) const;   // N/m, the energy's Hessian in the proxy
  // The device's stiffness d force / d device with the proxy in equilibrium against a contact of
  // stiffness K (N/m, nodes held): H (H - K)^-1 K, H the Hessian at e.
  Mat3 device_stiffness(const Vec3& e, const Mat3& K) const;
};
Coupling coupling(const Model& model, int probe, double radius);

// True when the tool of probe k (radius R) posed at `pose` overlaps surface triangle t (a
// sphere: the triangle comes within R of its centre; a punch: within R of its axis, behind its
// face).
bool tool_touches(const Model& model, int probe, double radius, const Vec3& pose,
                  const std::vector<Vec3>& x, int t);

// The friction of probe k on the body (probe friction > 0, after update_proxy): the tangential
// spring from the proxy to the stick point at positions x, at most mu times the normal force,
// added to the stick triangle's nodes by its barycentric weights (and k_vc P lambda to their
// blocks when node_block is given).
void friction_forces(const Model& model, int k, const ProbeState& probe, const std::vector<Vec3>& x,
                     Vec3* node_force, Mat3* node_block = nullptr);

// The surface's node spacing (m) at rest over the surface triangles `tris` (all of them when
// empty): the median of each triangle's two shorter edges, so a lattice's quad split in two gives
// its spacing, never the diagonal. 0 without triangles.
double surface_spacing(const Model& model, const std::vector<int>& tris = {});

// The distance (m) from point p to surface triangle t at positions x.
double triangle_distance(const Model& model, const std::vector<Vec3>& x, int t, const Vec3& p);

// True when point p lies inside the closed surface at positions x (winding number).
bool inside_surface(const Model& model, const std::vector<Vec3>& x, const Vec3& p);

}  // namespace conica
