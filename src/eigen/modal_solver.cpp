#include <Eigen/Cholesky>
#include <Eigen/Eigenvalues>
#include <Spectra/SymGEigsShiftSolver.h>

#include <chrono>
#include <cmath>
#include <sstream>
#include <stdexcept>

#include "eigen/cholmod_factor.hpp"
#include "modalcal/eigen.hpp"

namespace modalcal {

namespace {

constexpr double kTwoPi = 6.283185307179586;
// Below this size a dense solve is both simpler and faster than Lanczos, and Lanczos needs
// nev < ncv <= n anyway.
constexpr int kDenseLimit = 300;

double seconds_since(std::chrono::steady_clock::time_point t0) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
}

// Spectra operator concept for (K - sigma M)^{-1} over the CHOLMOD factor: the factorization
// itself happens in set_shift(), which Spectra calls once from the solver's constructor.
class ShiftInvertOperator {
 public:
  using Scalar = double;
  ShiftInvertOperator(detail::CholmodFactor& factor, const SparseMatrix& K, const SparseMatrix& M)
      : factor_(factor), K_(K), M_(M) {}
  Eigen::Index rows() const { return factor_.rows(); }
  Eigen::Index cols() const { return factor_.rows(); }
  void set_shift(double sigma) { ok_ = factor_.factorize(K_, M_, sigma, &failed_column_); }
  void perform_op(const double* x, double* y) const {
    factor_.solve(x, y);
    ++solves_;
  }
  bool ok() const { return ok_; }
  int failed_column() const { return failed_column_; }
  int solves() const { return solves_; }

 private:
  detail::CholmodFactor& factor_;
  const SparseMatrix& K_;
  const SparseMatrix& M_;
  bool ok_ = false;
  int failed_column_ = -1;
  mutable int solves_ = 0;
};

class MassOperator {
 public:
  using Scalar = double;
  explicit MassOperator(const SparseMatrix& M) : M_(M) {}
  Eigen::Index rows() const { return M_.rows(); }
  Eigen::Index cols() const { return M_.cols(); }
  void perform_op(const double* x, double* y) const {
    Eigen::Map<Vector>(y, M_.rows()).noalias() = M_ * Eigen::Map<const Vector>(x, M_.cols());
  }

 private:
  const SparseMatrix& M_;
};

std::string not_positive_definite_message(double sigma, int column) {
  std::ostringstream s;
  s << "K - sigma M is not positive definite (sigma = " << sigma << ", Cholesky failed at column "
    << column << "): with a negative shift this means K is indefinite. Likely causes: a negative "
    << "modulus, stiffness or mass (check parameter values and bounds), or a Poisson's ratio "
    << "at or beyond 0.5.";
  return s.str();
}

}  // namespace

std::string to_string(EigenStatus status) {
  switch (status) {
    case EigenStatus::Successful: return "Successful";
    case EigenStatus::NotConverging: return "NotConverging";
    case EigenStatus::NumericalIssue: return "NumericalIssue";
  }
  return "?";
}

double frequency_hz(double eigenvalue) {
  return std::copysign(std::sqrt(std::abs(eigenvalue)), eigenvalue) / kTwoPi;
}
double eigenvalue_of_hz(double hz) { return std::copysign(std::pow(kTwoPi * hz, 2), hz); }

bool ModalOptions::IsValid(std::string* error) const {
  auto bad = [&](const std::string& message) {
    if (error) *error = message;
    return false;
  };
  if (num_modes < 1) return bad("num_modes = " + std::to_string(num_modes) + ": must be >= 1");
  if (max_rigid_modes < 0 || max_rigid_modes > 6)
    return bad("max_rigid_modes = " + std::to_string(max_rigid_modes) + ": must be in 0..6");
  if (!(tolerance > 0 && tolerance <= 1e-2))
    return bad("tolerance = " + std::to_string(tolerance) + ": must be in (0, 1e-2]");
  if (max_iterations < 1) return bad("max_iterations = " + std::to_string(max_iterations) + ": must be >= 1");
  if (subspace_size != 0 && subspace_size <= num_modes + max_rigid_modes)
    return bad("subspace_size = " + std::to_string(subspace_size) + ": must be 0 or > num_modes + max_rigid_modes");
  if (!(initial_shift <= 0) || !std::isfinite(initial_shift))
    return bad("initial_shift = " + std::to_string(initial_shift) + ": must be 0 (automatic) or negative");
  if (!(rigid_tolerance > 0 && rigid_tolerance <= 1e-3))
    return bad("rigid_tolerance = " + std::to_string(rigid_tolerance) + ": must be in (0, 1e-3]");
  return true;
}

struct ModalSolver::Impl {
  explicit Impl(const SparseMatrix& pattern) : factor(pattern) {}
  detail::CholmodFactor factor;
};

ModalSolver::ModalSolver(const SparseMatrix& pattern, const ModalOptions& options) : options_(options) {
  std::string error;
  if (!options.IsValid(&error)) throw std::invalid_argument("ModalOptions: " + error);
  impl_ = std::make_unique<Impl>(pattern);
  shift_ = options.initial_shift;
}

ModalSolver::~ModalSolver() = default;

double ModalSolver::seconds_analyze() const { return impl_->factor.seconds_analyze(); }

void ModalSolver::set_num_modes(int n) {
  if (n < 1) throw std::invalid_argument("ModalSolver::set_num_modes: n = " + std::to_string(n) + " must be >= 1");
  options_.num_modes = n;
}

bool ModalSolver::factorize_shifted(const SparseMatrix& K, const SparseMatrix& M, double sigma,
                                    std::string* message) {
  int column = -1;
  const bool ok = impl_->factor.factorize(K, M, sigma, &column);
  if (!ok && message) *message = not_positive_definite_message(sigma, column);
  return ok;
}

Matrix ModalSolver::solve_factorized(const Matrix& rhs) const { return impl_->factor.solve(rhs); }

ModalResult ModalSolver::solve(const SparseMatrix& K, const SparseMatrix& M) {
  const auto t0 = std::chrono::steady_clock::now();
  ModalResult result;
  const int n = static_cast<int>(K.rows());
  const double trace_ratio = K.diagonal().sum() / M.diagonal().sum();
  if (!std::isfinite(trace_ratio) || !(trace_ratio > 0)) {
    result.message = "K or M has a non-positive or non-finite trace: check moduli, densities and "
                     "parameter values for zeros, negatives or NaN";
    return result;
  }
  // Without a previous solve, -1e-6 tr(K)/tr(M) lies near or below the lowest elastic eigenvalue
  // of practical meshes while keeping K - sigma M well conditioned for rigid-body modes.
  const double sigma = shift_ < 0 ? shift_ : -1e-6 * trace_ratio;
  result.shift = sigma;
  const int wanted = options_.num_modes + options_.max_rigid_modes;
  if (wanted > n) {
    result.message = "asked for " + std::to_string(wanted) + " modes (including up to " +
                     std::to_string(options_.max_rigid_modes) + " rigid-body modes) of a model with only " +
                     std::to_string(n) + " DOFs";
    return result;
  }

  Vector lambda;
  Matrix vectors;
  if (n <= kDenseLimit) {
    // Dense shift-invert: with A = K - sigma M = L L^T, the eigenvalues of L^{-1} M L^{-T} are
    // 1/(lambda - sigma); this tolerates a singular M (massless rotations).
    const Matrix A = Matrix(K) - sigma * Matrix(M);
    Eigen::LLT<Matrix> llt(A);
    ++result.factorizations;
    if (llt.info() != Eigen::Success) {
      result.message = not_positive_definite_message(sigma, -1);
      result.seconds_total = seconds_since(t0);
      return result;
    }
    Matrix C = llt.matrixL().solve(Matrix(M));
    C = llt.matrixL().solve(C.transpose()).transpose();
    Eigen::SelfAdjointEigenSolver<Matrix> es(C);
    const int count = wanted;
    lambda.resize(count);
    vectors.resize(n, count);
    for (int k = 0; k < count; ++k) {
      const int idx = n - 1 - k;  // largest 1/(lambda - sigma) first = lowest lambda
      lambda[k] = 1.0 / es.eigenvalues()[idx] + sigma;
      vectors.col(k) = llt.matrixU().solve(es.eigenvectors().col(idx));
    }
  } else {
    ShiftInvertOperator op(impl_->factor, K, M);
    MassOperator bop(M);
    const int ncv = options_.subspace_size > 0 ? options_.subspace_size : std::min(n, 2 * wanted + 1);
    const auto tf = std::chrono::steady_clock::now();
    Spectra::SymGEigsShiftSolver<ShiftInvertOperator, MassOperator, Spectra::GEigsMode::ShiftInvert> eigs(
        op, bop, wanted, ncv, sigma);
    result.seconds_factorize = seconds_since(tf);
    ++result.factorizations;
    if (!op.ok()) {
      result.message = not_positive_definite_message(sigma, op.failed_column());
      result.seconds_total = seconds_since(t0);
      return result;
    }
    eigs.init();
    eigs.compute(Spectra::SortRule::LargestMagn, options_.max_iterations, options_.tolerance,
                 Spectra::SortRule::SmallestAlge);
    result.operator_solves = op.solves();
    if (eigs.info() != Spectra::CompInfo::Successful) {
      result.status = eigs.info() == Spectra::CompInfo::NotConverging ? EigenStatus::NotConverging
                                                                       : EigenStatus::NumericalIssue;
      result.message = "shift-invert Lanczos did not converge in " + std::to_string(options_.max_iterations) +
                       " restarts (tolerance " + std::to_string(options_.tolerance) +
                       "): try a larger subspace_size or a looser tolerance";
      result.seconds_total = seconds_since(t0);
      return result;
    }
    lambda = eigs.eigenvalues();
    vectors = eigs.eigenvectors();
  }

  // Split rigid-body (near-zero) from elastic modes, normalize and fix signs.
  const double rigid_threshold = options_.rigid_tolerance * trace_ratio;
  std::vector<int> rigid, elastic;
  for (int k = 0; k < lambda.size(); ++k) {
    if (lambda[k] < -rigid_threshold) {
      std::ostringstream s;
      s << "K has a negative eigenvalue (" << lambda[k] << ", " << frequency_hz(lambda[k])
        << " Hz): K is indefinite. Likely causes: a negative modulus, stiffness or mass.";
      result.message = s.str();
      result.seconds_total = seconds_since(t0);
      return result;
    }
    (std::abs(lambda[k]) <= rigid_threshold ? rigid : elastic).push_back(k);
  }
  if (static_cast<int>(rigid.size()) > options_.max_rigid_modes) {
    result.message = std::to_string(rigid.size()) + " zero-frequency modes but at most " +
                     std::to_string(options_.max_rigid_modes) +
                     " expected: K is singular. Likely causes: supports are missing, a part is not "
                     "connected to the rest, or a joint or spring stiffness is zero.";
    result.seconds_total = seconds_since(t0);
    return result;
  }
  auto normalize = [&](Vector u) {
    u /= std::sqrt(u.dot(M * u));
    Eigen::Index imax;
    u.cwiseAbs().maxCoeff(&imax);
    if (u[imax] < 0) u = -u;
    return u;
  };
  const int ne = std::min(options_.num_modes, static_cast<int>(elastic.size()));
  result.eigenvalues.resize(ne);
  result.modes.resize(n, ne);
  result.residuals.resize(ne);
  for (int k = 0; k < ne; ++k) {
    const Vector u = normalize(vectors.col(elastic[k]));
    result.eigenvalues[k] = lambda[elastic[k]];
    result.modes.col(k) = u;
    const Vector Mu = M * u;
    result.residuals[k] = (K * u - lambda[elastic[k]] * Mu).norm() / (std::abs(lambda[elastic[k]]) * Mu.norm());
  }
  result.rigid_eigenvalues.resize(rigid.size());
  result.rigid_modes.resize(n, rigid.size());
  for (size_t k = 0; k < rigid.size(); ++k) {
    result.rigid_eigenvalues[k] = lambda[rigid[k]];
    result.rigid_modes.col(k) = normalize(vectors.col(rigid[k]));
  }
  if (ne < options_.num_modes) {
    result.status = EigenStatus::NumericalIssue;
    result.message = "found only " + std::to_string(ne) + " elastic modes of " + std::to_string(options_.num_modes);
    result.seconds_total = seconds_since(t0);
    return result;
  }
  result.status = EigenStatus::Successful;
  shift_ = -0.3 * result.eigenvalues[0];
  result.seconds_total = seconds_since(t0);
  return result;
}

}  // namespace modalcal
