// Shared pieces of the calibration (lab/calibration.h): progress text, the mean measured curve,
// the surrogate's force for a spec, and the column floor.
#include <Eigen/Dense>
#include <algorithm>
#include <atomic>
#include <cmath>
#include <cstdio>
#include <limits>
#include <thread>

#include "lab/calibration.h"
#include "lab/calibration_stages.h"

namespace conica::lab {
namespace detail {

std::string fmt(double v, int precision) {
  char buf[64];
  std::snprintf(buf, sizeof buf, "%.*g", precision, v);
  return buf;
}

std::string shapes_text(const std::vector<CardShape>& sh) {
  std::string t;
  for (size_t c = 0; c < sh.size(); ++c)
    t += (c ? "; " : "") + std::string("E_c ") + fmt(sh[c].modulus, 5) + " Pa, taper " +
         fmt(sh[c].taper, 4) + ", stroke " + fmt(sh[c].stroke, 4) +
         (sh[c].precompression > 0 ? ", pre-compression " + fmt(sh[c].precompression, 4) + " S"
                                   : std::string());
  return t;
}

void say(const FitOptions& options, const std::string& line) {
  if (options.progress) options.progress(line);
}

void parallel_for(int n, int threads, const std::function<void(int)>& fn) {
  if (threads <= 0) threads = static_cast<int>(std::max(1u, std::thread::hardware_concurrency()));
  threads = std::min(threads, n);
  std::atomic<int> next{0};
  auto work = [&] {
    for (int k = next++; k < n; k = next++) fn(k);
  };
  std::vector<std::thread> pool;
  for (int t = 1; t < threads; ++t) pool.emplace_back(work);
  work();
  for (std::thread& t : pool) t.join();
}

}  // namespace detail

namespace {

using detail::fmt;

// Lawson-Hanson non-negative least squares: min |A x - b| subject to x >= 0.
Eigen::VectorXd nnls(const Eigen::MatrixXd& A, const Eigen::VectorXd& b) {
  const int m = static_cast<int>(A.cols());
  Eigen::VectorXd x = Eigen::VectorXd::Zero(m);
  std::vector<char> passive(m, 0);
  const double tol = 1e-12 * std::max(1.0, A.norm() * b.norm());
  for (int outer = 0; outer < 3 * m; ++outer) {
    const Eigen::VectorXd grad = A.transpose() * (b - A * x);
    int t = -1;
    for (int j = 0; j < m; ++j)
      if (!passive[j] && grad[j] > tol && (t < 0 || grad[j] > grad[t])) t = j;
    if (t < 0) break;
    passive[t] = 1;
    for (int inner = 0; inner < 3 * m; ++inner) {
      std::vector<int> P;
      for (int j = 0; j < m; ++j)
        if (passive[j]) P.push_back(j);
      Eigen::MatrixXd Ap(A.rows(), P.size());
      for (size_t q = 0; q < P.size(); ++q) Ap.col(q) = A.col(P[q]);
      const Eigen::VectorXd zp = Ap.colPivHouseholderQr().solve(b);
      bool all_positive = true;
      for (size_t q = 0; q < P.size(); ++q) all_positive &= zp[q] > 0;
      if (all_positive) {
        x.setZero();
        for (size_t q = 0; q < P.size(); ++q) x[P[q]] = zp[q];
        break;
      }
      double alpha = 1;
      for (size_t q = 0; q < P.size(); ++q)
        if (zp[q] <= 0) alpha = std::min(alpha, x[P[q]] / (x[P[q]] - zp[q]));
      for (size_t q = 0; q < P.size(); ++q) {
        x[P[q]] += alpha * (zp[q] - x[P[q]]);
        if (x[P[q]] <= 1e-15) {
          x[P[q]] = 0;
          passive[P[q]] = 0;
        }
      }
    }
  }
  return x;
}

}  // namespace

ColumnFloor column_floor(const std::vector<double>& strain, const std::vector<double>& force,
                         int first, double area, const ShapeBounds& B, bool precompressed) {
  ColumnFloor out;
  const int n = static_cast<int>(strain.size());
  if (n != static_cast<int>(force.size()) || n - first < 2 || strain.empty()) return out;
  const double max_strain = strain.back();
  const double smin = std::max(B.stroke_min, std::min(0.99 * B.stroke_max, 1.02 * max_strain));
  // Basis: column stress per unit modulus, sigma(eps) = P(L0 eps) / L0^2 at E_c = 1 Pa.
  const ConicalCard base{1e9, 1e-3, 2e-3, 8e-3, 10e-3, 3};
  // Plain laws: 24 tapers x 24 strokes. Pre-compressed: 16 x 16 x 12 pre-compressions p from 0
  // to the largest that leaves (1 - p) s >= smin.
  const int nt = precompressed ? 16 : 24, ns = nt, np = precompressed ? 12 : 1;
  std::vector<CardShape> shapes;
  std::vector<std::vector<double>> cols;
  for (int i = 0; i < nt; ++i)
    for (int j = 0; j < ns; ++j)
      for (int q = 0; q < np; ++q) {
        CardShape sh{1.0, B.taper_min + (B.taper_max - B.taper_min) * i / (nt - 1),
                     smin + (B.stroke_max - smin) * j / (ns - 1)};
        if (np > 1)
          sh.precompression =
              std::max(0.0, std::min(B.precompression_max, 1 - smin / sh.stroke)) * q / (np - 1);
        if (q > 0 && sh.precompression == 0) continue;
        const ConicalCard card = card_with_shape(base, sh);
        if (!validate(card).empty()) continue;
        const ConicalLaw law(card);
        std::vector<double> c(n);
        bool ok = true;
        for (int k = 0; k < n && ok; ++k) {
          const double delta = strain[k] * card.L0;
          ok = delta < law.remaining_stroke();
          c[k] = ok ? law.evaluate_exact(delta).force / (card.L0 * card.L0) * area : 0;
        }
        if (!ok) continue;
        shapes.push_back(sh);
        cols.push_back(std::move(c));
      }
  const int m = static_cast<int>(cols.size());
  const int R = n - first;
  if (m == 0) return out;
  Eigen::MatrixXd A(R, m);
  Eigen::VectorXd scale(m);
  for (int j = 0; j < m; ++j) {
    for (int k = 0; k < R; ++k) A(k, j) = cols[j][first + k] / force[first + k];
    scale[j] = A.col(j).norm();
    A.col(j) /= scale[j];
  }
  // Iteratively reweighted least squares for the L1 error: weights 1 / max(|r|, eps).
  Eigen::VectorXd omega = Eigen::VectorXd::Ones(R), best_x;
  double best = std::numeric_limits<double>::infinity();
  for (int it = 0; it < 60; ++it) {
    const Eigen::VectorXd sw = omega.cwiseSqrt();
    const Eigen::VectorXd x = nnls(sw.asDiagonal() * A, sw);
    const Eigen::VectorXd r = A * x - Eigen::VectorXd::Ones(R);
    const double e = r.cwiseAbs().mean();
    if (e < best) {
      best = e;
      best_x = x;
    }
    const double eps = std::max(1e-7, 1e-3 * e);
    for (int k = 0; k < R; ++k) omega[k] = 1 / std::max(std::abs(r[k]), eps);
  }
  out.error = best;
  out.force.assign(n, 0.0);
  for (int j = 0; j < m; ++j) {
    const double w = best_x[j] / scale[j];  // modulus, Pa
    if (!(w > 0)) continue;
    CardShape sh = shapes[j];
    sh.modulus = w;
    out.shapes.push_back(sh);
    for (int k = 0; k < n; ++k) out.force[k] += w * cols[j][k];
  }
  return out;
}

CardShape shape_of(const ConicalCard& card) {
  const ConicalLaw law(card);
  return {law.k0() / card.L0, card.D1 / card.D2, law.stroke() / card.L0,
          card.precompression / law.stroke()};
}

bool mean_curve(const std::vector<Curve>& curves, const std::vector<double>& grid,
                std::vector<double>* mean, std::string* error) {
  mean->assign(grid.size(), 0.0);
  for (size_t c = 0; c < curves.size(); ++c) {
    const Curve& cv = curves[c];
    if (cv.empty() || cv.back().displacement < grid.back() * (1 - 1e-9)) {
      *error = "curve " + std::to_string(c + 1) + " ends at " +
               fmt(cv.empty() ? 0 : cv.back().displacement * 1e3) + " mm, before " +
               fmt(grid.back() * 1e3) + " mm";
      return false;
    }
    size_t j = 1;
    for (size_t k = 0; k < grid.size(); ++k) {
      while (j + 1 < cv.size() && cv[j].displacement < grid[k]) ++j;
      const CurvePoint &a = cv[j - 1], &b = cv[j];
      const double t = b.displacement > a.displacement
                           ? (grid[k] - a.displacement) / (b.displacement - a.displacement)
                           : 1.0;
      (*mean)[k] += (a.force + std::clamp(t, 0.0, 1.0) * (b.force - a.force)) / curves.size();
    }
  }
  return true;
}

std::vector<double> surrogate_force(const BodySpec& spec,
                                    const std::vector<SpringGroupSpec>& groups,
                                    const std::vector<double>& grid) {
  Model m;
  if (!build_model(spec, &m).empty() || m.planes.empty())
    return std::vector<double>(grid.size(), std::numeric_limits<double>::quiet_NaN());
  return detail::cell_surrogate(groups, spec.mapping, {plate_height(m), cross_section(m)}, grid,
                                spec.bulk_modulus, spec.shear_modulus, spec.shear_stiffening);
}

std::vector<double> surrogate_force(const BodySpec& spec, const ConicalCard& card,
                                    const std::vector<double>& grid) {
  std::vector<SpringGroupSpec> groups = spec.groups;
  for (auto& g : groups)
    if (g.card.law == LawKind::kConical) g.card.conical = card;
  return surrogate_force(spec, groups, grid);
}

}  // namespace conica::lab
