#pragma once
// Internal: block elimination of a full-space KKT system, the one piece of linear algebra shared
// by the block SQP (block_kkt.hpp) and the structured KKT solver Ipopt calls
// (ipopt/structured_kkt.hpp). The constraint Jacobian is block diagonal over the modes apart
// from the parameter columns, and so is the Lagrangian Hessian apart from the parameter rows.
// With, for mode i (local unknowns x_i = (u~_i, t_i), rows (r_i, n_i)), A_i = dc_i/dx_i,
// P_i = dc_i/dq, W_i = d2L/dx_i^2, C_i = d2L/dx_i dq, the KKT system with right-hand side
// (f_i, e_i, f_q)
//
//   W_i dx_i + C_i dq + A_i^T dy_i = f_i,   A_i dx_i + P_i dq = e_i,
//   sum_i (C_i^T dx_i + P_i^T dy_i) + W_qq dq = f_q
//
// gives dx_i = a_i - S_i dq, dy_i = b_i - T_i dq with
//   a_i = A_i^{-1} e_i,  S_i = A_i^{-1} P_i,  b_i = A_i^{-T} (f_i - W_i a_i),  T_i = A_i^{-T} (C_i - W_i S_i),
// and the m x m reduced (Schur) system H dq = h with
//   H = W_qq - sum_i (C_i^T S_i + S_i^T C_i - S_i^T W_i S_i),   h = f_q - sum_i (C_i^T a_i + P_i^T b_i).
// H = Z^T W Z on the null space Z = [-S; I] of the constraint Jacobian, so the KKT matrix has
// the inertia of the whole KKT matrix is that of H plus n_c positive and n_c negative
// eigenvalues (n_c constraints; Gould 1985): Ipopt's inertia test is a test on an m x m matrix.
// A_i = diag(s_i) B_i with B_i the symmetric bordered eigen-matrix, so one symmetric indefinite
// factorization per mode serves A_i and A_i^T. Cost per mode: that factorization and 2 (m + 1)
// solves - or, with a SharedShiftSolver, no factorization of B_i at all: its solves go through
// one factorization of K - sigma M shared by every mode (shared_shift_solve.hpp).

#include <functional>
#include <memory>
#include <string>
#include <vector>

#include "fullspace/mumps_factor.hpp"
#include "modalcal/types.hpp"

namespace modalcal::detail {

class SharedShiftSolver;

/// Mode i's blocks, in local indices 0..n (n: the eigenvalue unknown / normalization row).
struct ModeKktBlocks {
  SparseMatrix bordered;     ///< B_i, lower triangle (entries above the diagonal are ignored)
  Vector row_scale;          ///< s_i: A_i = diag(s_i) B_i
  SparseMatrix hessian;      ///< W_i, both triangles
  Matrix hessian_parameters; ///< C_i, (n + 1) x m
  Matrix jacobian_parameters;///< P_i, (n + 1) x m

  ModeKktBlocks() = default;
  ModeKktBlocks(const ModeKktBlocks&) = default;
  ModeKktBlocks& operator=(const ModeKktBlocks&) = default;
  // Eigen 3.4's SparseMatrix has no move (its "move" copies): moving a mode's blocks swaps them,
  // so that nothing is copied; the moved-from object holds what this one held.
  ModeKktBlocks(ModeKktBlocks&& other) noexcept { *this = std::move(other); }
  ModeKktBlocks& operator=(ModeKktBlocks&& other) noexcept {
    bordered.swap(other.bordered);
    row_scale.swap(other.row_scale);
    hessian.swap(other.hessian);
    hessian_parameters.swap(other.hessian_parameters);
    jacobian_parameters.swap(other.jacobian_parameters);
    return *this;
  }
};

class BlockElimination {
 public:
  /// `keep_factors`: keep every mode's factorization and blocks so that solve() can be called
  /// for any right-hand side after the elimination (memory: one factor per mode); without it
  /// only the right-hand side given to add_mode() is reduced, and one factor is held at a time.
  BlockElimination(int num_modes, int num_parameters, bool keep_factors);
  ~BlockElimination();

  /// Starts an elimination with H = W_qq and h = f_q (may be null). With `shared` (not owned,
  /// alive until the next begin()), the modes it has set solve with B_i through its one shared
  /// factorization (shared_shift_solve.hpp) instead of factoring B_i; a mode whose shared solves
  /// fail (no convergence, a mode missing from its basis) is factored after all.
  void begin(const Matrix& parameter_hessian, const Vector* parameter_rhs, SharedShiftSolver* shared = nullptr);
  /// Solves with mode i's bordered block B_i (through the shared solver, or by factoring it) and
  /// adds its part of H; with (f_i, e_i) also its part of h and the a_i, b_i that expand() uses.
  /// False with `error` (MUMPS's words) when B_i is singular.
  bool add_mode(int i, ModeKktBlocks blocks, const Vector* f, const Vector* e, std::string* error);
  /// Negative pivots of B_i (its inertia, Sylvester).
  int negative_pivots(int i) const { return negative_pivots_[i]; }
  /// Since construction: modes eliminated through the shared factorization, and modes where its
  /// solves fell short (in add_mode() or solve()) and B_i was factored instead.
  int shared_eliminations() const { return shared_eliminations_; }
  int shared_failures() const { return shared_failures_; }
  /// Counts modes that should have gone through a shared solver that could not be built.
  void count_shared_failures(int modes) { shared_failures_ += modes; }

  /// H, symmetrized, once every mode is added.
  const Matrix& reduced_hessian() const { return reduced_hessian_; }
  const Vector& reduced_rhs() const { return reduced_rhs_; }
  /// Mode i's (dx_i, dy_i) for a parameter step dq, for the right-hand side given to add_mode().
  void expand(int i, const Vector& dq, Vector* dx, Vector* dy) const;

  /// Right-hand sides of the whole system, per mode (f_i, e_i: (n + 1) x k) and for q (f_q,
  /// m x k), replaced by the solution (dx_i, dy_i, dq); `solve_reduced` solves H dq = h for the
  /// k columns of h in place. Requires keep_factors.
  /// `hessian_product(i, v)` gives W_i v for modes whose W_i was released; `bordered_block(i)`
  /// B_i's lower triangle again, for a shared mode whose solves fall short on these right-hand
  /// sides (it is then factored; without it, or when B_i is singular, std::runtime_error).
  void solve(std::vector<Matrix>* f, std::vector<Matrix>* e, Matrix* fq,
             const std::function<void(Matrix*)>& solve_reduced,
             const std::function<Matrix(int, const Matrix&)>& hessian_product = {},
             const std::function<SparseMatrix(int)>& bordered_block = {});
  /// Frees the kept W_i of mode i (solve() then needs `hessian_product`).
  void release_hessian(int i) { release(&modes_[i].blocks.hessian); }
  /// Frees a sparse matrix's storage (assigning an empty one keeps it).
  static void release(SparseMatrix* matrix) { SparseMatrix().swap(*matrix); }

 private:
  struct Mode {
    Matrix S, T;  // (n + 1) x m
    Vector a, b;  // for add_mode's right-hand side
    bool shared = false;                           // B_i solved through shared_
    std::unique_ptr<MumpsSymmetricFactor> factor;  // keep_factors, unless shared
    ModeKktBlocks blocks;                          // keep_factors (without B_i)
  };
  // In place B_i^{-1} X; false when it could not be solved to its tolerance.
  using BorderedSolve = std::function<bool(Matrix*)>;
  // right = [e ...] -> A^{-1} right; left = [f ...] -> A^{-T} (left - W A^{-1} right), column by
  // column; *reduction = C^T right + P^T left (the columns' part of h, or of H). False when a
  // solve with B_i fell short (the results are then its last iterates).
  static bool eliminate(const ModeKktBlocks& blocks, const BorderedSolve& solve_bordered, Matrix* right, Matrix* left,
                        const std::function<Matrix(const Matrix&)>& hessian_product, Matrix* reduction);
  BorderedSolve bordered_solve(int i);
  // Factors B_i (into the mode's kept factor, or the one reused mode after mode); the mode is no
  // longer shared.
  bool factor_bordered(int i, const SparseMatrix& bordered, std::string* error);
  int np_;
  bool keep_factors_;
  std::vector<Mode> modes_;
  std::vector<int> negative_pivots_;
  std::unique_ptr<MumpsSymmetricFactor> one_factor_;  // without keep_factors: reused mode after mode
  SharedShiftSolver* shared_ = nullptr;
  int shared_eliminations_ = 0, shared_failures_ = 0;
  Matrix reduced_hessian_;
  Vector reduced_rhs_;
  bool has_rhs_ = false;
  int added_ = 0;
};

}  // namespace modalcal::detail
