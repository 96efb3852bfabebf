#include "io/scene.h"

#include <google/protobuf/io/tokenizer.h>
#include <google/protobuf/text_format.h>

#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <sstream>

#include "conica/v1/scene.pb.h"
#include "io/mesh_reader.h"
#include "io/mesh_repair.h"

namespace conica::io {
namespace {

// Generated bodies (lattice, cylinder) are bounded in total, not only per axis: 400^3 cells would
// need about 100 GB. 100,000 cells (about 1.4 million springs) is five times the 20k-node block.
constexpr long kMaxGeneratedCells = 100000;

namespace pb = google::protobuf;

// Collects the text parser's first error with its position.
class FirstError : public pb::io::ErrorCollector {
 public:
  void AddError(int line, pb::io::ColumnNumber column, const std::string& message) override {
    if (message_.empty()) {
      std::ostringstream os;
      os << line + 1 << ":" << column + 1 << ": " << message;
      message_ = os.str();
    }
  }
  void AddWarning(int, pb::io::ColumnNumber, const std::string&) override {}
  const std::string& message() const { return message_; }

 private:
  std::string message_;
};

Vec3 vec(const v1::Vector3& v) { return Vec3(v.x(), v.y(), v.z()); }

std::string num(double v) {
  std::ostringstream os;
  os << v;
  return os.str();
}

// "file:line:col: " for the index-th value of a top-level field, or "file: " if unknown.
struct Locator {
  const std::string& name;
  const pb::TextFormat::ParseInfoTree& tree;
  std::string at(const char* field, int index = -1) const {
    const auto* f = v1::Scene::descriptor()->FindFieldByName(field);
    const auto loc = tree.GetLocation(f, index);
    if (loc.line < 0) return name + ": ";
    return name + ":" + std::to_string(loc.line + 1) + ":" + std::to_string(loc.column + 1) + ": ";
  }
};

std::string convert_card(const v1::SpringCard& c, SpringCard* out) {
  SpringCard card;
  if (c.has_conical()) {
    const auto& k = c.conical();
    card.law = LawKind::kConical;
    card.conical = ConicalCard{k.g(), k.d(), k.d1(), k.d2(), k.l0(), k.n_a(), k.precompression()};
    const std::string e = validate(card.conical);
    if (!e.empty()) return e;
  } else if (c.has_hooke()) {
    card.law = LawKind::kHooke;
    card.hooke_k = c.hooke().k();
    card.hooke_length = c.hooke().length();
  } else {
    return "card needs a law: conical { ... } or hooke { ... }";
  }
  if (c.has_stiffness_cap()) card.stiffness_cap = c.stiffness_cap();
  card.damping = c.damping();
  card.maxwell_k = c.maxwell_k();
  card.maxwell_tau = c.maxwell_tau();
  *out = card;
  return {};
}

}  // namespace

std::string find_material(const std::string& name, const std::string& scene_dir,
                          std::string* error) {
  namespace fs = std::filesystem;
  const bool plain = !name.empty() &&
                     name.find_first_not_of(
                         "ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz"
                         "0123456789_.-") == std::string::npos &&
                     name[0] != '.';
  if (!plain) {
    *error = "material \"" + name + "\" is not a plain name (letters, digits, _ . -)";
    return {};
  }
  std::vector<fs::path> dirs{fs::path(scene_dir.empty() ? "." : scene_dir) / "materials"};
  if (const char* env = std::getenv("CONICA_MATERIAL_PATH")) {
    std::string list = env;
    for (size_t a = 0; a <= list.size();) {
      const size_t b = std::min(list.find(':', a), list.size());
      if (b > a) dirs.emplace_back(list.substr(a, b - a));
      a = b + 1;
    }
  }
  std::string looked;
  for (const fs::path& d : dirs) {
    const fs::path f = d / (name + ".card");
    std::error_code ec;
    if (fs::is_regular_file(f, ec)) return f.string();
    looked += (looked.empty() ? "" : ", ") + f.string();
  }
  *error = "material \"" + name + "\": no card file (looked for " + looked +
           "; CONICA_MATERIAL_PATH adds folders)";
  return {};
}

Result<SceneFile> parse_scene(std::string_view text, const std::string& name,
                              const std::string& base_dir) {
  v1::Scene scene;
  pb::TextFormat::Parser parser;
  FirstError errors;
  pb::TextFormat::ParseInfoTree tree;
  parser.RecordErrorsTo(&errors);
  parser.WriteLocationsTo(&tree);
  if (!parser.ParseFromString(std::string(text), &scene)) {
    return Error{name + ":" + (errors.message().empty() ? " not a scene" : errors.message())};
  }
  const Locator loc{name, tree};
  SceneFile out;
  if (!scene.material().empty()) {
    if (scene.group_size() > 0 || scene.bulk_modulus() != 0 || scene.spread_modulus() != 0 ||
        scene.shear_modulus() != 0 || scene.shear_stiffening() != 0)
      return Error{loc.at("material") +
                   "a scene with a material gives no group, bulk_modulus, spread_modulus, "
                   "shear_modulus or shear_stiffening of its own (the card has them)"};
    std::string e;
    const std::string path = find_material(scene.material(), base_dir, &e);
    if (path.empty()) return Error{loc.at("material") + e};
    std::ifstream in(path, std::ios::binary);
    std::ostringstream text;
    text << in.rdbuf();
    v1::Scene card;
    pb::TextFormat::Parser card_parser;
    FirstError card_errors;
    card_parser.RecordErrorsTo(&card_errors);
    if (!in || !card_parser.ParseFromString(text.str(), &card))
      return Error{loc.at("material") + "material \"" + scene.material() + "\": " + path + ":" +
                   (card_errors.message().empty() ? " cannot read" : card_errors.message())};
    if (card.group_size() == 0 || card.has_lattice() || card.has_cylinder() || card.has_mesh() ||
        card.fixed_size() > 0 || card.probe_size() > 0 || card.plate_size() > 0 ||
        card.has_solver() || !card.material().empty())
      return Error{loc.at("material") + "material \"" + scene.material() + "\": " + path +
                   ": a material card holds groups and bulk_modulus, spread_modulus, "
                   "shear_modulus, shear_stiffening only (and at least one group)"};
    scene.set_bulk_modulus(card.bulk_modulus());
    scene.set_spread_modulus(card.spread_modulus());
    scene.set_shear_modulus(card.shear_modulus());
    scene.set_shear_stiffening(card.shear_stiffening());
    *scene.mutable_group() = card.group();
    out.material = scene.material();
    out.material_path = path;
  }
  out.name = scene.name();
  out.description = scene.description();
  out.path = name;
  BodySpec& b = out.spec;

  // Geometry.
  if (scene.has_lattice()) {
    const auto& l = scene.lattice();
    if (l.cells_size() != 3) return Error{loc.at("lattice") + "lattice needs 3 cells values"};
    for (int k = 0; k < 3; ++k)
      if (l.cells(k) < 1 || l.cells(k) > 400)
        return Error{loc.at("lattice") + "lattice cells must be in 1..400 (got " +
                     std::to_string(l.cells(k)) + ")"};
    const long cells = static_cast<long>(l.cells(0)) * l.cells(1) * l.cells(2);
    if (cells > kMaxGeneratedCells)
      return Error{loc.at("lattice") + "lattice of " + std::to_string(cells) +
                   " cells is over the limit of " + std::to_string(kMaxGeneratedCells)};
    const Vec3 size = vec(l.size());
    if (!(size.minCoeff() > 0) || !size.allFinite())
      return Error{loc.at("lattice") + "lattice size must be > 0 m on every axis"};
    b.mesh = make_box_lattice(size, {l.cells(0), l.cells(1), l.cells(2)});
    for (auto& n : b.mesh.nodes) n += vec(l.origin());
    out.geometry.kind = SceneGeometry::Kind::kLattice;
    out.geometry.size = size;
    out.geometry.cells = {l.cells(0), l.cells(1), l.cells(2)};
    out.geometry.origin = vec(l.origin());
  } else if (scene.has_cylinder()) {
    const auto& c = scene.cylinder();
    if (!(c.radius() > 0) || !(c.height() > 0) || !std::isfinite(c.radius() + c.height()))
      return Error{loc.at("cylinder") + "cylinder radius and height must be > 0 m"};
    if (c.cells_across() < 1 || c.cells_across() > 400 || c.cells_high() < 1 ||
        c.cells_high() > 400)
      return Error{loc.at("cylinder") + "cylinder cells_across and cells_high must be in 1..400"};
    const long cells = static_cast<long>(c.cells_across()) * c.cells_across() * c.cells_high();
    if (cells > kMaxGeneratedCells)
      return Error{loc.at("cylinder") + "cylinder of " + std::to_string(cells) +
                   " cells is over the limit of " + std::to_string(kMaxGeneratedCells)};
    b.mesh = make_cylinder_lattice(c.radius(), c.height(), c.cells_across(), c.cells_high());
    for (auto& n : b.mesh.nodes) n += vec(c.origin());
    out.geometry.kind = SceneGeometry::Kind::kCylinder;
    out.geometry.radius = c.radius();
    out.geometry.height = c.height();
    out.geometry.cells_across = c.cells_across();
    out.geometry.cells_high = c.cells_high();
    out.geometry.origin = vec(c.origin());
  } else if (scene.has_mesh()) {
    const auto& m = scene.mesh();
    if (m.path().empty()) return Error{loc.at("mesh") + "mesh path is empty"};
    std::filesystem::path p(m.path());
    if (p.is_relative()) p = std::filesystem::path(base_dir) / p;
    out.mesh_path = p.lexically_normal().string();
    auto file = read_mesh(out.mesh_path);
    if (!file) return Error{loc.at("mesh") + "cannot load mesh: " + file.error()};
    b.mesh = std::move(file.value().mesh);
    const double scale = m.has_scale() ? m.scale() : 1.0;
    if (!(scale > 0) || !std::isfinite(scale))
      return Error{loc.at("mesh") + "mesh scale must be > 0 (got " + num(scale) + ")"};
    for (auto& n : b.mesh.nodes) n = n * scale + vec(m.translate());
    if (!m.has_repair() || m.repair()) repair(b.mesh);
    out.geometry.kind = SceneGeometry::Kind::kMesh;
    out.geometry.scale = scale;
    out.geometry.translate = vec(m.translate());
    out.geometry.repair = !m.has_repair() || m.repair();
  } else {
    return Error{name + ": a scene needs geometry: lattice, cylinder or mesh { ... }"};
  }

  b.density = scene.density();
  if (!(b.density > 0) || !std::isfinite(b.density))
    return Error{loc.at("density") + "density must be > 0 kg/m^3 (got " + num(b.density) + ")"};
  b.mapping = scene.mapping() == v1::RAW ? Mapping::kRaw : Mapping::kStrain;
  b.bulk_modulus = scene.bulk_modulus();
  if (!(b.bulk_modulus >= 0) || !std::isfinite(b.bulk_modulus))
    return Error{loc.at("bulk_modulus") + "bulk_modulus must be >= 0 Pa (got " +
                 num(b.bulk_modulus) + ")"};
  b.spread_modulus = scene.spread_modulus();
  if (!(b.spread_modulus >= 0) || !std::isfinite(b.spread_modulus))
    return Error{loc.at("spread_modulus") + "spread_modulus must be >= 0 Pa (got " +
                 num(b.spread_modulus) + ")"};
  b.shear_modulus = scene.shear_modulus();
  if (!(b.shear_modulus >= 0) || !std::isfinite(b.shear_modulus))
    return Error{loc.at("shear_modulus") + "shear_modulus must be >= 0 Pa (got " +
                 num(b.shear_modulus) + ")"};
  if (b.spread_modulus > 0 && !(b.bulk_modulus > 0))
    return Error{loc.at("spread_modulus") + "spread_modulus needs bulk_modulus > 0"};
  b.shear_stiffening = scene.shear_stiffening();
  if (!(b.shear_stiffening >= 0) || !std::isfinite(b.shear_stiffening))
    return Error{loc.at("shear_stiffening") + "shear_stiffening must be >= 0 (got " +
                 num(b.shear_stiffening) + ")"};
  if (b.shear_stiffening > 0 && !(b.shear_modulus > 0))
    return Error{loc.at("shear_stiffening") +
                 "shear_stiffening needs shear_modulus > 0 (it stiffens the shear term)"};

  if (scene.group_size() == 0) return Error{name + ": a scene needs at least one group { ... }"};
  for (int g = 0; g < scene.group_size(); ++g) {
    const auto& gs = scene.group(g);
    SpringGroupSpec spec;
    spec.name = gs.name().empty() ? "group" + std::to_string(g) : gs.name();
    const std::string where =
        loc.at("group", g) + "group " + std::to_string(g) + " (\"" + spec.name + "\"): ";
    const std::string e = convert_card(gs.card(), &spec.card);
    if (!e.empty()) return Error{where + e};
    if (gs.families_size() > 0) {
      spec.families = 0;
      for (int f : gs.families()) {
        if (f == v1::EDGE)
          spec.families |= kEdge;
        else if (f == v1::FACE_DIAGONAL)
          spec.families |= kFaceDiagonal;
        else if (f == v1::BODY_DIAGONAL)
          spec.families |= kBodyDiagonal;
        else
          return Error{where + "unknown spring family"};
      }
    }
    spec.regions.assign(gs.regions().begin(), gs.regions().end());
    spec.axis = vec(gs.axis());
    if (gs.has_max_angle_deg()) spec.max_angle_deg = gs.max_angle_deg();
    b.groups.push_back(spec);
  }

  // Plane tolerance defaults to a millionth of the body's size.
  Vec3 lo = b.mesh.nodes.empty() ? Vec3::Zero() : b.mesh.nodes[0], hi = lo;
  for (const auto& n : b.mesh.nodes) {
    lo = lo.cwiseMin(n);
    hi = hi.cwiseMax(n);
  }
  const double size = (hi - lo).norm();
  for (int k = 0; k < scene.fixed_size(); ++k) {
    const auto& f = scene.fixed(k);
    FixedSelector sel;
    const std::string where = loc.at("fixed", k) + "fixed " + std::to_string(k) + ": ";
    if (f.has_plane()) {
      sel.kind = FixedSelector::Kind::kPlane;
      sel.normal = vec(f.plane().normal());
      if (!(sel.normal.norm() > 0)) return Error{where + "plane normal must be nonzero"};
      sel.normal.normalize();
      sel.offset = f.plane().offset();
      sel.tolerance = f.plane().has_tolerance() ? f.plane().tolerance() : 1e-6 * size;
    } else if (f.has_box()) {
      sel.kind = FixedSelector::Kind::kBox;
      sel.box_min = vec(f.box().min());
      sel.box_max = vec(f.box().max());
    } else if (f.selector_case() == v1::Fixed::kRegion) {
      sel.kind = FixedSelector::Kind::kRegion;
      sel.region = f.region();
    } else if (f.has_nodes()) {
      sel.kind = FixedSelector::Kind::kNodes;
      sel.nodes.assign(f.nodes().nodes().begin(), f.nodes().nodes().end());
    } else {
      return Error{where + "needs a selector: plane, box, region or nodes"};
    }
    if (f.axes_size() > 0) {
      sel.axes = 0;
      for (int a : f.axes()) {
        if (a < v1::X || a > v1::Z) return Error{where + "unknown axis"};
        sel.axes |= 1 << (a - v1::X);
      }
    }
    for (int w = 0; w < f.path_size(); ++w) {
      const auto& p = f.path(w);
      const std::string at = where + "path " + std::to_string(w) + ": ";
      if (!std::isfinite(p.time())) return Error{at + "time must be finite (s)"};
      if (w > 0 && !(p.time() > f.path(w - 1).time()))
        return Error{at + "time must be greater than the previous waypoint's (s)"};
      const Vec3 d = vec(p.displacement());
      if (!d.allFinite()) return Error{at + "displacement must be finite (m)"};
      sel.path_time.push_back(p.time());
      sel.path_displacement.push_back(d);
    }
    b.fixed.push_back(sel);
  }
  for (int k = 0; k < scene.probe_size(); ++k) {
    const auto& p = scene.probe(k);
    if (!(p.radius() > 0) || !std::isfinite(p.radius()))
      return Error{loc.at("probe", k) + "probe " + std::to_string(k) + ": radius must be > 0 m"};
    const std::string where = loc.at("probe", k) + "probe " + std::to_string(k) + ": ";
    if (!(p.stiffness() >= 0) || !std::isfinite(p.stiffness()))
      return Error{where + "stiffness must be >= 0 Pa/m (0: from the tissue)"};
    if (!(p.coupling() >= 0) || !std::isfinite(p.coupling()))
      return Error{where + "coupling must be >= 0 N/m (0: from the tissue)"};
    if (!(p.friction() >= 0) || !std::isfinite(p.friction()))
      return Error{where + "friction must be >= 0 (a Coulomb coefficient)"};
    ProbeSpec spec;
    spec.radius = p.radius();
    spec.stiffness = p.stiffness();
    spec.coupling = p.coupling();
    spec.friction = p.friction();
    spec.bonded = p.bonded();
    switch (p.contact()) {
      case v1::NODES:
        spec.contact = ContactModel::kNodes;
        break;
      case v1::CONTACT_MODEL_UNSPECIFIED:
      case v1::SURFACE:
        spec.contact = ContactModel::kSurface;
        break;
      default:
        return Error{where + "unknown contact model"};
    }
    if (spec.contact == ContactModel::kNodes && p.shape() != v1::SPHERE)
      return Error{where + "shape " + v1::ToolShape_Name(p.shape()) + " needs contact: SURFACE"};
    if (spec.contact == ContactModel::kNodes && p.friction() > 0)
      return Error{where + "friction needs contact: SURFACE"};
    switch (p.shape()) {
      case v1::SPHERE:
        spec.shape = ToolShape::kSphere;
        break;
      case v1::PUNCH:
        spec.shape = ToolShape::kPunch;
        break;
      case v1::PLANE:
        spec.shape = ToolShape::kPlane;
        break;
      default:
        return Error{where + "unknown shape"};
    }
    if (p.has_axis()) {
      spec.axis = vec(p.axis());
      if (!(spec.axis.norm() > 0) || !spec.axis.allFinite())
        return Error{where + "axis must be a nonzero vector"};
      spec.axis.normalize();
    }
    b.probes.push_back(spec);
  }
  for (int k = 0; k < scene.plate_size(); ++k) {
    const auto& p = scene.plate(k);
    PlaneSpec pl;
    pl.normal = vec(p.normal());
    if (!(pl.normal.norm() > 0))
      return Error{loc.at("plate", k) + "plate " + std::to_string(k) + ": normal must be nonzero"};
    pl.normal.normalize();
    pl.offset = p.offset();
    pl.stiffness = p.stiffness();
    pl.bonded = p.bonded();
    pl.bond_tolerance = p.bond_tolerance();
    if (!(pl.bond_tolerance >= 0) || !std::isfinite(pl.bond_tolerance))
      return Error{loc.at("plate", k) + "plate " + std::to_string(k) +
                   ": bond_tolerance must be >= 0 m"};
    pl.friction = p.friction();
    if (!(pl.friction >= 0) || !std::isfinite(pl.friction))
      return Error{loc.at("plate", k) + "plate " + std::to_string(k) +
                   ": friction must be >= 0 (a Coulomb coefficient)"};
    b.planes.push_back(pl);
  }
  const auto& s = scene.solver();
  SolverOptions& o = b.options;
  switch (s.integrator()) {
    case v1::EXPLICIT_EULER:
      o.integrator = Integrator::kExplicitEuler;
      break;
    case v1::IMPLICIT_EULER:
      o.integrator = Integrator::kImplicitEuler;
      break;
    default:
      o.integrator = Integrator::kSymplecticEuler;
      break;
  }
  const std::string swhere = loc.at("solver") + "solver: ";
  const double rate = s.has_rate_hz() ? s.rate_hz() : 1000.0;
  if (!(rate > 0) || rate > 1e6) return Error{swhere + "rate_hz must be in (0, 1e6]"};
  o.dt = 1.0 / rate;
  if (s.has_substeps()) o.substeps = s.substeps();
  if (s.has_newton_iterations()) o.newton_iterations = s.newton_iterations();
  if (s.has_cg_iterations()) o.cg_iterations = s.cg_iterations();
  if (s.has_cg_tolerance()) o.cg_tolerance = s.cg_tolerance();
  o.newton_tolerance = s.newton_tolerance();
  if (!(o.newton_tolerance >= 0) || !std::isfinite(o.newton_tolerance))
    return Error{swhere + "newton_tolerance must be a finite length >= 0 (m)"};
  if (s.linear_solver() == v1::FACTOR_CG) {
    if (o.integrator != Integrator::kImplicitEuler)
      return Error{swhere + "linear_solver FACTOR_CG needs integrator IMPLICIT_EULER"};
    o.linear_solver = LinearSolver::kFactorCG;
  }
  if (s.has_refactor_every()) o.refactor_every = s.refactor_every();
  if (s.has_refactor_iterations()) o.refactor_iterations = s.refactor_iterations();
  if (o.refactor_every < 0 || o.refactor_iterations < 0)
    return Error{swhere + "refactor_every and refactor_iterations must be >= 0"};
  o.body_rate_hz = s.body_rate_hz();
  o.body_reach = s.body_reach();
  if (s.has_exact_compliance()) o.exact_compliance = s.exact_compliance();
  if (s.has_exact_tangent()) o.exact_tangent = s.exact_tangent();
  if (s.has_bdf2()) o.bdf2 = s.bdf2();
  if (o.bdf2 && o.integrator != Integrator::kImplicitEuler)
    return Error{swhere + "bdf2 needs integrator IMPLICIT_EULER"};
  if (!(o.body_rate_hz >= 0) || o.body_rate_hz > rate || !(o.body_reach >= 0) ||
      !std::isfinite(o.body_reach))
    return Error{swhere + "body_rate_hz must be in [0, rate_hz] and body_reach >= 0 (m)"};
  if (o.body_rate_hz > 0 && o.integrator != Integrator::kImplicitEuler)
    return Error{swhere + "body_rate_hz (multi-rate serving) needs integrator IMPLICIT_EULER"};
  if (s.has_min_length_fraction()) o.min_length_fraction = s.min_length_fraction();
  if (s.has_max_speed()) o.max_speed = s.max_speed();
  o.mass_damping = s.mass_damping();
  o.gravity = vec(s.gravity());
  if (o.substeps < 1 || o.substeps > 1000) return Error{swhere + "substeps must be in 1..1000"};
  if (o.newton_iterations < 1 || o.cg_iterations < 1)
    return Error{swhere + "newton_iterations and cg_iterations must be >= 1"};
  if (o.mass_damping < 0) return Error{swhere + "mass_damping must be >= 0"};
  if (s.has_active_region()) {
    const auto& a = s.active_region();
    const std::string awhere = loc.at("solver") + "solver.active_region: ";
    if (o.integrator == Integrator::kImplicitEuler)
      return Error{awhere +
                   "needs SYMPLECTIC_EULER or EXPLICIT_EULER (the implicit step couples "
                   "every node)"};
    if (b.bulk_modulus > 0 || b.shear_modulus > 0)
      return Error{awhere +
                   "not with bulk_modulus or shear_modulus (the region's lists hold "
                   "springs only)"};
    if (!(a.tolerance() > 0) || !std::isfinite(a.tolerance()))
      return Error{awhere + "tolerance must be a positive length in m (got " + num(a.tolerance()) +
                   ")"};
    if (a.far_every() < -1 || a.far_every() > 1000)
      return Error{awhere + "far_every must be -1 (frozen), 0 (automatic) or 1..1000 ticks (got " +
                   std::to_string(a.far_every()) + ")"};
    o.active_region = true;
    o.active_tolerance = a.tolerance();
    o.active_far_every = a.far_every();
  }

  // Build once so that every semantic error surfaces at load, pointing at its group if any.
  Model model;
  const std::string e = build_model(b, &model);
  if (!e.empty()) {
    for (int g = 0; g < scene.group_size(); ++g)
      if (e.find("\"" + b.groups[g].name + "\"") != std::string::npos)
        return Error{loc.at("group", g) + e};
    for (int k = 0; k < scene.fixed_size(); ++k)
      if (e.rfind("fixed selector " + std::to_string(k), 0) == 0)
        return Error{loc.at("fixed", k) + e};
    for (int k = 0; k < scene.probe_size(); ++k)
      if (e.rfind("probe " + std::to_string(k) + ": ", 0) == 0)
        return Error{loc.at("probe", k) + e};
    for (int k = 0; k < scene.plate_size(); ++k)
      if (e.rfind("plane " + std::to_string(k) + " ", 0) == 0 ||
          e.rfind("plane " + std::to_string(k) + ":", 0) == 0)
        return Error{loc.at("plate", k) + "plate " + e.substr(6)};
    return Error{name + ": " + e};
  }
  return out;
}

Result<SceneFile> read_scene(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  if (!in) return Error{path + ": cannot open scene file"};
  std::ostringstream text;
  text << in.rdbuf();
  if (text.str().size() > (16u << 20)) return Error{path + ": scene file larger than 16 MiB"};
  const std::string dir = std::filesystem::path(path).parent_path().string();
  return parse_scene(text.str(), path, dir.empty() ? "." : dir);
}

std::string load_scene(const std::string& path, BodySpec* spec) {
  auto r = read_scene(path);
  if (!r) return r.error();
  *spec = std::move(r.value().spec);
  return {};
}

Result<Model> load_model(const std::string& path) {
  BodySpec spec;
  const std::string e = load_scene(path, &spec);
  if (!e.empty()) return Error{e};
  Model m;
  const std::string b = build_model(spec, &m);
  if (!b.empty()) return Error{path + ": " + b};
  return m;
}

}  // namespace conica::io
