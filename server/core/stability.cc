// Material stability of a body under homogeneous compression (stability.h).
#include "core/stability.h"

#include <Eigen/Eigenvalues>
#include <Eigen/LU>
#include <Eigen/SparseCholesky>
#include <Eigen/SparseCore>
#include <algorithm>
#include <cmath>
#include <limits>

#include "core/body.h"
#include "core/step.h"
#include "core/volume.h"

namespace conica {
namespace {

// The element terms' energy density at F (volume and isochoric neo-Hookean shear) and its first
// Piola stress.
double element_density(const Model& m, const Mat3& F, Mat3* P) {
  P->setZero();
  double w = 0;
  const double J = F.determinant();
  if (m.bulk_modulus > 0) {
    Mat3 cof;
    cof.col(0) = F.col(1).cross(F.col(2));
    cof.col(1) = F.col(2).cross(F.col(0));
    cof.col(2) = F.col(0).cross(F.col(1));
    w += 0.5 * m.bulk_modulus * (J - 1) * (J - 1);
    *P += m.bulk_modulus * (J - 1) * cof;
  }
  if (m.shear_modulus > 0) {
    Mat3 p;
    double c;
    w += isochoric_yeoh(F.data(), m.shear_modulus, m.shear_stiffening, p.data(), &c);
    *P += p;
  }
  return w;
}

// Flattened column-major index of F(i, A).
constexpr int idx(int i, int a) { return 3 * a + i; }

}  // namespace

HomogenisedState homogenised_state(const Model& m, const Mat3& F) {
  HomogenisedState out;
  double v0 = 0;
  for (const auto& t : m.tetrahedra)
    v0 += std::abs(tet_volume(m.rest[t[0]], m.rest[t[1]], m.rest[t[2]], m.rest[t[3]]));
  for (const auto& h : m.hexahedra) v0 += std::abs(hex_volume(m.rest, h));
  // Springs: e(l) = (a / b) E(delta), delta = b (l0 - l); e' = -a P(delta), e'' = a b k_t.
  for (const SpringGroup& g : m.groups) {
    for (int k = g.begin; k < g.end; ++k) {
      const Vec3 r = m.rest[m.spring_j[k]] - m.rest[m.spring_i[k]];
      const Vec3 d = F * r;
      const double l = d.norm();
      const double a = m.force_scale[k], b = m.deflection_scale[k];
      const double delta = b * (m.rest_length[k] - l);
      double e, p, kt;
      if (g.law) {
        const LawSample s = g.law->evaluate(delta);
        e = (a / b) * g.law->energy(delta);
        p = s.force;
        kt = s.stiffness;
      } else {
        e = (a / b) * 0.5 * g.card.hooke_k * delta * delta;
        p = g.card.hooke_k * delta;
        kt = g.card.hooke_k;
      }
      const double d1 = -a * p, d2 = a * b * kt;
      const Vec3 u = d / l;
      out.energy += e;
      out.stress += d1 * u * r.transpose();
      // [e'' u u^T + (e' / l)(I - u u^T)] (x) r r^T
      const Mat3 G = d2 * u * u.transpose() + (d1 / l) * (Mat3::Identity() - u * u.transpose());
      for (int A = 0; A < 3; ++A)
        for (int B = 0; B < 3; ++B) out.tangent.block<3, 3>(3 * A, 3 * B) += (r(A) * r(B)) * G;
    }
  }
  out.energy /= v0;
  out.stress /= v0;
  out.tangent /= v0;
  // Element terms: closed-form density and stress, tangent by central differences of the stress
  // (the densities are smooth at det F > 0; relative error ~1e-8).
  Mat3 P;
  out.energy += element_density(m, F, &P);
  out.stress += P;
  if (m.bulk_modulus > 0 || m.shear_modulus > 0) {
    const double h = 1e-6 * std::max(1.0, F.cwiseAbs().maxCoeff());
    for (int B = 0; B < 3; ++B)
      for (int j = 0; j < 3; ++j) {
        Mat3 Fp = F, Fm = F, Pp, Pm;
        Fp(j, B) += h;
        Fm(j, B) -= h;
        element_density(m, Fp, &Pp);
        element_density(m, Fm, &Pm);
        const Mat3 dP = (Pp - Pm) / (2 * h);
        for (int A = 0; A < 3; ++A)
          for (int i = 0; i < 3; ++i) out.tangent(idx(i, A), idx(j, B)) += dP(i, A);
      }
    out.tangent = 0.5 * (out.tangent + out.tangent.transpose()).eval();
  }
  return out;
}

namespace {

// Smallest eigenvalue of Q(n) and its eigenvector.
double acoustic_min(const Mat9& A, const Vec3& n, Vec3* polarisation) {
  Mat3 Q = Mat3::Zero();
  for (int i = 0; i < 3; ++i)
    for (int j = 0; j < 3; ++j)
      for (int a = 0; a < 3; ++a)
        for (int b = 0; b < 3; ++b) Q(i, j) += A(idx(i, a), idx(j, b)) * n(a) * n(b);
  // The eigenvalues alone when no polarisation is asked (the same arithmetic for them, less work).
  const Eigen::SelfAdjointEigenSolver<Mat3> es(
      Q, polarisation ? Eigen::ComputeEigenvectors : Eigen::EigenvaluesOnly);
  if (polarisation) *polarisation = es.eigenvectors().col(0);
  return es.eigenvalues()(0);
}

// A transformed by the orthogonal map R: A'_iAjB = R_ip R_Aq R_jr R_Bs A_pqrs (R a signed
// permutation here, so each entry is one entry of A with a sign).
Mat9 transformed(const Mat9& A, const Mat3& R) {
  Mat9 out = Mat9::Zero();
  int p[3];
  double s[3];
  for (int i = 0; i < 3; ++i)
    for (int k = 0; k < 3; ++k)
      if (R(i, k) != 0) {
        p[i] = k;
        s[i] = R(i, k);
      }
  for (int i = 0; i < 3; ++i)
    for (int a = 0; a < 3; ++a)
      for (int j = 0; j < 3; ++j)
        for (int b = 0; b < 3; ++b)
          out(idx(i, a), idx(j, b)) =
              s[i] * s[a] * s[j] * s[b] * A(idx(p[i], p[a]), idx(p[j], p[b]));
  return out;
}

// A unchanged by the square prism's symmetries about z: x -> -x, y -> -y, x <-> y.
bool square_prism_symmetric(const Mat9& A) {
  const double tol = 1e-12 * A.norm();
  Mat3 mx = Mat3::Identity(), my = Mat3::Identity(), swap = Mat3::Zero();
  mx(0, 0) = -1;
  my(1, 1) = -1;
  swap(0, 1) = swap(1, 0) = swap(2, 2) = 1;
  for (const Mat3& R : {mx, my, swap})
    if (!((transformed(A, R) - A).norm() <= tol)) return false;
  return true;
}

}  // namespace

SoftestWave softest_wave(const Mat9& A, int directions) {
  // Directions on a hemisphere (n and -n give the same Q): a Fibonacci lattice, then a pattern
  // search about the best one in shrinking steps. With the square prism's symmetry only the
  // lattice's directions with 0 <= y <= x are evaluated.
  const int kDirections = std::max(1, directions);
  const double golden = M_PI * (3 - std::sqrt(5.0));
  const bool eighth = square_prism_symmetric(A);
  SoftestWave best;
  best.modulus = std::numeric_limits<double>::infinity();
  for (int q = 0; q < kDirections; ++q) {
    const double z = 1 - (q + 0.5) / kDirections;  // (0, 1]
    const double r = std::sqrt(std::max(0.0, 1 - z * z)), phi = golden * q;
    const Vec3 n(r * std::cos(phi), r * std::sin(phi), z);
    if (eighth && !(n.y() >= 0 && n.y() <= n.x()) && q > 0) continue;
    const double v = acoustic_min(A, n, nullptr);
    if (v < best.modulus) {
      best.modulus = v;
      best.normal = n;
    }
  }
  for (double s = 0.05; s > 1e-6; s *= 0.5) {
    bool moved = true;
    while (moved) {
      moved = false;
      const Vec3 t1 = best.normal.unitOrthogonal(), t2 = best.normal.cross(t1);
      const Vec3 steps[4] = {t1, -t1, t2, -t2};
      for (const Vec3& t : steps) {
        const Vec3 n = (best.normal + s * t).normalized();
        const double v = acoustic_min(A, n, nullptr);
        if (v < best.modulus) {
          best.modulus = v;
          best.normal = n;
          moved = true;
        }
      }
    }
  }
  best.modulus = acoustic_min(A, best.normal, &best.polarisation);
  return best;
}

namespace {

struct PathPoint {
  bool solved = false;
  Vec3 stretch = Vec3::Ones();  // lateral 1, lateral 2, axial (axis frame)
  HomogenisedState state;
};

// Uniaxial compression e along frame column 2, the lateral stretches from `guess` by Newton on
// the lateral normal stresses.
PathPoint uniaxial_point(const Model& m, const Mat3& frame, double e, const Vec3& guess) {
  PathPoint pt;
  Eigen::Vector2d lam(guess(0), guess(1));
  auto vecT = [&](int c) {
    const Mat3 T = frame.col(c) * frame.col(c).transpose();
    return Eigen::Map<const Eigen::Matrix<double, 9, 1>>(T.data()).eval();
  };
  const Eigen::Matrix<double, 9, 1> T0 = vecT(0), T1 = vecT(1);
  for (int it = 0; it < 60; ++it) {
    const Mat3 F = frame * Vec3(lam(0), lam(1), 1 - e).asDiagonal() * frame.transpose();
    pt.state = homogenised_state(m, F);
    const Eigen::Map<const Eigen::Matrix<double, 9, 1>> P(pt.state.stress.data());
    const Eigen::Vector2d r(T0.dot(P), T1.dot(P));
    Eigen::Matrix2d J;
    J << T0.dot(pt.state.tangent * T0), T0.dot(pt.state.tangent * T1),
        T1.dot(pt.state.tangent * T0), T1.dot(pt.state.tangent * T1);
    const double scale = std::max(std::abs(J(0, 0)), std::abs(J(1, 1)));
    if (!(scale > 0) || !std::isfinite(scale)) return pt;
    if (r.norm() <= 1e-10 * scale) {
      pt.solved = true;
      pt.stretch = Vec3(lam(0), lam(1), 1 - e);
      return pt;
    }
    Eigen::Vector2d d = -J.fullPivLu().solve(r);
    if (!d.allFinite()) return pt;
    const double cap = 0.1 * lam.minCoeff();
    if (d.cwiseAbs().maxCoeff() > cap) d *= cap / d.cwiseAbs().maxCoeff();
    lam += d;
    if (!(lam.minCoeff() > 0)) return pt;
  }
  return pt;
}

Mat3 axis_frame(const Vec3& axis) {
  Mat3 frame;
  frame.col(2) = axis.normalized();
  frame.col(0) = frame.col(2).unitOrthogonal();
  frame.col(1) = frame.col(2).cross(frame.col(0));
  return frame;
}

}  // namespace

SoftestWave uniaxial_softest_wave(const Model& m, const Vec3& axis, double strain, int steps,
                                  int directions, Vec3* stretch) {
  const Mat3 frame = axis_frame(axis);
  if (stretch && std::abs((*stretch)(2) - (1 - strain)) < 1e-15) {
    const PathPoint pt = uniaxial_point(m, frame, strain, *stretch);
    if (pt.solved) {
      *stretch = pt.stretch;
      return softest_wave(pt.state.tangent, directions);
    }
  }
  Vec3 last = Vec3::Ones();
  for (int q = 1; q <= steps; ++q) {
    const PathPoint pt = uniaxial_point(m, frame, strain * q / steps, last);
    if (!pt.solved) {
      SoftestWave w;
      w.modulus = std::numeric_limits<double>::quiet_NaN();
      return w;
    }
    last = pt.stretch;
    if (q == steps) {
      if (stretch) *stretch = pt.stretch;
      return softest_wave(pt.state.tangent, directions);
    }
  }
  return softest_wave(homogenised_state(m, Mat3::Identity()).tangent, directions);
}

CompressionStability uniaxial_compression_stability(const Model& m, const Vec3& axis,
                                                    double max_strain, double step) {
  CompressionStability out;
  const Mat3 frame = axis_frame(axis);
  Vec3 last = Vec3::Ones();
  double e_last = 0;
  for (int q = 1;; ++q) {
    const double e = std::min(max_strain, q * step);
    const PathPoint pt = uniaxial_point(m, frame, e, last);
    if (!pt.solved) break;
    const SoftestWave w = softest_wave(pt.state.tangent);
    if (!(w.modulus > 0)) {
      // Bisect between the last stable strain and this one.
      double lo = e_last, hi = e;
      Vec3 lo_stretch = last;
      for (int b = 0; b < 14 && hi - lo > 1e-5; ++b) {
        const double mid = 0.5 * (lo + hi);
        const PathPoint pm = uniaxial_point(m, frame, mid, lo_stretch);
        if (pm.solved && softest_wave(pm.state.tangent).modulus > 0) {
          lo = mid;
          lo_stretch = pm.stretch;
        } else {
          hi = mid;
        }
      }
      out.onset_strain = hi;
      const PathPoint ph = uniaxial_point(m, frame, hi, lo_stretch);
      out.wave = ph.solved ? softest_wave(ph.state.tangent) : w;
      out.lateral_stretch = ph.solved ? ph.stretch : pt.stretch;
      out.checked_to = hi;
      return out;
    }
    out.wave = w;
    out.lateral_stretch = pt.stretch;
    out.checked_to = e;
    last = pt.stretch;
    e_last = e;
    if (e >= max_strain) break;
  }
  return out;
}

EquilibriumStability equilibrium_stability(const Model& m, const State& state) {
  const int nn = m.num_nodes();
  EquilibriumStability out;
  const std::vector<std::vector<int>> adj = node_neighbours(m);
  // Distance-2 colouring (greedy): two nodes of one colour have no neighbour in common, so the
  // force change at node j under a colour's perturbation comes from its one neighbour of it.
  std::vector<int> colour(nn, -1), seen;
  int colours = 0;
  for (int i = 0; i < nn; ++i) {
    seen.clear();
    for (int j : adj[i])
      for (int k : adj[j])
        if (colour[k] >= 0) seen.push_back(colour[k]);
    std::sort(seen.begin(), seen.end());
    int c = 0;
    for (int s : seen) {
      if (s == c)
        ++c;
      else if (s > c)
        break;
    }
    colour[i] = c;
    colours = std::max(colours, c + 1);
  }
  std::vector<std::vector<int>> members(colours);
  for (int i = 0; i < nn; ++i) members[colour[i]].push_back(i);
  // The perturbation: 1e-6 of the median spring rest length (or of the body's size).
  double scale = 0;
  if (m.num_springs() > 0) {
    std::vector<double> l = m.rest_length;
    std::nth_element(l.begin(), l.begin() + l.size() / 2, l.end());
    scale = l[l.size() / 2];
  } else {
    Vec3 lo = m.rest[0], hi = m.rest[0];
    for (const Vec3& x : m.rest) {
      lo = lo.cwiseMin(x);
      hi = hi.cwiseMax(x);
    }
    scale = (hi - lo).norm();
  }
  const double eps = 1e-6 * scale;
  // Free axes -> unknowns.
  std::vector<int> dof(3 * nn, -1);
  int n = 0;
  for (int i = 0; i < nn; ++i)
    for (int c = 0; c < 3; ++c)
      if (m.free_axes[i][c] != 0) dof[3 * i + c] = n++;
  if (n == 0) {
    out.factored = true;
    return out;
  }
  State s = state;
  for (Vec3& v : s.v) v.setZero();
  Workspace ws(m);
  std::vector<Vec3> fp(nn);
  std::vector<Eigen::Triplet<double>> entries;
  for (int c = 0; c < colours; ++c) {
    for (int a = 0; a < 3; ++a) {
      for (int i : members[c]) s.x[i][a] = state.x[i][a] + eps;
      compute_forces(m, s, ws);
      fp = ws.force;
      for (int i : members[c]) s.x[i][a] = state.x[i][a] - eps;
      compute_forces(m, s, ws);
      for (int i : members[c]) s.x[i][a] = state.x[i][a];
      for (int i : members[c]) {
        const int col = dof[3 * i + a];
        if (col < 0) continue;
        for (int j : adj[i])
          for (int b = 0; b < 3; ++b) {
            const int row = dof[3 * j + b];
            if (row < 0) continue;
            const double kij = -(fp[j][b] - ws.force[j][b]) / (2 * eps);
            // Symmetrised: (K + K^T) / 2, each entry from both of its columns.
            entries.emplace_back(row, col, 0.5 * kij);
            entries.emplace_back(col, row, 0.5 * kij);
          }
      }
    }
  }
  Eigen::SparseMatrix<double> K(n, n);
  K.setFromTriplets(entries.begin(), entries.end());
  std::vector<double> diag(n);
  for (int k = 0; k < n; ++k) diag[k] = std::abs(K.coeff(k, k));
  std::nth_element(diag.begin(), diag.begin() + n / 2, diag.end());
  out.shift = 1e-5 * diag[n / 2];
  for (int k = 0; k < n; ++k) K.coeffRef(k, k) += out.shift;
  Eigen::SimplicialLDLT<Eigen::SparseMatrix<double>, Eigen::Lower, Eigen::AMDOrdering<int>> ldlt(K);
  if (ldlt.info() != Eigen::Success) return out;
  out.factored = true;
  const Eigen::VectorXd d = ldlt.vectorD();
  for (int k = 0; k < n; ++k) out.negative += d[k] < 0;
  return out;
}

}  // namespace conica
