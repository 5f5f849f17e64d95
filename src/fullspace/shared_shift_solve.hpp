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
// is definite - when it is not, CG meets a non-positive curvature or does not converge, solve()
// says so, and the caller factors B_i instead.
// Inertia: where the complement is definite, B_i has E's negative eigenvalues plus one (Haynsworth;
// Sylvester for the border). A converged CG makes that likely, not certain (its Krylov space can
// miss a negative direction), so negative_eigenvalues() is an estimate: the structured KKT
// solver's inertia never uses it (that comes from the reduced Hessian).
// Memory: K, M, one Cholesky factor, V, K V and M V (n x k each); per mode a few vectors of n and
// k x k matrices (W_i is never formed).
//
// Example (per Newton iteration; update_shared_shift_solver() does the first two steps for a
// FullSpaceProblem):
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
  /// Normwise backward error at which CG stops, |r| <= tolerance (|b| + |A_i| |y|) (column
  /// 2-norms, |A_i| its largest row sum), or, once below `acceptable`, where it stops falling
  /// (the rounding floor, near sqrt(n) eps); solve() then checks the true residual to
  /// 10 x acceptable. As near a direct factorization's as the floor allows: stopping at 1e-13,
  /// Ipopt took one Newton iteration more than with per-mode factorizations (LFU, 13 764 DOFs, ten
  /// modes), with these the same three.
  double tolerance = 1e-15;
  double acceptable = 1e-12;
  int max_iterations = 200;
};

class SharedShiftSolver {
 public:
  explicit SharedShiftSolver(SharedShiftOptions options = {});
  ~SharedShiftSolver();
  SharedShiftSolver(const SharedShiftSolver&) = delete;
  SharedShiftSolver& operator=(const SharedShiftSolver&) = delete;

  /// Factors K - sigma M (K, M symmetric, stored in full, one pattern; the symbolic analysis is
  /// kept while the pattern is) and keeps K, M and the deflation basis (n x k, any scaling). False
  /// with `error` when K - sigma M is not definite. Forgets every mode.
  bool factor(const SparseMatrix& K, const SparseMatrix& M, double sigma, const Matrix& basis, std::string* error);
  /// Prepares mode i's solves: A_i = K / lambda_ref - ratio M, border M u (k products with A_i).
  void set_mode(int i, const Vector& mode, double lambda_ref, double ratio);
  /// rhs ((n + 1) x c) <- B_i^{-1} rhs. False (rhs: the last iterate) with `error` when CG met a
  /// non-positive curvature or did not converge in max_iterations.
  bool solve(int i, Matrix* rhs, std::string* error);
  /// Negative eigenvalues of B_i, as a factorization's negative pivots would count them, where
  /// the complement of the basis is definite (see above: an estimate).
  int negative_eigenvalues(int i) const { return modes_[i].negative_eigenvalues; }
  bool has_mode(int i) const { return i < static_cast<int>(modes_.size()) && modes_[i].ready; }
  /// True when `bordered` (B_i's lower triangle, as a factorization would be given it) has the
  /// diagonal and border of the B_i this solver holds for mode i: a check that both were
  /// linearized at the same point.
  bool agrees_with(int i, const SparseMatrix& bordered) const;
  /// CG iterations of the last solve() (the largest over its columns).
  int last_iterations() const { return last_iterations_; }
  void set_options(const SharedShiftOptions& options) { options_ = options; }

 private:
  friend bool update_shared_shift_solver(FullSpaceProblem&, const double*, SharedShiftSolver*, std::string*);
  struct Mode {
    bool ready = false;
    Vector u, Mu, Au;
    double mu = 1, lambda_ref = 1, ratio = 0;
    double norm = 0;        // |A_i|_inf
    Eigen::RowVectorXd a;   // (M u)^T V / mu: Pi V = V - u a
    Matrix Q;               // W = Pi V Q, M-orthonormal (k x k')
    Matrix coarse_inverse;  // E^{-1}
    int negative_eigenvalues = 0;
  };
  Matrix apply(const Mode& mode, const Matrix& X) const;  // A_i X
  Matrix project_rows(const Mode& mode, Matrix R) const;   // Pi^T R
  Matrix project(const Mode& mode, Matrix Z) const;        // Pi Z
  Matrix W_times(const Mode& mode, const Matrix& C) const;             // W C
  Matrix W_transpose_times(const Mode& mode, const Matrix& R) const;   // W^T R
  Matrix AW_times(const Mode& mode, const Matrix& C) const;            // Pi^T A W C
  Matrix AW_transpose_times(const Mode& mode, const Matrix& Z) const;  // (Pi^T A W)^T Z, Z in range(Pi)
  // Solves Pi^T A Pi Y = R (R orthogonal to u) by deflated PCG, in lockstep over the columns.
  bool deflated_cg(const Mode& mode, const Matrix& R, Matrix* Y, std::string* error);

  SharedShiftOptions options_;
  SparseMatrix K_, M_;
  std::unique_ptr<CholmodFactor> factor_;
  Matrix V_, KV_, MV_;  // the deflation basis and its products
  std::vector<Mode> modes_;
  int last_iterations_ = 0;
  Vector point_;            // update_shared_shift_solver(): the x it was brought to
  long basis_version_ = -1; // and the problem's deflation basis then
};

/// Brings `solver` to x for `problem`: K and M at p(x), every mode's u_i and t_i, the problem's
/// deflation basis, sigma = -0.1 min_i lambda_ref,i. Nothing to do when it already is at x with
/// the problem's current basis (Ipopt's inertia corrections refactor at one point). False with
/// `error` (the solver then holds no mode) when the problem has no basis or K - sigma M is not
/// definite.
bool update_shared_shift_solver(FullSpaceProblem& problem, const double* x, SharedShiftSolver* solver,
                                std::string* error);

}  // namespace modalcal::detail
