// Every term of ElementTerms (core/element_terms.h) against its own energy, one term at a time,
// on tetrahedra and on hexahedra (with the Gauss-point spread):
//   - its forces are minus a central difference of its energy;
//   - its system block is symmetric, positive semi-definite and blind to translations;
//   - the volume term's block is the exact Hessian at rest (a central difference of its forces),
//     and the shear term's quadratic form is the exact second variation mu gamma^2 V of a simple
//     shear (the analytic value, and a second difference of its energy);
//   - its diagonal blocks are the node blocks of its product.
#include "core/element_terms.h"

#include <gtest/gtest.h>

#include <Eigen/Eigenvalues>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <random>
#include <string>
#include <vector>

#include "core/body.h"
#include "core/step.h"
#include "core/volume.h"
#include "lattice_meshes.h"

namespace conica {
namespace {

using testing_meshes::Tetrahedralised;

struct Body {
  Model m;
  std::string name;
};

// A 20 x 30 x 20 mm box lattice with every element term (hexahedra: with the spread), or its
// tetrahedra; soft springs that play no part here.
Body ElementBody(bool tets) {
  BodySpec b;
  b.mesh = make_box_lattice(Vec3(0.02, 0.03, 0.02), {2, 3, 2});
  if (tets) b.mesh = Tetrahedralised(b.mesh);
  SpringCard c;
  c.law = LawKind::kHooke;
  c.hooke_k = 5;
  c.hooke_length = 0.01;
  b.groups.push_back({"all", c, kAllFamilies, {}, Vec3::Zero(), 10});
  b.bulk_modulus = 2e5;
  b.spread_modulus = tets ? 0 : 1.5e5;
  b.shear_modulus = 4e4;
  Body body;
  EXPECT_EQ(build_model(b, &body.m), "");
  body.name = tets ? "tetrahedra" : "hexahedra";
  return body;
}

std::vector<Vec3> Jittered(const Model& m, double amplitude, unsigned seed) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> u(-amplitude, amplitude);
  std::vector<Vec3> x = m.rest;
  for (Vec3& p : x) p += Vec3(u(rng), u(rng), u(rng));
  return x;
}

// x + s p.
std::vector<Vec3> Displaced(const std::vector<Vec3>& x, const std::vector<Vec3>& p, double s) {
  std::vector<Vec3> out = x;
  for (size_t i = 0; i < out.size(); ++i) out[i] += s * p[i];
  return out;
}

template <typename Term>
std::vector<Vec3> Forces(const Model& m, const std::vector<Vec3>& x, ElementScratch& E) {
  std::vector<Vec3> f(m.num_nodes(), Vec3::Zero());
  Term::add_forces(m, x, E, f);
  return f;
}

// y = (the term's h^2 H) p over the body, p and y per node.
template <typename Term>
std::vector<Vec3> Product(const Model& m, const ElementScratch& E, double h2,
                          const std::vector<Vec3>& p) {
  std::vector<Vec3> y(m.num_nodes(), Vec3::Zero());
  for_each_element(m, [&](auto n, int e, const auto& nodes) {
    constexpr int N = decltype(n)::value;
    double P[3][N], Y[3][N] = {};
    for (int a = 0; a < N; ++a)
      for (int c = 0; c < 3; ++c) P[c][a] = p[nodes[a]][c];
    Term::template times<N>(m, E, h2, e, P, Y);
    for (int a = 0; a < N; ++a)
      for (int c = 0; c < 3; ++c) y[nodes[a]][c] += Y[c][a];
  });
  return y;
}

double Dot(const std::vector<Vec3>& a, const std::vector<Vec3>& b) {
  double s = 0;
  for (size_t i = 0; i < a.size(); ++i) s += a[i].dot(b[i]);
  return s;
}

template <typename Term>
void CheckTerm(const Body& body) {
  const Model& m = body.m;
  SCOPED_TRACE(body.name);
  ASSERT_TRUE(Term::active(m));
  Workspace ws(m);
  ElementScratch& E = ws.elements;
  const int nn = m.num_nodes();
  const double h2 = 1e-6;  // (1 ms)^2

  // Forces are minus the gradient of the energy.
  const std::vector<Vec3> x = Jittered(m, 1e-3, 3);
  const std::vector<Vec3> f = Forces<Term>(m, x, E);
  const double eps = 1e-8;
  double fmax = 0;
  for (const Vec3& v : f) fmax = std::max(fmax, v.cwiseAbs().maxCoeff());
  ASSERT_GT(fmax, 0);
  for (int i = 0; i < nn; ++i)
    for (int c = 0; c < 3; ++c) {
      std::vector<Vec3> xp = x, xm = x;
      xp[i][c] += eps;
      xm[i][c] -= eps;
      const double fd = -(Term::energy(m, xp) - Term::energy(m, xm)) / (2 * eps);
      EXPECT_NEAR(f[i][c], fd, 1e-6 * fmax) << "node " << i << " axis " << c;
    }

  // The block at the jittered state (E holds what add_forces kept): symmetric, PSD, no
  // translation stiffness.
  Term::prepare_system(m, h2, E);
  std::mt19937 rng(11);
  std::uniform_real_distribution<double> u(-1, 1);
  double ref = 0;  // N, the largest entry of a product with a random p
  for (int trial = 0; trial < 4; ++trial) {
    std::vector<Vec3> p(nn), q(nn);
    for (int i = 0; i < nn; ++i) {
      p[i] = Vec3(u(rng), u(rng), u(rng));
      q[i] = Vec3(u(rng), u(rng), u(rng));
    }
    const std::vector<Vec3> hp = Product<Term>(m, E, h2, p), hq = Product<Term>(m, E, h2, q);
    const double scale = std::sqrt(Dot(hp, hp) * Dot(q, q)) + 1e-300;
    for (const Vec3& v : hp) ref = std::max(ref, v.cwiseAbs().maxCoeff());
    EXPECT_NEAR(Dot(q, hp), Dot(p, hq), 1e-12 * scale) << "symmetry, trial " << trial;
    EXPECT_GE(Dot(p, hp), -1e-12 * scale) << "semi-definite, trial " << trial;
  }
  for (int c = 0; c < 3; ++c) {
    std::vector<Vec3> t(nn, Vec3::Unit(c));
    const std::vector<Vec3> ht = Product<Term>(m, E, h2, t);
    double largest = 0;
    for (const Vec3& v : ht) largest = std::max(largest, v.norm());
    EXPECT_LT(largest, 1e-12 * ref) << "translation along axis " << c;
  }

  // The diagonal blocks are the node blocks of the product: column (i, c) of h^2 H read at node i.
  std::vector<double> d(6 * nn, 0.0);
  for_each_element(m, [&](auto n, int e, const auto& nodes) {
    constexpr int N = decltype(n)::value;
    Term::template diagonal<N>(m, E, h2, e, nodes, nn, d.data());
  });
  static constexpr int kEntry[3][3] = {{0, 3, 4}, {3, 1, 5}, {4, 5, 2}};
  for (int i = 0; i < nn; i += 5)
    for (int c = 0; c < 3; ++c) {
      std::vector<Vec3> unit(nn, Vec3::Zero());
      unit[i][c] = 1;
      const Vec3 col = Product<Term>(m, E, h2, unit)[i];
      for (int r = 0; r < 3; ++r)
        EXPECT_NEAR(d[kEntry[r][c] * nn + i], col[r], 1e-12 * ref)
            << "node " << i << " block (" << r << ", " << c << ")";
    }
}

TEST(ElementTermsTest, VolumeTermForcesBlockAndDiagonalAgreeWithItsEnergy) {
  for (bool tets : {true, false}) CheckTerm<VolumeTerm>(ElementBody(tets));
}

TEST(ElementTermsTest, ShearTermForcesBlockAndDiagonalAgreeWithItsEnergy) {
  for (bool tets : {true, false}) CheckTerm<ShearTerm>(ElementBody(tets));
}

TEST(ElementTermsTest, VolumeBlockIsTheExactHessianAtRest) {
  // At rest J = 1 (and every Gauss point's share is its rest share), so the dropped term
  // kappa (J - 1) d2V/dx2 vanishes: h^2 H p = -h^2 (f(x + e p) - f(x - e p)) / (2 e).
  for (bool tets : {true, false}) {
    const Body body = ElementBody(tets);
    const Model& m = body.m;
    SCOPED_TRACE(body.name);
    Workspace ws(m);
    const double h2 = 1e-6, eps = 1e-7;
    std::vector<Vec3> p = Jittered(m, 1.0, 5);
    for (int i = 0; i < m.num_nodes(); ++i) p[i] -= m.rest[i];
    Forces<VolumeTerm>(m, m.rest, ws.elements);  // keeps the gradients at rest
    const std::vector<Vec3> hp = Product<VolumeTerm>(m, ws.elements, h2, p);
    ElementScratch scratch = ws.elements;
    const std::vector<Vec3> fp = Forces<VolumeTerm>(m, Displaced(m.rest, p, eps), scratch);
    const std::vector<Vec3> fm = Forces<VolumeTerm>(m, Displaced(m.rest, p, -eps), scratch);
    double largest = 0;
    for (const Vec3& v : hp) largest = std::max(largest, v.cwiseAbs().maxCoeff());
    ASSERT_GT(largest, 0);
    for (int i = 0; i < m.num_nodes(); ++i)
      for (int c = 0; c < 3; ++c)
        EXPECT_NEAR(hp[i][c], -h2 * (fp[i][c] - fm[i][c]) / (2 * eps), 1e-6 * largest)
            << "node " << i << " axis " << c;
  }
}

TEST(ElementTermsTest, ShearBlockGivesTheSecondVariationOfASimpleShear) {
  // u = gamma y e_x from rest: F = I + gamma e_x e_y^T, J = 1, W = (mu / 2) gamma^2 per unit
  // volume exactly, so d2W/dgamma2 = mu V. The Laplacian block's quadratic form p^T H p with
  // p = y e_x must equal it (and a second difference of the term's energy).
  for (bool tets : {true, false}) {
    const Body body = ElementBody(tets);
    const Model& m = body.m;
    SCOPED_TRACE(body.name);
    Workspace ws(m);
    const double h2 = 1.0;
    std::vector<Vec3> p(m.num_nodes());
    for (int i = 0; i < m.num_nodes(); ++i) p[i] = Vec3(m.rest[i].y(), 0, 0);
    Forces<ShearTerm>(m, m.rest, ws.elements);
    ShearTerm::prepare_system(m, h2, ws.elements);
    const double quadratic = Dot(p, Product<ShearTerm>(m, ws.elements, h2, p));
    const double volume = 0.02 * 0.03 * 0.02;
    EXPECT_NEAR(quadratic, m.shear_modulus * volume, 1e-9 * m.shear_modulus * volume);
    const double g = 1e-4;
    std::vector<Vec3> xp = m.rest, xm = m.rest;
    for (int i = 0; i < m.num_nodes(); ++i) {
      xp[i] += g * p[i];
      xm[i] -= g * p[i];
    }
    const double second =
        (ShearTerm::energy(m, xp) - 2 * ShearTerm::energy(m, m.rest) + ShearTerm::energy(m, xm)) /
        (g * g);
    EXPECT_NEAR(quadratic, second, 1e-5 * quadratic);
  }
}

// The exact Hessian (element_term_hessian, what the multi-rate body's local compliance is built
// from) on a compressed, jittered body: its bilinear form u^T H v summed over the elements equals
// a mixed second difference of the terms' total energy (VolumeTerm::energy + ShearTerm::energy,
// not the forces it is differenced from), and there it differs from the Gauss-Newton blocks the
// Newton system holds (the curvature they leave out).
TEST(ElementTermsTest, ExactHessianIsTheSecondVariationOfTheEnergy) {
  for (bool tets : {true, false}) {
    const Body body = ElementBody(tets);
    const Model& m = body.m;
    SCOPED_TRACE(body.name);
    std::vector<Vec3> x = Jittered(m, 1e-3, 7);
    for (Vec3& q : x) q.z() *= 0.8;  // 20 % compressed: J != 1
    std::vector<Vec3> u = Jittered(m, 1.0, 8), v = Jittered(m, 1.0, 9);
    for (int i = 0; i < m.num_nodes(); ++i) {
      u[i] -= m.rest[i];
      v[i] -= m.rest[i];
    }
    double form = 0;
    std::vector<double> H(24 * 24);
    for_each_element(m, [&](auto n, int e, const auto& nodes) {
      constexpr int N = decltype(n)::value;
      Vec3 xe[N];
      for (int a = 0; a < N; ++a) xe[a] = x[nodes[a]];
      element_term_hessian<N>(m, e, xe, H.data());
      for (int a = 0; a < N; ++a)
        for (int b = 0; b < N; ++b)
          for (int i = 0; i < 3; ++i)
            for (int k = 0; k < 3; ++k)
              form += u[nodes[a]][i] * H[(3 * a + i) * 3 * N + 3 * b + k] * v[nodes[b]][k];
    });
    auto energy = [&](double su, double sv) {
      std::vector<Vec3> y = x;
      for (int i = 0; i < m.num_nodes(); ++i) y[i] += su * u[i] + sv * v[i];
      return VolumeTerm::energy(m, y) + ShearTerm::energy(m, y);
    };
    const double g = 1e-5;
    const double second =
        (energy(g, g) - energy(g, -g) - energy(-g, g) + energy(-g, -g)) / (4 * g * g);
    EXPECT_NEAR(form, second, 1e-4 * std::abs(second));
    // The Gauss-Newton blocks at x (both terms): their bilinear form.
    Workspace ws(m);
    Forces<VolumeTerm>(m, x, ws.elements);
    Forces<ShearTerm>(m, x, ws.elements);
    ShearTerm::prepare_system(m, 1.0, ws.elements);
    const double gn = Dot(u, Product<VolumeTerm>(m, ws.elements, 1.0, v)) +
                      Dot(u, Product<ShearTerm>(m, ws.elements, 1.0, v));
    std::printf("%s: u^T H v exact %.6g, second difference %.6g, Gauss-Newton %.6g\n",
                body.name.c_str(), form, second, gn);
    EXPECT_GT(std::abs(gn - second), 1e-2 * std::abs(second));
  }
}

// The closed-form tetrahedron Hessian (tet_term_hessian, what Newton's exact tangent and the
// multi-rate compliance take) equals the central difference of the terms' forces
// (element_term_hessian) element by element on a compressed, jittered body with shear stiffening,
// and the packed tangent (prepare_tet_tangents, expand_tet_tangent, tet_tangent_times) holds the
// same matrix where it is positive semi-definite, and its projection where it is not (its
// product and its expansion agree with each other).
TEST(ElementTermsTest, ClosedFormTetrahedronHessianIsTheForcesDifference) {
  for (const double stiffening : {0.0, 0.8}) {
    Body body = ElementBody(true);
    Model& m = body.m;
    m.shear_stiffening = stiffening;
    std::vector<Vec3> x = Jittered(m, 1e-3, 11);
    for (Vec3& q : x) q.z() *= 0.8;  // 20 % compressed: J != 1
    ElementScratch E;
    E.tet_tangent.assign(45 * m.tetrahedra.size(), 0.0);
    ElementScratch E0 = E;  // the same at rest: positive semi-definite, nothing projected
    EXPECT_EQ(prepare_tet_tangents(m, m.rest, 2.0, E0), 0);
    const int projected = prepare_tet_tangents(m, x, 2.0, E);
    const int nn = m.num_nodes();
    std::vector<double> p(3 * nn), y(3 * nn, 0.0), y_ref(3 * nn, 0.0);
    std::mt19937 rng(5);
    std::uniform_real_distribution<double> u(-1, 1);
    for (double& v : p) v = u(rng);
    double worst = 0, scale = 0;
    int indefinite = 0;
    for (size_t e = 0; e < m.tetrahedra.size(); ++e) {
      const auto& nodes = m.tetrahedra[e];
      Vec3 xe[4];
      for (int a = 0; a < 4; ++a) xe[a] = x[nodes[a]];
      double H[144], Hd[144], He[144];
      tet_term_hessian(m, static_cast<int>(e), xe, H);
      element_term_hessian<4>(m, static_cast<int>(e), xe, Hd);
      expand_tet_tangent(E.tet_tangent.data() + 45 * e, He);
      for (int k = 0; k < 144; ++k) {
        scale = std::max(scale, std::abs(Hd[k]));
        worst = std::max(worst, std::abs(H[k] - Hd[k]));
      }
      // The packed tangent: 2 H where H's block over nodes 1-3 (T) has no eigenvalue below
      // -1e-3 of its largest diagonal entry; elsewhere T with its negative eigenvalues clamped.
      using Mat12 = Eigen::Matrix<double, 12, 12, Eigen::RowMajor>;
      using Mat9 = Eigen::Matrix<double, 9, 9>;
      const Eigen::Map<const Mat12> Hm(H), Hem(He);
      const Mat12 Hs = 0.5 * (Hm + Hm.transpose());
      const Mat9 T = Hs.block<9, 9>(3, 3);
      const Eigen::SelfAdjointEigenSolver<Mat9> eh(T);
      if (eh.eigenvalues().minCoeff() >= -1e-3 * T.diagonal().maxCoeff()) {
        EXPECT_LT((Hem - 2.0 * Hs).cwiseAbs().maxCoeff(), 1e-9 * Hs.cwiseAbs().maxCoeff());
      } else {
        ++indefinite;
        const Mat9 Tp = eh.eigenvectors() * eh.eigenvalues().cwiseMax(0.0).asDiagonal() *
                        eh.eigenvectors().transpose();
        EXPECT_LT((Hem.block<9, 9>(3, 3) - 2.0 * Tp).cwiseAbs().maxCoeff(),
                  1e-9 * T.cwiseAbs().maxCoeff());
        const Mat12 He_full = Hem;
        const Eigen::SelfAdjointEigenSolver<Mat12> ee(He_full);
        EXPECT_GE(ee.eigenvalues().minCoeff(), -1e-9 * Hem.cwiseAbs().maxCoeff());
      }
      tet_tangent_times(E.tet_tangent.data() + 45 * e, nodes, nn, p.data(), y.data());
      for (int r = 0; r < 12; ++r)
        for (int c = 0; c < 12; ++c)
          y_ref[(r % 3) * nn + nodes[r / 3]] += He[12 * r + c] * p[(c % 3) * nn + nodes[c / 3]];
    }
    std::printf(
        "beta %.1f: closed form against the difference: largest gap %.3g of %.3g; %d of %zu "
        "elements indefinite, %d projected\n",
        stiffening, worst, scale, indefinite, m.tetrahedra.size(), projected);
    EXPECT_EQ(projected, indefinite);
    EXPECT_LT(worst, 1e-5 * scale);
    for (int k = 0; k < 3 * nn; ++k) EXPECT_NEAR(y[k], y_ref[k], 1e-9 * (1 + std::abs(y_ref[k])));
  }
}

// The element stage with both terms on takes the hexahedra in one pass (core/element_terms.cc,
// hex_terms): its forces are minus a central difference of the two terms' energies, and it keeps
// what the two terms' own passes keep (their independent routes: the volume from the map's
// Jacobian, the shear from the rest shape gradients), on a jittered lattice, on one jittered
// past J <= 0 at some Gauss points, and without the spread.
TEST(ElementTermsTest, OnePassOverTheHexahedraIsBothTermsPasses) {
  for (int variant = 0; variant < 3; ++variant) {
    const bool inverted = variant == 1;
    SCOPED_TRACE(variant == 0 ? "jittered" : inverted ? "some Gauss points inverted" : "no spread");
    Body body = ElementBody(false);
    body.m.shear_stiffening = 0.3;
    if (variant == 2) body.m.spread_modulus = 0;
    const Model& m = body.m;
    Workspace ws(m), ws_terms(m);
    State s = make_state(m);
    s.x = Jittered(m, inverted ? 8e-3 : 1e-3, 5);
    std::fill(ws.force.begin(), ws.force.end(), Vec3::Zero());
    element_forces(m, s, ws);
    std::vector<Vec3> f(m.num_nodes(), Vec3::Zero());
    VolumeTerm::add_forces(m, s.x, ws_terms.elements, f);
    ShearTerm::add_forces(m, s.x, ws_terms.elements, f);
    double fmax = 0;
    for (const Vec3& v : f) fmax = std::max(fmax, v.cwiseAbs().maxCoeff());
    ASSERT_GT(fmax, 0);
    int inverted_points = 0;
    for (size_t e = 0; e < m.hexahedra.size(); ++e)
      for (int q = 0; q < 8; ++q) {
        Vec3 xe[8];
        for (int a = 0; a < 8; ++a) xe[a] = s.x[m.hexahedra[e][a]];
        const Vec3* b = m.shear_b.data() + 64 * e + 8 * q;
        Mat3 F = Mat3::Zero();
        for (int a = 0; a < 8; ++a) F += xe[a] * b[a].transpose();
        inverted_points += F.determinant() <= 0;
      }
    if (inverted) EXPECT_GT(inverted_points, 0);
    const double eps = 1e-8;
    for (int i = 0; i < m.num_nodes(); ++i)
      for (int c = 0; c < 3; ++c) {
        EXPECT_NEAR(ws.force[i][c], f[i][c], 1e-12 * fmax) << "node " << i << " axis " << c;
        std::vector<Vec3> xp = s.x, xm = s.x;
        xp[i][c] += eps;
        xm[i][c] -= eps;
        const double fd = -(VolumeTerm::energy(m, xp) + ShearTerm::energy(m, xp) -
                            VolumeTerm::energy(m, xm) - ShearTerm::energy(m, xm)) /
                          (2 * eps);
        EXPECT_NEAR(ws.force[i][c], fd, 1e-6 * fmax) << "node " << i << " axis " << c;
      }
    const ElementScratch &E = ws.elements, &T = ws_terms.elements;
    auto same = [](const auto& a, const auto& b, const char* what) {
      ASSERT_EQ(a.size(), b.size()) << what;
      double scale = 0;
      for (const auto& v : b) scale = std::max(scale, v.norm());
      for (size_t k = 0; k < a.size(); ++k)
        EXPECT_NEAR((a[k] - b[k]).norm(), 0, 1e-12 * scale) << what << " entry " << k;
    };
    same(E.volume_grad, T.volume_grad, "volume_grad");
    same(E.spread_grad, T.spread_grad, "spread_grad");
    for (size_t k = 0; k < T.volume_coef.size(); ++k)
      EXPECT_DOUBLE_EQ(E.volume_coef[k], T.volume_coef[k]) << "volume_coef " << k;
    for (size_t k = 0; k < T.spread_coef.size(); ++k)
      EXPECT_DOUBLE_EQ(E.spread_coef[k], T.spread_coef[k]) << "spread_coef " << k;
    for (size_t k = 0; k < T.shear_coef.size(); ++k)
      EXPECT_NEAR(E.shear_coef[k], T.shear_coef[k], 1e-13 * std::abs(T.shear_coef[k]))
          << "shear_coef " << k;
  }
}

// inverse_cube_root (core/volume.h) against the standard library's cube root, one value at a
// time and eight at once, over 600 orders of magnitude and at the range's ends.
TEST(ElementTermsTest, InverseCubeRootIsTheLibrarysToAFewUnitsInTheLastPlace) {
  std::mt19937 rng(7);
  std::uniform_real_distribution<double> u(-690, 690);
  double worst = 0;
  for (int k = 0; k < 100000; k += 8) {
    double x[8], y[8];
    for (double& v : x) v = std::exp(u(rng));
    if (k == 0) {
      x[0] = 1;
      x[1] = 1e-310;  // below the guess's range: the library's own
      x[2] = 1.5e300;
      x[3] = 0.999999;
    }
    Lanes8 lanes;
    std::memcpy(&lanes, x, sizeof lanes);
    lanes = inverse_cube_roots(lanes);
    std::memcpy(y, &lanes, sizeof lanes);
    for (int i = 0; i < 8; ++i) {
      const double want = 1 / std::cbrt(x[i]);
      worst = std::max(worst, std::abs(y[i] - want) / want);
      EXPECT_EQ(y[i], inverse_cube_root(x[i])) << x[i];
    }
  }
  EXPECT_LT(worst, 2e-15);
}

TEST(ElementTermsTest, TheListHoldsEveryTermAndSkipsAbsentOnes) {
  // for_each_term visits the terms the model has, in the list's order.
  BodySpec b;
  b.mesh = make_box_lattice(Vec3(0.01, 0.01, 0.01), {1, 1, 1});
  SpringCard c;
  c.law = LawKind::kHooke;
  c.hooke_k = 5;
  c.hooke_length = 0.01;
  b.groups.push_back({"all", c, kAllFamilies, {}, Vec3::Zero(), 10});
  b.shear_modulus = 1e4;
  Model m;
  ASSERT_EQ(build_model(b, &m), "");
  std::vector<std::string> seen;
  for_each_term(m, [&](auto term) {
    seen.push_back(std::is_same_v<decltype(term), VolumeTerm> ? "volume" : "shear");
  });
  EXPECT_EQ(seen, std::vector<std::string>{"shear"});
  std::vector<std::string> listed, reversed;
  auto name = [](auto term) {
    return std::is_same_v<decltype(term), VolumeTerm> ? "volume" : "shear";
  };
  ElementTerms::for_each([&](auto term) { listed.push_back(name(term)); });
  ElementTerms::for_each_reversed([&](auto term) { reversed.push_back(name(term)); });
  EXPECT_EQ(listed, (std::vector<std::string>{"volume", "shear"}));
  EXPECT_EQ(reversed, (std::vector<std::string>{"shear", "volume"}));
}

}  // namespace
}  // namespace conica
