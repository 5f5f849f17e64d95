#pragma once
// Internal: solves of the singular systems (K - lambda_i M) x = b, x M-orthogonal to u_i, that
// the adjoint gradient (w_0i) and the eigenvector sensitivities need, reusing the factorization
// of K - sigma M from the forward solve instead of factorizing K - lambda_i M per mode.
//
// With U the computed modes (eigenvalues Lambda, including u_i and rigid-body modes), the
// solution splits into a modal part on U and a remainder in the M-orthogonal complement of U:
//   x = sum_{k != i} u_k (u_k^T b) / (Lambda_k - lambda_i) + y,
//   (K - lambda_i M) y = (I - M U U^T) b,  y M-orthogonal to U.
// On that complement K - lambda_i M is positive definite (every remaining eigenvalue exceeds
// lambda_i), so y comes from preconditioned conjugate gradients with preconditioner
// (I - U U^T M)(K - sigma M)^{-1}: the preconditioned spectrum is
// (lambda_k - lambda_i)/(lambda_k - sigma) in [(lambda_{L+1} - lambda_i)/(lambda_{L+1} - sigma), 1),
// so a few extra computed modes keep it well conditioned. Columns with different lambda_i run
// in lockstep so the preconditioner is one block solve per iteration (cheaper per column).

#include <functional>
#include <string>
#include <vector>

#include "modalcal/types.hpp"

namespace modalcal::detail {

struct DeflationBasis {
  Matrix modes;       ///< U, M-orthonormal columns (rigid-body and elastic modes)
  Vector eigenvalues; ///< Lambda
  Matrix mass_modes;  ///< M U
};

struct DeflatedSolveResult {
  Matrix solution;
  int iterations = 0;
  int column_solves = 0;  ///< right-hand sides passed to the preconditioner
  bool converged = false;
  std::string message;
};

/// Solves column c: (K - shift[c] M) x = B.col(c), where shift[c] is the eigenvalue of basis
/// column own[c] and B.col(c) is orthogonal to that mode. `precondition` applies
/// (K - sigma M)^{-1} to a block.
DeflatedSolveResult solve_deflated(const SparseMatrix& K, const SparseMatrix& M, const DeflationBasis& basis,
                                   const std::vector<int>& own, const Matrix& B,
                                   const std::function<Matrix(const Matrix&)>& precondition, double tolerance,
                                   int max_iterations);

/// The solves of solve_deflated for right-hand sides that several shifts share: for each
/// own[k], (K - lambda_own[k] M) X_k = B, with B.cols() columns each; the solution's columns are
/// X_0 | X_1 | ... in that order, as solve_deflated's for B repeated once per own[k].
///
/// With the preconditioner P = (K - sigma M)^{-1}, the preconditioned operator of shift lambda is
/// P (K - lambda M) = I + (sigma - lambda) T with T = P M: every shift's conjugate-gradient space
/// is the same Krylov space of T from P B (on the complement of the modes). It is built once, a
/// block of B.cols() columns per iteration, M-orthonormal; each shift's solution is the Galerkin
/// solution on it, which is what conjugate gradients reach in that space (they minimize the same
/// (K - lambda M)-norm of the error over it). The preconditioner thus sees B.cols() columns per
/// iteration instead of own.size() times as many. The space is kept whole: when it would exceed
/// `max_columns` columns before every residual meets the tolerance, the solves are left to
/// solve_deflated (counted in the result).
DeflatedSolveResult solve_deflated_shared(const SparseMatrix& K, const SparseMatrix& M, const DeflationBasis& basis,
                                          const std::vector<int>& own, const Matrix& B,
                                          const std::function<Matrix(const Matrix&)>& precondition,
                                          double tolerance, int max_iterations, Eigen::Index max_columns);

/// The same solves when the basis spans the whole space they are solved in (every Ritz pair of a
/// Rayleigh-Ritz model, Objective::set_span): then the modal part is the whole solution,
/// x_c = sum over k != own[c] of u_k (u_k^T b_c) / (lambda_k - lambda_own[c]).
Matrix solve_in_basis(const DeflationBasis& basis, const std::vector<int>& own, const Matrix& B);

}  // namespace modalcal::detail
