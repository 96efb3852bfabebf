#include "lab/fem_reference.h"

#include <Eigen/Dense>
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <limits>
#include <map>
#include <set>
#include <sstream>
#include <tuple>

namespace conica::lab {

namespace {

// Parametric corners of a hexahedron (VTK order) and the corner pairs of its 12 edges in
// CalculiX's midside order.
constexpr int kCorner[8][3] = {{-1, -1, -1}, {1, -1, -1}, {1, 1, -1}, {-1, 1, -1},
                               {-1, -1, 1},  {1, -1, 1},  {1, 1, 1},  {-1, 1, 1}};
constexpr int kEdge[12][2] = {{0, 1}, {1, 2}, {2, 3}, {3, 0}, {4, 5}, {5, 6},
                              {6, 7}, {7, 4}, {0, 4}, {1, 5}, {2, 6}, {3, 7}};

Vec3 trilinear(const Mesh& mesh, const std::array<int, 8>& h, const Vec3& xi) {
  Vec3 x = Vec3::Zero();
  for (int a = 0; a < 8; ++a) {
    const double w = (1 + kCorner[a][0] * xi.x()) * (1 + kCorner[a][1] * xi.y()) *
                     (1 + kCorner[a][2] * xi.z()) / 8;
    x += w * mesh.nodes[h[a]];
  }
  return x;
}

struct Bounds {
  Vec3 lo, hi;
  double tol;
};
Bounds bounds(const std::vector<Vec3>& nodes) {
  Bounds b{nodes.at(0), nodes.at(0), 0};
  for (const Vec3& x : nodes) {
    b.lo = b.lo.cwiseMin(x);
    b.hi = b.hi.cwiseMax(x);
  }
  b.tol = 1e-6 * (b.hi - b.lo).norm();
  return b;
}

}  // namespace

FemMesh make_c3d20_mesh(const Mesh& mesh, int refine, bool quarter) {
  FemMesh out;
  const Bounds b = bounds(mesh.nodes);
  out.centre = 0.5 * (b.lo + b.hi);
  const double q = b.tol;
  auto key = [q](const Vec3& x) {
    return std::make_tuple(std::lround(x.x() / q), std::lround(x.y() / q), std::lround(x.z() / q));
  };
  if (quarter) {
    // Mirror symmetry about x = cx and y = cy, node by node (to the merge tolerance, 10 q).
    std::set<std::tuple<long, long, long>> have;
    const double q10 = 10 * q;
    auto coarse = [q10](const Vec3& x) {
      return std::make_tuple(std::lround(x.x() / q10), std::lround(x.y() / q10),
                             std::lround(x.z() / q10));
    };
    for (const Vec3& x : mesh.nodes) have.insert(coarse(x));
    // The symmetry planes must run between elements, not through them.
    for (const auto& h : mesh.hexahedra) {
      Vec3 c = Vec3::Zero();
      for (int a : h) c += mesh.nodes[a] / 8;
      if (std::abs(c.x() - out.centre.x()) <= q10 || std::abs(c.y() - out.centre.y()) <= q10)
        quarter = false;
    }
    for (const Vec3& x : mesh.nodes) {
      if (!quarter) break;
      const Vec3 mx(2 * out.centre.x() - x.x(), x.y(), x.z());
      const Vec3 my(x.x(), 2 * out.centre.y() - x.y(), x.z());
      if (!have.count(coarse(mx)) || !have.count(coarse(my))) {
        quarter = false;
        break;
      }
    }
  }
  out.quarter = quarter;
  std::map<std::tuple<long, long, long>, int> index;
  auto node = [&](const Vec3& x) {
    auto [it, added] = index.emplace(key(x), static_cast<int>(out.nodes.size()));
    if (added) out.nodes.push_back(x);
    return it->second;
  };
  const int r = std::max(1, refine);
  for (const auto& h : mesh.hexahedra) {
    Vec3 c = Vec3::Zero();
    for (int a : h) c += mesh.nodes[a] / 8;
    if (quarter && (c.x() < out.centre.x() || c.y() < out.centre.y())) continue;
    for (int i = 0; i < r; ++i)
      for (int j = 0; j < r; ++j)
        for (int k = 0; k < r; ++k) {
          // Child's parametric box [lo, lo + 2/r] in each direction.
          const Vec3 lo(-1 + 2.0 * i / r, -1 + 2.0 * j / r, -1 + 2.0 * k / r);
          const double s = 1.0 / r;  // half-width in parametric units
          std::array<int, 20> e{};
          auto at = [&](const Vec3& child) {  // child coordinates in [-1, 1]^3
            return node(trilinear(mesh, h, lo + (child + Vec3::Ones()) * s));
          };
          Vec3 corners[8];
          for (int a = 0; a < 8; ++a) {
            corners[a] = Vec3(kCorner[a][0], kCorner[a][1], kCorner[a][2]);
            e[a] = at(corners[a]);
          }
          for (int m = 0; m < 12; ++m)
            e[8 + m] = at(0.5 * (corners[kEdge[m][0]] + corners[kEdge[m][1]]));
          out.elements.push_back(e);
        }
  }
  return out;
}

namespace {

// The distinct values of coordinate d of the nodes, ascending, merged within tol.
std::vector<double> grid_planes(const std::vector<Vec3>& nodes, int d, double tol) {
  std::vector<double> v;
  for (const Vec3& x : nodes) v.push_back(x[d]);
  std::sort(v.begin(), v.end());
  std::vector<double> out;
  for (double x : v)
    if (out.empty() || x - out.back() > tol) out.push_back(x);
  return out;
}

// The planes of p (ascending) kept on each side of c (only below it when below_only): those
// within keep of c, then outward every plane at most twice the previous cell's width from the
// last kept one; the outermost plane always.
std::vector<double> thin_planes(const std::vector<double>& p, double c, double keep, double tol,
                                bool below_only) {
  std::vector<double> out;
  for (int side : {-1, 1}) {
    if (below_only && side > 0) continue;
    std::vector<double> q;  // this side, nearest first (c itself, if a plane, on the lower side)
    for (double x : p)
      if (side * (x - c) > tol || (side < 0 && std::abs(x - c) <= tol)) q.push_back(x);
    std::sort(q.begin(), q.end(),
              [c](double a, double b) { return std::abs(a - c) < std::abs(b - c); });
    std::vector<double> kept;
    for (double x : q)
      if (kept.empty() || std::abs(x - c) <= keep + tol) kept.push_back(x);
    size_t next = kept.size();
    while (next < q.size()) {
      const double last = kept.back();
      const double gap =
          kept.size() >= 2 ? std::abs(last - kept[kept.size() - 2]) : std::abs(q[next] - last);
      size_t pick = next;
      while (pick + 1 < q.size() && std::abs(q[pick + 1] - last) <= 2 * gap + tol) ++pick;
      kept.push_back(q[pick]);
      next = pick + 1;
    }
    out.insert(out.end(), kept.begin(), kept.end());
  }
  if (below_only)
    for (double x : p)
      if (x - c > tol) out.push_back(x);
  std::sort(out.begin(), out.end());
  out.erase(std::unique(out.begin(), out.end(),
                        [tol](double a, double b) { return std::abs(a - b) <= tol; }),
            out.end());
  return out;
}

}  // namespace

std::string coarsen_box_lattice(const Mesh& mesh, const Vec3& axis, double keep, Mesh* out) {
  if (mesh.nodes.empty() || mesh.hexahedra.empty()) return "the mesh has no hexahedra";
  const Bounds b = bounds(mesh.nodes);
  std::vector<double> p[3];
  for (int d = 0; d < 3; ++d) p[d] = grid_planes(mesh.nodes, d, b.tol);
  const size_t nx = p[0].size(), ny = p[1].size(), nz = p[2].size();
  const char* not_box = "the body is not a full box lattice (a tensor grid of axis-aligned cells)";
  if (nx < 2 || ny < 2 || nz < 2 || mesh.nodes.size() != nx * ny * nz ||
      mesh.hexahedra.size() != (nx - 1) * (ny - 1) * (nz - 1))
    return not_box;
  double volume = 0;
  for (const auto& h : mesh.hexahedra) {
    Vec3 lo = mesh.nodes[h[0]], hi = lo;
    for (int a : h) {
      lo = lo.cwiseMin(mesh.nodes[a]);
      hi = hi.cwiseMax(mesh.nodes[a]);
    }
    volume += (hi - lo).prod();
  }
  const double box = (b.hi - b.lo).prod();
  if (std::abs(volume - box) > 1e-9 * box) return not_box;
  const std::vector<double> xs = thin_planes(p[0], axis.x(), keep, b.tol, false);
  const std::vector<double> ys = thin_planes(p[1], axis.y(), keep, b.tol, false);
  const std::vector<double> zs = thin_planes(p[2], b.hi.z(), keep, b.tol, true);
  *out = Mesh{};
  auto id = [&](size_t i, size_t j, size_t k) {
    return static_cast<int>((k * ys.size() + j) * xs.size() + i);
  };
  for (double z : zs)
    for (double y : ys)
      for (double x : xs) out->nodes.emplace_back(x, y, z);
  for (size_t k = 0; k + 1 < zs.size(); ++k)
    for (size_t j = 0; j + 1 < ys.size(); ++j)
      for (size_t i = 0; i + 1 < xs.size(); ++i) {
        std::array<int, 8> h{};
        for (int a = 0; a < 8; ++a)
          h[a] = id(i + (kCorner[a][0] > 0), j + (kCorner[a][1] > 0), k + (kCorner[a][2] > 0));
        out->hexahedra.push_back(h);
      }
  return {};
}

double yeoh_uniaxial_stress(const YeohLaw& l, double e) {
  const double lam = 1 - e;
  const double i1 = lam * lam + 2 / lam - 3;
  // Tension positive: 2 (lam - lam^-2) dW/dI1; compression positive: its negative.
  return -2 * (lam - 1 / (lam * lam)) * (l.c10 + 2 * l.c20 * i1 + 3 * l.c30 * i1 * i1);
}

std::string fit_yeoh(const std::vector<double>& strain, const std::vector<double>& stress,
                     double poisson, double min_strain, YeohLaw* law) {
  if (!(poisson < 0.5) || !(poisson > -1)) return "Poisson ratio must lie in (-1, 1/2)";
  std::vector<int> use;
  double emax = 0;
  for (size_t k = 0; k < strain.size() && k < stress.size(); ++k)
    if (strain[k] >= min_strain && strain[k] < 1 && stress[k] > 0 && std::isfinite(stress[k])) {
      use.push_back(static_cast<int>(k));
      emax = std::max(emax, strain[k]);
    }
  if (use.size() < 3) return "fewer than three points to fit the hyperelastic law";
  Eigen::MatrixXd a(use.size(), 3);
  Eigen::VectorXd y(use.size());
  for (size_t r = 0; r < use.size(); ++r) {
    const double e = strain[use[r]], lam = 1 - e;
    const double i1 = lam * lam + 2 / lam - 3, g = -2 * (lam - 1 / (lam * lam));
    const double w = 1 / stress[use[r]];  // relative error
    a(r, 0) = w * g;
    a(r, 1) = w * g * 2 * i1;
    a(r, 2) = w * g * 3 * i1 * i1;
    y(r) = 1;
  }
  const Eigen::Vector3d c = a.colPivHouseholderQr().solve(y);
  law->c10 = c(0);
  law->c20 = c(1);
  law->c30 = c(2);
  if (!(law->c10 > 0)) return "the fitted C10 is not positive";
  for (int k = 1; k <= 100; ++k) {
    const double e0 = emax * (k - 1) / 100, e1 = emax * k / 100;
    if (!(yeoh_uniaxial_stress(*law, e1) > yeoh_uniaxial_stress(*law, e0)))
      return "the fitted law softens in compression before the largest fitted strain";
  }
  const double mu = 2 * law->c10;
  const double k_bulk = 2 * mu * (1 + poisson) / (3 * (1 - 2 * poisson));
  law->d1 = 2 / k_bulk;
  return {};
}

namespace {

void write_set(std::ostringstream& o, const std::string& name, const std::vector<int>& nodes) {
  o << "*NSET, NSET=" << name << "\n";
  for (size_t k = 0; k < nodes.size(); ++k)
    o << nodes[k] + 1 << ((k + 1) % 12 == 0 || k + 1 == nodes.size() ? ",\n" : ", ");
}

}  // namespace

std::string write_calculix_deck(const FemMesh& mesh, const YeohLaw& law, const FemCase& c,
                                const std::string& title, std::string* deck, int* driven) {
  if (mesh.nodes.empty() || mesh.elements.empty()) return "the mesh has no elements";
  const Bounds b = bounds(mesh.nodes);
  const Vec3 ctr = mesh.centre;
  std::vector<int> top, base, symx, symy, drive;
  for (int i = 0; i < static_cast<int>(mesh.nodes.size()); ++i) {
    const Vec3& x = mesh.nodes[i];
    if (x.z() >= b.hi.z() - b.tol) top.push_back(i);
    if (x.z() <= b.lo.z() + b.tol) base.push_back(i);
    if (mesh.quarter && std::abs(x.x() - ctr.x()) <= b.tol) symx.push_back(i);
    if (mesh.quarter && std::abs(x.y() - ctr.y()) <= b.tol) symy.push_back(i);
  }
  if (c.test == FemCase::Test::kCompress) {
    drive = top;
  } else {
    // Whole element faces: a quadratic face driven at some of its nodes only is bent into a
    // spike by the shape functions (and its elements invert within the first millimetre).
    std::set<int> under;
    for (const auto& e : mesh.elements) {
      const int face[8] = {e[4], e[5], e[6], e[7], e[12], e[13], e[14], e[15]};  // top (5-8)
      bool on_top = true;
      for (int a : face) on_top = on_top && mesh.nodes[a].z() >= b.hi.z() - b.tol;
      // The face's centre (serendipity: corners -1/4 each, midside nodes +1/2 each).
      Vec3 m = Vec3::Zero();
      for (int a = 0; a < 4; ++a) m += -0.25 * mesh.nodes[face[a]] + 0.5 * mesh.nodes[face[4 + a]];
      if (on_top && std::hypot(m.x() - ctr.x(), m.y() - ctr.y()) <= c.punch_radius + b.tol)
        under.insert(face, face + 8);
    }
    drive.assign(under.begin(), under.end());
    if (drive.empty())
      return "no element face of the top lies under the punch (radius smaller than half a cell)";
  }
  if (driven) *driven = static_cast<int>(drive.size());
  const bool drive_held = c.test == FemCase::Test::kCompress ? c.bonded : c.punch_bonded;
  const bool base_clamped = c.bonded;
  // Rigid motion of a full model with a sliding base: the base node nearest the axis held in x
  // and y, the nearest one beside it in y.
  std::vector<int> pin_xy, pin_y;
  if (!mesh.quarter && !base_clamped && !(c.test == FemCase::Test::kCompress && drive_held)) {
    const Vec3 bc(ctr.x(), ctr.y(), b.lo.z());
    const Vec3 side = bc + Vec3(0.25 * (b.hi.x() - b.lo.x()), 0, 0);
    int pa = base.front(), pb = base.front();
    for (int i : base) {
      if ((mesh.nodes[i] - bc).norm() < (mesh.nodes[pa] - bc).norm()) pa = i;
      if ((mesh.nodes[i] - side).norm() < (mesh.nodes[pb] - side).norm()) pb = i;
    }
    pin_xy = {pa};
    if (pb != pa) pin_y = {pb};
  }
  std::ostringstream o;
  o.precision(12);
  o << "** " << title << "\n*HEADING\n" << title << "\n*NODE, NSET=NALL\n";
  for (size_t i = 0; i < mesh.nodes.size(); ++i)
    o << i + 1 << ", " << mesh.nodes[i].x() << ", " << mesh.nodes[i].y() << ", "
      << mesh.nodes[i].z() << "\n";
  o << "*ELEMENT, TYPE=" << (c.full_integration ? "C3D20" : "C3D20R") << ", ELSET=EALL\n";
  for (size_t e = 0; e < mesh.elements.size(); ++e) {
    o << e + 1;  // at most 16 entries a line: the number and 15 nodes, then 5
    for (int a = 0; a < 20; ++a) o << (a == 15 ? ",\n" : ", ") << mesh.elements[e][a] + 1;
    o << "\n";
  }
  write_set(o, "NDRIVE", drive);
  write_set(o, "NBASE", base);
  if (!symx.empty()) write_set(o, "NSYMX", symx);
  if (!symy.empty()) write_set(o, "NSYMY", symy);
  if (!pin_xy.empty()) write_set(o, "NPINXY", pin_xy);
  if (!pin_y.empty()) write_set(o, "NPINY", pin_y);
  // D2 and D3 (the (J - 1)^4 and (J - 1)^6 terms) are written as 1e30, i.e. absent: given as 0,
  // ccx 2.20 does not drop them. Its Yeoh law with C20 = C30 = 0 then differs from its own
  // NEO HOOKE law of the same C10 and D1 (4.7 % stiffer under a flat punch 0.05 mm deep, equal
  // under homogeneous compression) and Newton converges only linearly.
  o << "*MATERIAL, NAME=SILICONE\n*HYPERELASTIC, YEOH\n"
    << law.c10 << ", " << law.c20 << ", " << law.c30 << ", " << law.d1 << ", 1e30, 1e30\n"
    << "*SOLID SECTION, ELSET=EALL, MATERIAL=SILICONE\n*BOUNDARY\n";
  o << (base_clamped ? "NBASE, 1, 3\n" : "NBASE, 3, 3\n");
  if (!symx.empty()) o << "NSYMX, 1, 1\n";
  if (!symy.empty()) o << "NSYMY, 2, 2\n";
  if (!pin_xy.empty()) o << "NPINXY, 1, 2\n";
  if (!pin_y.empty()) o << "NPINY, 2, 2\n";
  if (drive_held) o << "NDRIVE, 1, 2\n";
  const double inc = 1.0 / std::max(1, c.increments);
  const double first = c.test == FemCase::Test::kIndent ? inc / 4 : inc;
  o << "*STEP, NLGEOM, INC=10000\n*STATIC\n"
    << first << ", 1., " << inc * 1e-4 << ", " << inc << "\n"
    << "*BOUNDARY\nNDRIVE, 3, 3, " << -c.travel << "\n"
    << "*NODE PRINT, NSET=NDRIVE, TOTALS=ONLY\nRF\n*END STEP\n";
  *deck = o.str();
  return {};
}

std::string read_calculix_totals(const std::string& dat, const FemCase& c, bool quarter,
                                 std::vector<FemPoint>* curve) {
  curve->assign(1, FemPoint{});
  std::istringstream in(dat);
  std::string line;
  while (std::getline(in, line)) {
    if (line.find("total force") == std::string::npos || line.find("NDRIVE") == std::string::npos)
      continue;
    const size_t at = line.rfind("time");
    if (at == std::string::npos) continue;
    const double t = std::strtod(line.c_str() + at + 4, nullptr);
    std::string values;
    while (std::getline(in, values))
      if (values.find_first_not_of(" \t\r") != std::string::npos) break;
    double f[3] = {0, 0, 0};
    if (std::sscanf(values.c_str(), "%lf %lf %lf", &f[0], &f[1], &f[2]) != 3)
      return "ccx output: no three force components after \"" + line + "\"";
    curve->push_back({t * c.travel, (quarter ? 4.0 : 1.0) * -f[2]});
  }
  if (curve->size() < 2) return "ccx output: no total force of set NDRIVE (did ccx converge?)";
  return {};
}

}  // namespace conica::lab
