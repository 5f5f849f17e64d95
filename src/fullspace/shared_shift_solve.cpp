#include "fullspace/shared_shift_solve.hpp"

#include <Eigen/Eigenvalues>

#include <algorithm>
#include <cmath>

#include "eigen/block_lanczos.hpp"  // symmetric_times
#include "eigen/cholmod_factor.hpp"
#include "fullspace/fullspace_problem.hpp"

namespace modalcal::detail {

SharedShiftSolver::SharedShiftSolver(SharedShiftOptions options) : options_(options) {}
SharedShiftSolver::~SharedShiftSolver() = default;

bool SharedShiftSolver::factor(const SparseMatrix& K, const SparseMatrix& M, double sigma, const Matrix& basis,
                               std::string* error) {
  if (K.rows() != M.rows() || K.nonZeros() != M.nonZeros() || basis.rows() != K.rows()) {
    if (error) *error = "K, M and the basis must have one size, and K and M one pattern";
    return false;
  }
  K_ = K;
  M_ = M;
  if (!factor_ || factor_->rows() != K.rows()) factor_ = std::make_unique<CholmodFactor>(K_);
  int failed = -1;
  if (!factor_->factorize(K_, M_, sigma, &failed)) {
    if (error)
      *error = "K - sigma M (sigma " + std::to_string(sigma) + ") is not positive definite at column " +
               std::to_string(failed);
    return false;
  }
  basis_ = basis;
  modes_.clear();
  return true;
}

Matrix SharedShiftSolver::apply(const Mode& mode, const Matrix& X) const {
  return symmetric_times(K_, X) / mode.lambda_ref - mode.ratio * symmetric_times(M_, X);
}

Matrix SharedShiftSolver::project_rows(const Mode& mode, Matrix R) const {
  R -= mode.Mu * (mode.u.transpose() * R / mode.mu);  // Pi^T = I - M u u^T / mu
  return R;
}

Matrix SharedShiftSolver::precondition(const Mode& mode, const Matrix& R) const {
  Matrix Z = factor_->solve(R);
  Z -= mode.u * (mode.Mu.transpose() * Z / mode.mu);  // Pi = I - u u^T M / mu
  return Z;
}

void SharedShiftSolver::set_mode(int i, const Vector& mode_vector, double lambda_ref, double ratio) {
  if (i >= static_cast<int>(modes_.size())) modes_.resize(i + 1);
  Mode& mode = modes_[i];
  mode.u = mode_vector;
  mode.Mu = M_ * mode_vector;
  mode.mu = mode.u.dot(mode.Mu);
  mode.lambda_ref = lambda_ref;
  mode.ratio = ratio;
  mode.Au = apply(mode, mode.u);
  // |A_i|, the largest absolute row sum (K and M share one pattern, both stored in full).
  Vector row_sums = Vector::Zero(K_.rows());
  for (int col = 0; col < K_.outerSize(); ++col) {
    SparseMatrix::InnerIterator k(K_, col), mm(M_, col);
    for (; k && mm; ++k, ++mm) row_sums[k.row()] += std::abs(k.value() / lambda_ref - ratio * mm.value());
  }
  mode.norm = row_sums.maxCoeff();
  // W = Pi V, M-orthonormalized; the direction of V along u (it projects to nearly nothing) drops.
  Matrix W = basis_ - mode.u * (mode.Mu.transpose() * basis_ / mode.mu);
  const Eigen::SelfAdjointEigenSolver<Matrix> gram(W.transpose() * symmetric_times(M_, W));
  const Vector& g = gram.eigenvalues();
  const double keep = 1e-8 * std::max(g.size() ? g.maxCoeff() : 0.0, 1e-300);
  std::vector<int> kept;
  for (int j = 0; j < g.size(); ++j)
    if (g[j] > keep) kept.push_back(j);
  Matrix Q(W.cols(), static_cast<Eigen::Index>(kept.size()));
  for (size_t j = 0; j < kept.size(); ++j)
    Q.col(static_cast<Eigen::Index>(j)) = gram.eigenvectors().col(kept[j]) / std::sqrt(g[kept[j]]);
  mode.W = W * Q;
  mode.AW = project_rows(mode, apply(mode, mode.W));
  const Eigen::SelfAdjointEigenSolver<Matrix> coarse(mode.W.transpose() * mode.AW);
  const Vector& e = coarse.eigenvalues();
  const double floor = 1e-13 * std::max(e.size() ? e.cwiseAbs().maxCoeff() : 0.0, 1e-300);
  Vector inverse(e.size());
  mode.negative_eigenvalues = 1;  // the border's
  for (int j = 0; j < e.size(); ++j) {
    inverse[j] = std::abs(e[j]) > floor ? 1 / e[j] : 0.0;
    mode.negative_eigenvalues += e[j] < 0;
  }
  mode.coarse_inverse = coarse.eigenvectors() * inverse.asDiagonal() * coarse.eigenvectors().transpose();
  mode.ready = true;
}

bool SharedShiftSolver::agrees_with(int i, const SparseMatrix& bordered) const {
  if (!has_mode(i)) return false;
  const Mode& mode = modes_[i];
  const Eigen::Index n = mode.u.size();
  if (bordered.rows() != n + 1) return false;
  const Vector diagonal = K_.diagonal() / mode.lambda_ref - mode.ratio * M_.diagonal();
  Vector border = Vector::Zero(n), seen_diagonal = Vector::Zero(n);
  for (int col = 0; col < bordered.outerSize(); ++col)
    for (SparseMatrix::InnerIterator it(bordered, col); it; ++it) {
      if (it.row() == n && col < n) border[col] += it.value();
      else if (it.row() == col && col < n) seen_diagonal[col] += it.value();
    }
  const double tolerance = 1e-10;
  return (border + mode.Mu).norm() <= tolerance * mode.Mu.norm() &&
         (seen_diagonal - diagonal).norm() <= tolerance * std::max(diagonal.norm(), 1e-300);
}

bool SharedShiftSolver::deflated_cg(const Mode& mode, const Matrix& R0, Matrix* Y, std::string* error) {
  const int m = static_cast<int>(R0.cols());
  // The part in span(W) exactly; what is left is A-conjugate to W.
  *Y = mode.W * (mode.coarse_inverse * (mode.W.transpose() * R0));
  Matrix R = R0 - mode.AW * (mode.coarse_inverse * (mode.W.transpose() * R0));
  // Converged at a normwise backward error of `tolerance`: |r| <= tol (|b| + |A| |y|) (2-norms,
  // |A| by its largest row sum). Relative to |b| alone, a right-hand side that is round-off (a
  // constraint already met) could never be.
  auto converged = [&](int c) {
    return R.col(c).norm() <= options_.tolerance * (R0.col(c).norm() + mode.norm * Y->col(c).norm());
  };
  // Search directions A-conjugate to W: z - W E^{-1} (A W)^T z.
  auto conjugate_to_W = [&](Matrix Z) {
    Z -= mode.W * (mode.coarse_inverse * (mode.AW.transpose() * Z));
    return Z;
  };
  std::vector<bool> active(m);
  bool any = false;
  for (int c = 0; c < m; ++c) any |= (active[c] = !converged(c));
  Matrix Z = conjugate_to_W(precondition(mode, R));
  Matrix P = Z;
  Vector rz(m);
  for (int c = 0; c < m; ++c) rz[c] = R.col(c).dot(Z.col(c));
  last_iterations_ = 0;
  while (any) {
    if (last_iterations_ == options_.max_iterations) {
      if (error) *error = "deflated CG did not converge in " + std::to_string(options_.max_iterations) + " iterations";
      return false;
    }
    ++last_iterations_;
    const Matrix Q = project_rows(mode, apply(mode, P));
    for (int c = 0; c < m; ++c) {
      if (!active[c]) continue;
      const double curvature = P.col(c).dot(Q.col(c));
      if (!(curvature > 0)) {
        if (error)
          *error = "K - lambda M is not definite beyond the deflation basis (curvature " + std::to_string(curvature) +
                   "): a mode below this one is missing from the basis";
        return false;
      }
      const double alpha = rz[c] / curvature;
      Y->col(c) += alpha * P.col(c);
      R.col(c) -= alpha * Q.col(c);
    }
    any = false;
    for (int c = 0; c < m; ++c) any |= (active[c] = active[c] && !converged(c));
    if (!any) break;
    // r^T z is unchanged by the conjugation (W^T r = 0), and p already is conjugate to W.
    Z = conjugate_to_W(precondition(mode, R));
    for (int c = 0; c < m; ++c) {
      if (!active[c]) continue;
      const double rz_new = R.col(c).dot(Z.col(c));
      P.col(c) = Z.col(c) + (rz_new / rz[c]) * P.col(c);
      rz[c] = rz_new;
    }
  }
  return true;
}

bool SharedShiftSolver::solve(int i, Matrix* rhs, std::string* error) {
  const Mode& mode = modes_[i];
  const Eigen::Index n = mode.u.size();
  const Matrix f = rhs->topRows(n);
  const Vector c = -rhs->row(n).transpose() / mode.mu;  // x's component along u
  const Matrix R = project_rows(mode, f - mode.Au * c.transpose());
  Matrix Y;
  const bool converged = deflated_cg(mode, R, &Y, error);
  const Matrix X = Y + mode.u * c.transpose();
  const Matrix AX = apply(mode, Y) + mode.Au * c.transpose();
  rhs->topRows(n) = X;
  rhs->row(n) = (mode.u.transpose() * (AX - f)) / mode.mu;
  return converged;
}

std::unique_ptr<SharedShiftSolver> shared_shift_solver(FullSpaceProblem& problem, const double* x,
                                                       std::string* error) {
  const Matrix& basis = problem.deflation_basis();
  if (basis.cols() == 0 || basis.rows() != problem.num_dofs() || !x) {
    if (error) *error = "no deflation basis or no point (no forward solve given to the problem)";
    return nullptr;
  }
  double lowest = INFINITY;
  for (int i = 0; i < problem.num_modes(); ++i) lowest = std::min(lowest, problem.reference_eigenvalue(i));
  auto solver = std::make_unique<SharedShiftSolver>();
  const SparseMatrix& M = problem.mass_matrix(x);
  if (!solver->factor(problem.stiffness_matrix(x), M, -0.1 * lowest, basis, error)) return nullptr;
  for (int i = 0; i < problem.num_modes(); ++i)
    solver->set_mode(i, problem.mode_vector(x, i), problem.reference_eigenvalue(i), problem.eigenvalue_ratio(x, i));
  return solver;
}

}  // namespace modalcal::detail
