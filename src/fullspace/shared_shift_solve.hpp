#pragma once
// Internal: solves with the bordered eigen-blocks of a FullSpaceProblem's modes,
//
//   B_i = [[A_i, -b_i], [-b_i^T, 0]],   A_i = K / lambda_ref,i - t_i M,   b_i = M u_i,
//
// for every mode from ONE Cholesky factorization of K - sigma M (sigma below the spectrum, so it is
// definite) instead of one indefinite factorization per mode: the cost of a Newton iteration's
// linear algebra becomes nearly independent of the number of modes, and its memory that of one
// factor (docs/benchmarks.md, "One shared factorization for every mode's bordered block").
//
// For any pair (u_i, t_i), not only an eigenpair: with mu = u^T M u, c = -g / mu and the
// M-orthogonal projector Pi = I - u u^T M / mu,
//   B_i [x; xi] = [f; g]  <=>  x = y + c u,  Pi^T A Pi y = Pi^T (f - c A u),  u^T M y = 0,
//                               xi = u^T (A x - f) / mu.
// Pi^T A Pi is indefinite where modes lie below t_i (rigid-body and lower modes). A basis V of
// approximate eigenvectors (the last forward solve's) takes them out: with W = Pi V,
// M-orthonormalized, and E = W^T A W, conjugate gradients run on the A-conjugate complement of W
// (deflated CG: Saad, Yeung, Erhel and Guyomarc'h, SIAM J. Sci. Comput. 21, 2000) preconditioned
// by Pi (K - sigma M)^{-1}, while W E^{-1} W^T supplies the part in span(W) exactly. The result is
// exact for any V; V decides how fast CG converges (preconditioned spectrum near
// (lambda_k - lambda_i) / (lambda_k - sigma) over the modes k beyond V) and whether the complement
// is definite - when it is not, CG meets a non-positive curvature and solve() says so, and the
// caller factors B_i instead. Inertia: B_i has E's negative eigenvalues plus one (Sylvester), so
// mode_index() is what a factorization's negative pivots would give.
//
// Example (per Newton iteration):
//   SharedShiftSolver shared;
//   shared.factor(K, M, sigma, forward_modes, &why);        // one Cholesky factorization
//   for (int i = 0; i < l; ++i) shared.set_mode(i, u_i, lambda_ref_i, t_i);
//   shared.solve(i, &rhs, &why);                            // rhs (n + 1) x c <- B_i^{-1} rhs

#include <memory>
#include <string>
#include <vector>

#include "modalcal/types.hpp"

namespace modalcal::detail {

class CholmodFactor;
class FullSpaceProblem;

struct SharedShiftOptions {
  /// Normwise backward error at which CG stops: |r| <= tolerance (|b| + |A_i| |y|).
  double tolerance = 1e-13;
  int max_iterations = 200;
};

class SharedShiftSolver {
 public:
  explicit SharedShiftSolver(SharedShiftOptions options = {});
  ~SharedShiftSolver();
  SharedShiftSolver(const SharedShiftSolver&) = delete;
  SharedShiftSolver& operator=(const SharedShiftSolver&) = delete;

  /// Factors K - sigma M (K, M symmetric, stored in full, one pattern) and keeps K, M and the
  /// deflation basis (n x k, any scaling). False with `error` when K - sigma M is not definite.
  bool factor(const SparseMatrix& K, const SparseMatrix& M, double sigma, const Matrix& basis, std::string* error);
  /// Prepares mode i's solves: A_i = K / lambda_ref - ratio M, border M u (k products with A_i).
  void set_mode(int i, const Vector& mode, double lambda_ref, double ratio);
  /// rhs ((n + 1) x c) <- B_i^{-1} rhs. False (rhs: the last iterate) with `error` when CG met a
  /// non-positive curvature or did not converge in max_iterations.
  bool solve(int i, Matrix* rhs, std::string* error);
  /// Negative eigenvalues of B_i, as a factorization's negative pivots would count them.
  int negative_eigenvalues(int i) const { return modes_[i].negative_eigenvalues; }
  bool has_mode(int i) const { return i < static_cast<int>(modes_.size()) && modes_[i].ready; }
  /// True when `bordered` (B_i's lower triangle, as a factorization would be given it) has the
  /// diagonal and border of the B_i this solver holds for mode i: a check that both were
  /// linearized at the same point.
  bool agrees_with(int i, const SparseMatrix& bordered) const;
  /// CG iterations of the last solve() (the largest over its columns).
  int last_iterations() const { return last_iterations_; }

 private:
  struct Mode {
    bool ready = false;
    Vector u, Mu, Au;
    double mu = 1, lambda_ref = 1, ratio = 0;
    double norm = 0;        // |A_i|_inf
    Matrix W, AW;           // deflation vectors (n x k') and Pi^T A W
    Matrix coarse_inverse;  // E^{-1}
    int negative_eigenvalues = 0;
  };
  Matrix apply(const Mode& mode, const Matrix& X) const;  // A_i X
  Matrix project_rows(const Mode& mode, Matrix R) const;   // Pi^T R
  Matrix precondition(const Mode& mode, const Matrix& R) const;  // Pi (K - sigma M)^{-1} R
  // Solves Pi^T A Pi Y = R (R orthogonal to u) by deflated PCG, in lockstep over the columns.
  bool deflated_cg(const Mode& mode, const Matrix& R, Matrix* Y, std::string* error);

  SharedShiftOptions options_;
  SparseMatrix K_, M_;
  std::unique_ptr<CholmodFactor> factor_;
  Matrix basis_;
  std::vector<Mode> modes_;
  int last_iterations_ = 0;
};

/// The shared solver at x for `problem` (K and M at p(x), every mode's u_i and t_i), with the
/// problem's deflation basis and sigma = -0.1 min_i lambda_ref,i. Null with `error` when the
/// problem has no basis or K - sigma M is not definite.
std::unique_ptr<SharedShiftSolver> shared_shift_solver(FullSpaceProblem& problem, const double* x,
                                                       std::string* error);

}  // namespace modalcal::detail
