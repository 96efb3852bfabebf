// The compile stage (compile.cc): the spring layout covers every spring once, in runs that join
// consecutive nodes and chunks of one group; the per-node spring lists hold each spring at both
// ends; the hard-stop length is the card's solid height or the minimum length fraction; and the
// far field's spectral bound contains the largest eigenvalue of M^-1 K, computed here densely.
#include <gtest/gtest.h>

#include <Eigen/Eigenvalues>
#include <algorithm>
#include <cmath>
#include <limits>
#include <vector>

#include "core/body.h"
#include "core/step.h"
#include "lattice_meshes.h"

namespace conica {
namespace {

using testing_meshes::Lattice;
using testing_meshes::Tetrahedralised;

SpringCard Conical() {
  SpringCard c;
  c.conical = ConicalCard{2e8, 1e-3, 2e-3, 8e-3, 10e-3, 3};
  c.stiffness_cap = 20;
  return c;
}

TEST(CompileTest, RunsAndChunksCoverEverySpringOnceWithinItsGroup) {
  const Model m = Lattice(Conical(), {5, 4, 3}, 0.01);
  const Workspace ws(m);
  const SpringLayout& L = ws.layout;
  ASSERT_FALSE(L.runs.empty()) << "a lattice's springs are in runs";
  std::vector<int> seen(m.num_springs(), 0);
  for (const SpringLayout::Run& r : L.runs)
    for (int t = 0; t < r.n; ++t) {
      ++seen[r.k + t];
      EXPECT_EQ(m.spring_i[r.k + t], r.i + t);
      EXPECT_EQ(m.spring_j[r.k + t], r.j + t);
    }
  for (int k = 0; k < m.num_springs(); ++k) ASSERT_EQ(seen[k], 1) << "spring " << k;
  int next = 0;
  for (size_t c = 0; c < L.chunks.size(); ++c) {
    const SpringLayout::Chunk& ch = L.chunks[c];
    EXPECT_EQ(ch.k0, next) << "chunks are consecutive";
    next = ch.k1;
    EXPECT_LE(ch.k1 - ch.k0, SpringLayout::kChunkSprings);
    EXPECT_GE(ch.k0, m.groups[ch.group].begin);
    EXPECT_LE(ch.k1, m.groups[ch.group].end);
    EXPECT_EQ(L.runs[ch.first_run].k, ch.k0);
    const SpringLayout::Run& last = L.runs[ch.last_run - 1];
    EXPECT_EQ(last.k + last.n, ch.k1);
    for (int k = ch.k0; k < ch.k1; ++k) EXPECT_EQ(L.spring_chunk[k], static_cast<int>(c));
  }
  EXPECT_EQ(next, m.num_springs());
}

TEST(CompileTest, NodeSpringListsHoldEachSpringAtBothEnds) {
  BodySpec b;
  b.mesh = Tetrahedralised(make_box_lattice(Vec3(0.02, 0.02, 0.01), {2, 2, 1}));
  b.groups.push_back({"tissue", Conical(), kAllFamilies, {}, Vec3::Zero(), 10});
  Model m;
  ASSERT_EQ(build_model(b, &m), "");
  const Workspace ws(m);
  const SpringLayout& L = ws.layout;
  ASSERT_EQ(static_cast<int>(L.node_spring_start.size()), m.num_nodes() + 1);
  for (int i = 0; i < m.num_nodes(); ++i) {
    std::vector<int> expect;
    for (int k = 0; k < m.num_springs(); ++k)
      if (m.spring_i[k] == i || m.spring_j[k] == i) expect.push_back(k);
    std::vector<int> got(L.node_springs.begin() + L.node_spring_start[i],
                         L.node_springs.begin() + L.node_spring_start[i + 1]);
    std::sort(got.begin(), got.end());
    EXPECT_EQ(got, expect) << "node " << i;
  }
  for (int k = 0; k < m.num_springs(); ++k)
    EXPECT_EQ(L.spring_group[k], 0) << "one group: every spring in it";
}

TEST(CompileTest, HardStopLengthIsTheSolidHeightOrTheLengthFraction) {
  // The paper's eq. (3): the solid height of a conical spring is Ls = sqrt((n_a d)^2 - (r2 -
  // r1)^2), its stroke S = L0 - Ls (card units); a spring of deflection scale b (card units per
  // metre) reaches it at length l0 - S / b, unless the minimum length fraction is longer.
  SpringCard card = Conical();
  card.conical = ConicalCard{2e8, 1e-3, 2e-3, 6e-3, 10e-3, 3};
  const Model m = Lattice(card, {2, 2, 2}, 0.01);
  const Workspace ws(m);
  const ConicalCard& cc = card.conical;
  const double ls = std::sqrt(std::pow(cc.n_a * cc.d, 2) - std::pow((cc.D2 - cc.D1) / 2, 2));
  const double stroke = cc.L0 - ls;
  for (int k = 0; k < m.num_springs(); k += 7) {
    const double l0 = m.rest_length[k];
    const double stop = l0 - stroke / m.deflection_scale[k];
    const double expect = std::max(stop, m.options.min_length_fraction * l0);
    EXPECT_DOUBLE_EQ(ws.layout.min_length[k], expect) << "spring " << k;
    EXPECT_DOUBLE_EQ(ws.layout.min_length2[k], expect * expect);
    EXPECT_GT(ws.layout.min_length[k], 0);
    EXPECT_LT(ws.layout.min_length[k], l0);
  }
  Model off = m;
  off.options.hard_stop = false;
  EXPECT_EQ(Workspace(off).layout.min_length[0], -std::numeric_limits<double>::infinity());
}

TEST(CompileTest, SpectralBoundContainsTheLargestEigenvalueOfTheLinearPhase) {
  // M^-1 K of the body at rest (K = sum a b K0 d d^T over free axes), assembled densely here and
  // solved by Eigen: the Lanczos bound must contain its largest eigenvalue within a few percent,
  // and the Gershgorin bound behind far_max_every must contain it too.
  SpringCard c;
  c.law = LawKind::kHooke;
  c.hooke_k = 50;
  c.hooke_length = 0.01;
  Model m = Lattice(c, {3, 3, 2}, 0.01);
  const int nn = m.num_nodes(), n3 = 3 * nn;
  Eigen::MatrixXd K = Eigen::MatrixXd::Zero(n3, n3);
  std::vector<double> node_k(nn, 0.0);
  for (int k = 0; k < m.num_springs(); ++k) {
    const int i = m.spring_i[k], j = m.spring_j[k];
    const Vec3 d = (m.rest[j] - m.rest[i]).normalized();
    const double kax = m.force_scale[k] * m.deflection_scale[k] * c.hooke_k;
    const Mat3 B = kax * d * d.transpose();
    K.block<3, 3>(3 * i, 3 * i) += B;
    K.block<3, 3>(3 * j, 3 * j) += B;
    K.block<3, 3>(3 * i, 3 * j) -= B;
    K.block<3, 3>(3 * j, 3 * i) -= B;
    node_k[i] += kax;
    node_k[j] += kax;
  }
  Eigen::VectorXd s(n3);  // M^-1/2 on free axes
  for (int i = 0; i < nn; ++i)
    for (int a = 0; a < 3; ++a) s[3 * i + a] = std::sqrt(m.inv_mass[i]) * m.free_axes[i][a];
  const Eigen::MatrixXd A = s.asDiagonal() * K * s.asDiagonal();
  const double lambda = Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd>(A).eigenvalues()(n3 - 1);
  ASSERT_GT(lambda, 0);
  const double bound = far_spectral_bound(m);
  EXPECT_GE(bound, lambda * (1 - 1e-9));
  EXPECT_LE(bound, 1.05 * lambda);
  double gershgorin = 0;
  for (int i = 0; i < nn; ++i) gershgorin = std::max(gershgorin, 2 * node_k[i] * m.inv_mass[i]);
  EXPECT_GE(gershgorin, lambda);
  // far_max_every is the interval with H sqrt(gershgorin) <= 0.9 * 2.
  const Workspace ws(m);
  const double H = ws.bounds.far_max_every * m.options.dt;
  EXPECT_LE(H * std::sqrt(gershgorin), 1.8 + 1e-12);
  EXPECT_GT((ws.bounds.far_max_every + 1) * m.options.dt * std::sqrt(gershgorin), 1.8 - 1e-12);
}

}  // namespace
}  // namespace conica
