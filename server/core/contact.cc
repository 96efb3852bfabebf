#include "core/contact.h"

#include <Eigen/Cholesky>
#include <Eigen/Geometry>
#include <Eigen/LU>
#include <algorithm>
#include <cmath>
#include <limits>

namespace conica {
namespace {

// Gauss-Legendre on [0, 1].
constexpr int kGauss = 4;
constexpr double kGaussX[kGauss] = {0.0694318442029737, 0.3300094782075719, 0.6699905217924281,
                                    0.9305681557970263};
constexpr double kGaussW[kGauss] = {0.1739274225687269, 0.3260725774312731, 0.3260725774312731,
                                    0.1739274225687269};
// Dunavant's degree-4 rule on a triangle: barycentric points and weights (sum 1).
constexpr double kTriA = 0.445948490915965, kTriB = 0.091576213509771;
constexpr double kTriPoints[6][3] = {{1 - 2 * kTriA, kTriA, kTriA}, {kTriA, 1 - 2 * kTriA, kTriA},
                                     {kTriA, kTriA, 1 - 2 * kTriA}, {1 - 2 * kTriB, kTriB, kTriB},
                                     {kTriB, 1 - 2 * kTriB, kTriB}, {kTriB, kTriB, 1 - 2 * kTriB}};
constexpr double kTriW[6] = {0.223381589678011, 0.223381589678011, 0.223381589678011,
                             0.109951743655322, 0.109951743655322, 0.109951743655322};

// A sphere's disc against a triangle whose edges are all at most this fraction of the disc's
// radius is integrated with the rim's arcs replaced by chords (sphere_triangle).
constexpr double kChordEdge = 0.5;

// Symmetric 3 x 3 from its six entries xx yy zz xy xz yz.
Mat3 symmetric(const double s[6]) {
  Mat3 m;
  m << s[0], s[3], s[4], s[3], s[1], s[5], s[4], s[5], s[2];
  return m;
}

// What a tool does to a surface point y inside it: penetration g, the unit direction u the point
// is pushed along, and the curvature 1 / r of the tool's surface there (0 for a flat face), whose
// term p / r (I - u u^T) the tool's stiffness carries.
struct Penetration {
  double g = 0;
  Vec3 u = Vec3::Zero();
  double curvature = 0;  // 1/m
};

// A sphere of radius R around c: g = R - |y - c|, pushed radially.
struct SphereTool {
  const Vec3& c;
  double R;
  bool at(const Vec3& y, Penetration* pen) const {
    const Vec3 d = y - c;
    const double r2 = d.squaredNorm();
    if (!(r2 < R * R) || !(r2 > 0)) return false;
    const double r = std::sqrt(r2), ir = 1 / r;
    *pen = {R - r, d * ir, ir};
    return true;
  }
};

// A punch's face centred at c pushing along unit a: g = -(y - c).a behind it, pushed along a.
struct PunchTool {
  const Vec3& c;
  const Vec3& axis;
  bool at(const Vec3& y, Penetration* pen) const {
    const double g = -(y - c).dot(axis);
    if (!(g > 0)) return false;
    *pen = {g, axis, 0};
    return true;
  }
};

// Accumulates the layer's integrand at Gauss points of one triangle, in sums local to it that
// flush() adds to the tool's totals and the nodes once per triangle (the tool's energy and
// stiffness only when `terms` asks for them).
template <typename Tool>
struct Accumulator {
  const ContactLayer& layer;
  const Tool& tool;
  ToolContact* out;
  Vec3* f[3];  // node forces (null: not wanted)
  Mat3* b[3];  // node blocks (null: not wanted)
  unsigned terms = kToolAll;
  double* ar[3] = {nullptr, nullptr, nullptr};  // node area shares (null: not wanted)
  Mat3* pr = nullptr;                           // the triangle's six pair blocks (null: not wanted)
  double al[3] = {0, 0, 0};
  double pl[6][6] = {};
  double plc[6][6] = {};
  bool touched = false;
  double energy = 0, s0 = 0, depth = 0;
  Vec3 force = Vec3::Zero();
  double S1[6] = {}, S2[6] = {};  // sum w (-p' - p k) u u^T and sum w p' u u^T (k: curvature)
  Vec3 fl[3] = {Vec3::Zero(), Vec3::Zero(), Vec3::Zero()};
  double bl[3][6] = {};

  // Point y of barycentric coordinates l, area weight w (m^2).
  void add(const Vec3& y, const double l[3], double w) {
    Penetration pen;
    if (!tool.at(y, &pen)) return;
    double p, dp;
    if (terms & kToolEnergy) {
      double psi;
      layer.eval(pen.g, &p, &dp, &psi);
      energy += w * psi;
    } else {
      layer_pressure(layer, pen.g, &p, &dp);
    }
    const Vec3& u = pen.u;
    force -= (w * p) * u;
    depth = std::max(depth, pen.g);
    touched = true;
    if (ar[0])
      for (int a = 0; a < 3; ++a) al[a] += w * l[a];
    const bool stiffness = terms & kToolStiffness;
    if (!stiffness && !b[0] && !pr) {
      if (f[0])
        for (int a = 0; a < 3; ++a) fl[a] += (w * l[a] * p) * u;
      return;
    }
    const double uu[6] = {u.x() * u.x(), u.y() * u.y(), u.z() * u.z(),
                          u.x() * u.y(), u.x() * u.z(), u.y() * u.z()};
    // With the pair blocks asked for, the lumped blocks (their row sums) and S2 (their sum) come
    // from them in flush(): sum_b l_b = 1.
    if (stiffness) {
      s0 += w * p * pen.curvature;
      const double c1 = w * (-dp - p * pen.curvature), c2 = w * dp;
      for (int k = 0; k < 6; ++k) S1[k] += c1 * uu[k];
      if (!pr)
        for (int k = 0; k < 6; ++k) S2[k] += c2 * uu[k];
    }
    for (int a = 0; a < 3; ++a) {
      if (f[a]) fl[a] += (w * l[a] * p) * u;
      if (b[a] && !pr) {
        const double wa = w * l[a] * dp;
        for (int k = 0; k < 6; ++k) bl[a][k] += wa * uu[k];
      }
    }
    if (pr) {
      const double wd = w * dp;
      const double c[6] = {wd * l[0] * l[0], wd * l[1] * l[1], wd * l[2] * l[2],
                           wd * l[0] * l[1], wd * l[0] * l[2], wd * l[1] * l[2]};
      for (int j = 0; j < 6; ++j)
        for (int k = 0; k < 6; ++k) pl[j][k] += c[j] * uu[k];
      {
        const double wc = -w * p * pen.curvature;
        const double cc[6] = {wc * l[0] * l[0], wc * l[1] * l[1], wc * l[2] * l[2],
                              wc * l[0] * l[1], wc * l[0] * l[2], wc * l[1] * l[2]};
        const double pu[6] = {1 - uu[0], 1 - uu[1], 1 - uu[2], -uu[3], -uu[4], -uu[5]};
        for (int j = 0; j < 6; ++j)
          for (int k = 0; k < 6; ++k) plc[j][k] += cc[j] * pu[k];
      }
    }
  }

  void flush() {
    if (!touched) return;
    if (pr)  // K_aa + K_ab + K_ac, and S2 their sum over a (pairs 00 11 22 01 02 12)
      for (int k = 0; k < 6; ++k) {
        bl[0][k] = pl[0][k] + pl[3][k] + pl[4][k];
        bl[1][k] = pl[1][k] + pl[3][k] + pl[5][k];
        bl[2][k] = pl[2][k] + pl[4][k] + pl[5][k];
        S2[k] = bl[0][k] + bl[1][k] + bl[2][k];
      }
    out->energy += energy;
    out->force += force;
    if (terms & kToolStiffness) {
      out->stiffness += symmetric(S1) + s0 * Mat3::Identity();
      out->stiffness_psd -= symmetric(S2);
    }
    out->depth = std::max(out->depth, depth);
    for (int a = 0; a < 3; ++a) {
      if (f[a]) *f[a] += fl[a];
      if (b[a]) *b[a] += symmetric(bl[a]);
      if (ar[a]) *ar[a] += al[a];
    }
    if (pr) {
      const bool curvature = !(terms & kToolPairPressureOnly);
      for (int j = 0; j < 6; ++j)
        pr[j] += curvature ? Mat3(symmetric(pl[j]) + symmetric(plc[j])) : symmetric(pl[j]);
    }
  }
};

Vec3 closest_on_triangle(const Vec3& p, const Vec3& a, const Vec3& b, const Vec3& c, Vec3* bary);

// The integral over the part of triangle (Q0, Q1, Q2) inside the disc of radius `a` about the
// origin, in their plane (unit normal n; the Q are relative to the disc's centre): calls
// add(l, w) at Gauss points of barycentric coordinates l with area weights w (times `scale`).
// The region is convex: it is cut into pieces from its point O nearest the disc's centre,
// {O + s (A + t D)}, A = Q_k - O, D = Q_{k+1} - Q_k, s in [0, s_max(t)], t split where the edge
// meets the rim, so every piece has the rim or the edge as a smooth boundary and a non-negative
// area element s ((A x D) . n) ds dt.
template <typename Add>
void disc_triangle(const Vec3 Q[3], const Vec3& n, double a, double scale, Add&& add) {
  const double a2 = a * a;
  if (Q[0].squaredNorm() <= a2 && Q[1].squaredNorm() <= a2 && Q[2].squaredNorm() <= a2) {
    // The whole triangle lies in the disc, where the integrand is smooth: one rule on it.
    const double area = 0.5 * (Q[1] - Q[0]).cross(Q[2] - Q[0]).norm() * scale;
    for (int k = 0; k < 6; ++k) add(kTriPoints[k], area * kTriW[k]);
    return;
  }
  Vec3 bo;
  const Vec3 O = closest_on_triangle(Vec3::Zero(), Q[0], Q[1], Q[2], &bo);
  if (!(O.squaredNorm() < a2)) return;  // the disc misses the triangle
  const Vec3 e1 = Q[1] - Q[0], e2 = Q[2] - Q[0];
  const double g11 = e1.dot(e1), g12 = e1.dot(e2), g22 = e2.dot(e2);
  const double det = g11 * g22 - g12 * g12;
  if (!(det > 0)) return;
  const Vec3 d1 = (g22 * e1 - g12 * e2) / det, d2 = (g11 * e2 - g12 * e1) / det;
  const double wo = O.squaredNorm() - a2;  // < 0
  for (int k = 0; k < 3; ++k) {
    const Vec3& Qa = Q[k];
    const Vec3& Qb = Q[(k + 1) % 3];
    const Vec3 A = Qa - O, D = Qb - Qa;
    if (!(A.cross(D).dot(n) > 0)) continue;  // O on this edge
    // The edge point Q_a + t D is on the rim at the roots of |D|^2 t^2 + 2 (Q_a.D) t + |Q_a|^2 -
    // a^2.
    double breaks[4] = {0, 1, 1, 1};
    int nb = 1;
    const double qa = D.squaredNorm(), qb = Qa.dot(D), qc = Qa.squaredNorm() - a2;
    const double disc = qb * qb - qa * qc;
    if (qa > 0 && disc > 0) {
      const double sq = std::sqrt(disc);
      for (double t : {(-qb - sq) / qa, (-qb + sq) / qa})
        if (t > 0 && t < 1) breaks[nb++] = t;
    }
    breaks[nb++] = 1;
    // Polar coordinates about O on each piece: rays at angle theta (one panel: a piece spans
    // less than 180 degrees, and a second panel changes the force on a flat face by less than
    // 1e-5), out to the edge or the rim, whichever the piece has as its boundary.
    const double along_edge = A.cross(D).dot(n);
    for (int piece = 0; piece + 1 < nb; ++piece) {
      const double t0 = breaks[piece], t1 = breaks[piece + 1];
      if (!(t1 > t0)) continue;
      const Vec3 ea = A + t0 * D, eb = A + t1 * D;
      const double span = std::atan2(ea.cross(eb).dot(n), ea.dot(eb));  // in (0, pi)
      if (!(span > 0)) continue;
      const Vec3 u1 = ea.normalized(), u2 = n.cross(u1);
      // The piece's boundary: the rim when its midpoint lies outside the disc, else the edge.
      const bool rim = (Qa + 0.5 * (t0 + t1) * D).squaredNorm() > a2;
      // A fixed rule per piece, so the integral is continuous as the tool moves.
      constexpr int panels = 1;
      for (int pn = 0; pn < panels; ++pn)
        for (int i = 0; i < kGauss; ++i) {
          Vec3 w;     // the ray's direction (rim) or its end on the edge (edge)
          double wt;  // weight of the ray
          if (rim) {
            // Polar: rays at angle theta, out to the rim, area element rho d rho d theta.
            const double dth = span / panels, th = (pn + kGaussX[i]) * dth;
            w = std::cos(th) * u1 + std::sin(th) * u2;
            const double ow = O.dot(w);
            const double rmax = -ow + std::sqrt(std::max(0.0, ow * ow - wo));
            w *= rmax;
            wt = dth * kGaussW[i] * rmax * rmax * scale;
          } else {
            // Along the edge: rays to O + A + t D, area element s ((A x D) . n) ds dt.
            const double dt = (t1 - t0) / panels, t = t0 + (pn + kGaussX[i]) * dt;
            w = A + t * D;
            wt = dt * kGaussW[i] * along_edge * scale;
          }
          for (int j = 0; j < kGauss; ++j) {
            const Vec3 r = O + kGaussX[j] * w - Q[0];
            double l[3];
            l[1] = d1.dot(r);
            l[2] = d2.dot(r);
            l[0] = 1 - l[1] - l[2];
            add(l, wt * kGaussX[j] * kGaussW[j]);
          }
        }
    }
  }
}

// A convex polygon inside triangle (p0, p1, p2) of `area` (m^2), corners L[0..n) in barycentric
// coordinates: split from its first corner into triangles that each get Dunavant's rule.
template <typename Acc>
void fan_triangle_rule(const Vec3* L, int n, const Vec3& p0, const Vec3& p1, const Vec3& p2,
                       double area, Acc& acc) {
  for (int q = 1; q + 1 < n; ++q) {
    const Vec3 e1 = L[q] - L[0], e2 = L[q + 1] - L[0];
    const double frac = std::abs(e1[1] * e2[2] - e1[2] * e2[1]);  // sub-area / triangle area
    if (!(frac > 0)) continue;
    for (int k = 0; k < 6; ++k) {
      const Vec3 l =
          kTriPoints[k][0] * L[0] + kTriPoints[k][1] * L[q] + kTriPoints[k][2] * L[q + 1];
      const double lw[3] = {l[0], l[1], l[2]};
      acc.add(l[0] * p0 + l[1] * p1 + l[2] * p2, lw, area * frac * kTriW[k]);
    }
  }
}

// The sphere (centre c, radius R) against triangle (p0, p1, p2): the integral over the part of
// the triangle inside the ball, the disc the ball cuts from the triangle's plane.
void sphere_triangle(const Vec3& p0, const Vec3& p1, const Vec3& p2, Accumulator<SphereTool>& acc) {
  const Vec3 nv = (p1 - p0).cross(p2 - p0);
  const double area2 = nv.norm();
  if (!(area2 > 0)) return;
  const Vec3 n = nv / area2;
  const Vec3& c = acc.tool.c;
  const double R = acc.tool.R;
  const double z = (c - p0).dot(n);
  if (!(std::abs(z) < R)) return;
  const Vec3 F = c - z * n;  // the disc's centre in the triangle's plane
  const Vec3 Q[3] = {p0 - F, p1 - F, p2 - F};
  const double a = std::sqrt(R * R - z * z);
  const double edge2 = std::max(
      {(Q[1] - Q[0]).squaredNorm(), (Q[2] - Q[1]).squaredNorm(), (Q[0] - Q[2]).squaredNorm()});
  if (edge2 <= kChordEdge * kChordEdge * a * a) {
    // A triangle small against the disc: the part inside it is the polygon of the corners inside
    // and the rim's crossings of the edges, each arc between two crossings replaced by its chord,
    // split from its first corner into triangles that each get Dunavant's rule (p(g) is smooth
    // inside the disc). What the chords leave out is a sliver at most c^2 / (8 a) wide (c <=
    // kChordEdge a: the chord) where g <= (a / R) c^2 / (8 a), so it carries a fraction of order
    // (c / a)^4 / 64 of the force the triangle's rim band does; a sphere's pressure vanishes at
    // the rim, which is what makes this small (not so for a punch, whose rim carries its full
    // pressure). Continuous as the tool moves: the polygon's corners move continuously.
    const double a2 = a * a;
    Vec3 L[6];
    int np = 0;
    for (int i = 0; i < 3; ++i) {
      const int j = (i + 1) % 3;
      if (Q[i].squaredNorm() < a2) L[np++] = Vec3::Unit(i);
      // |Q_i + t D|^2 = a^2, roots in (0, 1) in order along the edge.
      const Vec3 D = Q[j] - Q[i];
      const double qa = D.squaredNorm(), qb = Q[i].dot(D), qc = Q[i].squaredNorm() - a2;
      const double disc = qb * qb - qa * qc;
      if (!(qa > 0) || !(disc >= 0)) continue;
      const double sq = std::sqrt(disc);
      for (double t : {(-qb - sq) / qa, (-qb + sq) / qa})
        if (t > 0 && t < 1) L[np++] = (1 - t) * Vec3::Unit(i) + t * Vec3::Unit(j);
    }
    fan_triangle_rule(L, np, p0, p1, p2, 0.5 * area2, acc);
  } else {
    disc_triangle(Q, n, a, 1.0, [&](const double* l, double w) {
      acc.add(l[0] * p0 + l[1] * p1 + l[2] * p2, l, w);
    });
  }
  if (acc.touched) {  // the exact depth: R less the distance to the triangle
    Vec3 b;
    const double d = (closest_on_triangle(c, p0, p1, p2, &b) - c).norm();
    acc.depth = std::max(acc.depth, R - d);
  }
  acc.flush();
}

// The punch (end face centred at c, pushing along unit a, radius R) against a triangle: its
// footprint is the disc of radius R about the axis in the face plane; the triangle is projected
// along the axis onto that plane (an affine map: barycentric coordinates carry over, areas scale
// by the ratio of the real to the projected area).
void punch_triangle(const Vec3& p0, const Vec3& p1, const Vec3& p2, double R,
                    Accumulator<PunchTool>& acc) {
  const Vec3& ax = acc.tool.axis;
  const Vec3& c = acc.tool.c;
  const double area2 = (p1 - p0).cross(p2 - p0).norm();
  if (!(area2 > 0)) return;
  const Mat3 P = Mat3::Identity() - ax * ax.transpose();
  const Vec3 Q[3] = {P * (p0 - c), P * (p1 - c), P * (p2 - c)};
  const Vec3 pn = (Q[1] - Q[0]).cross(Q[2] - Q[0]);
  const double proj_area2 = pn.norm();
  if (!(proj_area2 > 1e-12 * area2)) return;  // the triangle is edge-on to the punch
  disc_triangle(Q, pn / proj_area2, R, area2 / proj_area2, [&](const double* l, double w) {
    acc.add(l[0] * p0 + l[1] * p1 + l[2] * p2, l, w);
  });
  acc.flush();
}

// A plane (through c, pushing along unit a; the tool fills {y : (y - c).a < 0}) against a
// triangle: the part of the triangle behind the plane (g = -(y - c).a > 0, linear on the
// triangle) is clipped out exactly, a triangle or a quadrilateral, split from its first corner
// into triangles that each get Dunavant's rule (the integrand p(g) is smooth there: the kink of
// p at g = 0 lies on the clipped boundary). The depth is exact: the largest g at a corner.
void plane_triangle(const Vec3& p0, const Vec3& p1, const Vec3& p2, Accumulator<PunchTool>& acc) {
  const Vec3& ax = acc.tool.axis;
  const Vec3& c = acc.tool.c;
  const double area = 0.5 * (p1 - p0).cross(p2 - p0).norm();
  if (!(area > 0)) return;
  const double g[3] = {-(p0 - c).dot(ax), -(p1 - c).dot(ax), -(p2 - c).dot(ax)};
  // The clipped polygon's corners in barycentric coordinates (at most four).
  Vec3 L[4];
  int n = 0;
  for (int i = 0; i < 3; ++i) {
    const int j = (i + 1) % 3;
    if (g[i] > 0) L[n++] = Vec3::Unit(i);
    if ((g[i] > 0) != (g[j] > 0)) {
      const double s = g[i] / (g[i] - g[j]);  // the edge i -> j crosses the plane here
      L[n++] = (1 - s) * Vec3::Unit(i) + s * Vec3::Unit(j);
    }
  }
  if (n < 3) return;
  fan_triangle_rule(L, n, p0, p1, p2, area, acc);
  if (acc.touched) acc.depth = std::max({acc.depth, g[0], g[1], g[2]});
  acc.flush();
}

// Closest point to p on triangle (a, b, c) (Ericson, Real-Time Collision Detection 5.1.5), with
// its barycentric coordinates.
Vec3 closest_on_triangle(const Vec3& p, const Vec3& a, const Vec3& b, const Vec3& c, Vec3* bary) {
  const Vec3 ab = b - a, ac = c - a, ap = p - a;
  const double d1 = ab.dot(ap), d2 = ac.dot(ap);
  if (d1 <= 0 && d2 <= 0) {
    *bary = Vec3(1, 0, 0);
    return a;
  }
  const Vec3 bp = p - b;
  const double d3 = ab.dot(bp), d4 = ac.dot(bp);
  if (d3 >= 0 && d4 <= d3) {
    *bary = Vec3(0, 1, 0);
    return b;
  }
  const double vc = d1 * d4 - d3 * d2;
  if (vc <= 0 && d1 >= 0 && d3 <= 0) {
    const double v = d1 / (d1 - d3);
    *bary = Vec3(1 - v, v, 0);
    return a + v * ab;
  }
  const Vec3 cp = p - c;
  const double d5 = ab.dot(cp), d6 = ac.dot(cp);
  if (d6 >= 0 && d5 <= d6) {
    *bary = Vec3(0, 0, 1);
    return c;
  }
  const double vb = d5 * d2 - d1 * d6;
  if (vb <= 0 && d2 >= 0 && d6 <= 0) {
    const double w = d2 / (d2 - d6);
    *bary = Vec3(1 - w, 0, w);
    return a + w * ac;
  }
  const double va = d3 * d6 - d5 * d4;
  if (va <= 0 && (d4 - d3) >= 0 && (d5 - d6) >= 0) {
    const double w = (d4 - d3) / ((d4 - d3) + (d5 - d6));
    *bary = Vec3(0, 1 - w, w);
    return b + w * (c - b);
  }
  const double denom = 1 / (va + vb + vc);
  const double v = vb * denom, w = vc * denom;
  *bary = Vec3(1 - v - w, v, w);
  return a + ab * v + ac * w;
}

// Parameter in [0, 1] at which segment p -> q first meets triangle (a, b, c), or 2 when it does
// not (Moller-Trumbore, both sides).
double segment_triangle(const Vec3& p, const Vec3& q, const Vec3& a, const Vec3& b, const Vec3& c) {
  const Vec3 d = q - p, e1 = b - a, e2 = c - a;
  const Vec3 h = d.cross(e2);
  const double det = e1.dot(h);
  if (std::abs(det) < 1e-30) return 2;
  const double inv = 1 / det;
  const Vec3 s = p - a;
  const double u = inv * s.dot(h);
  if (u < 0 || u > 1) return 2;
  const Vec3 qv = s.cross(e1);
  const double v = inv * d.dot(qv);
  if (v < 0 || u + v > 1) return 2;
  const double t = inv * e2.dot(qv);
  return t >= 0 && t <= 1 ? t : 2;
}

// A triangle's centroid and the largest centroid-vertex distance (m): its bounding sphere.
double triangle_bound(const Vec3& p0, const Vec3& p1, const Vec3& p2, Vec3* center) {
  *center = (p0 + p1 + p2) / 3;
  return std::sqrt(std::max(
      {(p0 - *center).squaredNorm(), (p1 - *center).squaredNorm(), (p2 - *center).squaredNorm()}));
}

// Surface triangle t's frame at positions x: its edges from node 0 and its unit normal.
Mat3 triangle_frame(const Model& m, const std::vector<Vec3>& x, int t) {
  const auto& f = m.surface[t];
  Mat3 E;
  E.col(0) = x[f[1]] - x[f[0]];
  E.col(1) = x[f[2]] - x[f[0]];
  E.col(2) = E.col(0).cross(E.col(1)).normalized();
  return E;
}

// A point riding on the surface: the point of barycentric coordinates `bary` on triangle t plus
// `offset` in the triangle's frame, at positions x (the proxy's anchor, the friction's stick
// point).
Vec3 carried_point(const Model& m, const std::vector<Vec3>& x, int t, const Vec3& bary,
                   const Vec3& offset) {
  const auto& f = m.surface[t];
  return bary[0] * x[f[0]] + bary[1] * x[f[1]] + bary[2] * x[f[2]] +
         triangle_frame(m, x, t) * offset;
}

// The point of the listed surface triangles (all when list is null) nearest y at positions x,
// with its triangle and barycentric coordinates (*tri unchanged when count is 0).
Vec3 nearest_surface_point(const Model& m, const std::vector<Vec3>& x, const int* list, int count,
                           const Vec3& y, int* tri, Vec3* bary) {
  double best = std::numeric_limits<double>::infinity();
  Vec3 at = y;
  for (int q = 0; q < count; ++q) {
    const int t = list ? list[q] : q;
    const auto& f = m.surface[t];
    Vec3 b;
    const Vec3 c = closest_on_triangle(y, x[f[0]], x[f[1]], x[f[2]], &b);
    const double d2 = (c - y).squaredNorm();
    if (d2 < best) {
      best = d2;
      at = c;
      *tri = t;
      *bary = b;
    }
  }
  return at;
}

// The unit axis of probe k's tool when it is a plane (gather_candidates' `plane`), else null.
const Vec3* plane_axis(const Model& m, int k) {
  return m.probes[k].shape == ToolShape::kPlane ? &m.probes[k].axis : nullptr;
}

}  // namespace

void anchor_proxy(const Model& m, const std::vector<Vec3>& x, const int* list, int count,
                  double reach, ProbeState* p) {
  p->anchor = -1;
  int t = -1;
  Vec3 b;
  const Vec3 near = nearest_surface_point(m, x, list, count, p->proxy, &t, &b);
  if (t >= 0 && (near - p->proxy).norm() < reach) {
    p->anchor = t;
    p->anchor_bary = b;
    p->anchor_offset = triangle_frame(m, x, t).inverse() * (p->proxy - near);
  }
}

double probe_radius(const Model& m, int k, const ProbeState& p) {
  return p.radius > 0 ? p.radius : m.probes[k].radius;
}

double coupling_stiffness(const Model& m, int k, double R) {
  const double kvc = m.probes[k].coupling;
  return kvc > 0 ? kvc : kCouplingFactor * m.contact_modulus * R;
}

Coupling coupling(const Model& m, int k, double R) {
  return Coupling{coupling_stiffness(m, k, R), kCouplingReach * R};
}

double Coupling::energy(const Vec3& e) const {
  const double d = e.norm();
  return d <= reach ? 0.5 * k * d * d : k * reach * (d - 0.5 * reach);
}

Vec3 Coupling::force(const Vec3& e) const {
  const double d = e.norm();
  return d <= reach ? Vec3(k * e) : Vec3((k * reach / d) * e);
}

Mat3 Coupling::hessian(const Vec3& e) const {
  const double d = e.norm();
  if (d <= reach) return k * Mat3::Identity();
  const Vec3 u = e / d;
  return (k * reach / d) * (Mat3::Identity() - u * u.transpose());
}

Mat3 Coupling::device_stiffness(const Vec3& e, const Mat3& K) const {
  // Saturated, H has no stiffness along the stretch: a trace of k keeps H - K invertible where
  // the contact has none either (a frictionless pull along the surface).
  const Mat3 H = hessian(e) + 1e-9 * k * Mat3::Identity();
  return H * (H - K).inverse() * K;
}

bool tool_touches(const Model& m, int k, double R, const Vec3& pose, const std::vector<Vec3>& x,
                  int t) {
  const auto& f = m.surface[t];
  const Vec3 &p0 = x[f[0]], &p1 = x[f[1]], &p2 = x[f[2]];
  Vec3 b;
  if (m.probes[k].shape == ToolShape::kSphere)
    return (closest_on_triangle(pose, p0, p1, p2, &b) - pose).squaredNorm() < R * R;
  const Vec3& a = m.probes[k].axis;
  const Mat3 P = Mat3::Identity() - a * a.transpose();
  const bool behind = (p0 - pose).dot(a) < 0 || (p1 - pose).dot(a) < 0 || (p2 - pose).dot(a) < 0;
  if (m.probes[k].shape == ToolShape::kPlane) return behind;
  return behind &&
         closest_on_triangle(Vec3::Zero(), P * (p0 - pose), P * (p1 - pose), P * (p2 - pose), &b)
                 .squaredNorm() < R * R;
}

double surface_spacing(const Model& m, const std::vector<int>& tris) {
  const int n = tris.empty() ? static_cast<int>(m.surface.size()) : static_cast<int>(tris.size());
  std::vector<double> edges;
  edges.reserve(2 * n);
  for (int q = 0; q < n; ++q) {
    const auto& f = m.surface[tris.empty() ? q : tris[q]];
    double l[3] = {(m.rest[f[1]] - m.rest[f[0]]).norm(), (m.rest[f[2]] - m.rest[f[1]]).norm(),
                   (m.rest[f[0]] - m.rest[f[2]]).norm()};
    std::sort(l, l + 3);
    edges.push_back(l[0]);
    edges.push_back(l[1]);
  }
  if (edges.empty()) return 0;
  std::nth_element(edges.begin(), edges.begin() + static_cast<long>(edges.size() / 2), edges.end());
  return edges[edges.size() / 2];
}

double triangle_distance(const Model& m, const std::vector<Vec3>& x, int t, const Vec3& p) {
  const auto& f = m.surface[t];
  Vec3 b;
  return (closest_on_triangle(p, x[f[0]], x[f[1]], x[f[2]], &b) - p).norm();
}

ContactLayer contact_layer(const Model& m, int k, double R) {
  ContactLayer layer;
  const double ks = m.probes[k].stiffness;
  layer.k = ks > 0 ? ks : kContactStiffnessFactor * m.contact_modulus / R;
  layer.g_max = kContactDepthFraction * R;
  return layer;
}

double contact_modulus(const Model& m) {
  // Springs: an isotropic central-force network, E = sum(k_ax l0^2) / (6 V), nu = 1/4.
  double volume = 0;
  for (const auto& t : m.surface) {
    const Vec3 &a = m.rest[t[0]], &b = m.rest[t[1]], &c = m.rest[t[2]];
    volume += a.dot(b.cross(c)) / 6;  // divergence theorem over the outward surface
  }
  volume = std::abs(volume);
  double kl2 = 0;
  for (const SpringGroup& g : m.groups) {
    const double k0 = g.law ? g.law->rest_stiffness() : g.card.hooke_k;
    for (int s = g.begin; s < g.end; ++s)
      kl2 += m.force_scale[s] * m.deflection_scale[s] * k0 * m.rest_length[s] * m.rest_length[s];
  }
  const double E_net = volume > 0 ? kl2 / (6 * volume) : 0.0;
  const double nu_net = 0.25;
  double G = E_net / (2 * (1 + nu_net)) + m.shear_modulus;
  double K = E_net / (3 * (1 - 2 * nu_net)) + m.bulk_modulus;
  if (!(G > 0)) G = 1.0;  // a body of no stiffness: any positive value keeps the layer defined
  if (!(K > 0)) K = G;
  const double E = 9 * K * G / (3 * K + G);
  const double nu = (3 * K - 2 * G) / (2 * (3 * K + G));
  return E / (1 - nu * nu);
}

void tool_contact(const Model& m, int k, double R, const Vec3& pose, const std::vector<Vec3>& x,
                  const int* tris, int n, ToolContact* out, Vec3* node_force, Mat3* node_block,
                  unsigned terms, double* node_area, Mat3* node_pair) {
  *out = ToolContact{};
  const ContactLayer layer = contact_layer(m, k, R);
  const int count = tris ? n : static_cast<int>(m.surface.size());
  const ProbeSpec& spec = m.probes[k];
  const Vec3 axis = spec.axis.normalized();
  for (int q = 0; q < count; ++q) {
    const int t = tris ? tris[q] : q;
    const auto& tri = m.surface[t];
    const Vec3 &p0 = x[tri[0]], &p1 = x[tri[1]], &p2 = x[tri[2]];
    Vec3* f[3] = {nullptr, nullptr, nullptr};
    Mat3* b[3] = {nullptr, nullptr, nullptr};
    double* ar[3] = {nullptr, nullptr, nullptr};
    for (int a = 0; a < 3; ++a) {
      if (node_force) f[a] = &node_force[tri[a]];
      if (node_block) b[a] = &node_block[tri[a]];
      if (node_area) ar[a] = &node_area[tri[a]];
    }
    bool touched;
    if (spec.shape == ToolShape::kSphere) {
      // Quick reject: the triangle's bounding sphere misses the ball.
      Vec3 cen;
      const double rad = triangle_bound(p0, p1, p2, &cen);
      if ((cen - pose).squaredNorm() >= (R + rad) * (R + rad)) continue;
      const SphereTool tool{pose, R};
      Accumulator<SphereTool> acc{
          layer, tool, out, {f[0], f[1], f[2]}, {b[0], b[1], b[2]}, terms, {ar[0], ar[1], ar[2]}};
      if (node_pair && tris) acc.pr = node_pair + 6 * q;
      sphere_triangle(p0, p1, p2, acc);
      touched = acc.touched;
    } else {
      // Quick reject: every vertex in front of the face.
      if ((p0 - pose).dot(axis) >= 0 && (p1 - pose).dot(axis) >= 0 && (p2 - pose).dot(axis) >= 0)
        continue;
      const PunchTool tool{pose, axis};
      Accumulator<PunchTool> acc{
          layer, tool, out, {f[0], f[1], f[2]}, {b[0], b[1], b[2]}, terms, {ar[0], ar[1], ar[2]}};
      if (node_pair && tris) acc.pr = node_pair + 6 * q;
      if (spec.shape == ToolShape::kPlane)
        plane_triangle(p0, p1, p2, acc);
      else
        punch_triangle(p0, p1, p2, R, acc);
      touched = acc.touched;
    }
    out->faces += touched;
  }
}

void friction_forces(const Model& m, int k, const ProbeState& p, const std::vector<Vec3>& x,
                     Vec3* node_force, Mat3* node_block) {
  if (!(m.probes[k].friction > 0) || p.stick < 0 || !(p.friction_limit > 0)) return;
  const auto& f = m.surface[p.stick];
  const Vec3& b = p.stick_bary;
  const Vec3 xs = carried_point(m, x, p.stick, b, p.stick_offset);
  const double kt = coupling_stiffness(m, k, probe_radius(m, k, p));
  const Mat3 P = Mat3::Identity() - p.contact_normal * p.contact_normal.transpose();
  Vec3 fb = kt * (P * (p.proxy - xs));
  if (fb.norm() > p.friction_limit) fb *= p.friction_limit / fb.norm();
  for (int a = 0; a < 3; ++a) {
    node_force[f[a]] += b[a] * fb;
    if (node_block) node_block[f[a]] += (b[a] * kt) * P;
  }
}

bool inside_surface(const Model& m, const std::vector<Vec3>& x, const Vec3& p) {
  // Generalised winding number: the solid angles of the outward triangles seen from p sum to
  // 4 pi inside a closed surface and 0 outside (Van Oosterom and Strackee's formula).
  double omega = 0;
  for (const auto& t : m.surface) {
    const Vec3 a = x[t[0]] - p, b = x[t[1]] - p, c = x[t[2]] - p;
    const double la = a.norm(), lb = b.norm(), lc = c.norm();
    const double num = a.dot(b.cross(c));
    const double den = la * lb * lc + a.dot(b) * lc + a.dot(c) * lb + b.dot(c) * la;
    omega += 2 * std::atan2(num, den);
  }
  return omega > 2 * M_PI;
}

void ContactCandidates::reserve(const Model& m) {
  if (triangles.capacity() < m.surface.size()) triangles.reserve(m.surface.size());
  if (near.capacity() < m.surface.size()) near.reserve(m.surface.size());
  if (x_pass.capacity() < m.surface_nodes.size()) x_pass.reserve(m.surface_nodes.size());
}

namespace {

// Squared distance (m^2) from point y to the segment a + s (b - a), s in [0, 1].
double segment_distance2(const Vec3& y, const Vec3& a, const Vec3& b) {
  const Vec3 seg = b - a;
  const double seg2 = seg.squaredNorm();
  const double s = seg2 > 0 ? std::clamp((y - a).dot(seg) / seg2, 0.0, 1.0) : 0.0;
  return (y - (a + s * seg)).squaredNorm();
}

// True when triangle t's bounding sphere comes within `reach` of the sweep a -> b of the tool's
// pose; for a plane (plane: its unit axis, the tool filling the half-space behind it), within
// `reach` of the half-space at either end of the sweep (a plane moves by translation only).
bool within_reach(const Model& m, const std::vector<Vec3>& x, int t, const Vec3& a, const Vec3& b,
                  double reach, const Vec3* plane) {
  const auto& f = m.surface[t];
  Vec3 cen;
  const double rad = triangle_bound(x[f[0]], x[f[1]], x[f[2]], &cen);
  if (plane) return (cen - a).dot(*plane) - rad < reach || (cen - b).dot(*plane) - rad < reach;
  const double lim = reach + rad;
  return segment_distance2(cen, a, b) < lim * lim;
}

// The broad phase (ContactCandidates): c->triangles = the triangles within `reach` of the sweep
// start -> target (plane: the unit axis of a plane tool, else null), from the list of the last
// pass while it provably holds them all, else after a new pass over the surface.
void gather_candidates(const Model& m, const std::vector<Vec3>& x, const Vec3& start,
                       const Vec3& target, double reach, double skin, const Vec3* plane,
                       ContactCandidates* c) {
  const int ns = static_cast<int>(m.surface_nodes.size());
  bool keep = c->model == &m && c->reach_pass == reach && c->skin_pass == skin &&
              static_cast<int>(c->x_pass.size()) == ns;
  if (keep) {
    const double swept = std::max((start - c->start_pass).norm(), (target - c->target_pass).norm());
    const double room = (skin - swept) / 3;  // the surface nodes may have moved this far
    keep = room > 0;
    const double room2 = room * room;
    for (int j = 0; keep && j < ns; ++j)
      keep = (x[m.surface_nodes[j]] - c->x_pass[j]).squaredNorm() < room2;
  }
  if (!keep) {
    c->near.clear();
    const int nt = static_cast<int>(m.surface.size());
    for (int t = 0; t < nt; ++t)
      if (within_reach(m, x, t, start, target, reach + skin, plane)) c->near.push_back(t);
    c->x_pass.resize(ns);
    for (int j = 0; j < ns; ++j) c->x_pass[j] = x[m.surface_nodes[j]];
    c->start_pass = start;
    c->target_pass = target;
    c->reach_pass = reach;
    c->skin_pass = skin;
    c->model = &m;
    ++c->passes;
  }
  c->triangles.clear();
  for (int t : c->near)
    if (within_reach(m, x, t, start, target, reach, plane)) c->triangles.push_back(t);
}

}  // namespace

void update_proxy(const Model& m, int k, const std::vector<Vec3>& x, ContactCandidates* candidates,
                  ProbeState* p, int max_evaluations) {
  p->evaluations = 0;
  p->force.setZero();
  p->stiffness.setZero();
  p->contacts = 0;
  p->depth = 0;
  if (candidates) candidates->triangles.clear();
  if (!p->active) {
    p->proxy_placed = false;
    p->proxy_velocity.setZero();
    p->anchor = -1;
    p->stick = -1;
    p->friction_force.setZero();
    p->friction_limit = 0;
    for (int i : p->bonded) {  // lifted off: released
      p->bond[i] = Vec3::Constant(std::nan(""));
      p->bond_area[i] = 0;
    }
    p->bonded.clear();
    return;
  }
  const double R = probe_radius(m, k, *p);
  const Coupling link = coupling(m, k, R);
  const double kvc = link.k;
  const Vec3 target = p->center;
  const Vec3 last_proxy = p->proxy;
  const bool was_placed = p->proxy_placed;
  const int nt = static_cast<int>(m.surface.size());
  const bool spec_is_sphere = m.probes[k].shape == ToolShape::kSphere;
  const Vec3* plane = plane_axis(m, k);
  ToolContact c;  // the layer at the proxy's pose
  // The proxy never moves deeper than this into the surface it sees (the barrier's linear
  // extension starts there).
  const double g_stop = 0.9 * kContactDepthFraction * R;
  // Start: the last proxy carried by the surface point it rode on, or, for a tool just placed,
  // the target itself or (inside the body) the nearest point of the surface.
  Vec3 start = p->proxy;
  if (!p->proxy_placed) {
    // A tool just placed starts where it touches the surface at most: outside the body, backed
    // off along the nearest face's normal until it no longer overlaps it, so that it sinks in at
    // the depth rate like any other move instead of striking the surface at once.
    start = target;
    if (plane) {
      // A plane: moved back along its axis until every surface node is at least `clear` in
      // front of it.
      const double clear = 1e-3 * R;
      double front = std::numeric_limits<double>::infinity();
      for (int j : m.surface_nodes) front = std::min(front, (x[j] - target).dot(*plane));
      if (front < clear) start = target + (front - clear) * *plane;
    } else if (nt > 0) {
      int t = 0;
      Vec3 b;
      const Vec3 at = nearest_surface_point(m, x, nullptr, nt, target, &t, &b);
      const bool inside = inside_surface(m, x, target);
      const double dist = (target - at).norm();
      // Away from the surface: along the nearest face's normal from inside, else straight away
      // from the nearest surface point.
      const Vec3 away =
          inside || !(dist > 0) ? Vec3(triangle_frame(m, x, t).col(2)) : Vec3((target - at) / dist);
      const double clear = std::max(spec_is_sphere ? R : 0.0, 1e-3 * R);
      if (inside || dist < clear) start = at + clear * away;
    }
    p->proxy_placed = true;
  } else if (p->anchor >= 0 && p->anchor < nt) {
    start = carried_point(m, x, p->anchor, p->anchor_bary, p->anchor_offset);
    // Carried by a surface that has not moved: the proxy where it was, not its round trip through
    // the anchor's coordinates (which moves it by round-off, so that replies against a paused
    // body would alternate in their last bits instead of repeating).
    if ((start - p->proxy).norm() <= 1e-12 * R) start = p->proxy;
  }
  // Candidates: triangles whose bounding sphere meets the capsule from start to target, widened
  // by the tool's reach.
  const double reach = kCandidateReach * R;
  const int* cand = nullptr;
  int nc = nt;
  if (candidates) candidates->reserve(m);
  auto gather = [&](const Vec3& from, const Vec3& to) {
    if (!candidates) return;
    gather_candidates(m, x, from, to, reach, kCandidateSkin * R, plane, candidates);
    cand = candidates->triangles.data();
    nc = static_cast<int>(candidates->triangles.size());
  };
  // The point riding on the surface nearest y among the listed triangles (triangle, barycentric
  // coordinates, offset in its frame), for the stick point.
  auto attach = [&](const Vec3& y, int* tri, Vec3* bary, Vec3* offset) {
    const Vec3 near = nearest_surface_point(m, x, cand, nc, y, tri, bary);
    if (*tri >= 0) *offset = triangle_frame(m, x, *tri).inverse() * (y - near);
    return near;
  };
  // The first crossing of the reference point's move with the pose a -> b with the surface
  // (parameter in [0, 1], or 2 when none). The reference point stays out of the body: the
  // sphere's centre; for a punch, the point one radius behind its face, inside the punch.
  const Vec3 ref = spec_is_sphere ? Vec3::Zero() : Vec3(-R * m.probes[k].axis);
  auto first_crossing = [&](const Vec3& a, const Vec3& b) {
    double tmin = 2;
    for (int q = 0; q < nc; ++q) {
      const auto& f = m.surface[cand ? cand[q] : q];
      tmin = std::min(tmin, segment_triangle(a + ref, b + ref, x[f[0]], x[f[1]], x[f[2]]));
    }
    return tmin;
  };
  // The layer's faces integrated by this update, summed over its evaluations (kProxyFaceBudget).
  int faces_spent = 0;
  auto evaluate = [&](const Vec3& pose, ToolContact* out) {
    ++p->evaluations;
    tool_contact(m, k, R, pose, x, cand, nc, out);
    faces_spent += out->faces;
  };
  // Another evaluation fits the update's face budget (the first kProxyMinEvaluations always do).
  auto affordable = [&] {
    return p->evaluations < kProxyMinEvaluations || faces_spent < kProxyFaceBudget;
  };
  bool landed = false;  // a far jump put down over the target (c: the layer there)
  if (spec_is_sphere && was_placed && p->bonded.empty() && nt > 0 &&
      (target - start).norm() > kProxyJump * R) {
    // A far jump (a device teleported, or clients taking turns with one probe): the sphere is
    // put down touching the surface over the target (or at the target, if that is free), as a
    // tool just placed is, and sinks from there at the depth rate, when the move there crosses no
    // surface; instead of the Newton solve sliding it there step by step (up to max_evaluations
    // layer evaluations against a long candidate list on every update) while the coupling,
    // stretched across the jump, pushes the tissue along.
    // The nearest surface point and the mean normal of the faces that share it (one face, or
    // those meeting at the edge or vertex it lies on): the side of the surface the target is on.
    double best = std::numeric_limits<double>::infinity();
    Vec3 near = target, normal = Vec3::Zero();
    for (int q = 0; q < nt; ++q) {
      const auto& f = m.surface[q];
      Vec3 bary;
      const Vec3 y = closest_on_triangle(target, x[f[0]], x[f[1]], x[f[2]], &bary);
      const double d = (y - target).norm();
      const Vec3 n = (x[f[1]] - x[f[0]]).cross(x[f[2]] - x[f[0]]).normalized();
      if (d < best - 1e-9 * R) {
        best = d;
        near = y;
        normal = n;
      } else if (d <= best + 1e-9 * R) {
        normal += n;
      }
    }
    const double dist = (target - near).norm();
    if (normal.norm() > 0) normal.normalize();
    const bool outside = (target - near).dot(normal) >= 0;
    // Out of the surface: along the normal at the face, or, at an edge or a vertex, straight
    // from the nearest point (in its normal cone).
    Vec3 away = normal;
    if (dist > 1e-9 * R) away = (outside ? 1.0 : -1.0) * (target - near) / dist;
    Vec3 over = outside && dist >= R ? target : Vec3(near + R * away);
    // The move goes straight, or, when that crosses the surface (the tool sits in a dent, the
    // target is past a bulge), through the air: lifted a radius off the surface it leaves,
    // across, and down onto the target (each leg within the candidates' reach of the move).
    auto clear_path = [&] {
      if (first_crossing(start, over) > 1) return true;
      ToolContact here;  // lifted along its push, or, free, as the target is
      evaluate(start, &here);
      const Vec3 up = here.force.norm() > 0 ? Vec3(here.force.normalized()) : away;
      const Vec3 lift = start + R * up, land = over + R * away;
      return first_crossing(start, lift) > 1 && first_crossing(lift, land) > 1 &&
             first_crossing(land, over) > 1;
    };
    // Not for a target deep inside (more than a radius under the surface): that is followed at
    // the depth rate from where the tool is.
    if ((outside || dist <= R) && (over - start).norm() > kProxyJump * R) {
      gather(start, over);
      if (clear_path()) {
        ToolContact there;
        evaluate(over, &there);
        // Touching other faces than the nearest one (in a corner, a dent): backed off along
        // their push once.
        if (there.depth > kProxyDepthRate * R && there.force.norm() > 0) {
          const Vec3 back = over + there.depth * there.force.normalized();
          if (first_crossing(over, back) > 1) {
            over = back;
            evaluate(over, &there);
          }
        }
        if (there.depth <= kProxyDepthRate * R) {
          start = over;
          c = there;
          landed = true;
        }
      }
    }
  }
  gather(start, target);
  Vec3 at = start;
  if (!landed) evaluate(at, &c);
  int evaluations = 1;  // of the layer in this Newton solve (max_evaluations)
  // One update sinks the tool by at most kProxyDepthRate R further into the surface it sees: a
  // device that jumps deep is followed over a few ticks instead of striking the surface at once.
  const double g_limit = std::min(g_stop, c.depth + kProxyDepthRate * R);
  // Coulomb friction (probe friction mu > 0): a tangential spring of stiffness k_vc from the
  // proxy to its stick point x_s (carried by the surface like the proxy), energy
  // k_vc / 2 |P (x - x_s)|^2 with P the projector off the contact normal n; when its force would
  // exceed mu times the normal force the stick point slides until it equals it.
  const double mu = m.probes[k].friction;
  const double kt = kvc;
  Mat3 P = Mat3::Zero();  // zero: no friction term
  Vec3 xs = Vec3::Zero();
  // Bonded nodes (nodes held): springs k_i from proxy + bond[i] to x_i, energy
  // sum k_i / 2 |x_i - bond[i] - y|^2 = kb / 2 |y - z|^2 + e_b, z the k-weighted mean of
  // x_i - bond[i], e_b the energy at y = z.
  const double k_layer = contact_layer(m, k, R).k;
  double kb = 0, eb = 0;
  Vec3 z = Vec3::Zero();
  for (int i : p->bonded) {
    const double ki = k_layer * p->bond_area[i];
    kb += ki;
    z += ki * (x[i] - p->bond[i]);
  }
  if (kb > 0) z /= kb;
  for (int i : p->bonded)
    eb += 0.5 * k_layer * p->bond_area[i] * (x[i] - p->bond[i] - z).squaredNorm();
  auto extra_energy = [&](const Vec3& y) {
    return 0.5 * kt * (P * (y - xs)).squaredNorm() + 0.5 * kb * (y - z).squaredNorm() + eb;
  };
  // Newton on Phi from `at` (c: the layer at `at`).
  auto newton = [&](Vec3& at, ToolContact& c) {
    evaluations = 1;  // the bound is per solve (friction's slip passes solve again)
    double phi = link.energy(at - target) + c.energy + extra_energy(at);
    for (int it = 0; it < 16 && evaluations < max_evaluations && affordable(); ++it) {
      const Vec3 grad = link.force(at - target) - c.force + kt * (P * (at - xs)) + kb * (at - z);
      if (grad.norm() <= 1e-14 * (kvc * R)) break;
      // Newton on the exact Hessian where it is positive definite, else on its positive part.
      const Mat3 Hf = kt * P + kb * Mat3::Identity();
      // (Saturated, the coupling's Hessian has no stiffness along its stretch; where that
      // leaves the matrix indefinite, the linear coupling's k_vc I stands in for it.)
      const Eigen::LDLT<Mat3> exact(link.hessian(at - target) - c.stiffness + Hf);
      const bool definite =
          exact.info() == Eigen::Success && exact.vectorD().minCoeff() > 1e-9 * kvc;
      Vec3 dx = definite
                    ? Vec3(-exact.solve(grad))
                    : Vec3(-(kvc * Mat3::Identity() - c.stiffness_psd + Hf).ldlt().solve(grad));
      // Converged to round-off: the layer's Gauss sums do not resolve a smaller step or decrease.
      if (dx.norm() <= 1e-10 * R || -grad.dot(dx) <= 1e-13 * std::abs(phi)) break;
      // The depth rate: a step that would sink the tool further than the update's limit keeps
      // its move along the surface and sinks only to the limit (0.99 of the room left; the
      // depth changes as minus the move along the layer's outward force to first order), the
      // rest of the way being the next update's. Without it the line search halves such a step
      // once per layer evaluation until the bound ends the solve.
      bool rate_bound = false;
      if (c.faces > 0 && c.force.norm() > 0) {
        const Vec3 n = c.force.normalized();
        const double room = 0.99 * std::max(0.0, g_limit - c.depth), sink = -n.dot(dx);
        if (sink > room) {
          dx += (sink - room) * n;
          rate_bound = true;
        }
      }
      const double cross = first_crossing(at, at + dx);
      if (cross <= 1) dx *= 0.9 * cross;
      // A small step (a device that moved a little since the last tick) is taken as it is: the
      // quadratic model is exact to O(|dx|^2) there, and the layer is evaluated once per update.
      // Not with friction, whose slip needs the normal force at the step's end.
      if (!(P.squaredNorm() > 0) && dx.norm() <= kProxyTrustStep * R &&
          (rate_bound || c.depth + dx.norm() < g_limit)) {
        at += dx;
        break;
      }
      double alpha = 1;
      ToolContact trial;
      Vec3 next = at;
      double phi_next = phi;
      bool accepted = false;
      for (int ls = 0; ls < kProxyLineSearch && evaluations < max_evaluations && affordable();
           ++ls) {
        next = at + alpha * dx;
        evaluate(next, &trial);
        ++evaluations;
        phi_next = link.energy(next - target) + trial.energy + extra_energy(next);
        const bool shallow = trial.depth < g_limit || trial.depth <= c.depth;
        if (shallow && phi_next <= phi + 1e-4 * alpha * grad.dot(dx)) {
          accepted = true;
          break;
        }
        // Too deep: shortened to where the depth meets the limit, the depth taken as changing
        // with the move along the trial's outward push (exact on a flat face), instead of halving
        // again and again (a device that jumps into the surface from off it).
        const double sink = trial.force.norm() > 0 ? -trial.force.normalized().dot(dx) : 0;
        if (!shallow && sink > 0) {
          const double back = (trial.depth - 0.99 * g_limit) / sink;
          alpha = std::clamp(alpha - back, 0.05 * alpha, 0.5 * alpha);
        } else {
          alpha *= 0.5;
        }
      }
      if (!accepted) break;
      const double moved = (next - at).norm();
      at = next;
      c = trial;
      phi = phi_next;
      if (moved <= 1e-12 * R) break;
    }
  };
  newton(at, c);
  // Free and at the target to round-off: exactly at it, so a tool off the body feels exactly 0.
  if (c.faces == 0 && kb == 0 && (at - target).norm() <= 1e-9 * R) at = target;
  p->friction_force.setZero();
  p->sliding = false;
  bool sticking = false;
  if (mu > 0 && c.faces > 0 && c.force.norm() > 0) {
    const Vec3 n = c.force.normalized();
    P = Mat3::Identity() - n * n.transpose();
    // The stick point: carried from the last update, or where the tool first touched.
    xs = at;
    if (p->stick >= 0 && p->stick < nt)
      xs = carried_point(m, x, p->stick, p->stick_bary, p->stick_offset);
    newton(at, c);
    Vec3 n_now = n;
    double limit = mu * std::abs(c.force.dot(n));
    if (kt * (P * (at - xs)).norm() > limit) {
      // Slip: the stick point follows the tool so that the friction force is mu times the
      // normal force, and the proxy is solved again against it, until the two agree.
      p->sliding = true;
      for (int pass = 0; pass < 4; ++pass) {
        const Vec3 e = P * (at - xs);
        if (!(e.norm() > 0)) break;
        xs = at - (limit / kt) * e.normalized();
        newton(at, c);
        if (!(c.force.norm() > 0)) break;
        n_now = c.force.normalized();
        P = Mat3::Identity() - n_now * n_now.transpose();
        limit = mu * std::abs(c.force.dot(n_now));
        if (std::abs(kt * (P * (at - xs)).norm() - limit) <= 1e-3 * limit) break;
      }
    } else {
      sticking = true;
    }
    p->friction_force = kt * (P * (at - xs));  // on the body, at the stick point
    p->contact_normal = n_now;
    p->friction_limit = limit;
    // Store the stick point on the surface for the next update and the contact stage.
    p->stick = -1;
    attach(xs, &p->stick, &p->stick_bary, &p->stick_offset);
  } else {
    p->stick = -1;
    p->friction_limit = 0;
  }
  // The proxy's velocity, the contact stage's reference for the layer's damping (nodes moving with
  // the tool are not damped): zero after a jump (a tool just placed, a far jump put down, a move of
  // more than kProxyJump R in one update), which is a teleport, not a motion; taken as one, it
  // would drag the nodes under the tool at metres per second.
  const bool jumped = !was_placed || landed || (at - last_proxy).norm() > kProxyJump * R;
  p->proxy_velocity = jumped ? Vec3::Zero() : Vec3((at - last_proxy) / m.options.dt);
  p->proxy = at;
  p->depth = c.depth;
  p->contacts = c.faces;
  p->force = link.force(at - target);
  // dF/dt = H (H - K')^-1 K' (H = k_vc I unsaturated): the coupling in series with the layer
  // (and, sticking, the friction spring: K' = K - k_t P; the bonds: K' -= kb I), nodes held.
  if (c.faces > 0 || kb > 0) {
    p->stiffness =
        link.device_stiffness(at - target, c.stiffness - (sticking ? Mat3(kt * P) : Mat3::Zero()) -
                                               kb * Mat3::Identity());
  }
  anchor_proxy(m, x, cand, nc, reach, p);
  // A bonded tool glues the surface it now covers: each node with a share of it is bonded where
  // it is relative to the proxy (the first time), and its bonded area grows to that share.
  if (m.probes[k].bonded && c.faces > 0) {
    ToolContact cover;
    ++p->evaluations;
    tool_contact(m, k, R, at, x, cand, nc, &cover, nullptr, nullptr, kToolForceOnly,
                 p->covered.data());
    for (int q = 0; q < nc; ++q)
      for (int i : m.surface[cand ? cand[q] : q]) {
        double& share = p->covered[i];
        if (share > 0) {
          if (std::isnan(p->bond[i].x())) {
            p->bond[i] = x[i] - at;
            p->bonded.push_back(i);
          }
          p->bond_area[i] = std::max(p->bond_area[i], share);
        }
        share = 0;
      }
  }
}

void hold_proxy(const Model& m, int k, const std::vector<Vec3>& x, ContactCandidates* candidates,
                ProbeState* p) {
  if (!p->active || !p->proxy_placed) {
    update_proxy(m, k, x, candidates, p);
    return;
  }
  const double R = probe_radius(m, k, *p);
  const double reach = kCandidateReach * R;
  if (candidates) {
    candidates->reserve(m);
    candidates->triangles.clear();
    gather_candidates(m, x, p->proxy, p->proxy, reach, kCandidateSkin * R, plane_axis(m, k),
                      candidates);
  }
  const int nt = static_cast<int>(m.surface.size());
  const int* cand = candidates ? candidates->triangles.data() : nullptr;
  const int nc = candidates ? static_cast<int>(candidates->triangles.size()) : nt;
  ToolContact c;
  tool_contact(m, k, R, p->proxy, x, cand, nc, &c, nullptr, nullptr, kToolStiffness);
  const Coupling link = coupling(m, k, R);
  p->proxy_velocity.setZero();
  p->depth = c.depth;
  p->contacts = c.faces;
  p->force = link.force(p->proxy - p->center);
  p->stiffness.setZero();
  if (c.faces > 0) p->stiffness = link.device_stiffness(p->proxy - p->center, c.stiffness);
  anchor_proxy(m, x, cand, nc, reach, p);
}

}  // namespace conica
