#include "core/body.h"

#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>
#include <map>
#include <numeric>
#include <set>
#include <sstream>

#include "core/boundary.h"
#include "core/contact.h"
#include "core/multirate.h"
#include "core/volume.h"

namespace conica {
namespace {

// Corner c of a VTK-ordered hexahedron has lattice coordinates kCorner[c] in {0,1}^3.
constexpr int kCorner[8][3] = {{0, 0, 0}, {1, 0, 0}, {1, 1, 0}, {0, 1, 0},
                               {0, 0, 1}, {1, 0, 1}, {1, 1, 1}, {0, 1, 1}};

int pair_family(int a, int b) {
  int differ = 0;
  for (int k = 0; k < 3; ++k) differ += kCorner[a][k] != kCorner[b][k];
  return differ == 1 ? kEdge : differ == 2 ? kFaceDiagonal : kBodyDiagonal;
}

struct RawSpring {
  int i, j;
  int family;
  double volume_share;       // m^3
  std::vector<int> regions;  // region indices of the elements holding it
};

// Orders each group's springs by node offset (j - i), then i, when that puts them in runs: springs
// k, k+1, ... joining nodes i+t and j+t. A lattice numbered row by row is almost all runs, which
// the step reads and writes as contiguous streams (see Workspace::runs). Meshes without that
// structure keep the (i, j) order, whose node reuse suits scattered numbering better.
void order_springs_in_runs(std::vector<std::vector<const RawSpring*>>& by_group) {
  auto by_offset = [](const RawSpring* a, const RawSpring* b) {
    return std::make_pair(a->j - a->i, a->i) < std::make_pair(b->j - b->i, b->i);
  };
  size_t springs = 0, runs = 0;
  for (auto springs_of_group : by_group) {
    std::sort(springs_of_group.begin(), springs_of_group.end(), by_offset);
    springs += springs_of_group.size();
    for (size_t k = 0; k < springs_of_group.size(); ++k)
      runs += k == 0 || springs_of_group[k]->i != springs_of_group[k - 1]->i + 1 ||
              springs_of_group[k]->j != springs_of_group[k - 1]->j + 1;
  }
  constexpr size_t kMinMeanRun = 4;
  if (runs == 0 || springs < kMinMeanRun * runs) return;
  for (auto& springs_of_group : by_group)
    std::sort(springs_of_group.begin(), springs_of_group.end(), by_offset);
}

std::string fmt(double v) {
  std::ostringstream os;
  os.precision(6);
  os << v;
  return os.str();
}

}  // namespace

double SpringCard::k0() const {
  if (law == LawKind::kHooke) return hooke_k;
  return ConicalLaw(conical).k0();
}

double Model::total_mass() const { return std::accumulate(mass.begin(), mass.end(), 0.0); }

const char* integrator_name(Integrator i) {
  switch (i) {
    case Integrator::kSymplecticEuler:
      return "symplectic";
    case Integrator::kExplicitEuler:
      return "explicit";
    case Integrator::kImplicitEuler:
      return "implicit";
  }
  return "unknown";
}

const char* stage_name(Stage stage) {
  static constexpr const char* kNames[kNumStages] = {"proxies",   "region",    "springs",
                                                     "elements",  "contact",   "integrate",
                                                     "hard_stop", "far_field", "guard"};
  const int k = static_cast<int>(stage);
  return k >= 0 && k < kNumStages ? kNames[k] : "unknown";
}

Mesh make_box_lattice(const Vec3& size, const std::array<int, 3>& cells) {
  Mesh m;
  const int nx = cells[0] + 1, ny = cells[1] + 1, nz = cells[2] + 1;
  auto id = [&](int i, int j, int k) { return i + nx * (j + ny * k); };
  m.nodes.reserve(static_cast<size_t>(nx) * ny * nz);
  for (int k = 0; k < nz; ++k)
    for (int j = 0; j < ny; ++j)
      for (int i = 0; i < nx; ++i)
        m.nodes.emplace_back(size.x() * i / cells[0], size.y() * j / cells[1],
                             size.z() * k / cells[2]);
  for (int k = 0; k < cells[2]; ++k)
    for (int j = 0; j < cells[1]; ++j)
      for (int i = 0; i < cells[0]; ++i) {
        std::array<int, 8> h;
        for (int c = 0; c < 8; ++c)
          h[c] = id(i + kCorner[c][0], j + kCorner[c][1], k + kCorner[c][2]);
        m.hexahedra.push_back(h);
      }
  return m;
}

Mesh make_cylinder_lattice(double radius, double height, int cells_across, int cells_high) {
  Mesh m = make_box_lattice(Vec3(2, 2, height), {cells_across, cells_across, cells_high});
  for (Vec3& n : m.nodes) {
    const double u = n.x() - 1, v = n.y() - 1;
    n.x() = radius * u * std::sqrt(1 - v * v / 2);
    n.y() = radius * v * std::sqrt(1 - u * u / 2);
  }
  return m;
}

double tet_volume(const Vec3& a, const Vec3& b, const Vec3& c, const Vec3& d) {
  return (b - a).cross(c - a).dot(d - a) / 6.0;
}

double hex_volume(const Mesh& mesh, const std::array<int, 8>& h) {
  return hex_volume(mesh.nodes, h);
}

double body_volume(const Model& model) {
  const std::vector<Vec3>& x = model.rest;
  double v = 0;
  for (const auto& t : model.tetrahedra)
    v += std::abs(tet_volume(x[t[0]], x[t[1]], x[t[2]], x[t[3]]));
  for (const auto& h : model.hexahedra) v += std::abs(hex_volume(x, h));
  return v;
}

std::vector<std::vector<int>> node_neighbours(const Model& m) {
  const int nn = m.num_nodes();
  std::vector<std::vector<int>> adj(nn);
  for (int i = 0; i < nn; ++i) adj[i].push_back(i);
  auto link = [&](int a, int b) {
    adj[a].push_back(b);
    adj[b].push_back(a);
  };
  for (int k = 0; k < m.num_springs(); ++k) link(m.spring_i[k], m.spring_j[k]);
  auto link_all = [&](const auto& nodes) {
    for (size_t a = 0; a < nodes.size(); ++a)
      for (size_t b = a + 1; b < nodes.size(); ++b) link(nodes[a], nodes[b]);
  };
  for (const auto& t : m.tetrahedra) link_all(t);
  for (const auto& h : m.hexahedra) link_all(h);
  for (auto& a : adj) {
    std::sort(a.begin(), a.end());
    a.erase(std::unique(a.begin(), a.end()), a.end());
  }
  return adj;
}

double hex_volume(const std::vector<Vec3>& nodes, const std::array<int, 8>& h) {
  // Six tetrahedra around the diagonal 0-6.
  static constexpr int kTets[6][4] = {{0, 1, 2, 6}, {0, 2, 3, 6}, {0, 3, 7, 6},
                                      {0, 7, 4, 6}, {0, 4, 5, 6}, {0, 5, 1, 6}};
  double v = 0;
  for (const auto& t : kTets)
    v += tet_volume(nodes[h[t[0]]], nodes[h[t[1]]], nodes[h[t[2]]], nodes[h[t[3]]]);
  return v;
}

namespace {

// Outward boundary triangles: faces used by exactly one element.
std::vector<std::array<int, 3>> boundary_triangles(const Mesh& m) {
  std::map<std::array<int, 3>, std::pair<int, std::array<int, 3>>> faces;
  auto add = [&](std::array<int, 3> f) {
    std::array<int, 3> key = f;
    std::sort(key.begin(), key.end());
    auto [it, inserted] = faces.try_emplace(key, 1, f);
    if (!inserted) ++it->second.first;
  };
  for (const auto& t : m.tetrahedra)
    for (const auto& f : kTetFaces) add({t[f[0]], t[f[1]], t[f[2]]});
  // Hexahedron faces are keyed by their four nodes (neighbours may split them differently).
  std::map<std::array<int, 4>, std::pair<int, std::array<int, 4>>> quads;
  for (const auto& h : m.hexahedra) {
    for (const auto& q : kHexFaces) {
      std::array<int, 4> f = {h[q[0]], h[q[1]], h[q[2]], h[q[3]]}, key = f;
      std::sort(key.begin(), key.end());
      auto [it, inserted] = quads.try_emplace(key, 1, f);
      if (!inserted) ++it->second.first;
    }
  }
  std::vector<std::array<int, 3>> out;
  for (const auto& [key, v] : faces)
    if (v.first == 1) out.push_back(v.second);
  for (const auto& [key, v] : quads)
    if (v.first == 1) {
      const auto& q = v.second;
      out.push_back({q[0], q[1], q[2]});
      out.push_back({q[0], q[2], q[3]});
    }
  return out;
}

bool axis_match(const SpringGroupSpec& g, const Vec3& dir) {
  if (g.axis.squaredNorm() == 0) return true;
  const double c = std::abs(g.axis.normalized().dot(dir.normalized()));
  return c >= std::cos(g.max_angle_deg * M_PI / 180.0) - 1e-12;
}

}  // namespace

std::string build_model(const BodySpec& spec, Model* out) {
  const Mesh& mesh = spec.mesh;
  const int nn = static_cast<int>(mesh.nodes.size());
  if (!(spec.density > 0) || !std::isfinite(spec.density))
    return "density must be > 0 kg/m^3 (got " + fmt(spec.density) + ")";
  if (nn == 0) return "the mesh has no nodes";
  if (mesh.tetrahedra.empty() && mesh.hexahedra.empty())
    return "the mesh has no tetrahedra or hexahedra";
  if (spec.groups.empty()) return "no spring group: a body needs at least one spring card";
  if (!(spec.options.dt > 0) || spec.options.substeps < 1)
    return "dt must be > 0 s and substeps >= 1";
  for (const auto& g : spec.groups) {
    if (g.card.law == LawKind::kConical) {
      const std::string e = validate(g.card.conical);
      if (!e.empty()) return "spring group \"" + g.name + "\": " + e;
      if (!(g.card.stiffness_cap > 1))
        return "spring group \"" + g.name + "\": stiffness_cap must be > 1 (a multiple of K0)";
    } else if (!(g.card.hooke_k > 0) || !std::isfinite(g.card.hooke_k)) {
      return "spring group \"" + g.name + "\": hooke stiffness must be > 0 N/m";
    } else if (spec.mapping == Mapping::kStrain && !(g.card.hooke_length > 0)) {
      return "spring group \"" + g.name + "\": hooke length must be > 0 m for strain mapping";
    }
    if (g.card.damping < 0 || g.card.maxwell_k < 0 || g.card.maxwell_tau < 0)
      return "spring group \"" + g.name + "\": damping and Maxwell parameters must be >= 0";
    if (g.card.maxwell_k > 0 && !(g.card.maxwell_tau > 0))
      return "spring group \"" + g.name + "\": maxwell_tau must be > 0 s when maxwell_k > 0";
  }
  for (const auto& n : mesh.nodes)
    if (!n.allFinite()) return "the mesh has a non-finite node coordinate";
  for (const auto& [name, value] : {std::pair{"bulk_modulus", spec.bulk_modulus},
                                    std::pair{"spread_modulus", spec.spread_modulus},
                                    std::pair{"shear_modulus", spec.shear_modulus}}) {
    if (!(value >= 0) || !std::isfinite(value))
      return std::string(name) + " must be >= 0 Pa (got " + fmt(value) + ")";
    if (value > 0 && spec.options.active_region)
      return std::string(name) +
             " and the active region do not go together: the region's "
             "lists hold springs only";
  }
  if (spec.spread_modulus > 0 && !(spec.bulk_modulus > 0))
    return "spread_modulus needs bulk_modulus > 0";
  if (!(spec.shear_stiffening >= 0) || !std::isfinite(spec.shear_stiffening))
    return "shear_stiffening must be >= 0 (got " + fmt(spec.shear_stiffening) + ")";
  if (spec.shear_stiffening > 0 && !(spec.shear_modulus > 0))
    return "shear_stiffening needs shear_modulus > 0 (it stiffens the shear term)";

  // Element volumes, lumped masses and raw springs with volume shares.
  std::vector<double> mass(nn, 0.0);
  std::map<std::pair<int, int>, RawSpring> springs;
  std::vector<std::vector<int>> tet_regions(mesh.tetrahedra.size()),
      hex_regions(mesh.hexahedra.size());
  for (size_t r = 0; r < mesh.regions.size(); ++r) {
    for (int t : mesh.regions[r].tetrahedra) tet_regions.at(t).push_back(static_cast<int>(r));
    for (int h : mesh.regions[r].hexahedra) hex_regions.at(h).push_back(static_cast<int>(r));
  }
  int used_families = 0;
  for (const auto& g : spec.groups) used_families |= g.families;
  auto add_spring = [&](int a, int b, int family, double share, const std::vector<int>& regs) {
    if (a == b) return;
    auto key = std::minmax(a, b);
    auto [it, inserted] = springs.try_emplace({key.first, key.second},
                                              RawSpring{key.first, key.second, family, 0, {}});
    it->second.volume_share += share;
    for (int r : regs)
      if (std::find(it->second.regions.begin(), it->second.regions.end(), r) ==
          it->second.regions.end())
        it->second.regions.push_back(r);
  };
  for (size_t e = 0; e < mesh.tetrahedra.size(); ++e) {
    const auto& t = mesh.tetrahedra[e];
    const double v = std::abs(
        tet_volume(mesh.nodes[t[0]], mesh.nodes[t[1]], mesh.nodes[t[2]], mesh.nodes[t[3]]));
    for (int k = 0; k < 4; ++k) mass[t[k]] += spec.density * v / 4;
    for (int a = 0; a < 4; ++a)
      for (int b = a + 1; b < 4; ++b) add_spring(t[a], t[b], kEdge, v / 6, tet_regions[e]);
  }
  int per_hex = 0;
  for (int a = 0; a < 8; ++a)
    for (int b = a + 1; b < 8; ++b) per_hex += (pair_family(a, b) & used_families) != 0;
  for (size_t e = 0; e < mesh.hexahedra.size(); ++e) {
    const auto& h = mesh.hexahedra[e];
    const double v = std::abs(hex_volume(mesh, h));
    for (int k = 0; k < 8; ++k) mass[h[k]] += spec.density * v / 8;
    for (int a = 0; a < 8; ++a)
      for (int b = a + 1; b < 8; ++b) {
        const int fam = pair_family(a, b);
        if (fam & used_families) add_spring(h[a], h[b], fam, v / per_hex, hex_regions[e]);
      }
  }

  // Assign springs to groups (first match), sorted by group.
  std::vector<std::vector<const RawSpring*>> by_group(spec.groups.size());
  int unmatched = 0;
  for (const auto& [key, s] : springs) {
    const Vec3 dir = mesh.nodes[s.j] - mesh.nodes[s.i];
    if (dir.norm() <= 0) {
      return "zero-length spring between nodes " + std::to_string(s.i) + " and " +
             std::to_string(s.j) + " (duplicate nodes: repair the mesh first)";
    }
    bool placed = false;
    for (size_t g = 0; g < spec.groups.size() && !placed; ++g) {
      const auto& gs = spec.groups[g];
      if (!(gs.families & s.family)) continue;
      if (!axis_match(gs, dir)) continue;
      if (!gs.regions.empty()) {
        bool in = false;
        for (int r : s.regions)
          for (const auto& name : gs.regions) in |= mesh.regions[r].name == name;
        if (!in) continue;
      }
      by_group[g].push_back(&s);
      placed = true;
    }
    unmatched += !placed;
  }
  for (size_t g = 0; g < spec.groups.size(); ++g)
    if (by_group[g].empty())
      return "spring group \"" + spec.groups[g].name + "\" matches no spring";
  if (unmatched > 0)
    return std::to_string(unmatched) + " springs match no spring group (add a catch-all group)";
  order_springs_in_runs(by_group);

  Model m;
  m.rest = mesh.nodes;
  m.mass = mass;
  m.fixed.assign(nn, 0);
  m.tetrahedra = mesh.tetrahedra;
  m.hexahedra = mesh.hexahedra;
  m.shear_modulus = spec.shear_modulus;
  m.shear_stiffening = spec.shear_stiffening;
  if (m.shear_modulus > 0) {
    std::array<Vec3, 8> x;
    std::array<Vec3, 64> b;
    double v0[8];
    for (size_t e = 0; e < m.tetrahedra.size(); ++e) {
      for (int a = 0; a < 4; ++a) x[a] = mesh.nodes[m.tetrahedra[e][a]];
      const double v = tet_shape_gradients(x.data(), b.data());
      if (!(std::abs(v) > 0) || !b[0].allFinite())
        return "shear_modulus: tetrahedron " + std::to_string(e) + " has no volume";
      m.shear_b.insert(m.shear_b.end(), b.begin(), b.begin() + 4);
      m.shear_v0.push_back(std::abs(v));
    }
    for (size_t e = 0; e < m.hexahedra.size(); ++e) {
      for (int a = 0; a < 8; ++a) x[a] = mesh.nodes[m.hexahedra[e][a]];
      if (!hex_shape_gradients(x.data(), b.data(), v0))
        return "shear_modulus: hexahedron " + std::to_string(e) + " is degenerate";
      m.shear_b.insert(m.shear_b.end(), b.begin(), b.end());
      for (int a = 0; a < 8; ++a)
        for (int j = 0; j < 3; ++j)
          for (int q = 0; q < 8; ++q) m.hex_b.push_back(b[8 * q + a][j]);
      for (double v : v0) m.shear_v0.push_back(std::abs(v));
    }
  }
  m.bulk_modulus = spec.bulk_modulus;
  if (m.bulk_modulus > 0) {
    // An element of no volume has no J; a hundred-millionth of the mean is taken for none.
    Vec3 g[8];
    double total = 0;
    for (const auto& t : m.tetrahedra) {
      m.tet_rest_volume.push_back(element_volume(mesh.nodes, t.data(), 4, g));
      total += std::abs(m.tet_rest_volume.back());
    }
    m.spread_modulus = spec.spread_modulus;
    for (const auto& h : m.hexahedra) {
      double vq[8];
      m.hex_rest_volume.push_back(element_volume(mesh.nodes, h.data(), 8, g, vq));
      total += std::abs(m.hex_rest_volume.back());
      m.hex_rest_gauss.insert(m.hex_rest_gauss.end(), vq, vq + 8);
    }
    const double tiny = 1e-8 * total / (m.tetrahedra.size() + m.hexahedra.size());
    for (size_t e = 0; e < m.tet_rest_volume.size(); ++e)
      if (!(std::abs(m.tet_rest_volume[e]) > tiny))
        return "bulk_modulus: tetrahedron " + std::to_string(e) + " has no volume";
    for (size_t e = 0; e < m.hex_rest_volume.size(); ++e)
      if (!(std::abs(m.hex_rest_volume[e]) > tiny))
        return "bulk_modulus: hexahedron " + std::to_string(e) + " has no volume";
  }
  m.options = spec.options;
  m.mapping = spec.mapping;
  m.probes = spec.probes;
  m.planes = spec.planes;
  for (size_t g = 0; g < spec.groups.size(); ++g) {
    SpringGroup grp;
    grp.name = spec.groups[g].name;
    grp.card = spec.groups[g].card;
    if (grp.card.law == LawKind::kConical) {
      const double k0 = ConicalLaw(grp.card.conical).k0();
      grp.law.emplace(grp.card.conical, grp.card.stiffness_cap * k0);
    }
    grp.viscous = grp.card.damping > 0 || grp.card.maxwell_k > 0;
    grp.begin = m.num_springs();
    const double L = grp.card.free_length();
    for (const RawSpring* s : by_group[g]) {
      const double l0 = (mesh.nodes[s->j] - mesh.nodes[s->i]).norm();
      m.spring_i.push_back(s->i);
      m.spring_j.push_back(s->j);
      m.rest_length.push_back(l0);
      if (spec.mapping == Mapping::kStrain) {
        m.deflection_scale.push_back(L / l0);
        m.force_scale.push_back(s->volume_share / (l0 * L * L));
      } else {
        m.deflection_scale.push_back(1.0);
        m.force_scale.push_back(1.0);
      }
    }
    grp.end = m.num_springs();
    m.groups.push_back(std::move(grp));
  }

  // Nodes that no element references have no mass: fix them so they never move.
  for (int i = 0; i < nn; ++i)
    if (!(mass[i] > 0)) m.fixed[i] = 7;
  // Fixed selectors.
  for (size_t k = 0; k < spec.fixed.size(); ++k) {
    const auto& f = spec.fixed[k];
    int count = 0;
    if (f.axes < 1 || f.axes > 7)
      return "fixed selector " + std::to_string(k) + ": axes must be 1..7";
    NodeMotion motion;
    auto fix = [&](int i) {
      ++count;
      m.fixed[i] |= static_cast<std::uint8_t>(f.axes);
      if (!f.path_time.empty()) motion.nodes.push_back(i);
    };
    switch (f.kind) {
      case FixedSelector::Kind::kPlane: {
        const Vec3 n = f.normal.normalized();
        for (int i = 0; i < nn; ++i)
          if (std::abs(n.dot(mesh.nodes[i]) - f.offset) <= f.tolerance) fix(i);
        break;
      }
      case FixedSelector::Kind::kBox:
        for (int i = 0; i < nn; ++i)
          if ((mesh.nodes[i].array() >= f.box_min.array()).all() &&
              (mesh.nodes[i].array() <= f.box_max.array()).all())
            fix(i);
        break;
      case FixedSelector::Kind::kRegion: {
        bool found = false;
        for (const auto& r : mesh.regions) {
          if (r.name != f.region) continue;
          found = true;
          for (int t : r.tetrahedra)
            for (int i : mesh.tetrahedra[t]) fix(i);
          for (int h : r.hexahedra)
            for (int i : mesh.hexahedra[h]) fix(i);
        }
        if (!found)
          return "fixed selector " + std::to_string(k) + ": no region \"" + f.region + "\"";
        break;
      }
      case FixedSelector::Kind::kNodes:
        for (int i : f.nodes) {
          if (i < 0 || i >= nn)
            return "fixed selector " + std::to_string(k) + ": node " + std::to_string(i) +
                   " out of range [0, " + std::to_string(nn) + ")";
          fix(i);
        }
        break;
    }
    if (count == 0 && f.kind != FixedSelector::Kind::kNodes)
      return "fixed selector " + std::to_string(k) + " matches no node";
    if (!f.path_time.empty()) {
      if (std::string e = make_motion(f.path_time, f.path_displacement, f.axes, &motion);
          !e.empty())
        return "fixed selector " + std::to_string(k) + ": " + e;
      m.motions.push_back(std::move(motion));
    }
  }
  if (std::string e = bond_plates(mesh.nodes, &m); !e.empty()) return e;
  m.inv_mass.resize(nn);
  m.free_axes.resize(nn);
  for (int i = 0; i < nn; ++i) {
    m.inv_mass[i] = m.fixed[i] == 7 ? 0.0 : 1.0 / m.mass[i];
    for (int a = 0; a < 3; ++a) m.free_axes[i][a] = (m.fixed[i] >> a) & 1 ? 0.0 : 1.0;
  }

  m.surface = boundary_triangles(mesh);
  m.normal.assign(nn, Vec3::Zero());
  for (const auto& t : m.surface) {
    const Vec3 an =
        (mesh.nodes[t[1]] - mesh.nodes[t[0]]).cross(mesh.nodes[t[2]] - mesh.nodes[t[0]]);
    for (int k : t) m.normal[k] += an;  // area-weighted
  }
  for (Vec3& n : m.normal)
    if (n.norm() > 0) n.normalize();
  std::set<int> sn;
  for (const auto& t : m.surface) sn.insert(t.begin(), t.end());
  m.surface_nodes.assign(sn.begin(), sn.end());

  // Plate penalties default to a fraction of the explicit stability limit of the lightest
  // surface node, so that contact alone never destabilises a step.
  double m_min = std::numeric_limits<double>::infinity();
  for (int i : m.surface_nodes)
    if (m.mass[i] > 0) m_min = std::min(m_min, m.mass[i]);
  const double h = m.options.dt / m.options.substeps;
  const double k_default = 0.2 * m_min / (h * h);
  // Probes: the contact layer and the coupling default to the tissue's contact modulus
  // (core/contact.h), not to the step.
  m.contact_modulus = contact_modulus(m);
  // Multi-rate serving: the node penalty from the tissue, not the step (the body's step is not
  // the tick's): ten times a node's share of the tissue, E* times the median spring length, so
  // that the penalty's give is about a tenth of the tissue's under the probe.
  auto multirate_node_stiffness = [&m] {
    return m.rest_length.empty() ? 1.0 : 10 * tissue_share_stiffness(m);
  };
  for (size_t k = 0; k < m.probes.size(); ++k) {
    ProbeSpec& p = m.probes[k];
    const std::string which = "probe " + std::to_string(k) + ": ";
    if (!(p.radius > 0) || !std::isfinite(p.radius)) return which + "radius must be > 0 m";
    if (!(p.stiffness >= 0) || !std::isfinite(p.stiffness))
      return which + "stiffness must be >= 0 Pa/m (0: from the tissue)";
    if (!(p.coupling >= 0) || !std::isfinite(p.coupling))
      return which + "coupling must be >= 0 N/m (0: from the tissue)";
    if (!(p.friction >= 0) || !std::isfinite(p.friction))
      return which + "friction must be >= 0 (a Coulomb coefficient)";
    if (!(p.axis.norm() > 0) || !p.axis.allFinite()) return which + "axis must be nonzero";
    p.axis.normalize();
    if (m.options.body_rate_hz > 0 && p.friction > 0)
      return which + "friction is not served multi-rate (solver body_rate_hz): set friction 0";
    if (p.shape != ToolShape::kSphere && p.contact == ContactModel::kNodes)
      return which + "a punch or plane needs contact: SURFACE";
    if (p.bonded && p.contact == ContactModel::kNodes)
      return which + "bonded needs contact: SURFACE";
    if (p.bonded && p.friction > 0)
      return which + "bonded and friction exclude each other (a bonded tool does not slip)";
    if (p.bonded && m.options.body_rate_hz > 0)
      return which + "a bonded tool is not served multi-rate (solver body_rate_hz)";
    if (p.bonded && m.options.active_region)
      return which + "a bonded tool needs every node integrated (no solver.active_region)";
    // A plane touches the body wherever it meets it: the region of the active region and of the
    // multi-rate tick is a ball about the tool.
    if (p.shape == ToolShape::kPlane && m.options.body_rate_hz > 0)
      return which +
             "a PLANE tool is not served multi-rate (solver body_rate_hz): its contact is "
             "not local";
    if (p.shape == ToolShape::kPlane && m.options.active_region)
      return which +
             "a PLANE tool needs every node integrated (no solver.active_region): its "
             "contact is not local";
    if (p.contact == ContactModel::kNodes && p.stiffness <= 0)
      p.stiffness = m.options.body_rate_hz > 0 ? multirate_node_stiffness() : k_default;
  }
  for (size_t k = 0; k < m.planes.size(); ++k) {
    PlaneSpec& p = m.planes[k];
    if (!(p.normal.norm() > 0)) return "plane normal must be nonzero";
    if (!(p.friction >= 0) || !std::isfinite(p.friction))
      return "plane " + std::to_string(k) + ": friction must be >= 0 (a Coulomb coefficient)";
    p.normal.normalize();
    if (p.stiffness <= 0) p.stiffness = k_default;
  }
  *out = std::move(m);
  return {};
}

Model make_spring_pair(const SpringCard& card, double l0, double mass,
                       const SolverOptions& options) {
  Model m;
  m.rest = {Vec3::Zero(), Vec3(0, 0, l0)};
  m.mass = {mass, mass};
  m.fixed = {7, 3};
  m.inv_mass = {0.0, 1.0 / mass};
  m.free_axes = {Vec3::Zero(), Vec3(0, 0, 1)};
  m.normal = {Vec3::Zero(), Vec3::Zero()};
  m.spring_i = {0};
  m.spring_j = {1};
  m.rest_length = {l0};
  m.force_scale = {1.0};
  m.deflection_scale = {1.0};
  SpringGroup g;
  g.name = "spring";
  g.card = card;
  if (card.law == LawKind::kConical)
    g.law.emplace(card.conical, card.stiffness_cap * ConicalLaw(card.conical).k0());
  g.viscous = card.damping > 0 || card.maxwell_k > 0;
  g.begin = 0;
  g.end = 1;
  m.groups = {g};
  m.options = options;
  m.mapping = Mapping::kRaw;
  return m;
}

State make_state(const Model& model) {
  State s;
  s.x = model.rest;
  s.v.assign(model.rest.size(), Vec3::Zero());
  if (model.options.bdf2) {
    s.x_prev = s.x;
    s.v_prev = s.v;
  }
  s.maxwell.assign(model.rest_length.size(), 0.0);
  s.probes.resize(model.probes.size());
  for (size_t k = 0; k < model.probes.size(); ++k) {
    s.probes[k].radius = model.probes[k].radius;
    if (model.probes[k].bonded) {
      s.probes[k].bond.assign(model.rest.size(), Vec3::Constant(std::nan("")));
      s.probes[k].bond_area.assign(model.rest.size(), 0.0);
      s.probes[k].covered.assign(model.rest.size(), 0.0);
      s.probes[k].bonded.reserve(model.surface_nodes.size());
    }
  }
  s.planes.resize(model.planes.size());
  for (size_t k = 0; k < model.planes.size(); ++k) {
    s.planes[k].offset = model.planes[k].offset;
    if (model.planes[k].friction > 0)
      s.planes[k].stick = model.rest;  // the nodes where they are (the plate at its start)
  }
  // Active region: everything awake until the first tick chooses. Chunk entries are sized for the
  // most a layout can have (one spring each).
  const size_t nn = model.rest.size(), ns = model.rest_length.size();
  RegionState& r = s.region;
  r.awake.assign(nn, 1);
  r.wake.assign(nn, 0);
  r.active.assign(ns, 0);
  r.active_scale = model.force_scale;
  r.spring_on.assign(ns, 1);
  r.chunk_awake.assign(ns, 1);
  r.chunk_slow.assign(ns, 0);
  r.chunk_active_count.assign(ns, 0);
  r.awake_list.reserve(nn);
  r.border.reserve(nn);
  r.in_border.assign(nn, 0);
  r.slow.reserve(ns);
  r.slow_scale.assign(ns, 0.0);
  r.flipped.reserve(nn);
  r.impulse.assign(nn, Vec3::Zero());
  for (auto* f : {&r.far_fx, &r.far_fy, &r.far_fz}) f->assign(nn, 0.0);
  return s;
}

}  // namespace conica
