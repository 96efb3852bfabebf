#include "core/volume.h"

#include <Eigen/LU>
#include <cmath>

namespace conica {
namespace {

// Reference corners of the VTK hexahedron on [-1, 1]^3.
constexpr double kCorner[8][3] = {{-1, -1, -1}, {1, -1, -1}, {1, 1, -1}, {-1, 1, -1},
                                  {-1, -1, 1},  {1, -1, 1},  {1, 1, 1},  {-1, 1, 1}};

// dN_a / dxi_k at the 8 Gauss points xi = corner / sqrt(3) (weights 1): [point][node][k].
struct HexGradients {
  double d[8][8][3];
  HexGradients() {
    const double r = 1.0 / std::sqrt(3.0);
    for (int q = 0; q < 8; ++q) {
      const double xi[3] = {r * kCorner[q][0], r * kCorner[q][1], r * kCorner[q][2]};
      for (int a = 0; a < 8; ++a) {
        const double* c = kCorner[a];
        const double f[3] = {1 + c[0] * xi[0], 1 + c[1] * xi[1], 1 + c[2] * xi[2]};
        d[q][a][0] = c[0] * f[1] * f[2] / 8;
        d[q][a][1] = f[0] * c[1] * f[2] / 8;
        d[q][a][2] = f[0] * f[1] * c[2] / 8;
      }
    }
  }
};

const HexGradients& hex_gradients() {
  static const HexGradients g;
  return g;
}

}  // namespace

double tet_volume_gradient(const Vec3* x, Vec3* g) {
  const Vec3 a = x[1] - x[0], b = x[2] - x[0], c = x[3] - x[0];
  g[1] = b.cross(c) / 6.0;
  g[2] = c.cross(a) / 6.0;
  g[3] = a.cross(b) / 6.0;
  g[0] = -(g[1] + g[2] + g[3]);
  return a.dot(g[1]);
}

double hex_volume_gradient(const Vec3* x, Vec3* g, double* vq, Vec3* gq) {
  const HexGradients& hg = hex_gradients();
  for (int a = 0; a < 8; ++a) g[a].setZero();
  double v = 0;
  for (int q = 0; q < 8; ++q) {
    // Columns of the map's Jacobian: dx/dxi_k.
    Vec3 j[3] = {Vec3::Zero(), Vec3::Zero(), Vec3::Zero()};
    for (int a = 0; a < 8; ++a)
      for (int k = 0; k < 3; ++k) j[k] += hg.d[q][a][k] * x[a];
    // d det / d column k = cofactor column k.
    const Vec3 c0 = j[1].cross(j[2]), c1 = j[2].cross(j[0]), c2 = j[0].cross(j[1]);
    const double det = j[0].dot(c0);
    v += det;
    if (vq) vq[q] = det;
    for (int a = 0; a < 8; ++a) {
      const Vec3 ga = hg.d[q][a][0] * c0 + hg.d[q][a][1] * c1 + hg.d[q][a][2] * c2;
      g[a] += ga;
      if (gq) gq[8 * q + a] = ga;
    }
  }
  return v;
}

double element_volume(const std::vector<Vec3>& x, const int* nodes, int n, Vec3* g, double* vq,
                      Vec3* gq) {
  Vec3 p[8];
  for (int a = 0; a < n; ++a) p[a] = x[nodes[a]];
  return n == 4 ? tet_volume_gradient(p, g) : hex_volume_gradient(p, g, vq, gq);
}

Eigen::Matrix3d deformation_gradient(const std::vector<Vec3>& x, const int* nodes, int n,
                                     const Vec3* b) {
  Eigen::Matrix3d F = Eigen::Matrix3d::Zero();
  for (int a = 0; a < n; ++a) F += x[nodes[a]] * b[a].transpose();
  return F;
}

double tet_shape_gradients(const Vec3* x, Vec3* b) {
  Eigen::Matrix3d dm;
  dm << x[1] - x[0], x[2] - x[0], x[3] - x[0];
  const double det = dm.determinant();
  const Eigen::Matrix3d inv = dm.inverse();  // rows: gradients of the barycentric coordinates
  for (int a = 1; a < 4; ++a) b[a] = inv.row(a - 1).transpose();
  b[0] = -(b[1] + b[2] + b[3]);
  return det / 6.0;
}

bool hex_shape_gradients(const Vec3* x, Vec3* b, double* v0) {
  const HexGradients& hg = hex_gradients();
  for (int q = 0; q < 8; ++q) {
    Eigen::Matrix3d j = Eigen::Matrix3d::Zero();
    for (int a = 0; a < 8; ++a)
      for (int k = 0; k < 3; ++k) j.col(k) += hg.d[q][a][k] * x[a];
    v0[q] = j.determinant();
    if (!(std::abs(v0[q]) > 0)) return false;
    const Eigen::Matrix3d jinv_t = j.inverse().transpose();
    for (int a = 0; a < 8; ++a)
      b[8 * q + a] = jinv_t * Vec3(hg.d[q][a][0], hg.d[q][a][1], hg.d[q][a][2]);
  }
  return true;
}

double isochoric_yeoh(const double* f, double mu, double beta, double* p, double* coef) {
  const Eigen::Map<const Eigen::Matrix3d> F(f);
  Eigen::Map<Eigen::Matrix3d> P(p);
  const double J = F.determinant();
  if (!(J > 0)) {
    P.setZero();
    *coef = 1;
    return 0;
  }
  const double y = inverse_cube_root(J), m = y * y, i1 = F.squaredNorm();
  const double d = m * i1 - 3;        // I1b - 3 >= 0
  const double g = 1 + 2 * beta * d;  // 2 dW/dI1b / mu
  *coef = g * m;
  const double mt = mu * g;
  // F^-T = cofactor(F) / J.
  Eigen::Matrix3d cof;
  cof.col(0) = F.col(1).cross(F.col(2));
  cof.col(1) = F.col(2).cross(F.col(0));
  cof.col(2) = F.col(0).cross(F.col(1));
  P = mt * m * (F - (i1 / (3 * J)) * cof);
  return 0.5 * mu * d * (1 + beta * d);
}

}  // namespace conica
