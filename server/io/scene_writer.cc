#include "io/scene_writer.h"

#include <google/protobuf/text_format.h>

#include <filesystem>
#include <fstream>

#include "conica/v1/scene.pb.h"

namespace conica::io {
namespace {

void set(const Vec3& v, v1::Vector3* out) {
  out->set_x(v.x());
  out->set_y(v.y());
  out->set_z(v.z());
}

void set_card(const SpringCard& c, v1::SpringCard* out) {
  if (c.law == LawKind::kConical) {
    v1::ConicalSpring* k = out->mutable_conical();
    k->set_g(c.conical.G);
    k->set_d(c.conical.d);
    k->set_d1(c.conical.D1);
    k->set_d2(c.conical.D2);
    k->set_l0(c.conical.L0);
    k->set_n_a(c.conical.n_a);
    k->set_precompression(c.conical.precompression);
  } else {
    out->mutable_hooke()->set_k(c.hooke_k);
    out->mutable_hooke()->set_length(c.hooke_length);
  }
  out->set_stiffness_cap(c.stiffness_cap);
  out->set_damping(c.damping);
  out->set_maxwell_k(c.maxwell_k);
  out->set_maxwell_tau(c.maxwell_tau);
}

void set_group(const SpringGroupSpec& g, v1::SpringGroup* out) {
  out->set_name(g.name);
  set_card(g.card, out->mutable_card());
  if (g.families != kAllFamilies) {
    if (g.families & kEdge) out->add_families(v1::EDGE);
    if (g.families & kFaceDiagonal) out->add_families(v1::FACE_DIAGONAL);
    if (g.families & kBodyDiagonal) out->add_families(v1::BODY_DIAGONAL);
  }
  for (const std::string& r : g.regions) out->add_regions(r);
  if (g.axis.norm() > 0) set(g.axis, out->mutable_axis());
  if (g.axis.norm() > 0 || g.max_angle_deg != SpringGroupSpec{}.max_angle_deg)
    out->set_max_angle_deg(g.max_angle_deg);
}

// The material fields of a Scene: volume terms and groups.
void set_material(const BodySpec& b, v1::Scene* out) {
  out->set_bulk_modulus(b.bulk_modulus);
  out->set_spread_modulus(b.spread_modulus);
  out->set_shear_modulus(b.shear_modulus);
  out->set_shear_stiffening(b.shear_stiffening);
  for (const SpringGroupSpec& g : b.groups) set_group(g, out->add_group());
}

void set_fixed(const FixedSelector& f, v1::Fixed* out) {
  switch (f.kind) {
    case FixedSelector::Kind::kPlane:
      set(f.normal, out->mutable_plane()->mutable_normal());
      out->mutable_plane()->set_offset(f.offset);
      out->mutable_plane()->set_tolerance(f.tolerance);
      break;
    case FixedSelector::Kind::kBox:
      set(f.box_min, out->mutable_box()->mutable_min());
      set(f.box_max, out->mutable_box()->mutable_max());
      break;
    case FixedSelector::Kind::kRegion:
      out->set_region(f.region);
      break;
    case FixedSelector::Kind::kNodes:
      for (int n : f.nodes) out->mutable_nodes()->add_nodes(n);
      break;
  }
  if (f.axes != 7)
    for (int a = 0; a < 3; ++a)
      if (f.axes & (1 << a)) out->add_axes(static_cast<v1::Axis>(v1::X + a));
  for (size_t w = 0; w < f.path_time.size() && w < f.path_displacement.size(); ++w) {
    v1::Waypoint* p = out->add_path();
    p->set_time(f.path_time[w]);
    set(f.path_displacement[w], p->mutable_displacement());
  }
}

void set_probe(const ProbeSpec& p, v1::Probe* out) {
  out->set_radius(p.radius);
  out->set_stiffness(p.stiffness);
  out->set_contact(p.contact == ContactModel::kSurface ? v1::SURFACE : v1::NODES);
  out->set_shape(p.shape == ToolShape::kPunch   ? v1::PUNCH
                 : p.shape == ToolShape::kPlane ? v1::PLANE
                                                : v1::SPHERE);
  if (p.axis != ProbeSpec{}.axis) set(p.axis, out->mutable_axis());
  out->set_coupling(p.coupling);
  out->set_friction(p.friction);
  out->set_bonded(p.bonded);
}

void set_solver(const SolverOptions& o, v1::Solver* out) {
  switch (o.integrator) {
    case Integrator::kExplicitEuler:
      out->set_integrator(v1::EXPLICIT_EULER);
      break;
    case Integrator::kImplicitEuler:
      out->set_integrator(v1::IMPLICIT_EULER);
      break;
    default:
      out->set_integrator(v1::SYMPLECTIC_EULER);
      break;
  }
  out->set_rate_hz(1.0 / o.dt);
  out->set_substeps(o.substeps);
  out->set_newton_iterations(o.newton_iterations);
  out->set_cg_iterations(o.cg_iterations);
  out->set_cg_tolerance(o.cg_tolerance);
  out->set_newton_tolerance(o.newton_tolerance);
  if (o.linear_solver == LinearSolver::kFactorCG) out->set_linear_solver(v1::FACTOR_CG);
  if (o.linear_solver == LinearSolver::kFactorCG || o.body_rate_hz > 0) {  // multi-rate reads them
    out->set_refactor_every(o.refactor_every);
    out->set_refactor_iterations(o.refactor_iterations);
  }
  out->set_body_rate_hz(o.body_rate_hz);
  out->set_body_reach(o.body_reach);
  if (o.body_rate_hz > 0) out->set_exact_compliance(o.exact_compliance);
  if (o.integrator == Integrator::kImplicitEuler) out->set_exact_tangent(o.exact_tangent);
  if (o.bdf2) out->set_bdf2(true);
  out->set_mass_damping(o.mass_damping);
  if (o.gravity.norm() > 0) set(o.gravity, out->mutable_gravity());
  out->set_min_length_fraction(o.min_length_fraction);
  out->set_max_speed(o.max_speed);
  if (o.active_region) {
    out->mutable_active_region()->set_tolerance(o.active_tolerance);
    out->mutable_active_region()->set_far_every(o.active_far_every);
  }
}

// `path` relative to folder `dir` (both as the process sees them), or as it is if it has none.
std::string relative_to(const std::string& path, const std::string& dir) {
  namespace fs = std::filesystem;
  std::error_code ec;
  const fs::path a = fs::absolute(path, ec), d = fs::absolute(dir.empty() ? "." : dir, ec);
  if (ec) return path;
  const fs::path r = a.lexically_normal().lexically_relative(d.lexically_normal());
  return r.empty() ? path : r.string();
}

std::string print(const v1::Scene& scene) {
  std::string out;
  google::protobuf::TextFormat::Printer printer;
  printer.PrintToString(scene, &out);
  return out;
}

}  // namespace

std::string scene_text(const SceneFile& s, const std::string& dir) {
  v1::Scene scene;
  scene.set_name(s.name);
  scene.set_description(s.description);
  const SceneGeometry& g = s.geometry;
  switch (g.kind) {
    case SceneGeometry::Kind::kLattice: {
      v1::Lattice* l = scene.mutable_lattice();
      set(g.size, l->mutable_size());
      for (int c : g.cells) l->add_cells(c);
      if (g.origin.norm() > 0) set(g.origin, l->mutable_origin());
      break;
    }
    case SceneGeometry::Kind::kCylinder: {
      v1::Cylinder* c = scene.mutable_cylinder();
      c->set_radius(g.radius);
      c->set_height(g.height);
      c->set_cells_across(g.cells_across);
      c->set_cells_high(g.cells_high);
      if (g.origin.norm() > 0) set(g.origin, c->mutable_origin());
      break;
    }
    case SceneGeometry::Kind::kMesh: {
      v1::MeshFile* m = scene.mutable_mesh();
      m->set_path(relative_to(s.mesh_path, dir));
      if (g.scale != 1) m->set_scale(g.scale);
      if (g.translate.norm() > 0) set(g.translate, m->mutable_translate());
      if (!g.repair) m->set_repair(false);
      break;
    }
  }
  const BodySpec& b = s.spec;
  scene.set_density(b.density);
  scene.set_mapping(b.mapping == Mapping::kRaw ? v1::RAW : v1::STRAIN);
  set_material(b, &scene);
  for (const FixedSelector& f : b.fixed) set_fixed(f, scene.add_fixed());
  for (const ProbeSpec& p : b.probes) set_probe(p, scene.add_probe());
  for (const PlaneSpec& p : b.planes) {
    v1::Plate* plate = scene.add_plate();
    set(p.normal, plate->mutable_normal());
    plate->set_offset(p.offset);
    plate->set_stiffness(p.stiffness);
    plate->set_bonded(p.bonded);
    plate->set_bond_tolerance(p.bond_tolerance);
    plate->set_friction(p.friction);
  }
  set_solver(b.options, scene.mutable_solver());
  return print(scene);
}

std::string material_text(const BodySpec& body) {
  v1::Scene scene;
  set_material(body, &scene);
  return print(scene);
}

std::string write_text_file(const std::string& path, const std::string& text) {
  std::ofstream out(path, std::ios::binary);
  out << text;
  out.close();
  if (!out) return path + ": cannot write";
  return {};
}

}  // namespace conica::io
