// The implicit system's sparse assembly and CHOLMOD factor (core/sparse_system.h).
#include "core/sparse_system.h"

#include <cholmod.h>

#include <Eigen/Dense>
#include <algorithm>
#include <cstdlib>
#include <utility>

#include "core/body.h"
#include "core/element_terms.h"
#include "core/step.h"

// libgomp's, when CHOLMOD brings it (Debian's CHOLMOD is built with OpenMP); null otherwise.
extern "C" void omp_set_max_active_levels(int) __attribute__((weak));

namespace conica {

struct SystemFactor::Cholmod {
  cholmod_common c;
  cholmod_sparse* A = nullptr;
  cholmod_factor* L = nullptr;
  cholmod_dense* B = nullptr;
  Cholmod() {
    cholmod_start(&c);
    c.print = 0;  // the core prints nothing; failures are reported through the return value
    c.error_handler = nullptr;
  }
  ~Cholmod() {
    if (B) cholmod_free_dense(&B, &c);
    if (L) cholmod_free_factor(&L, &c);
    if (A) cholmod_free_sparse(&A, &c);
    cholmod_finish(&c);
  }
};

SystemFactor::SystemFactor(const Model& m, Kind kind)
    : nn_(m.num_nodes()), kind_(kind), c_(std::make_unique<Cholmod>()) {
  const int nn = nn_, ns = m.num_springs();
  // Block pattern: for every block column J the block rows I <= J that can be nonzero (the
  // mesh graph's neighbours of J up to J; sorted).
  const std::vector<std::vector<int>> graph = node_neighbours(m);
  std::vector<int> start(nn + 1, 0), rows;
  for (int j = 0; j < nn; ++j) {
    const std::vector<int>& g = graph[j];
    rows.insert(rows.end(), g.begin(), std::upper_bound(g.begin(), g.end(), j));
    start[j + 1] = static_cast<int>(rows.size());
  }
  auto block = [&](int i, int j) {
    if (i > j) std::swap(i, j);
    return static_cast<int>(
        std::lower_bound(rows.begin() + start[j], rows.begin() + start[j + 1], i) - rows.begin());
  };
  const int nb = static_cast<int>(rows.size());
  blocks_.assign(9 * static_cast<size_t>(nb), 0.0);
  diag_block_.resize(nn);
  for (int i = 0; i < nn; ++i) diag_block_[i] = block(i, i);
  spring_blocks_.resize(3 * static_cast<size_t>(ns));
  for (int k = 0; k < ns; ++k) {
    const int i = m.spring_i[k], j = m.spring_j[k];
    spring_blocks_[3 * k] = block(i, i);
    spring_blocks_[3 * k + 1] = block(j, j);
    spring_blocks_[3 * k + 2] = block(i, j);
  }
  for_each_element(m, [&](auto n, int, const auto& nodes) {
    constexpr int N = decltype(n)::value;
    for (int a = 0; a < N; ++a)
      for (int b = 0; b < N; ++b)
        element_blocks_.push_back(nodes[a] <= nodes[b] ? block(nodes[a], nodes[b]) : -1);
  });
  // Each surface triangle's corner pairs (0, 1), (0, 2), (1, 2): the surface layers' pair blocks
  // (ContactScratch::pair); -1 where the pair is not in the mesh graph (its block is then lumped
  // onto the two diagonals).
  for (const auto& tri : m.surface)
    for (auto [a, b] : {std::pair{0, 1}, std::pair{0, 2}, std::pair{1, 2}}) {
      const int i = std::min(tri[a], tri[b]), j = std::max(tri[a], tri[b]);
      const int id = block(i, j);
      surface_blocks_.push_back(id < start[j + 1] && rows[id] == i ? id : -1);
    }
  free_.resize(3 * static_cast<size_t>(nn));
  for (int i = 0; i < nn; ++i)
    for (int c = 0; c < 3; ++c) free_[c * nn + i] = m.free_axes[i][c];

  // Scalar upper triangle in compressed columns: column 3 J + c holds, for every block (I, J) in
  // row order, rows 3 I + r (r <= c on the diagonal block).
  const int n = 3 * nn;
  std::vector<int> colp(n + 1, 0), rowi;
  for (int j = 0; j < nn; ++j)
    for (int c = 0; c < 3; ++c) {
      for (int b = start[j]; b < start[j + 1]; ++b) {
        const int i = rows[b];
        for (int r = 0; r < 3; ++r) {
          if (i == j && r > c) continue;
          const bool fr = m.free_axes[i][r] != 0, fc = m.free_axes[j][c] != 0;
          rowi.push_back(3 * i + r);
          src_.push_back(fr && fc ? 9 * b + 3 * r + c : (i == j && r == c) ? -1 : -2);
        }
      }
      colp[3 * j + c + 1] = static_cast<int>(rowi.size());
    }
  cholmod_common& cc = c_->c;
  c_->A = cholmod_allocate_sparse(n, n, rowi.size(), 1, 1, 1, CHOLMOD_REAL, &cc);
  auto* p = static_cast<int*>(c_->A->p);
  auto* ri = static_cast<int*>(c_->A->i);
  std::copy(colp.begin(), colp.end(), p);
  std::copy(rowi.begin(), rowi.end(), ri);
  auto* x = static_cast<double*>(c_->A->x);
  for (size_t k = 0; k < src_.size(); ++k) x[k] = src_[k] == -1 ? 1.0 : 0.0;
  // Simplicial by default: CG pays a solve per iteration and the factorisation runs off the step;
  // on the bodies measured (docs/performance.md) the simplicial solve is the faster one.
  cc.supernodal = kind == Kind::kSupernodal ? CHOLMOD_SUPERNODAL : CHOLMOD_SIMPLICIAL;
  // The fill-reducing ordering: AMD and CHOLMOD's nested dissection (METIS bisection) both, the
  // one with the fewer flops kept. On the 3,243-node liver nested dissection gives 10 % fewer
  // entries in L and 26 % fewer flops per factorisation (docs/performance.md).
  cc.nmethods = 2;
  cc.method[0].ordering = CHOLMOD_AMD;
  cc.method[1].ordering = CHOLMOD_NESDIS;
  c_->L = cholmod_analyze(c_->A, &cc);
  iperm_.assign(n, 0);
  if (c_->L) {
    const auto* perm = static_cast<const int*>(c_->L->Perm);
    for (int k = 0; k < n; ++k) iperm_[perm[k]] = k;
    if (c_->L->is_super) {
      const auto* pi = static_cast<const int*>(c_->L->pi);
      for (size_t s = 0; s < c_->L->nsuper; ++s)
        max_nsrow_ = std::max(max_nsrow_, pi[s + 1] - pi[s]);
      x_.resize(n);
      t_.resize(max_nsrow_);
    }
  }
  c_->B = cholmod_zeros(n, 1, CHOLMOD_REAL, &cc);
  work_.assign(n, 0.0);
}

SystemFactor::~SystemFactor() = default;

std::int64_t SystemFactor::nonzeros() const { return static_cast<std::int64_t>(src_.size()); }
std::int64_t SystemFactor::factor_nonzeros() const { return static_cast<std::int64_t>(c_->c.lnz); }
bool SystemFactor::supernodal() const { return c_->L && c_->L->is_super; }

void SystemFactor::assemble(const Model& m, const Workspace& ws,
                            const std::vector<Vec3>* exact_at) {
  const int nn = nn_, ns = m.num_springs();
  double* __restrict bv = blocks_.data();
  std::fill(blocks_.begin(), blocks_.end(), 0.0);
  auto add_diag = [&](int b, double v) {
    bv[9 * b] += v;
    bv[9 * b + 4] += v;
    bv[9 * b + 8] += v;
  };
  for (int i = 0; i < nn; ++i) add_diag(diag_block_[i], ws.system.mass[i]);
  for (int q = 0; q < ws.contact.num_nodes; ++q) {
    const int i = ws.contact.nodes[q];
    const Vec3& cn = ws.contact.n[i];
    const Mat3 b = cn * cn.transpose() + ws.system.h2 * ws.contact.block[i];
    double* d = bv + 9 * diag_block_[i];
    for (int r = 0; r < 3; ++r)
      for (int c = 0; c < 3; ++c) d[3 * r + c] += b(r, c);
  }
  for (int t = 0; t < ws.contact.num_pairs; ++t) {  // the surface layers' faces
    const int tri = ws.contact.pair_tris[t];
    const auto& nodes = m.surface[tri];
    const Mat3* K = ws.contact.pair.data() + 6 * t;
    auto add = [&](int id, const Mat3& b) {
      double* d = bv + 9 * id;
      for (int r = 0; r < 3; ++r)
        for (int c = 0; c < 3; ++c) d[3 * r + c] += ws.system.h2 * b(r, c);
    };
    for (int a = 0; a < 3; ++a) add(diag_block_[nodes[a]], K[a]);
    constexpr int kA[3] = {0, 0, 1}, kB[3] = {1, 2, 2};
    for (int j = 0; j < 3; ++j) {
      const int id = surface_blocks_[3 * tri + j];
      if (id >= 0) {
        add(id, K[3 + j]);
      } else {
        add(diag_block_[nodes[kA[j]]], K[3 + j]);
        add(diag_block_[nodes[kB[j]]], K[3 + j]);
      }
    }
  }
  const double* alpha = ws.system.alpha.data();
  const double* beta = ws.system.beta.data();
  for (int k = 0; k < ns; ++k) {
    const double u[3] = {ws.springs.ux[k], ws.springs.uy[k], ws.springs.uz[k]};
    const double ab = alpha[k] - beta[k];
    double B[9];
    for (int r = 0; r < 3; ++r)
      for (int c = 0; c < 3; ++c) B[3 * r + c] = ab * u[r] * u[c] + (r == c ? beta[k] : 0.0);
    double* ii = bv + 9 * spring_blocks_[3 * k];
    double* jj = bv + 9 * spring_blocks_[3 * k + 1];
    double* ij = bv + 9 * spring_blocks_[3 * k + 2];
    for (int t = 0; t < 9; ++t) {
      ii[t] += B[t];
      jj[t] += B[t];
      ij[t] -= B[t];
    }
  }
  const double h2 = ws.system.h2;
  const int* eb = element_blocks_.data();
  const bool exact_terms = exact_at && (m.bulk_modulus > 0 || m.shear_modulus > 0);
  // The Newton iteration's exact tangent, unless the last factorisation of one failed.
  const bool tangent = !exact_terms && ws.elements.tangent && !gauss_newton_next_;
  assembled_tangent_ = tangent;
  double He[12 * 12];
  // He's scale: the exact Hessian as it is, the Newton iteration's tangent already times h^2.
  const double he_scale = exact_terms ? h2 : 1.0;
  for_each_element(m, [&](auto n, int e, const auto& nodes) {
    constexpr int N = decltype(n)::value;
    // Tetrahedra only: a hexahedron's eight Gauss points differenced cost about 40 ms per
    // assembly on the 600-hexahedron phantom (its factorisation: 7 ms).
    const bool exact = N == 4 && (exact_terms || tangent);
    if (exact && exact_terms) {
      Vec3 xe[N];
      for (int a = 0; a < N; ++a) xe[a] = (*exact_at)[nodes[a]];
      if constexpr (N == 4) tet_term_hessian(m, e, xe, He);
    } else if (exact) {  // h^2 already in
      expand_tet_tangent(ws.elements.tet_tangent.data() + 45 * static_cast<size_t>(e), He);
    }
    for (int a = 0; a < N; ++a)
      for (int b = 0; b < N; ++b) {
        const int id = eb[N * a + b];
        if (id < 0) continue;
        double H[3][3] = {};
        if (exact) {
          for (int r = 0; r < 3; ++r)
            for (int c = 0; c < 3; ++c) H[r][c] = he_scale * He[(3 * a + r) * 3 * N + 3 * b + c];
        } else {
          for_each_term(m,
                        [&](auto term) { term.template block<N>(m, ws.elements, h2, e, a, b, H); });
        }
        double* d = bv + 9 * id;
        for (int r = 0; r < 3; ++r)
          for (int c = 0; c < 3; ++c) d[3 * r + c] += H[r][c];
      }
    eb += N * N;
  });
  auto* x = static_cast<double*>(c_->A->x);
  const int* src = src_.data();
  const size_t nz = src_.size();
  for (size_t k = 0; k < nz; ++k) x[k] = src[k] >= 0 ? bv[src[k]] : (src[k] == -1 ? 1.0 : 0.0);
  factored_ = false;
}

bool SystemFactor::factorize() {
  // CHOLMOD's supernodal factorisation runs parts of each large supernode in OpenMP teams of a
  // size fixed at its build (4 threads in Debian's). On the two cores the design counts on (the
  // 1 kHz loop on one, the body on the other) those teams wait on each other and on the loop:
  // the phantom's factorisation took 35 ms of wall time for 18 ms of CPU and about 3,800 futex
  // calls per factorisation, against 8 ms without them (docs/performance.md, "Multi-rate
  // serving"). No parallel region of the factorising thread is made active (libgomp keeps the
  // setting per thread): every team is that thread alone.
  if (&omp_set_max_active_levels != nullptr) omp_set_max_active_levels(0);
  cholmod_common& cc = c_->c;
  factored_ =
      cholmod_factorize(c_->A, c_->L, &cc) && cc.status == CHOLMOD_OK && c_->L->minor == c_->L->n;
  // An exact tangent that is not positive definite: the next assembly takes the Gauss-Newton
  // blocks; after a Gauss-Newton factor, the exact tangent again.
  gauss_newton_next_ = !factored_ && assembled_tangent_;
  // solve() reads a simplicial LDL^T factor in place (the analysis asked for one), or solves
  // with a supernodal one through CHOLMOD.
  factored_ = factored_ && (c_->L->is_super || !c_->L->is_ll);
  // The preconditioner's copy of a supernodal factor in single precision (precondition()).
  if (factored_ && c_->L->is_super) {
    const auto* lx = static_cast<const double*>(c_->L->x);
    lxf_.resize(c_->L->xsize);
    for (size_t q = 0; q < c_->L->xsize; ++q) lxf_[q] = static_cast<float>(lx[q]);
    xf_.resize(3 * static_cast<size_t>(nn_));
    tf_.resize(static_cast<size_t>(max_nsrow_));
  }
  return factored_;
}

// z = P^T L^-T D^-1 L^-1 P r with the simplicial LDL^T factor read in place (CHOLMOD's layout:
// column j's first entry is D(j), the unit diagonal of L is not stored): no allocation.
void SystemFactor::solve(const double* r, double* z) {
  if (c_->L->is_super) {
    supernodal_solve(r, z, 1);
    return;
  }
  const int nn = nn_, n = 3 * nn;
  const cholmod_factor* L = c_->L;
  const auto* perm = static_cast<const int*>(L->Perm);
  const auto* lp = static_cast<const int*>(L->p);
  const auto* li = static_cast<const int*>(L->i);
  const auto* lnz = static_cast<const int*>(L->nz);
  const auto* lx = static_cast<const double*>(L->x);
  double* __restrict b = static_cast<double*>(c_->B->x);
  double* __restrict x = work_.data();
  const double* f = free_.data();
  for (int i = 0; i < nn; ++i)
    for (int c = 0; c < 3; ++c) b[3 * i + c] = r[c * nn + i] * f[c * nn + i];
  for (int k = 0; k < n; ++k) x[k] = b[perm[k]];
  for (int j = 0; j < n; ++j) {
    const double xj = x[j];
    for (int q = lp[j] + 1; q < lp[j] + lnz[j]; ++q) x[li[q]] -= lx[q] * xj;
  }
  for (int j = 0; j < n; ++j) x[j] /= lx[lp[j]];
  for (int j = n - 1; j >= 0; --j) {
    double xj = x[j];
    for (int q = lp[j] + 1; q < lp[j] + lnz[j]; ++q) xj -= lx[q] * x[li[q]];
    x[j] = xj;
  }
  for (int k = 0; k < n; ++k) b[perm[k]] = x[k];
  for (int i = 0; i < nn; ++i)
    for (int c = 0; c < 3; ++c) z[c * nn + i] = b[3 * i + c] * f[c * nn + i];
}

void SystemFactor::solve_many(const double* r, double* z, int k) {
  const int n = 3 * nn_;
  if (!c_->L->is_super) {
    for (int q = 0; q < k; ++q) solve(r + q * n, z + q * n);
    return;
  }
  supernodal_solve(r, z, k);
}

namespace {
// Right-hand sides of a supernodal sweep, k per row of the permuted system (row-major), a plain
// vector when there is one (Eigen's vector kernels: about 10 % faster solves than k = 1 rows).
template <int Cols, typename Scalar = double>
using Rhs =
    Eigen::Matrix<Scalar, Eigen::Dynamic, Cols, Cols == 1 ? Eigen::ColMajor : Eigen::RowMajor>;

// The supernodal factor's columns of supernode s: nsrow x nscol, column-major at px[s], rows
// Ls[pi[s]..pi[s + 1]) (the first nscol its own columns).
// Scalar float: the values of a single-precision copy (lx).
template <typename Scalar = double>
struct Supernodes {
  const int *super, *pi, *px, *ls;
  const Scalar* lx;
  size_t count;
  explicit Supernodes(const cholmod_factor* L, const Scalar* values = nullptr)
      : super(static_cast<const int*>(L->super)),
        pi(static_cast<const int*>(L->pi)),
        px(static_cast<const int*>(L->px)),
        ls(static_cast<const int*>(L->s)),
        lx(values ? values : reinterpret_cast<const Scalar*>(L->x)),
        count(L->nsuper) {}
  int first(size_t s) const { return super[s]; }
  int cols(size_t s) const { return super[s + 1] - super[s]; }
  int below(size_t s) const { return pi[s + 1] - pi[s] - cols(s); }
  const int* rows_below(size_t s) const { return ls + pi[s] + cols(s); }
  Eigen::Map<const Eigen::Matrix<Scalar, Eigen::Dynamic, Eigen::Dynamic>, 0, Eigen::OuterStride<>>
  block(size_t s) const {
    const int ld = pi[s + 1] - pi[s];
    return {lx + px[s], ld, cols(s), Eigen::OuterStride<>(ld)};
  }
};

// L Y = Y in place (x: k entries per row; t: scratch of the largest supernode's rows below times
// k). With `live` (a flag per row, set where Y can be nonzero), supernodes whose rows are all
// zero are skipped and the flags follow the rows each sweep fills.
template <int Cols, typename Scalar = double>
void forward_sweep(const Supernodes<Scalar>& L, Scalar* x, Scalar* t, int k, char* live = nullptr) {
  for (size_t s = 0; s < L.count; ++s) {
    const int k1 = L.first(s), nscol = L.cols(s), below = L.below(s);
    if (live) {
      if (std::find(live + k1, live + k1 + nscol, 1) == live + k1 + nscol) continue;
      std::fill(live + k1, live + k1 + nscol, 1);  // the diagonal block's solve fills them
    }
    const auto Ls = L.block(s);
    Eigen::Map<Rhs<Cols, Scalar>> X1(x + static_cast<size_t>(k1) * k, nscol, k);
    Ls.topRows(nscol).template triangularView<Eigen::Lower>().solveInPlace(X1);
    if (below == 0) continue;
    Eigen::Map<Rhs<Cols, Scalar>> T(t, below, k);
    T.noalias() = Ls.bottomRows(below) * X1;
    const int* rows = L.rows_below(s);
    for (int q = 0; q < below; ++q) {
      Scalar* xr = x + static_cast<size_t>(rows[q]) * k;
      const Scalar* tr = t + static_cast<size_t>(q) * k;
      for (int c = 0; c < k; ++c) xr[c] -= tr[c];
      if (live) live[rows[q]] = 1;
    }
  }
}

// L^T X = X in place (as forward_sweep, without skipping).
template <int Cols, typename Scalar = double>
void backward_sweep(const Supernodes<Scalar>& L, Scalar* x, Scalar* t, int k) {
  for (size_t s = L.count; s-- > 0;) {
    const int k1 = L.first(s), nscol = L.cols(s), below = L.below(s);
    const auto Ls = L.block(s);
    Eigen::Map<Rhs<Cols, Scalar>> X1(x + static_cast<size_t>(k1) * k, nscol, k);
    if (below > 0) {
      const int* rows = L.rows_below(s);
      for (int q = 0; q < below; ++q)
        std::copy_n(x + static_cast<size_t>(rows[q]) * k, k, t + static_cast<size_t>(q) * k);
      X1.noalias() -=
          Ls.bottomRows(below).transpose() * Eigen::Map<const Rhs<Cols, Scalar>>(t, below, k);
    }
    Ls.topRows(nscol).transpose().template triangularView<Eigen::Upper>().solveInPlace(X1);
  }
}

// z = P^T L^-T L^-1 P r on the free axes (zero on fixed ones) for k right-hand sides, through X
// (k entries per row of the permuted system, row-major) and the update scratch t, in the
// factor's scalar: what supernodal_solve and precondition share.
template <typename Scalar>
void permuted_sweeps(const Supernodes<Scalar>& L, const int* iperm, const double* free, int nn,
                     const double* r, double* z, int k, Scalar* x, Scalar* t) {
  const int n = 3 * nn;
  for (int i = 0; i < nn; ++i)
    for (int c = 0; c < 3; ++c) {
      Scalar* xr = x + static_cast<size_t>(iperm[3 * i + c]) * k;
      const double f = free[c * nn + i];
      for (int q = 0; q < k; ++q)
        xr[q] = static_cast<Scalar>(r[static_cast<size_t>(q) * n + c * nn + i] * f);
    }
  if (k == 1) {
    forward_sweep<1, Scalar>(L, x, t, 1);
    backward_sweep<1, Scalar>(L, x, t, 1);
  } else {
    forward_sweep<Eigen::Dynamic, Scalar>(L, x, t, k);
    backward_sweep<Eigen::Dynamic, Scalar>(L, x, t, k);
  }
  for (int i = 0; i < nn; ++i)
    for (int c = 0; c < 3; ++c) {
      const Scalar* xr = x + static_cast<size_t>(iperm[3 * i + c]) * k;
      const double f = free[c * nn + i];
      for (int q = 0; q < k; ++q)
        z[static_cast<size_t>(q) * n + c * nn + i] = static_cast<double>(xr[q]) * f;
    }
}
}  // namespace

// P^T L^-T L^-1 P with the supernodal factor read in place, supernode by supernode (Eigen's
// dense kernels on each one's columns, nsrow x nscol column-major at px[s], rows Ls[pi[s]..]):
// no BLAS call, so that the body thread's solves never run BLAS beside the factor thread's
// factorisation (Debian's serial OpenBLAS is not safe to call from two threads at once), and no
// allocation once the scratch has the size of k right-hand sides.
void SystemFactor::supernodal_solve(const double* r, double* z, int k) {
  const int nn = nn_, n = 3 * nn;
  if (x_.size() < static_cast<size_t>(n) * k) x_.resize(static_cast<size_t>(n) * k);
  if (t_.size() < static_cast<size_t>(max_nsrow_) * k)
    t_.resize(static_cast<size_t>(max_nsrow_) * k);
  permuted_sweeps(Supernodes<>(c_->L), iperm_.data(), free_.data(), nn, r, z, k, x_.data(),
                  t_.data());
}

// supernodal_solve's sweeps on the single-precision copy of the factor: half the memory each
// sweep reads (the solve is bound by it), for a preconditioner whose own error (a factor some
// body steps old) is far above single precision's 6e-8.
void SystemFactor::precondition(const double* r, double* z) {
  if (!c_->L->is_super || lxf_.size() != c_->L->xsize) {
    solve(r, z);
    return;
  }
  permuted_sweeps(Supernodes<float>(c_->L, lxf_.data()), iperm_.data(), free_.data(), nn_, r, z, 1,
                  xf_.data(), tf_.data());
}

void SystemFactor::inverse_block(const int* nodes, int num, double* w, int ld) {
  const int nn = nn_, n = 3 * nn, k = 3 * num;
  const cholmod_factor* L = c_->L;
  for (int c = 0; c < k; ++c) std::fill(w + static_cast<size_t>(c) * ld, w + c * ld + k, 0.0);
  if (k == 0) return;
  if (!L->is_super) {  // column by column, in full
    y_.assign(static_cast<size_t>(2) * n, 0.0);
    for (int col = 0; col < k; ++col) {
      const int i = nodes[col / 3], c = col % 3;
      std::fill(y_.begin(), y_.begin() + n, 0.0);
      y_[c * nn + i] = 1.0;
      solve(y_.data(), y_.data() + n);
      for (int row = 0; row < k; ++row)
        w[static_cast<size_t>(col) * ld + row] = y_[n + (row % 3) * nn + nodes[row / 3]];
    }
    return;
  }
  // Y (row-major, k entries per row of the permuted system): E's unit columns, then the forward
  // solve supernode by supernode (columns k1..k2 - 1, rows Ls[pi[s]..pi[s + 1]), the first
  // nscol of them its own columns; values column-major, nsrow x nscol). yz_ is zero between
  // calls: the sweep writes only the rows it marks live, and those are cleared below, so a call
  // costs the rows on the elimination tree's paths, not n k.
  if (yz_.size() < static_cast<size_t>(n) * k) yz_.resize(static_cast<size_t>(n) * k, 0.0);
  double* const y = yz_.data();
  live_.assign(n, 0);
  for (int col = 0; col < k; ++col) {
    const int i = nodes[col / 3], c = col % 3;
    if (free_[c * nn + i] == 0) continue;
    const int row = iperm_[3 * i + c];
    y[static_cast<size_t>(row) * k + col] = 1.0;
    live_[row] = 1;
  }
  if (t_.size() < static_cast<size_t>(max_nsrow_) * k)
    t_.resize(static_cast<size_t>(max_nsrow_) * k);
  forward_sweep<Eigen::Dynamic>(Supernodes<>(L), y, t_.data(), k, live_.data());
  // W = Y^T Y over Y's live rows, gathered to the top (each row moved is cleared where it was).
  int m = 0;
  for (int row = 0; row < n; ++row)
    if (live_[row]) {
      if (m != row) {
        double* const from = y + static_cast<size_t>(row) * k;
        std::copy(from, from + k, y + static_cast<size_t>(m) * k);
        std::fill(from, from + k, 0.0);
      }
      ++m;
    }
  Eigen::Map<const Rhs<Eigen::Dynamic>> G(y, m, k);
  Eigen::Map<Eigen::MatrixXd, 0, Eigen::OuterStride<>> W(w, k, k, Eigen::OuterStride<>(ld));
  W.noalias() = G.transpose() * G;
  std::fill(y, y + static_cast<size_t>(m) * k, 0.0);
}

void SystemFactor::multiply(const double* p, double* y) const {
  const int nn = nn_, n = 3 * nn;
  std::vector<double> pn(n), yn(n, 0.0);
  for (int i = 0; i < nn; ++i)
    for (int c = 0; c < 3; ++c) pn[3 * i + c] = p[c * nn + i];
  const auto* cp = static_cast<const int*>(c_->A->p);
  const auto* ri = static_cast<const int*>(c_->A->i);
  const auto* x = static_cast<const double*>(c_->A->x);
  for (int col = 0; col < n; ++col)
    for (int k = cp[col]; k < cp[col + 1]; ++k) {
      const int row = ri[k];
      yn[row] += x[k] * pn[col];
      if (row != col) yn[col] += x[k] * pn[row];
    }
  for (int i = 0; i < nn; ++i)
    for (int c = 0; c < 3; ++c) y[c * nn + i] = yn[3 * i + c];
}

FactorScratch::FactorScratch(const Model& m)
    : current(std::make_unique<SystemFactor>(m)),
      next(std::make_unique<SystemFactor>(m)),
      b(3 * static_cast<size_t>(m.num_nodes()), 0.0) {}

}  // namespace conica
