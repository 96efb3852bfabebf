// The implicit system as a sparse matrix, and its Cholesky factor (CHOLMOD), for the
// LinearSolver::kFactorCG preconditioner of the backward Euler step (core/implicit.cc).
//
// A is the matrix the matrix-free product applies (step.h, implicit.cc), over 3 n scalar
// unknowns numbered node-major (3 i + c):
//   A = M (1 + h mu)                                              (mass, per node)
//     + sum_s  [+B_s on (i,i) and (j,j), -B_s on (i,j) and (j,i)],
//              B_s = beta I + (alpha - beta) d d^T                 (springs)
//     + sum_e  h^2 H_e                                             (element terms' blocks,
//                                                                   core/element_terms.h)
//     + n n^T + h^2 B_i per node in contact                        (plates, probe layers)
// restricted to free axes: A_f = P A P + (I - P), P the free-axis mask, so that A_f is positive
// definite and A_f^-1 r = A^-1 r on the free axes for r with no fixed component.
//
// The pattern (which node blocks can be nonzero: the diagonal, every spring's pair, every pair of
// an element's nodes) is fixed when the Workspace is compiled, and so is CHOLMOD's symbolic
// analysis (fill-reducing ordering, supernodes). Per factorisation only the values change:
//   assemble()   values of A_f from the system the Newton iteration built: no allocation
//   factorize()  numeric factorisation reusing the analysis: allocates inside CHOLMOD, so it
//                runs off the step (a worker thread, loop/factor_worker.h) or, when the owner
//                has no worker, inside the step that asked for it
//   solve()      z = A_f^-1 r by the factor's triangular solves, in place: no allocation
#pragma once

#include <atomic>
#include <cstdint>
#include <memory>
#include <vector>

#include "core/model.h"

namespace conica {

struct Workspace;

class SystemFactor {
 public:
  // Simplicial LDL^T: solve() reads the factor in place and allocates nothing (the 1 kHz step).
  // Supernodal LL^T (BLAS): a much faster numeric factorisation on the larger bodies; its solves
  // read it in place with Eigen's dense kernels (no BLAS call: the body thread solves while
  // another thread factors), allocating only at a larger number of right-hand sides.
  enum class Kind { kSimplicial, kSupernodal };
  // The pattern and the symbolic analysis (allocates).
  explicit SystemFactor(const Model& m, Kind kind = Kind::kSimplicial);
  ~SystemFactor();
  SystemFactor(const SystemFactor&) = delete;
  SystemFactor& operator=(const SystemFactor&) = delete;

  // The values of A_f at the system ws.system, ws.elements and ws.contact describe (after the
  // Newton iteration's coefficients and prepare_system): the tetrahedra's exact tangent when the
  // iteration took it (ElementScratch::tangent; after a factorisation of it failed, the next
  // assembly takes the Gauss-Newton blocks), the surface layers' faces with their pair blocks.
  // With exact_at (the positions the system was prepared at), the tetrahedra's element-term
  // blocks are their exact Hessians there (tet_term_hessian) whatever the iteration took: the
  // tangent a converged step follows, for the multi-rate body's local compliance
  // (core/multirate.h); it may be indefinite. Hexahedra keep the Gauss-Newton blocks.
  void assemble(const Model& m, const Workspace& ws, const std::vector<Vec3>* exact_at = nullptr);
  // Numeric factorisation of the assembled values; false when A_f is not positive definite
  // (the factor is then unusable).
  bool factorize();
  bool factored() const { return factored_; }
  // z = A_f^-1 r, component-major vectors of 3 n entries; z is zero on fixed axes.
  void solve(const double* r, double* z);
  // The same for k right-hand sides at once (r and z: k such vectors one after the other), in
  // one pass of the supernodal solve (allocates its scratch at a larger k).
  void solve_many(const double* r, double* z, int k);
  // z ~ A_f^-1 r for a preconditioner: a supernodal factor's sweeps in single precision (a copy
  // of its values made at factorize()), otherwise solve(). No allocation.
  void precondition(const double* r, double* z);
  // The block of A_f^-1 over the given nodes' 3 num axes (node a's axis c at row and column
  // 3 a + c), into w (column-major, leading dimension ld >= 3 num): zero rows and columns on
  // fixed axes. With a supernodal factor P A_f P^T = L L^T it is Y^T Y, Y = L^-1 P E (E the
  // axes' unit columns): one forward solve, which visits only the supernodes on the elimination
  // tree's paths from the nodes' columns to the root (the others see zero right-hand sides);
  // a simplicial factor solves the columns in full. Allocates its scratch at a larger num.
  void inverse_block(const int* nodes, int num, double* w, int ld);
  // y = A_f p with the assembled values (component-major), for tests.
  void multiply(const double* p, double* y) const;

  int num_unknowns() const { return 3 * nn_; }
  std::int64_t nonzeros() const;         // upper triangle of A_f
  std::int64_t factor_nonzeros() const;  // of the factor L
  bool supernodal() const;
  Kind kind() const { return kind_; }

 private:
  struct Cholmod;  // CHOLMOD's handles, kept out of this header
  int nn_ = 0;
  Kind kind_ = Kind::kSimplicial;
  std::vector<int> spring_blocks_;   // (3 num_springs): blocks (i,i), (j,j), (min,max)
  std::vector<int> element_blocks_;  // per element (tetrahedra, then hexahedra) N x N block
                                     // ids of its node pairs (a, b), -1 where node a > node b
  std::vector<int> diag_block_;      // (num_nodes)
  std::vector<int> surface_blocks_;  // (3 surface triangles) corner pairs 01 02 12, -1: none
  bool assembled_tangent_ = false;   // the last assembly took the exact tetrahedron tangent
  bool gauss_newton_next_ = false;   // ... and its factorisation failed: the next one does not
  std::vector<double> blocks_;       // (9 num_blocks) row-major 3 x 3 values
  std::vector<int> src_;             // (nonzeros) the block entry of each CSC entry, -1: a fixed
                                     // axis's unit diagonal, -2: zero (a fixed axis's coupling)
  std::vector<double> free_;         // (3 num_nodes) component-major free-axis mask
  std::vector<double> work_;         // (3 num_nodes) the solve's permuted vector
  std::vector<int> iperm_;           // (3 num_nodes) the factor's row of each unknown
  std::vector<double> y_;            // inverse_block's column and its solve on a simplicial factor
  std::vector<double> t_;            // the supernodal sweeps' update
  std::vector<double> x_;            // the supernodal solve's right-hand sides (row-major)
  int max_nsrow_ = 0;                // the supernodes' largest row count
  std::vector<float> lxf_;           // a supernodal factor's values in single precision
  std::vector<float> xf_, tf_;       // precondition()'s right-hand side and update
  void supernodal_solve(const double* r, double* z, int k);
  std::vector<char> live_;  // (3 num_nodes) rows of Y that can be nonzero
  std::vector<double> yz_;  // inverse_block's Y on a supernodal factor, zero between calls
  std::unique_ptr<Cholmod> c_;
  bool factored_ = false;
};

// The kFactorCG solver's state in the Workspace: the factor in use and the next one, which is
// assembled by the step and factored by a worker thread (or by the step when there is none),
// handed over through `next_state`.
struct FactorScratch {
  enum : int {
    kIdle = 0,       // `next` belongs to the step
    kAssembled = 1,  // `next` holds new values and belongs to the worker until it is factored
    kFactored = 2,   // the worker is done: the step swaps it in
    kFailed = 3,     // the worker's factorisation failed: the step counts it, back to kIdle
    kStop = 4,       // the worker ends
  };
  explicit FactorScratch(const Model& m);
  std::unique_ptr<SystemFactor> current;  // what CG preconditions with (factored() or not)
  std::unique_ptr<SystemFactor> next;
  std::atomic<int> next_state{kIdle};
  bool worker = false;    // set by the owner: a worker thread factors `next` (loop/factor_worker.h)
  int age = 0;            // steps since `current` was assembled
  bool wanted = true;     // a new factor is wanted at the next Newton iteration
  std::vector<double> b;  // (3 num_nodes) scratch
};

}  // namespace conica
