// The implicit system assembled as a sparse matrix (core/sparse_system.h) against the matrix-free
// product the Newton iteration uses (which tests/core/implicit_test.cc checks against a central
// difference of the forces), its Cholesky solve against that product and against a dense Eigen
// solve, and the kFactorCG step against a converged block-Jacobi CG step.
#include "core/sparse_system.h"

#include <SuiteSparse_config.h>
#include <gtest/gtest.h>

#include <Eigen/Dense>
#include <algorithm>
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <new>
#include <random>
#include <thread>
#include <vector>

#include "core/body.h"
#include "core/step.h"
#include "core/step_detail.h"
#include "lattice_meshes.h"
#include "loop/factor_worker.h"

// Allocations made on a thread while it counts (operator new and CHOLMOD's malloc).
#include "../counting_new.h"

namespace {
void* counting_malloc(std::size_t n) {
  if (counting_new::counting) ++counting_new::allocations;
  return std::malloc(n);
}
void* counting_calloc(std::size_t n, std::size_t k) {
  if (counting_new::counting) ++counting_new::allocations;
  return std::calloc(n, k);
}
void* counting_realloc(void* p, std::size_t n) {
  if (counting_new::counting) ++counting_new::allocations;
  return std::realloc(p, n);
}
}  // namespace

namespace conica {
namespace {

using testing_meshes::Tetrahedralised;

// A 20 x 20 x 15 mm block of the EF30 card with volume, spread (hexahedra) and shear terms on a
// frictionless base, pressed by a probe (node contact) and by a side plate; hexahedra or
// tetrahedra. kFactorCG unless `jacobi`; `contact` the probe's; `exact`: Newton's matrix with the
// tetrahedra's exact tangent.
Model Block(bool tets, bool jacobi = false, ContactModel contact = ContactModel::kNodes,
            bool exact = false) {
  BodySpec b = testing_meshes::Ef30Block(tets, 1e-3);
  FixedSelector base;
  base.kind = FixedSelector::Kind::kPlane;
  base.axes = 4;  // z only: the base slides
  b.fixed.push_back(base);
  FixedSelector corner;
  corner.kind = FixedSelector::Kind::kBox;
  corner.box_min = Vec3(-1e-4, -1e-4, -1e-4);
  corner.box_max = Vec3(1e-4, 1e-4, 1e-4);
  corner.axes = 3;
  b.fixed.push_back(corner);
  PlaneSpec plate;  // pushes the x = 20 mm face in by 0.4 mm
  plate.normal = Vec3(-1, 0, 0);
  plate.offset = -0.0196;
  b.planes = {plate};
  b.probes.push_back(ProbeSpec{0.006, 0, contact});
  b.options.integrator = Integrator::kImplicitEuler;
  b.options.exact_tangent = exact;
  b.options.linear_solver = jacobi ? LinearSolver::kBlockJacobiCG : LinearSolver::kFactorCG;
  b.options.mass_damping = 20;
  Model m;
  EXPECT_EQ(build_model(b, &m), "");
  return m;
}

// The probe pressed `depth` into the top centre.
void Press(State& s, double depth) { set_probe(s, 0, Vec3(0.01, 0.01, 0.015 + 0.006 - depth)); }

// A pressed state: 40 steps of the block-Jacobi solver while the probe goes 3 mm deep.
State Pressed(const Model& m) {
  Model j = m;
  j.options.linear_solver = LinearSolver::kBlockJacobiCG;
  State s = make_state(j);
  Workspace ws(j);
  for (int k = 0; k < 40; ++k) {
    Press(s, 3e-3 * (k + 1) / 40);
    step(j, s, ws);
  }
  return s;
}

std::vector<double> Random(const Model& m, unsigned seed) {
  const int nn = m.num_nodes();
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> u(-1, 1);
  std::vector<double> p(3 * nn);
  for (int i = 0; i < nn; ++i)
    for (int c = 0; c < 3; ++c) p[c * nn + i] = u(rng) * m.free_axes[i][c];
  return p;
}

double MaxAbs(const std::vector<double>& v) {
  double a = 0;
  for (double x : v) a = std::max(a, std::abs(x));
  return a;
}

// The dense matrix of the matrix-free product, column by column, on the free axes (*free: their
// component-major indices).
Eigen::MatrixXd DenseSystem(const Model& m, State& s, Workspace& ws, std::vector<int>* free) {
  const int nn = m.num_nodes(), n3 = 3 * nn;
  free->clear();
  for (int c = 0; c < 3; ++c)
    for (int i = 0; i < nn; ++i)
      if (m.free_axes[i][c]) free->push_back(c * nn + i);
  const int nf = static_cast<int>(free->size());
  Eigen::MatrixXd A(nf, nf);
  std::vector<double> e(n3, 0.0), y(n3);
  for (int q = 0; q < nf; ++q) {
    e[(*free)[q]] = 1;
    detail::system_product(m, s, ws, m.options.dt, e.data(), y.data());
    e[(*free)[q]] = 0;
    for (int r = 0; r < nf; ++r) A(r, q) = y[(*free)[r]];
  }
  return A;
}

// The dense solve A^-1 r over the free axes (r component-major, A from DenseSystem).
Eigen::VectorXd DenseSolve(const Eigen::MatrixXd& A, const std::vector<int>& free,
                           const std::vector<double>& r) {
  Eigen::VectorXd rf(static_cast<Eigen::Index>(free.size()));
  for (size_t q = 0; q < free.size(); ++q) rf[static_cast<Eigen::Index>(q)] = r[free[q]];
  return A.ldlt().solve(rf);
}

// The largest |z - zd| over the free axes (z component-major, zd from DenseSolve).
double ErrorOnFree(const std::vector<double>& z, const std::vector<int>& free,
                   const Eigen::VectorXd& zd) {
  double err = 0;
  for (size_t q = 0; q < free.size(); ++q)
    err = std::max(err, std::abs(z[free[q]] - zd[static_cast<Eigen::Index>(q)]));
  return err;
}

// z (component-major) is exactly zero on every fixed axis.
void ExpectZeroOnFixedAxes(const Model& m, const std::vector<double>& z) {
  const int nn = m.num_nodes();
  for (int i = 0; i < nn; ++i)
    for (int c = 0; c < 3; ++c)
      if (!m.free_axes[i][c]) {
        EXPECT_EQ(z[c * nn + i], 0.0) << "node " << i << " axis " << c;
      }
}

class SparseSystemTest : public ::testing::TestWithParam<bool> {};

TEST_P(SparseSystemTest, AssembledMatrixTimesAVectorIsTheMatrixFreeProduct) {
  const Model m = Block(GetParam());
  State s = Pressed(m);
  Workspace ws(m);
  ASSERT_TRUE(ws.factor);
  const int n3 = 3 * m.num_nodes();
  // The premise: probe and plate in contact, springs in compression (the clamped geometric
  // term), every element term present.
  for (int seed : {1, 2, 3}) {
    const std::vector<double> p = Random(m, seed);
    std::vector<double> y(n3), ya(n3);
    detail::system_product(m, s, ws, m.options.dt, p.data(), y.data());
    ASSERT_GT(ws.contact.num_nodes, 0);
    ws.factor->current->assemble(m, ws);
    ws.factor->current->multiply(p.data(), ya.data());
    std::vector<double> d(n3);
    for (int k = 0; k < n3; ++k) d[k] = ya[k] - y[k];
    EXPECT_LT(MaxAbs(d), 1e-12 * MaxAbs(y)) << "seed " << seed;
  }
  EXPECT_GT(ws.factor->current->factor_nonzeros(), ws.factor->current->nonzeros());
}

// The same with the surface tool pressing (the layer's faces as pair blocks) and Newton's matrix
// on the tetrahedra's exact tangent: the assembled matrix is the matrix-free product, and it is
// symmetric positive definite (a dense Cholesky factorisation of it succeeds).
TEST_P(SparseSystemTest, AssembledSurfaceLayerAndExactTangentAreTheMatrixFreeProduct) {
  const Model m = Block(GetParam(), false, ContactModel::kSurface, true);
  State s = Pressed(m);
  Workspace ws(m);
  step(m, s, ws);  // the proxy stage lists the faces near the tool in this workspace
  const int n3 = 3 * m.num_nodes();
  for (int seed : {1, 2}) {
    const std::vector<double> p = Random(m, seed);
    std::vector<double> y(n3), ya(n3);
    detail::system_product(m, s, ws, m.options.dt, p.data(), y.data());
    ASSERT_GT(ws.contact.num_pairs, 0);          // faces under the tool
    EXPECT_EQ(ws.elements.tangent, GetParam());  // tetrahedra: the exact tangent
    ws.factor->current->assemble(m, ws);
    ws.factor->current->multiply(p.data(), ya.data());
    std::vector<double> d(n3);
    for (int k = 0; k < n3; ++k) d[k] = ya[k] - y[k];
    EXPECT_LT(MaxAbs(d), 1e-12 * MaxAbs(y)) << "seed " << seed;
  }
  std::vector<int> free;
  const Eigen::MatrixXd A = DenseSystem(m, s, ws, &free);
  EXPECT_LT((A - A.transpose()).cwiseAbs().maxCoeff(), 1e-12 * A.cwiseAbs().maxCoeff());
  EXPECT_EQ(Eigen::LLT<Eigen::MatrixXd>(A).info(), Eigen::Success);
}

TEST_P(SparseSystemTest, FactorSolveInvertsTheMatrixFreeSystemLikeADenseSolve) {
  const Model m = Block(GetParam());
  State s = Pressed(m);
  Workspace ws(m);
  const int n3 = 3 * m.num_nodes();
  std::vector<int> free;
  const Eigen::MatrixXd A = DenseSystem(m, s, ws, &free);
  std::vector<double> y(n3);
  ws.factor->current->assemble(m, ws);
  ASSERT_TRUE(ws.factor->current->factorize());
  const std::vector<double> r = Random(m, 9);
  std::vector<double> z(n3);
  ws.factor->current->solve(r.data(), z.data());
  const Eigen::VectorXd zd = DenseSolve(A, free, r);
  EXPECT_LT(ErrorOnFree(z, free, zd), 1e-9 * zd.cwiseAbs().maxCoeff());
  // And A z = r through the matrix-free product; z vanishes on fixed axes.
  detail::system_product(m, s, ws, m.options.dt, z.data(), y.data());
  std::vector<double> res(n3);
  for (int k = 0; k < n3; ++k) res[k] = y[k] - r[k];
  EXPECT_LT(MaxAbs(res), 1e-9 * MaxAbs(r));
  ExpectZeroOnFixedAxes(m, z);
}

// The preconditioner's single-precision sweeps of a supernodal factor against the dense solve:
// within a few ulps of single precision times A's condition where the solve is within 1e-9,
// zero on fixed axes; a simplicial factor's precondition() is its solve().
TEST_P(SparseSystemTest, SinglePrecisionPreconditionerIsTheDenseSolveToSinglePrecision) {
  const Model m = Block(GetParam());
  State s = Pressed(m);
  Workspace ws(m);
  const int n3 = 3 * m.num_nodes();
  std::vector<int> free;
  const Eigen::MatrixXd A = DenseSystem(m, s, ws, &free);
  const std::vector<double> r = Random(m, 11);
  const Eigen::VectorXd zd = DenseSolve(A, free, r);
  Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd> eig(A, Eigen::EigenvaluesOnly);
  const double cond = eig.eigenvalues().maxCoeff() / eig.eigenvalues().minCoeff();
  for (SystemFactor::Kind kind :
       {SystemFactor::Kind::kSupernodal, SystemFactor::Kind::kSimplicial}) {
    const bool super = kind == SystemFactor::Kind::kSupernodal;
    SystemFactor f(m, kind);
    detail::prepare_system_at(m, s, ws, m.options.dt);
    f.assemble(m, ws);
    ASSERT_TRUE(f.factorize());
    std::vector<double> z(n3, -1.0), zs(n3, -1.0);
    f.precondition(r.data(), z.data());
    f.solve(r.data(), zs.data());
    const double err = ErrorOnFree(z, free, zd), err_solve = ErrorOnFree(zs, free, zd);
    const double scale = zd.cwiseAbs().maxCoeff();
    std::printf(
        "%s: precondition() within %.3g of the dense solve, solve() within %.3g (relative; "
        "A's condition %.3g)\n",
        super ? "supernodal" : "simplicial", err / scale, err_solve / scale, cond);
    EXPECT_LT(err_solve, 1e-9 * scale);
    if (super) {
      EXPECT_LT(err, 1e-6 * cond * scale);  // single precision: 6e-8 per operation
      EXPECT_GT(err, err_solve);            // and it is single precision
    } else {
      EXPECT_EQ(z, zs);
    }
    ExpectZeroOnFixedAxes(m, z);
  }
}

// The block of A^-1 over a few nodes (a corner node with fixed axes among them), as the
// multi-rate body's local compliance takes it, against the dense inverse: the supernodal
// factor's pruned forward solve and the simplicial factor's full solves.
TEST_P(SparseSystemTest, InverseBlockIsTheDenseInverseOverTheNodes) {
  const Model m = Block(GetParam());
  State s = Pressed(m);
  Workspace ws(m);
  const int nn = m.num_nodes();
  std::vector<int> free;
  const Eigen::MatrixXd A = DenseSystem(m, s, ws, &free);
  const Eigen::MatrixXd Ainv = A.ldlt().solve(Eigen::MatrixXd::Identity(A.rows(), A.cols()));
  std::vector<int> index(3 * nn, -1);  // component-major axis -> row of A
  for (size_t q = 0; q < free.size(); ++q) index[free[q]] = static_cast<int>(q);
  // The nodes nearest the top centre, and the fixed corner at the origin.
  std::vector<std::pair<double, int>> near;
  for (int i = 0; i < nn; ++i) near.emplace_back((s.x[i] - Vec3(0.01, 0.01, 0.015)).norm(), i);
  std::sort(near.begin(), near.end());
  std::vector<int> nodes;
  for (int a = 0; a < 12; ++a) nodes.push_back(near[a].second);
  int corner = 0;
  for (int i = 0; i < nn; ++i)
    if (s.x[i].norm() < s.x[corner].norm()) corner = i;
  nodes.push_back(corner);
  const int k = 3 * static_cast<int>(nodes.size()), ld = k + 2;
  for (SystemFactor::Kind kind :
       {SystemFactor::Kind::kSupernodal, SystemFactor::Kind::kSimplicial}) {
    SystemFactor f(m, kind);
    detail::prepare_system_at(m, s, ws, m.options.dt);
    f.assemble(m, ws);
    ASSERT_TRUE(f.factorize());
    std::vector<double> w(static_cast<size_t>(ld) * k, -1.0);
    f.inverse_block(nodes.data(), static_cast<int>(nodes.size()), w.data(), ld);
    double err = 0, scale = 0;
    int fixed = 0;
    for (int c = 0; c < k; ++c)
      for (int r = 0; r < k; ++r) {
        const int ir = index[(r % 3) * nn + nodes[r / 3]], ic = index[(c % 3) * nn + nodes[c / 3]];
        const double ref = ir >= 0 && ic >= 0 ? Ainv(ir, ic) : 0.0;
        fixed += ir < 0 && r == c;
        err = std::max(err, std::abs(w[static_cast<size_t>(c) * ld + r] - ref));
        scale = std::max(scale, std::abs(ref));
      }
    EXPECT_GT(fixed, 0);  // the corner's fixed axes are in the block
    EXPECT_LT(err, 1e-9 * scale) << (kind == SystemFactor::Kind::kSupernodal ? "supernodal"
                                                                             : "simplicial");
  }
}

// One Newton step, solved by CG with a fresh factor and by block-Jacobi CG run to convergence.
TEST_P(SparseSystemTest, PreconditionedSolveReachesTheConvergedNewtonStep) {
  Model mf = Block(GetParam());
  Model mj = Block(GetParam(), true);
  for (Model* m : {&mf, &mj}) {
    m->options.newton_iterations = 1;
    m->options.cg_tolerance = 1e-13;
  }
  mj.options.cg_iterations = 5000;
  const State s0 = Pressed(mf);
  State sf = s0, sj = s0;
  Workspace wf(mf), wj(mj);
  Press(sf, 3.2e-3);
  Press(sj, 3.2e-3);
  step(mf, sf, wf);
  step(mj, sj, wj);
  EXPECT_EQ(sf.counters.factorizations, 1u);
  EXPECT_LE(sf.counters.cg_iterations - s0.counters.cg_iterations, 3u);
  EXPECT_GT(sj.counters.cg_iterations - s0.counters.cg_iterations, 30u);
  double diff = 0, motion = 0;
  for (int i = 0; i < mf.num_nodes(); ++i) {
    diff = std::max(diff, (sf.x[i] - sj.x[i]).norm());
    motion = std::max(motion, (sj.x[i] - s0.x[i]).norm());
  }
  ASSERT_GT(motion, 0);
  EXPECT_LT(diff, 1e-8 * motion);
}

// A press with the factor renewed only on demand: the trajectory is the converged one and CG
// takes a few iterations per Newton iteration with a factor many steps old.
TEST_P(SparseSystemTest, StaleFactorKeepsTheConvergedTrajectoryInFewIterations) {
  Model mf = Block(GetParam());
  Model mj = Block(GetParam(), true);
  for (Model* m : {&mf, &mj}) m->options.cg_tolerance = 1e-10;
  mj.options.cg_iterations = 5000;
  mf.options.cg_iterations = 100;
  State sf = make_state(mf), sj = make_state(mj);
  Workspace wf(mf), wj(mj);
  constexpr int kSteps = 120;
  for (int k = 0; k < kSteps; ++k) {
    const double depth = 4e-3 * std::min(1.0, (k + 1) / 80.0);
    Press(sf, depth);
    Press(sj, depth);
    step(mf, sf, wf);
    step(mj, sj, wj);
  }
  double diff = 0, motion = 0;
  for (int i = 0; i < mf.num_nodes(); ++i) {
    diff = std::max(diff, (sf.x[i] - sj.x[i]).norm());
    motion = std::max(motion, (sj.x[i] - mf.rest[i]).norm());
  }
  EXPECT_LT(diff, 1e-6 * motion);
  EXPECT_LT((sf.probes[0].force - sj.probes[0].force).norm(), 1e-6 * sj.probes[0].force.norm());
  const double per_solve =
      double(sf.counters.cg_iterations) / (kSteps * mf.options.newton_iterations);
  EXPECT_LE(per_solve, mf.options.refactor_iterations + 1.0);
  EXPECT_LT(sf.counters.factorizations, kSteps / 2u);  // 37-38 here, during the ramp
  EXPECT_EQ(sf.counters.factor_failures, 0u);
  EXPECT_EQ(sf.counters.rollbacks, 0u);
}

// With a worker thread factoring, the stepping thread allocates nothing, CHOLMOD included, and
// the factors the worker hands over are taken into use.
TEST(SparseFactorWorkerTest, StepAllocatesNothingWhileAWorkerFactors) {
  SuiteSparse_config.malloc_func = counting_malloc;
  SuiteSparse_config.calloc_func = counting_calloc;
  SuiteSparse_config.realloc_func = counting_realloc;
  const Model m = Block(true);
  State s = make_state(m);
  Workspace ws(m);
  long allocations = 0;
  {
    loop::FactorWorker worker(ws.factor.get());
    for (int k = 0; k < 200; ++k) {
      Press(s, 3e-3 * std::min(1.0, (k + 1) / 100.0));
      counting_new::counting = true;
      step(m, s, ws);
      counting_new::counting = false;
      if (k > 0)
        allocations += counting_new::allocations;  // the first step's assembly sizes nothing either
      counting_new::allocations = 0;
      std::this_thread::sleep_for(std::chrono::microseconds(200));  // a 1 kHz loop's rest
    }
  }
  SuiteSparse_config.malloc_func = std::malloc;
  SuiteSparse_config.calloc_func = std::calloc;
  SuiteSparse_config.realloc_func = std::realloc;
  EXPECT_EQ(allocations, 0);
  EXPECT_GE(s.counters.factorizations, 2u);
  EXPECT_EQ(s.counters.factor_failures, 0u);
  EXPECT_EQ(s.counters.rollbacks, 0u);
}

// newton_tolerance turns the Newton budget into a cap: the step stops once an update moves no
// node farther than the tolerance, and lands where the whole budget lands, within it. With the
// Gauss-Newton blocks one iteration is measurably short of it; with the exact tangent
// (tetrahedra's element terms) one iteration lands closer than with them.
TEST_P(SparseSystemTest, NewtonToleranceStopsAtTheConvergedStep) {
  const Model base = Block(GetParam());
  const State pressed = Pressed(base);
  for (const LinearSolver solver : {LinearSolver::kFactorCG, LinearSolver::kBlockJacobiCG}) {
    // iterations: Newton iterations, plus the ends the factor's estimate made (an iteration
    // whose update the factor's preconditioner alone found within the tolerance).
    std::uint64_t estimates = 0;
    auto step_with = [&](int newton, double tol, std::uint64_t* iterations, bool exact = true) {
      Model m = base;
      m.options.exact_tangent = exact;
      m.options.linear_solver = solver;
      m.options.newton_iterations = newton;
      m.options.newton_tolerance = tol;
      m.options.cg_iterations = 400;
      m.options.cg_tolerance = 1e-12;
      State s = pressed;
      Workspace ws(m);
      Press(s, 3.4e-3);  // 0.4 mm deeper than the pressed state
      const std::uint64_t n0 = s.counters.newton_iterations, e0 = s.counters.newton_estimates;
      step(m, s, ws);
      estimates = s.counters.newton_estimates - e0;
      *iterations = s.counters.newton_iterations - n0 + estimates;
      return s;
    };
    std::uint64_t n_full = 0, n_tol = 0, n_one = 0;
    const State full = step_with(10, 0, &n_full);
    const State early = step_with(10, 1e-8, &n_tol);
    const std::uint64_t early_estimates = estimates;
    const State one = step_with(1, 0, &n_one, false);
    std::uint64_t n_one_exact = 0;
    const State one_exact = step_with(1, 0, &n_one_exact, true);
    EXPECT_EQ(n_full, 10u);
    EXPECT_EQ(n_one, 1u);
    EXPECT_GE(n_tol, 2u);
    EXPECT_LT(n_tol, 10u);
    double d_early = 0, d_one = 0, d_one_exact = 0;
    for (int i = 0; i < base.num_nodes(); ++i) {
      d_early = std::max(d_early, (early.x[i] - full.x[i]).norm());
      d_one = std::max(d_one, (one.x[i] - full.x[i]).norm());
      d_one_exact = std::max(d_one_exact, (one_exact.x[i] - full.x[i]).norm());
    }
    const bool factor = solver == LinearSolver::kFactorCG;
    // Block-Jacobi has no estimate; the factor's (fresh here) ends the converged step.
    EXPECT_EQ(early_estimates, factor ? 1u : 0u);
    std::printf(
        "%s: Newton iterations %llu of 10; largest node distance to the full budget %.3g m "
        "(one iteration: %.3g m Gauss-Newton, %.3g m exact tangent)\n",
        factor ? "factor CG" : "block-Jacobi CG", static_cast<unsigned long long>(n_tol), d_early,
        d_one, d_one_exact);
    EXPECT_LT(d_early, 1e-8) << factor;
    EXPECT_GT(d_one, 10 * 1e-8) << factor;  // the comparison can tell an unconverged step
    if (GetParam()) {                       // tetrahedra
      EXPECT_LT(d_one_exact, 0.1 * d_one) << factor;
    }
  }
}

int ThreadsOfThisProcess() {
  int n = 0;
  for ([[maybe_unused]] const auto& e : std::filesystem::directory_iterator("/proc/self/task")) ++n;
  return n;
}

// The supernodal factorisation of a body the size of the phantom (10 x 10 x 6 hexahedra, 847
// nodes: supernodes large enough for CHOLMOD's OpenMP teams) runs on the factorising thread
// alone: no thread is started to compete with the 1 kHz loop, and the factor still solves the
// system.
TEST(SupernodalFactorTest, FactorisesOnTheCallingThreadAlone) {
  BodySpec b = testing_meshes::Ef30Block(false);
  b.mesh = make_box_lattice(Vec3(0.05, 0.05, 0.03), {10, 10, 6});
  FixedSelector base;
  base.kind = FixedSelector::Kind::kPlane;
  b.fixed.push_back(base);
  b.options.integrator = Integrator::kImplicitEuler;
  b.options.linear_solver = LinearSolver::kFactorCG;
  b.options.dt = 0.01;
  Model m;
  ASSERT_EQ(build_model(b, &m), "");
  State s = make_state(m);
  Workspace ws(m);
  const int before = ThreadsOfThisProcess();
  SystemFactor f(m, SystemFactor::Kind::kSupernodal);
  // Factored on a thread other than the one that made it (as the body thread does).
  bool factored = false;
  int during = 0;
  std::thread body([&] {
    detail::prepare_system_at(m, s, ws, m.options.dt);
    f.assemble(m, ws);
    factored = f.factorize();
    during = ThreadsOfThisProcess();
  });
  body.join();
  ASSERT_TRUE(factored);
  ASSERT_TRUE(f.supernodal());
  EXPECT_EQ(during, before + 1);  // this thread and the factorising one
  EXPECT_EQ(ThreadsOfThisProcess(), before);
  // A x = r solved: the factor is the system's.
  const std::vector<double> r = Random(m, 7);
  std::vector<double> z(r.size()), y(r.size());
  f.solve(r.data(), z.data());
  f.multiply(z.data(), y.data());
  double e = 0;
  for (size_t k = 0; k < r.size(); ++k) e = std::max(e, std::abs(y[k] - r[k]));
  EXPECT_LT(e, 1e-9 * MaxAbs(r));
}

INSTANTIATE_TEST_SUITE_P(HexahedraTetrahedra, SparseSystemTest, ::testing::Bool(),
                         [](const auto& info) { return info.param ? "tets" : "hexes"; });

}  // namespace
}  // namespace conica
