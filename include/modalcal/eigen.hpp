#pragma once
/// \file eigen.hpp
/// The forward modal solve: the lowest modes of \f$K u = \lambda M u\f$ by shift-invert
/// block Lanczos on a CHOLMOD supernodal factorization of \f$K - \sigma M\f$, with
/// single-vector Lanczos (Spectra) as fallback and a dense solve up to 300 DOFs.
///
/// The symbolic analysis (fill-reducing ordering, supernode structure) depends only on the
/// sparsity pattern, which is fixed for a given model, so it is done once in the constructor
/// and reused for every parameter value: inside a calibration loop each solve costs one
/// numeric factorization plus the Lanczos iterations.
///
/// The block iteration (Grimes, Lewis & Simon 1994) applies \f$S = (K - \sigma M)^{-1} M\f$
/// to a few vectors at once: CHOLMOD then solves with level-3 BLAS, 2 (4 columns) to 4
/// (16 columns) times cheaper per right-hand side than one at a time, and little else is spent
/// besides the solves (one product with M per block, full M-reorthogonalization, a
/// Rayleigh-Ritz step on a small matrix, one check of the true residuals).
///
/// The shift is negative (\f$\sigma = -0.3\lambda_1\f$ once \f$\lambda_1\f$ is known), so
/// \f$K - \sigma M\f$ stays positive definite for free-free models with rigid-body modes; a
/// failed Cholesky factorization then means K itself is indefinite (a negative modulus or
/// stiffness), which is reported as such.
///
/// \code
/// modalcal::ModalSolver solver(system.pattern(), options);
/// modalcal::ModalResult r = solver.solve(K, M);
/// if (r.status != modalcal::EigenStatus::Successful) std::cerr << r.message;
/// \endcode

#include <memory>
#include <string>

#include "modalcal/export.hpp"
#include "modalcal/types.hpp"

namespace modalcal {

/// Outcome of a numerical computation (as in Spectra's CompInfo).
enum class EigenStatus { Successful, NotConverging, NumericalIssue };
MODALCAL_EXPORT std::string to_string(EigenStatus status);

struct MODALCAL_EXPORT ModalOptions {
  /// Number of elastic (non-rigid) modes wanted. Range: >= 1.
  int num_modes = 10;
  /// Largest number of rigid-body (zero-frequency) modes the model may have: 6 for a
  /// free-free model, 0 for a supported one. More zero modes than this is reported as a
  /// singular K (missing supports or an unconnected part). Range: 0..6.
  int max_rigid_modes = 6;
  /// Convergence tolerance. With nev = num_modes + max_rigid_modes, block Lanczos stops when
  /// each of the nev lowest Ritz pairs \f$(\lambda, u)\f$, \f$\theta = 1/(\lambda - \sigma)\f$,
  /// \f$S = (K - \sigma M)^{-1} M\f$, passes both
  /// - \f$\|S u - \theta u\|_M \le \text{tolerance}\,\theta\f$ (the residual of the
  ///   shift-inverted problem, Spectra's test), and
  /// - \f$\|K u - \lambda M u\|_2 \le \text{tolerance}\,|\lambda|\,\|M u\|_2 +
  ///   \epsilon \|K\|_1 \|u\|_2\f$, the last term (\f$\epsilon = 2.2\cdot 10^{-16}\f$) being the
  ///   rounding error of computing K u; for a rigid-body mode
  ///   (\f$|\lambda| \le\f$ rigid_tolerance s, s below),
  ///   \f$\|K u - \lambda M u\|_2 \le \text{tolerance}\,\|K\|_1 \|u\|_2\f$.
  ///
  /// The Spectra fallback applies the first test only. ModalResult::residuals reports the
  /// relative residuals reached. Range: (0, 1e-2].
  double tolerance = 1e-10;
  /// Maximum number of restarts (thick restarts of block Lanczos, implicit ones of Spectra).
  /// Range: >= 1.
  int max_iterations = 1000;
  /// Krylov subspace size: basis columns before a restart. 0 means automatic: for block Lanczos
  /// max(6 nev, nev + 12 block_size), at least nev + 2 block_size (it takes 2 n subspace_size
  /// doubles for the basis and its product with M); for Spectra 2 nev + 1. Why these values:
  /// docs/design.md, "Forward modal solve". Range: 0 or > nev.
  int subspace_size = 0;
  /// Columns per block of the shift-invert block Lanczos iteration; 1 selects single-vector
  /// Lanczos (Spectra); 0 means automatic, currently 4. CHOLMOD solves 4 right-hand sides for
  /// about 2 times the cost of one (8 for 3 times, 16 for 4 times), while the block Krylov space
  /// needs more columns to converge; the measurements behind the default are in docs/design.md,
  /// "Forward modal solve". Range: 0..64.
  int block_size = 0;
  /// Initial shift sigma (must be < 0), or 0 to choose one from the stiffness-to-mass scale s
  /// (below). After each successful solve the solver moves the shift to -0.3 times the lowest
  /// elastic eigenvalue.
  double initial_shift = 0.0;
  /// A mode is rigid if \f$\lambda < \text{rigid\_tolerance}\cdot s\f$, with the scale
  /// \f$s = \min(\mathrm{tr}(K)/\mathrm{tr}(M),\ \mathrm{median}_i K_{ii}/M_{ii})\f$ over the DOFs
  /// with mass: the median keeps a few penalty-stiff joints from raising the threshold above the
  /// lowest elastic modes. Range: (0, 1e-3].
  double rigid_tolerance = 1e-9;
  /// Returns false and explains which field violates which condition.
  bool IsValid(std::string* error) const;
};

struct MODALCAL_EXPORT ModalResult {
  EigenStatus status = EigenStatus::NumericalIssue;
  std::string message;               ///< why it failed, with the likely cause
  Vector eigenvalues;                ///< elastic modes, ascending
  Matrix modes;                      ///< columns, \f$u^T M u = 1\f$, largest component positive
  Vector residuals;                  ///< \f$\|K u - \lambda M u\| / (\lambda \|M u\|)\f$ per mode
                                     ///< (the solve fails when one exceeds max(1e-3, 100 tolerance))
  Vector rigid_eigenvalues;          ///< rigid-body modes found (near zero)
  Matrix rigid_modes;
  double shift = 0;                  ///< the shift used
  int factorizations = 0;
  int operator_solves = 0;           ///< right-hand sides solved with (K - sigma M)^{-1}
  /// Columns per block of the Lanczos iteration that produced the modes: 0 for the dense path
  /// (<= 300 DOFs), 1 for single-vector Lanczos (Spectra, also the fallback of the block path).
  int block_size = 0;
  double seconds_factorize = 0, seconds_total = 0;
};

/// Frequency in Hz of an eigenvalue \f$\lambda = \omega^2\f$ (negative eigenvalues give
/// negative frequencies, so that they stay visible in reports).
MODALCAL_EXPORT double frequency_hz(double eigenvalue);
/// Eigenvalue of a frequency in Hz.
MODALCAL_EXPORT double eigenvalue_of_hz(double hz);

class MODALCAL_EXPORT ModalSolver {
 public:
  /// Symbolic analysis of `pattern` (the pattern of K and M; both triangles stored).
  /// \throws std::invalid_argument if the options are invalid or the pattern is not square.
  ModalSolver(const SparseMatrix& pattern, const ModalOptions& options);
  ~ModalSolver();
  ModalSolver(const ModalSolver&) = delete;
  ModalSolver& operator=(const ModalSolver&) = delete;

  /// Lowest modes of (K, M); K and M must have the constructor's pattern.
  ModalResult solve(const SparseMatrix& K, const SparseMatrix& M);
  /// Rayleigh-Ritz in the span of V's columns: the pairs of \f$V^T K V\, y = \theta\, V^T M V\, y\f$
  /// as modes \f$u = V y\f$, every one of them (rigid and elastic split, normalized and signed as
  /// solve() does). `residuals` say how far the first options().num_modes elastic ones are from
  /// eigenpairs of (K, M); the others' are NaN. The Ritz values bound the eigenvalues from above,
  /// and are exact when span(V) holds the modes. It costs two sparse products with V's columns
  /// and a dense eigenproblem of V's width, and leaves the factorization alone: for many nearby
  /// (K, M) that one span serves, e.g. the steps of a refit (Objective::set_span). Fails
  /// (status, message) when fewer than options().num_modes elastic Ritz pairs exist or V is
  /// dependent in M.
  /// \throws std::invalid_argument if V's columns are not of K's size or fewer than
  /// num_modes + max_rigid_modes.
  ModalResult solve_in_span(const SparseMatrix& K, const SparseMatrix& M, const Matrix& V) const;
  /// The same with \f$K_r = V^T K V\f$ and \f$M_r = V^T M V\f$ given, as
  /// ParametricSystem::assemble_projected makes them without a product of K with V; K and M then
  /// serve only the first modes' residuals and the stiffness-to-mass scale. With `residuals`
  /// false every residual is NaN and no product with K or M is made: those two products cost
  /// more than the rest of the solve on a mesh of 1e4 DOFs and a span of 90 columns, and a walk
  /// in a span checks its end on the whole model instead.
  /// \throws std::invalid_argument as above, or if Kr and Mr are not square of V's width.
  ModalResult solve_in_span(const Matrix& Kr, const Matrix& Mr, const Matrix& V, const SparseMatrix& K,
                            const SparseMatrix& M, bool residuals = true) const;
  const ModalOptions& options() const { return options_; }
  void set_num_modes(int n);
  /// The most modes (elastic and rigid together) a solve can find: every one of a small model's,
  /// which is solved densely, else one fewer than the DOFs (Lanczos).
  int most_modes() const;
  /// Seconds spent in the one-time symbolic analysis.
  double seconds_analyze() const;
  /// The shift the next solve starts from.
  double shift() const { return shift_; }

  /// Factorizes \f$A = K - \sigma M\f$ (sigma may be any value keeping A positive definite)
  /// and solves A X = B: used by benchmarks to measure the floor and by adjoint solves.
  /// Returns false with `message` set if A is not positive definite.
  bool factorize_shifted(const SparseMatrix& K, const SparseMatrix& M, double sigma,
                         std::string* message);
  Matrix solve_factorized(const Matrix& rhs) const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
  ModalOptions options_;
  double shift_ = 0;
};

}  // namespace modalcal
