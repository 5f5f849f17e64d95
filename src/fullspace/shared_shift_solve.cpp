#include "fullspace/shared_shift_solve.hpp"

#include <Eigen/Eigenvalues>

#include <algorithm>
#include <cmath>
#include <cstring>

#include "eigen/block_lanczos.hpp"  // symmetric_times
#include "eigen/cholmod_factor.hpp"
#include "fullspace/fullspace_problem.hpp"

namespace modalcal::detail {

namespace {

bool same_pattern(const SparseMatrix& a, const SparseMatrix& b) {
  return a.rows() == b.rows() && a.cols() == b.cols() && a.nonZeros() == b.nonZeros() && a.isCompressed() &&
         b.isCompressed() &&
         std::memcmp(a.outerIndexPtr(), b.outerIndexPtr(), sizeof(int) * (a.outerSize() + 1)) == 0 &&
         std::memcmp(a.innerIndexPtr(), b.innerIndexPtr(), sizeof(int) * a.nonZeros()) == 0;
}

// Per column of a lockstep CG: its best iterate so far and when to stop. Past the rounding floor
// CG's iterates wander off (its directions become noise), so a column returns to its best.
class BestIterates {
 public:
  BestIterates(const Matrix& Y, const Matrix& R, const SharedShiftOptions& options)
      : options_(options), error_(Vector::Constant(Y.cols(), INFINITY)), stalled_(Y.cols(), 0), Y_(Y), R_(R) {}

  // Column c's iterate, of backward error e: true when the column is done (at `tolerance`, or
  // below `acceptable` and not halved in two iterations), its best iterate then in Y and R.
  bool record(int c, double e, Matrix* Y, Matrix* R) {
    if (e < error_[c]) {
      stalled_[c] = e < 0.5 * error_[c] ? 0 : stalled_[c] + 1;
      error_[c] = e;
      Y_.col(c) = Y->col(c);
      R_.col(c) = R->col(c);
    } else {
      ++stalled_[c];
    }
    const bool done = e <= options_.tolerance || (error_[c] <= options_.acceptable && stalled_[c] >= 2);
    if (done) restore(c, Y, R);
    return done;
  }
  // Puts column c's best iterate into Y and R; true when it is acceptable.
  bool restore(int c, Matrix* Y, Matrix* R) const {
    Y->col(c) = Y_.col(c);
    R->col(c) = R_.col(c);
    return error_[c] <= options_.acceptable;
  }

 private:
  const SharedShiftOptions& options_;
  Vector error_;
  std::vector<int> stalled_;
  Matrix Y_, R_;
};

}  // namespace

SharedShiftSolver::SharedShiftSolver(SharedShiftOptions options) : options_(options) {}
SharedShiftSolver::~SharedShiftSolver() = default;

bool SharedShiftSolver::factor(const SparseMatrix& K, const SparseMatrix& M, double sigma, const Matrix& basis,
                               std::string* error) {
  modes_.clear();
  if (!same_pattern(K, M) || basis.rows() != K.rows()) {
    if (error) *error = "K and M must share one compressed pattern, and the basis their size";
    return false;
  }
  const bool analysed = factor_ && same_pattern(K, K_);
  K_ = K;
  M_ = M;
  if (!analysed) factor_ = std::make_unique<CholmodFactor>(K_);  // the symbolic analysis, once per pattern
  int failed = -1;
  if (!factor_->factorize(K_, M_, sigma, &failed)) {
    if (error)
      *error = "K - sigma M (sigma " + std::to_string(sigma) + ") is not positive definite at column " +
               std::to_string(failed);
    return false;
  }
  V_ = basis;
  KV_ = symmetric_times(K_, V_);
  MV_ = symmetric_times(M_, V_);
  return true;
}

Matrix SharedShiftSolver::apply(const Mode& mode, const Matrix& X) const {
  return symmetric_times(K_, X) / mode.lambda_ref - mode.ratio * symmetric_times(M_, X);
}

Matrix SharedShiftSolver::project_rows(const Mode& mode, Matrix R) const {
  R -= mode.Mu * (mode.u.transpose() * R / mode.mu);  // Pi^T = I - M u u^T / mu
  return R;
}

Matrix SharedShiftSolver::project(const Mode& mode, Matrix Z) const {
  Z -= mode.u * (mode.Mu.transpose() * Z / mode.mu);  // Pi = I - u u^T M / mu
  return Z;
}

// W = Pi V Q = (V - u a) Q with a = (M u)^T V / mu, held as Q and a only: the n x k products with
// V are shared by every mode.
Matrix SharedShiftSolver::W_times(const Mode& mode, const Matrix& C) const {
  const Matrix QC = mode.Q * C;
  return V_ * QC - mode.u * (mode.a * QC);
}

Matrix SharedShiftSolver::W_transpose_times(const Mode& mode, const Matrix& R) const {
  return mode.Q.transpose() * (V_.transpose() * R - mode.a.transpose() * (mode.u.transpose() * R));
}

// Pi^T A W C = Pi^T ((A V) Q C - (A u) a Q C), A V = K V / lambda_ref - t M V.
Matrix SharedShiftSolver::AW_times(const Mode& mode, const Matrix& C) const {
  const Matrix QC = mode.Q * C;
  return project_rows(mode, KV_ * (QC / mode.lambda_ref) - MV_ * (mode.ratio * QC) - mode.Au * (mode.a * QC));
}

// (Pi^T A W)^T Z = W^T A Z for Z in range(Pi) = Q^T ((A V)^T Z - a^T (A u)^T Z).
Matrix SharedShiftSolver::AW_transpose_times(const Mode& mode, const Matrix& Z) const {
  const Matrix AVZ = KV_.transpose() * Z / mode.lambda_ref - mode.ratio * (MV_.transpose() * Z);
  return mode.Q.transpose() * (AVZ - mode.a.transpose() * (mode.Au.transpose() * Z));
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
  // |A_i|, its largest absolute row sum (K and M share one pattern).
  Vector row_sums = Vector::Zero(K_.rows());
  for (Eigen::Index k = 0; k < K_.nonZeros(); ++k)
    row_sums[K_.innerIndexPtr()[k]] += std::abs(K_.valuePtr()[k] / lambda_ref - ratio * M_.valuePtr()[k]);
  mode.norm = row_sums.maxCoeff();
  // Pi V, M-orthonormalized by Q; V's direction along u projects to nearly nothing and drops.
  mode.a = mode.Mu.transpose() * V_ / mode.mu;
  const Matrix MPV = MV_ - mode.Mu * mode.a;  // M Pi V
  const Matrix PV = V_ - mode.u * mode.a;
  const Eigen::SelfAdjointEigenSolver<Matrix> gram(PV.transpose() * MPV);
  const Vector& g = gram.eigenvalues();
  const double keep = 1e-8 * std::max(g.size() ? g.maxCoeff() : 0.0, 1e-300);
  std::vector<int> kept;
  for (int j = 0; j < g.size(); ++j)
    if (g[j] > keep) kept.push_back(j);
  mode.Q.resize(V_.cols(), static_cast<Eigen::Index>(kept.size()));
  for (size_t j = 0; j < kept.size(); ++j)
    mode.Q.col(static_cast<Eigen::Index>(j)) = gram.eigenvectors().col(kept[j]) / std::sqrt(g[kept[j]]);
  // E = W^T A W, inverted on its eigenvectors (numerically zero eigenvalues left out).
  const Eigen::SelfAdjointEigenSolver<Matrix> coarse(
      W_transpose_times(mode, AW_times(mode, Matrix::Identity(mode.Q.cols(), mode.Q.cols()))));
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
  // Entry by entry: a parameter that acts on a few DOFs must not hide in a norm over all of them.
  const double tolerance = 1e-10;
  const double diagonal_scale = K_.diagonal().cwiseAbs().maxCoeff() / mode.lambda_ref +
                                std::abs(mode.ratio) * M_.diagonal().cwiseAbs().maxCoeff();
  return (border + mode.Mu).cwiseAbs().maxCoeff() <= tolerance * mode.Mu.cwiseAbs().maxCoeff() &&
         (seen_diagonal - diagonal).cwiseAbs().maxCoeff() <= tolerance * std::max(diagonal_scale, 1e-300);
}

bool SharedShiftSolver::deflated_cg(const Mode& mode, const Matrix& R0, Matrix* Y, std::string* error) {
  const int m = static_cast<int>(R0.cols());
  // The part in span(W) exactly; what is left is A-conjugate to W.
  const Matrix coarse = mode.coarse_inverse * W_transpose_times(mode, R0);
  *Y = W_times(mode, coarse);
  Matrix R = R0 - AW_times(mode, coarse);
  // Each column runs until its normwise backward error |r| / (|b| + |A| |y|) (2-norms of the
  // columns, |A| the largest row sum) reaches `tolerance`, or, once below `acceptable`, stops
  // falling: the rounding floor, near sqrt(n) eps, lies between the two and grows with n.
  // (Relative to |b| alone, a right-hand side that is round-off - a constraint already met -
  // could never converge.)
  auto backward_error = [&](int c) {
    return R.col(c).norm() / std::max(R0.col(c).norm() + mode.norm * Y->col(c).norm(), 1e-300);
  };
  BestIterates best(*Y, R, options_);
  auto converged = [&](int c) { return best.record(c, backward_error(c), Y, &R); };
  std::vector<int> active;
  for (int c = 0; c < m; ++c)
    if (!converged(c)) active.push_back(c);
  // The active columns' preconditioned residuals z = Pi (K - sigma M)^{-1} r (the columns in the
  // order of `active`).
  auto precondition = [&]() -> Matrix {
    Matrix Ra(R.rows(), static_cast<Eigen::Index>(active.size()));
    for (size_t a = 0; a < active.size(); ++a) Ra.col(static_cast<Eigen::Index>(a)) = R.col(active[a]);
    return project(mode, factor_->solve(Ra));
  };
  // Search directions A-conjugate to W: z - W E^{-1} (A W)^T z.
  auto conjugate_to_W = [&](const Matrix& Z) -> Matrix {
    return Z - W_times(mode, mode.coarse_inverse * AW_transpose_times(mode, Z));
  };
  Matrix P = Matrix::Zero(R.rows(), m);
  Vector rz = Vector::Zero(m);
  last_iterations_ = 0;
  for (bool first = true; !active.empty(); first = false) {
    const Matrix Z = precondition();
    const Matrix conjugate = conjugate_to_W(Z);
    for (size_t a = 0; a < active.size(); ++a) {
      const int c = active[a];
      const double rz_new = R.col(c).dot(Z.col(static_cast<Eigen::Index>(a)));
      P.col(c) = conjugate.col(static_cast<Eigen::Index>(a)) + (first ? 0.0 : rz_new / rz[c]) * P.col(c);
      rz[c] = rz_new;
    }
    if (last_iterations_ == options_.max_iterations) {
      bool acceptable = true;
      for (int c : active) acceptable = best.restore(c, Y, &R) && acceptable;
      if (!acceptable && error)
        *error = "deflated CG did not converge in " + std::to_string(options_.max_iterations) + " iterations";
      return acceptable;
    }
    ++last_iterations_;
    Matrix Pa(P.rows(), static_cast<Eigen::Index>(active.size()));
    for (size_t a = 0; a < active.size(); ++a) Pa.col(static_cast<Eigen::Index>(a)) = P.col(active[a]);
    const Matrix Q = project_rows(mode, apply(mode, Pa));
    std::vector<int> still;
    for (size_t a = 0; a < active.size(); ++a) {
      const int c = active[a];
      const auto q = Q.col(static_cast<Eigen::Index>(a));
      const double curvature = P.col(c).dot(q);
      if (!(curvature > 0)) {
        if (best.restore(c, Y, &R)) continue;  // at the rounding floor: done
        if (error)
          *error = "K - lambda M is not definite beyond the deflation basis (curvature " + std::to_string(curvature) +
                   "): a mode below this one is missing from the basis";
        return false;
      }
      const double alpha = rz[c] / curvature;
      Y->col(c) += alpha * P.col(c);
      R.col(c) -= alpha * q;
      if (!converged(c)) still.push_back(c);
    }
    active.swap(still);
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
  const Matrix AX = apply(mode, X);
  rhs->topRows(n) = X;
  rhs->row(n) = (mode.u.transpose() * (AX - f)) / mode.mu;
  if (!converged) return false;
  // The recursively updated residual can fall below the tolerance after the true one has
  // stopped falling: check the true one, with a margin for that drift.
  const Matrix true_residual = project_rows(mode, AX - f);
  for (int k = 0; k < true_residual.cols(); ++k)
    if (true_residual.col(k).norm() > 10 * options_.acceptable * (R.col(k).norm() + mode.norm * X.col(k).norm())) {
      if (error) *error = "deflated CG's true residual stayed above its tolerance";
      return false;
    }
  return true;
}

bool update_shared_shift_solver(FullSpaceProblem& problem, const double* x, SharedShiftSolver* solver,
                                std::string* error) {
  const Matrix& basis = problem.deflation_basis();
  if (basis.cols() == 0 || basis.rows() != problem.num_dofs() || !x) {
    if (error) *error = "no deflation basis (no forward solve given to the problem) or no point";
    return false;
  }
  const Eigen::Map<const Vector> point(x, problem.num_variables());
  if (solver->point_.size() == point.size() && solver->point_ == point &&
      solver->basis_version_ == problem.deflation_basis_version())
    return true;  // the same B_i (Ipopt's inertia corrections change only the Hessian)
  solver->point_.resize(0);
  double lowest = INFINITY;
  for (int i = 0; i < problem.num_modes(); ++i) lowest = std::min(lowest, problem.reference_eigenvalue(i));
  const SparseMatrix& M = problem.mass_matrix(x);
  if (!solver->factor(problem.stiffness_matrix(x), M, -0.1 * lowest, basis, error)) return false;
  for (int i = 0; i < problem.num_modes(); ++i)
    solver->set_mode(i, problem.mode_vector(x, i), problem.reference_eigenvalue(i), problem.eigenvalue_ratio(x, i));
  solver->point_ = point;
  solver->basis_version_ = problem.deflation_basis_version();
  return true;
}

}  // namespace modalcal::detail
