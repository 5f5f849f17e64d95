#pragma once
// Internal: the Newton (KKT) system of a FullSpaceProblem at (x, y), solved by per-mode block
// elimination (block_elimination.hpp) instead of one factorization of the whole matrix; the
// right-hand side is (-g, -c) with g the gradient of the Lagrangian and c the constraints. Cost
// per mode: one sparse symmetric indefinite factorization of the bordered B_i and 2 (m + 1)
// solves, against Ipopt-with-MUMPS's factorization of the whole 2 l (n + 1) + m KKT matrix
// (docs/benchmarks.md: where the time goes).

#include <memory>
#include <string>
#include <vector>

#include "fullspace/fullspace_problem.hpp"
#include "fullspace/block_elimination.hpp"
#include "fullspace/shared_shift_solve.hpp"

namespace modalcal::detail {

class BlockKktSystem {
 public:
  /// With `shared_factorization`, the modes' bordered blocks are solved through one
  /// factorization of K - sigma M per build (shared_shift_solve.hpp; the problem's deflation
  /// basis must be set), a mode where that fails by its own factorization.
  explicit BlockKktSystem(FullSpaceProblem& problem, bool shared_factorization = false);

  /// Evaluates the derivatives at (x, y) and eliminates every mode. False (with `error` naming
  /// the mode and the likely cause) when a bordered block is singular.
  bool build(const Vector& x, const Vector& y, std::string* error);

  /// Gradient of the Lagrangian g + A^T y and constraint values at the last build.
  const Vector& lagrangian_gradient() const { return lagrangian_gradient_; }
  const Vector& constraints() const { return constraints_; }
  const Vector& objective_gradient() const { return objective_gradient_; }
  /// Reduced (Schur) Hessian H and right-hand side h in the parameters.
  const Matrix& reduced_hessian() const { return elimination_.reduced_hessian(); }
  const Vector& reduced_rhs() const { return elimination_.reduced_rhs(); }
  /// Negative pivots of B_i: the index (1-based) of the eigenpair u_i is near, by Sylvester's law
  /// (B_i's inertia is that of K - lambda M on the M-complement of u_i, plus one of each sign).
  int mode_index(int i) const { return mode_index_[i]; }
  /// Mode eliminations through the shared factorization, and its failures (then factored).
  int shared_eliminations() const { return elimination_.shared_eliminations(); }
  int shared_failures() const { return elimination_.shared_failures(); }

  /// The full step (dx, dy) for a parameter step dq.
  void step(const Vector& dq, Vector* dx, Vector* dy) const;

 private:
  ModeKktBlocks mode_blocks(int i) const;  // from the values of the last build

  FullSpaceProblem& problem_;
  int n_ = 0, l_ = 0, np_ = 0;
  // Structure, fixed: where every Jacobian and Hessian entry goes.
  struct Slot {
    int mode = -1;       // -1: both indices are parameters (Hessian q-q)
    int row = 0, col = 0;  // local indices (mode block: 0..n; parameter: 0..np-1)
    enum Kind { ModeBlock, ParameterColumn, ParameterPair } kind = ModeBlock;
  };
  std::vector<int> jac_rows_, jac_cols_, hes_rows_, hes_cols_;
  std::vector<Slot> jac_slots_, hes_slots_;
  std::vector<std::vector<int>> jac_entries_, hes_entries_;  // per mode: its entries' positions
  std::vector<int> parameter_pairs_;                          // Hessian q-q entries
  std::vector<double> jac_values_, hes_values_;
  BlockElimination elimination_;
  bool shared_factorization_ = false;
  std::unique_ptr<SharedShiftSolver> shared_;
  std::vector<int> mode_index_;
  Vector lagrangian_gradient_, constraints_, objective_gradient_;
};

}  // namespace modalcal::detail
