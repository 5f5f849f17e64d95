#include <Eigen/Cholesky>
#include <Eigen/Eigenvalues>
#include <Spectra/SymGEigsShiftSolver.h>

#include <algorithm>
#include <new>
#include <chrono>
#include <cmath>
#include <sstream>
#include <stdexcept>
#include <vector>

#include "eigen/block_lanczos.hpp"
#include "eigen/cholmod_factor.hpp"
#include "modalcal/eigen.hpp"
#include "support/text_util.hpp"

namespace modalcal {

namespace {

/// The median of `values` (not empty), which it reorders.
double median_of(std::vector<double>* values) {
  const auto middle = values->begin() + static_cast<std::ptrdiff_t>(values->size() / 2);
  std::nth_element(values->begin(), middle, values->end());
  return *middle;
}

/// The stiffness-to-mass scale that places the first shift and the rigid-body threshold:
/// tr(K)/tr(M), or the median of K_ii/M_ii over the DOFs with mass when that is lower. A few
/// penalty-stiff joints or springs (1e14 against a structure's 1e8) dominate the trace, which
/// then put real elastic modes below the rigid-body threshold ("K is singular"); the median
/// does not see them, and on an ordinary mesh it is close to the trace ratio.
double stiffness_mass_scale(const SparseMatrix& K, const SparseMatrix& M, double trace_ratio) {
  const Vector k = K.diagonal(), m = M.diagonal();
  std::vector<double> ratios;
  ratios.reserve(static_cast<size_t>(k.size()));
  for (Eigen::Index i = 0; i < k.size(); ++i)
    if (m[i] > 0 && k[i] > 0) ratios.push_back(k[i] / m[i]);
  if (ratios.empty()) return trace_ratio;
  return std::min(trace_ratio, median_of(&ratios));
}

constexpr double kTwoPi = 6.283185307179586;
// A largest diagonal entry of K this many times the median one comes from a penalty stiffness:
// the portal frame's spread is 5e6 with a joint of 1e16 against its 1e8, which still solves, and
// 5e7 with 1e17, which does not.
constexpr double kPenaltySpread = 1e6;
// Below this size a dense solve is both simpler and faster than Lanczos, and Lanczos needs
// nev < ncv <= n anyway.
constexpr int kDenseLimit = 300;

double seconds_since(std::chrono::steady_clock::time_point t0) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
}

// Spectra operator concept for (K - sigma M)^{-1} over a CHOLMOD factor that already holds
// K - sigma M: the block path and this fallback share one factorization, so set_shift(), which
// Spectra calls once from the solver's constructor with that same sigma, has nothing to do.
class ShiftInvertOperator {
 public:
  using Scalar = double;
  explicit ShiftInvertOperator(const detail::CholmodFactor& factor) : factor_(factor) {}
  Eigen::Index rows() const { return factor_.rows(); }
  Eigen::Index cols() const { return factor_.rows(); }
  void set_shift(double) {}
  void perform_op(const double* x, double* y) const {
    factor_.solve(x, y);
    ++solves_;
  }
  int solves() const { return solves_; }

 private:
  const detail::CholmodFactor& factor_;
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

// Eigenpairs of (K, M), ascending, before the rigid/elastic split.
struct Eigenpairs {
  Vector lambda;
  Matrix vectors;
  // M and K times the vectors, when the solve has them already (Rayleigh-Ritz); empty otherwise.
  // With mass_norms (u^T M u of every vector, a Ritz model's) they may hold only the first
  // vectors, and the residuals are computed for those alone.
  Matrix mass_vectors, stiffness_vectors;
  Vector mass_norms;
};

// Dense shift-invert: with A = K - sigma M = L L^T, the eigenvalues of L^{-1} M L^{-T} are
// 1/(lambda - sigma); this tolerates a singular M (massless rotations).
bool dense_eigenpairs(const SparseMatrix& K, const SparseMatrix& M, double sigma, int wanted, ModalResult* result,
                      Eigenpairs* pairs) {
  const int n = static_cast<int>(K.rows());
  const Matrix A = Matrix(K) - sigma * Matrix(M);
  Eigen::LLT<Matrix> llt(A);
  ++result->factorizations;
  if (llt.info() != Eigen::Success) {
    result->message = not_positive_definite_message(sigma, -1);
    return false;
  }
  Matrix C = llt.matrixL().solve(Matrix(M));
  C = llt.matrixL().solve(C.transpose()).transpose();
  Eigen::SelfAdjointEigenSolver<Matrix> es(C);
  pairs->lambda.resize(wanted);
  pairs->vectors.resize(n, wanted);
  for (int k = 0; k < wanted; ++k) {
    const int idx = n - 1 - k;  // largest 1/(lambda - sigma) first = lowest lambda
    pairs->lambda[k] = 1.0 / es.eigenvalues()[idx] + sigma;
    pairs->vectors.col(k) = llt.matrixU().solve(es.eigenvectors().col(idx));
  }
  return true;
}

// Block size when ModalOptions::block_size is 0 (see its documentation for the measurements).
constexpr int kAutomaticBlockSize = 4;

detail::BlockLanczosOptions block_options(const ModalOptions& options, int wanted, double rigid_threshold) {
  detail::BlockLanczosOptions block;
  block.nev = wanted;
  block.block_size = options.block_size > 0 ? options.block_size : kAutomaticBlockSize;
  // The automatic size holds the 13-14 blocks that 10 modes took and the 23 that 20 took on
  // the LFU model (7e4-1.5e5 DOFs) without a restart.
  const int basis = options.subspace_size > 0 ? options.subspace_size : std::max(6 * wanted, wanted + 12 * block.block_size);
  // Room for the kept Ritz vectors plus two blocks after a thick restart.
  block.max_basis = std::max(basis, wanted + 2 * block.block_size);
  block.max_restarts = options.max_iterations;
  block.tolerance = options.tolerance;
  block.rigid_threshold = rigid_threshold;
  return block;
}

// Spectra's result: the eigenpairs, or why there are none.
template <typename Eigs>
bool spectra_result(Eigs& eigs, const ModalOptions& options, ModalResult* result, Eigenpairs* pairs) {
  if (eigs.info() != Spectra::CompInfo::Successful) {
    result->status = eigs.info() == Spectra::CompInfo::NotConverging ? EigenStatus::NotConverging
                                                                      : EigenStatus::NumericalIssue;
    result->message = "shift-invert Lanczos did not converge in " + std::to_string(options.max_iterations) +
                      " restarts (tolerance " + std::to_string(options.tolerance) +
                      "): try a larger subspace_size or a looser tolerance";
    return false;
  }
  pairs->lambda = eigs.eigenvalues();
  pairs->vectors = eigs.eigenvectors();
  return true;
}

// Single-vector shift-invert Lanczos (Spectra) on the factorization of K - sigma M.
bool spectra_eigenpairs(const detail::CholmodFactor& factor, const SparseMatrix& M, double sigma, int wanted,
                        const ModalOptions& options, ModalResult* result, Eigenpairs* pairs) {
  const int n = factor.rows();
  ShiftInvertOperator op(factor);
  MassOperator bop(M);
  const int ncv = options.subspace_size > 0 ? options.subspace_size : std::min(n, 2 * wanted + 1);
  try {
    Spectra::SymGEigsShiftSolver<ShiftInvertOperator, MassOperator, Spectra::GEigsMode::ShiftInvert> eigs(
        op, bop, wanted, ncv, sigma);
    eigs.init();
    eigs.compute(Spectra::SortRule::LargestMagn, options.max_iterations, options.tolerance,
                 Spectra::SortRule::SmallestAlge);
    result->operator_solves += op.solves();
    return spectra_result(eigs, options, result, pairs);
  } catch (const std::bad_alloc&) {
    throw;
  } catch (const std::exception&) {
    // Spectra's own words ("TridiagEigen: eigen decomposition failed") name no cause a user knows.
    result->operator_solves += op.solves();
    result->status = EigenStatus::NumericalIssue;
    result->message =
        "shift-invert Lanczos broke down on non-finite or wildly scaled values: K or M is so ill-conditioned "
        "(extreme moduli, densities or stiffnesses?) that the iteration lost all accuracy";
    return false;
  }
}

// One factorization of K - sigma M, then block Lanczos, or Spectra if it is asked for
// (block_size = 1) or the block iteration does not converge.
bool sparse_eigenpairs(detail::CholmodFactor& factor, const SparseMatrix& K, const SparseMatrix& M, double sigma,
                       int wanted, double rigid_threshold, const ModalOptions& options, ModalResult* result,
                       Eigenpairs* pairs) {
  const auto tf = std::chrono::steady_clock::now();
  int column = -1;
  const bool factorized = factor.factorize(K, M, sigma, &column);
  result->seconds_factorize = seconds_since(tf);
  ++result->factorizations;
  if (!factorized) {
    result->message = not_positive_definite_message(sigma, column);
    return false;
  }
  if (options.block_size != 1) {
    const detail::BlockLanczosOptions block_opts = block_options(options, wanted, rigid_threshold);
    const detail::BlockLanczosResult block = detail::block_lanczos(factor, K, M, sigma, block_opts);
    result->operator_solves += block.solves;
    if (block.converged) {
      result->block_size = block_opts.block_size;
      pairs->lambda = block.eigenvalues;
      pairs->vectors = block.vectors;
      return true;
    }
  }
  result->block_size = 1;
  return spectra_eigenpairs(factor, M, sigma, wanted, options, result, pairs);
}

/// max K_ii / median K_ii over the DOFs with stiffness: how far the stiffest DOF (a penalty
/// joint or spring) stands above the structure's typical one.
double stiffness_spread(const SparseMatrix& K) {
  const Vector diagonal = K.diagonal();
  std::vector<double> k;
  for (const double kii : diagonal)
    if (kii > 0) k.push_back(kii);
  if (k.empty()) return 1;
  const double largest = *std::max_element(k.begin(), k.end());
  return largest / median_of(&k);
}

// A solved mode's relative residual is near the rounding floor (1e-12 or below); one above 1e-3
// (or 100 times a loose ModalOptions::tolerance) is no eigenpair at all. Two causes: M has fewer
// nonzero eigenvalues than modes were asked for (a block of density 0 carrying a point mass: the
// solve then returns vectors in M's null space), or a joint or spring so much stiffer than the
// structure that the factorization of K - sigma M keeps too few digits of the structure (a
// penalty for a rigid connection, 1e17 on the portal frame's 1e8). Reporting such vectors as
// modes would pass garbage on as frequencies.
bool residuals_plausible(const SparseMatrix& K, const ModalOptions& options, ModalResult* result) {
  const double most = std::max(1e-3, 100 * options.tolerance);
  for (Eigen::Index k = 0; k < result->residuals.size(); ++k) {
    if (result->residuals[k] <= most) continue;
    std::ostringstream s;
    s << "elastic mode " << k + 1 << " is no eigenpair (its relative residual is above " << most
      << " or not a number): ";
    const double spread = stiffness_spread(K);
    if (spread > kPenaltySpread)
      s << "K's largest diagonal entry is " << detail::number_text(spread, 2)
        << " times its median one. Likely causes: a joint or spring stiffness used as a penalty for a rigid "
           "connection, too stiff for the factorization to keep the structure's digits (a rigid coupling models "
           "one exactly); or fewer mass-carrying degrees "
           "of freedom than options.num_modes (a block with density 0).";
    else
      s << "the mass matrix has fewer nonzero eigenvalues than modes were asked for. Likely causes: a block with "
           "density 0, or fewer mass-carrying degrees of freedom than options.num_modes.";
    result->status = EigenStatus::NumericalIssue;
    result->message = s.str();
    return false;
  }
  return true;
}

// Splits rigid-body (near-zero) from elastic modes, normalizes (u^T M u = 1), fixes signs
// (largest component positive) and computes the residuals; false with a message if K is
// indefinite or singular or too few elastic modes were found.
bool split_modes(const SparseMatrix& K, const SparseMatrix& M, const Eigenpairs& pairs, double rigid_threshold,
                 const ModalOptions& options, int keep, ModalResult* result) {
  const Vector& lambda = pairs.lambda;
  std::vector<int> rigid, elastic;
  for (int k = 0; k < lambda.size(); ++k) {
    if (lambda[k] < -rigid_threshold) {
      std::ostringstream s;
      s << "K has a negative eigenvalue (" << lambda[k] << ", " << frequency_hz(lambda[k])
        << " Hz): K is indefinite. Likely causes: a negative modulus, stiffness or mass.";
      result->message = s.str();
      return false;
    }
    (std::abs(lambda[k]) <= rigid_threshold ? rigid : elastic).push_back(k);
  }
  if (static_cast<int>(rigid.size()) > options.max_rigid_modes) {
    result->message = std::to_string(rigid.size()) + " zero-frequency modes but at most " +
                      std::to_string(options.max_rigid_modes) +
                      " expected: K is singular. Likely causes: supports are missing, a part is not "
                      "connected to the rest, or a joint or spring stiffness is zero.";
    return false;
  }
  // All products with M and K in one pass over each matrix.
  Matrix U = pairs.vectors;
  const bool norms_given = pairs.mass_norms.size() == U.cols();
  Matrix MU = pairs.mass_vectors.size() != 0 || norms_given ? pairs.mass_vectors : detail::symmetric_times(M, U);
  Matrix KU_given = pairs.stiffness_vectors;
  for (int k = 0; k < U.cols(); ++k) {
    const double scale = 1.0 / std::sqrt(norms_given ? pairs.mass_norms[k] : U.col(k).dot(MU.col(k)));
    Eigen::Index imax;
    U.col(k).cwiseAbs().maxCoeff(&imax);
    const double sign = U(imax, k) < 0 ? -scale : scale;
    U.col(k) *= sign;
    if (k < MU.cols()) MU.col(k) *= sign;
    if (k < KU_given.cols()) KU_given.col(k) *= sign;
  }
  const int ne = std::min(keep, static_cast<int>(elastic.size()));
  result->eigenvalues.resize(ne);
  result->modes.resize(U.rows(), ne);
  result->residuals.resize(ne);
  for (int k = 0; k < ne; ++k) {
    result->eigenvalues[k] = lambda[elastic[k]];
    result->modes.col(k) = U.col(elastic[k]);
  }
  // A Ritz model (norms given) has the products it has residuals for, perhaps none.
  const Matrix KU = KU_given.size() != 0 || norms_given ? Matrix() : detail::symmetric_times(K, result->modes);
  for (int k = 0; k < ne; ++k) {
    if (elastic[k] >= MU.cols()) {
      result->residuals[k] = NAN;  // a Ritz pair beyond those whose products were made
      continue;
    }
    const double l = result->eigenvalues[k];
    const auto Mu = MU.col(elastic[k]);
    const Matrix& stiffness = KU.size() != 0 ? KU : KU_given;
    const auto Ku = stiffness.col(KU.size() != 0 ? k : elastic[k]);
    result->residuals[k] = (Ku - l * Mu).norm() / (std::abs(l) * Mu.norm());
  }
  result->rigid_eigenvalues.resize(rigid.size());
  result->rigid_modes.resize(U.rows(), rigid.size());
  for (size_t k = 0; k < rigid.size(); ++k) {
    result->rigid_eigenvalues[k] = lambda[rigid[k]];
    result->rigid_modes.col(k) = U.col(rigid[k]);
  }
  if (ne < options.num_modes) {
    result->status = EigenStatus::NumericalIssue;
    result->message = "found only " + std::to_string(ne) + " elastic modes of " + std::to_string(options.num_modes);
    return false;
  }
  return true;
}

// The stiffness-to-mass scale of (K, M) (stiffness_mass_scale), or 0 with the result's message
// set when a trace shows K or M unusable.
double checked_scale(const SparseMatrix& K, const SparseMatrix& M, ModalResult* result) {
  const double trace_ratio = K.diagonal().sum() / M.diagonal().sum();
  if (!std::isfinite(trace_ratio) || !(trace_ratio > 0)) {
    result->message = K.diagonal().sum() <= 0
                          ? "K has a non-positive trace, so K is indefinite: a negative modulus or stiffness "
                            "(check parameter values and bounds)"
                          : "K or M has a non-positive or non-finite trace: check moduli, densities and "
                            "parameter values for zeros, negatives or NaN";
    return 0;
  }
  return stiffness_mass_scale(K, M, trace_ratio);
}

// Every Ritz pair of (K, M) in span(V), ascending, from Kr = V^T K V and Mr = V^T M V:
// Kr y = theta Mr y, the vectors V y with y^T Mr y = 1. Solved shift-inverted as the dense path
// solves, so that the lowest values keep their relative accuracy however stiff the span's other
// directions are. K and M times the first `products` vectors, for their residuals.
bool ritz_pairs(const Matrix& Kr, const Matrix& Mr, const Matrix& V, double sigma, int products,
                const SparseMatrix& K, const SparseMatrix& M, ModalResult* result, Eigenpairs* pairs) {
  Eigenpairs reduced;
  if (!dense_eigenpairs(Kr.sparseView(), Mr.sparseView(), sigma, static_cast<int>(V.cols()), result, &reduced))
    return false;
  pairs->lambda = reduced.lambda;
  pairs->mass_norms = (reduced.vectors.transpose() * Mr * reduced.vectors).diagonal();
  pairs->vectors = V * reduced.vectors;
  if (products == 0) return true;  // no residuals asked for
  const Matrix first = pairs->vectors.leftCols(std::min<Eigen::Index>(products, V.cols()));
  pairs->mass_vectors = detail::symmetric_times(M, first);
  pairs->stiffness_vectors = detail::symmetric_times(K, first);
  return true;
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
  if (num_modes < 1) return bad("num_modes = " + detail::option_text(num_modes) + ": must be >= 1");
  if (max_rigid_modes < 0 || max_rigid_modes > 6)
    return bad("max_rigid_modes = " + detail::option_text(max_rigid_modes) + ": must be in 0..6");
  if (!(tolerance > 0 && tolerance <= 1e-2))
    return bad("tolerance = " + detail::option_text(tolerance) + ": must be in (0, 1e-2]");
  if (max_iterations < 1) return bad("max_iterations = " + detail::option_text(max_iterations) + ": must be >= 1");
  if (subspace_size != 0 && subspace_size <= num_modes + max_rigid_modes)
    return bad("subspace_size = " + detail::option_text(subspace_size) + ": must be 0 or > num_modes + max_rigid_modes");
  if (!(initial_shift <= 0) || !std::isfinite(initial_shift))
    return bad("initial_shift = " + detail::option_text(initial_shift) + ": must be 0 (automatic) or negative");
  if (!(rigid_tolerance > 0 && rigid_tolerance <= 1e-3))
    return bad("rigid_tolerance = " + detail::option_text(rigid_tolerance) + ": must be in (0, 1e-3]");
  if (block_size < 0 || block_size > 64)
    return bad("block_size = " + detail::option_text(block_size) + ": must be in 0..64");
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

int ModalSolver::most_modes() const {
  const int n = impl_->factor.rows();
  return n <= kDenseLimit ? n : n - 1;
}

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
  const double scale = checked_scale(K, M, &result);
  if (!(scale > 0)) return result;
  // Without a previous solve, -1e-6 times the stiffness-to-mass scale lies near or below the
  // lowest elastic eigenvalue of practical meshes while keeping K - sigma M well conditioned for
  // rigid-body modes.
  const double sigma = shift_ < 0 ? shift_ : -1e-6 * scale;
  result.shift = sigma;
  const int wanted = options_.num_modes + options_.max_rigid_modes;
  // The dense path finds every mode; Lanczos at most n - 1 (Spectra's nev <= n - 1).
  if (wanted > most_modes()) {
    result.message = "asked for " + std::to_string(wanted) + " modes (including up to " +
                     std::to_string(options_.max_rigid_modes) + " rigid-body modes) of a model with only " +
                     std::to_string(n) + " DOFs" +
                     (n > kDenseLimit ? " (Lanczos finds at most " + std::to_string(n - 1) + " of them)" : "");
    return result;
  }
  const double rigid_threshold = options_.rigid_tolerance * scale;
  Eigenpairs pairs;
  // The dense path also factorizes K - sigma M with CHOLMOD: adjoint and sensitivity solves
  // (solve_factorized) use that factorization whichever path found the modes.
  const bool found =
      n <= kDenseLimit
          ? dense_eigenpairs(K, M, sigma, wanted, &result, &pairs) && impl_->factor.factorize(K, M, sigma, nullptr)
          : sparse_eigenpairs(impl_->factor, K, M, sigma, wanted, rigid_threshold, options_, &result, &pairs);
  if (found && split_modes(K, M, pairs, rigid_threshold, options_, options_.num_modes, &result) &&
      residuals_plausible(K, options_, &result)) {
    result.status = EigenStatus::Successful;
    shift_ = -0.3 * result.eigenvalues[0];
  }
  result.seconds_total = seconds_since(t0);
  return result;
}

ModalResult ModalSolver::solve_in_span(const SparseMatrix& K, const SparseMatrix& M, const Matrix& V) const {
  if (V.rows() != K.rows()) return solve_in_span(Matrix(), Matrix(), V, K, M);  // its message
  const Matrix KV = detail::symmetric_times(K, V), MV = detail::symmetric_times(M, V);
  return solve_in_span(V.transpose() * KV, V.transpose() * MV, V, K, M);
}

ModalResult ModalSolver::solve_in_span(const Matrix& Kr, const Matrix& Mr, const Matrix& V, const SparseMatrix& K,
                                       const SparseMatrix& M, bool residuals) const {
  const auto t0 = std::chrono::steady_clock::now();
  ModalResult result;
  const int wanted = options_.num_modes + options_.max_rigid_modes;
  if (V.rows() != K.rows() || V.cols() < wanted)
    throw std::invalid_argument("ModalSolver::solve_in_span: the span has " + std::to_string(V.cols()) +
                                " columns of length " + std::to_string(V.rows()) + "; it needs at least " +
                                std::to_string(wanted) + " of length " + std::to_string(K.rows()));
  if (Kr.rows() != V.cols() || Kr.cols() != V.cols() || Mr.rows() != V.cols() || Mr.cols() != V.cols())
    throw std::invalid_argument("ModalSolver::solve_in_span: the reduced matrices are not " +
                                std::to_string(V.cols()) + " x " + std::to_string(V.cols()));
  const double scale = checked_scale(K, M, &result);
  if (!(scale > 0)) return result;
  Eigenpairs pairs;
  const double sigma = shift_ < 0 ? shift_ : -1e-6 * scale;
  const Matrix symmetric_Kr = 0.5 * (Kr + Kr.transpose()), symmetric_Mr = 0.5 * (Mr + Mr.transpose());
  if (ritz_pairs(symmetric_Kr, symmetric_Mr, V, sigma, residuals ? wanted : 0, K, M, &result, &pairs) &&
      split_modes(K, M, pairs, options_.rigid_tolerance * scale, options_, static_cast<int>(V.cols()), &result))
    result.status = EigenStatus::Successful;
  result.seconds_total = seconds_since(t0);
  return result;
}

}  // namespace modalcal
