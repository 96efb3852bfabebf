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
    for (int i : top)
      if (std::hypot(mesh.nodes[i].x() - ctr.x(), mesh.nodes[i].y() - ctr.y()) <=
          c.punch_radius + b.tol)
        drive.push_back(i);
    if (drive.empty()) return "no node of the top face lies under the punch (radius too small)";
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
  o << "*MATERIAL, NAME=SILICONE\n*HYPERELASTIC, YEOH\n"
    << law.c10 << ", " << law.c20 << ", " << law.c30 << ", " << law.d1 << ", 0., 0.\n"
    << "*SOLID SECTION, ELSET=EALL, MATERIAL=SILICONE\n*BOUNDARY\n";
  o << (base_clamped ? "NBASE, 1, 3\n" : "NBASE, 3, 3\n");
  if (!symx.empty()) o << "NSYMX, 1, 1\n";
  if (!symy.empty()) o << "NSYMY, 2, 2\n";
  if (!pin_xy.empty()) o << "NPINXY, 1, 2\n";
  if (!pin_y.empty()) o << "NPINY, 2, 2\n";
  if (drive_held) o << "NDRIVE, 1, 2\n";
  const double inc = 1.0 / std::max(1, c.increments);
  o << "*STEP, NLGEOM, INC=10000\n*STATIC\n"
    << inc << ", 1., " << inc * 1e-4 << ", " << inc << "\n"
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
