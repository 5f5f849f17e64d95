#pragma once
/// \file fullspace.hpp
/// Full-space calibration: eigenvectors, eigenvalues and parameters are all unknowns of one
/// equality-constrained problem, solved by Newton's method with the exact sparse constraint
/// Jacobian and Lagrangian Hessian (the all-at-once approach SAND2015-11101 names as future work;
/// Biros & Ghattas, SISC 2005, for PDE-constrained optimization): Ipopt's interior-point method,
/// or an SQP whose KKT systems are solved by per-mode block elimination (`newton_solver`).
///
/// \f[ \min_{\tilde u_i, t_i, q}\; J \quad\text{s.t.}\quad
///     r_i = \frac{D_i}{\bar m}\Big(\frac{K(p)}{\lambda_{m,i}} - t_i M(p)\Big)\tilde u_i = 0,\qquad
///     n_i = \tfrac{n}{2}\Big(\frac{\tilde u_i^T M(p) \tilde u_i}{s_u^2} - 1\Big) = 0,\qquad
///     \underline q \le q \le \overline q, \f]
/// nondimensionalized so that every unknown and every constraint row is O(1): the eigenvalue as
/// \f$t_i = \lambda_i / \lambda_{m,i}\f$, the mode as \f$\tilde u_i = s_u u_i\f$ with
/// \f$s_u^2 = \mathrm{tr}\,M(p_0)\f$, the rows by the mean diagonal mass
/// \f$\bar m = s_u^2 / n\f$ and the diagonal \f$D_i = \bar m\,(\mathrm{diag} K/\lambda_{m,i} + \mathrm{diag} M)^{-1}\f$
/// (at p_0), the parameters in the optimizer's scaling q (log10 p, p / p_ref).
/// In physical units (\f$\lambda \sim 10^8\f$ for kHz modes) Ipopt fails (docs/design.md,
/// "Nondimensionalization").
///
/// The main risk is converging to the wrong eigenpairs: nothing in the constraints says that
/// \f$u_i\f$ is the i-th mode, and from far starts the iteration can slide onto higher modes or
/// let two \f$u_i\f$ collapse onto one eigenpair. The driver therefore
///   1. globalizes with reduced-space L-BFGS (always on the right modes: every evaluation pairs a
///      forward solve) until the projected gradient has fallen by `globalization_reduction`,
///      first on the eigenvalue terms alone (`eigenvalues_first`), then on the whole objective,
///      both with the logarithmic eigenvalue misfit (`globalization_misfit`);
///   2. starts the Newton phase from the forward solution there, signs aligned with the measured shapes,
///      multipliers from the adjoint (\f$y_i = w_i\f$, \f$z_i = 2\eta_i\f$, scaled), warm started
///      with a small barrier parameter;
///   3. guards every iteration: a forward solve at the current p, paired as the reduced
///      objective pairs, must have M-weighted MAC >= `guard_mac` with each \f$u_i\f$ (skipped
///      where the iterate has hardly moved from the last guarded point, `guard_step`); if not,
///      Newton is stopped, the Newton direction in q is kept but the modes are not: a backtracking
///      search on the reduced objective along the segment from the last guarded point to the
///      current p picks the restart point (reduced L-BFGS if no point on it decreases J), and
///      Newton restarts from the forward solution there. J decreases from restart to restart
///      (the block solver also hands its point back to the globalization when its line search
///      keeps cutting the Newton steps);
///   4. verifies the end point against a forward solve (same modes, MAC >= `verify_mac`,
///      eigenvalues within `verify_eigenvalue_tolerance`) and reports a run that fails this as not
///      converged, whatever the Newton solver said.
///   5. where the converged point pairs two measured modes with model modes in crossed order,
///      globalizes again from there on the eigenvalues in frequency order and keeps the lower of the
///      two minima (`max_crossing_escapes`).
///
/// \code
/// modalcal::Problem problem = modalcal::load_problem("problems/lfu/synthetic.yaml");
/// modalcal::Objective objective(problem);
/// modalcal::FullSpaceSummary s = modalcal::minimize_fullspace(objective, problem.initial_values(), {});
/// std::cout << s.FullReport();
/// \endcode

#include <functional>
#include <optional>
#include <string>
#include <vector>

#include "modalcal/export.hpp"
#include "modalcal/objective.hpp"
#include "modalcal/reduced.hpp"

namespace modalcal {

struct MODALCAL_EXPORT FullSpaceOptions {
  /// Newton-phase (Ipopt or block SQP) iterations, over all restarts. Range: >= 0; 0 evaluates the
  /// start only, without globalization or Newton step, and ends with MaxIterations.
  int max_iterations = 200;
  /// KKT error (primal and dual infeasibility, complementarity) at which the Newton phase stops:
  /// Ipopt's `tol` and its unscaled constr_viol/dual_inf/compl_inf tolerances; for the block
  /// solver max(|c|_inf, |projected grad L|_inf). The phase also stops, converged, at the
  /// rounding floor of its constraints: gradient and complementarity below the tolerance, the
  /// constraint violation under 100 x tolerance, and a full Newton step that cut it less than
  /// 4-fold or a violation within 4 x that of the Newton start, a forward solve's, where that was
  /// above the tolerance (large models, whose per-mode solves cannot meet 1e-10; newton_status
  /// Stopped_At_Rounding_Floor). Range: (0, 1).
  double tolerance = 1e-10;
  /// Barrier parameter Ipopt starts from (warm start; Ipopt only). Range: > 0. The default is
  /// `tolerance` / 10, where Ipopt's monotone update of the barrier parameter ends: the Newton
  /// phase starts near the solution, and from a larger value Ipopt takes one more iteration to
  /// lower it, as the complementarity it tests is about the barrier parameter.
  double mu_init = 1e-11;
  /// Who solves the Newton phase's KKT systems.
  ///  - `Ipopt`: Ipopt's interior-point Newton method, MUMPS on the whole KKT matrix of order
  ///    2 l (n + 1) + m (the design's reference path; its cost grows with the fill of the coupled
  ///    saddle blocks: docs/benchmarks.md).
  ///  - `BlockElimination`: an SQP iteration on the same problem and derivatives whose KKT
  ///    systems are solved per mode: one sparse LDL^T of the bordered
  ///    \f$[[K - \lambda_i M, -M u_i], [-(M u_i)^T, 0]]\f$ (order n + 1) per mode (or one shared
  ///    factorization for all modes, see `bordered_solves`) and an m x m
  ///    Schur complement on the parameters (the reduced Hessian, whose eigenvalues are the inertia
  ///    test). Bounds on p by an active-set QP in a trust box, steps by Ipopt's filter line search
  ///    (src/fullspace/block_newton.hpp).
  enum class NewtonSolver { Ipopt, BlockElimination };
  NewtonSolver newton_solver = NewtonSolver::Ipopt;
  /// Who factors Ipopt's KKT matrices (no effect with BlockElimination, which is structured).
  ///  - `Structured`: the per-mode block elimination of BlockElimination, inside Ipopt's own
  ///    interior-point iteration: Ipopt's linear solver interface reaches it through the project's
  ///    libpardiso.so (src/fullspace/structured_kkt.hpp). The inertia Ipopt tests comes from the
  ///    m x m reduced Hessian. Matrices of another layout (the restoration phase) and
  ///    Jacobian-regularized ones go to MUMPS on the whole matrix.
  ///  - `Mumps`: MUMPS on the whole KKT matrix, Ipopt's usual path (the reference; slow beyond a
  ///    few thousand DOFs).
  enum class KktSolver { Structured, Mumps };
  KktSolver kkt_solver = KktSolver::Structured;
  /// How the structured solves (KktSolver::Structured and BlockElimination) solve each mode's
  /// bordered block \f$B_i = [[K - \lambda_i M, -M u_i], [-(M u_i)^T, 0]]\f$ per Newton iteration.
  ///  - `PerMode`: a sparse LDL^T (MUMPS) of every B_i: l factorizations, l factors in memory.
  ///  - `Shared`: one Cholesky factorization of K - sigma M (sigma below the spectrum) for all
  ///    modes, and per mode conjugate gradients deflated by the last forward solve's modes
  ///    (src/fullspace/shared_shift_solve.hpp); a mode where they fail is factored after all.
  ///    Cheaper in time and far in memory on large models (docs/benchmarks.md, "One shared
  ///    factorization for every mode's bordered block"); slightly dearer on small ones.
  ///  - `Automatic`: Shared from `shared_factorization_min_dofs` free DOFs on, else PerMode.
  enum class BorderedSolves { Automatic, PerMode, Shared };
  BorderedSolves bordered_solves = BorderedSolves::Automatic;
  /// Where Automatic switches to Shared. Range: >= 0.
  int shared_factorization_min_dofs = 60000;
  enum class Hessian { Exact, LimitedMemory };
  /// Exact Lagrangian Hessian (Newton, quadratic locally) or Ipopt's L-BFGS approximation
  /// (Ipopt only: BlockElimination always uses the exact Hessian).
  Hessian hessian = Hessian::Exact;
  /// Reduced L-BFGS iterations before the full-space Newton phase at most; 0 disables it.
  /// Range: >= 0.
  int globalization_iterations = 50;
  /// The globalization stops once the projected gradient has fallen by this factor (or it has
  /// converged). Range: (0, 1].
  double globalization_reduction = 1e-2;
  /// Eigenvalue misfit the globalization minimizes (see ObjectiveOptions::EigenvalueMisfit); the
  /// Newton phase always minimizes the objective's own (relative) misfit, and the globalization's
  /// history records the values of the misfit it minimized. `Logarithmic` removes the stationary
  /// points of far too soft starts, where the relative misfit saturates (docs/design.md,
  /// "Globalization").
  ObjectiveOptions::EigenvalueMisfit globalization_misfit = ObjectiveOptions::EigenvalueMisfit::Logarithmic;
  /// Begin the globalization on the eigenvalue terms alone: every shape weight kappa_i set to 0
  /// while the measured shapes still pair the modes by MAC, then go on with the whole objective.
  /// Mode-shape terms add local minima that the eigenvalues alone do not have (docs/design.md,
  /// "Globalization"). No effect without weighted shape terms or without weighted eigenvalue terms.
  bool eigenvalues_first = true;
  /// Forward solve and MAC check of every u_i at every Newton iteration.
  bool mode_guard = true;
  /// M-weighted MAC below which the guard declares u_i to have left its mode. Range: (0, 1).
  double guard_mac = 0.8;
  /// The guard's forward solve is skipped at an iterate whose scaled parameters q are within
  /// `guard_step` (max norm) of the last guarded point's and whose constraints are met to
  /// `guard_step` (scaled rows): there every u_i is nearly an eigenvector of K(p), M(p) at
  /// parameters the last forward solve saw, so no mode can have traded places. This skips the
  /// guard at the Newton start (the start is a forward solution) and in the last, quadratically
  /// convergent iterations; the final check (`verify_mac`) still solves. 0 guards every
  /// iteration. Range: [0, 0.1].
  double guard_step = 1e-3;
  /// Restarts after the guard fires. Range: >= 0.
  int max_restarts = 10;
  /// Escapes from a minimum where paired modes cross: when the Newton phase converged where two
  /// measured modes pair by MAC with model modes in the opposite order of their frequencies (a
  /// model mode would have to pass another to fit both), the driver globalizes again from there,
  /// first on the eigenvalue terms compared in frequency order
  /// (ObjectiveOptions::eigenvalues_in_frequency_order), then on the whole objective, runs the
  /// Newton phase again and keeps the end point with the lower J; at most this many times
  /// (docs/design.md, "Escape from crossed pairs"). No effect without weighted eigenvalue terms or
  /// without globalization. Range: >= 0.
  int max_crossing_escapes = 1;
  /// Final check: M-weighted MAC of u_i with the paired forward mode. Range: (0, 1).
  double verify_mac = 0.99;
  /// Final check: relative eigenvalue difference with the paired forward mode. Range: (0, 1).
  double verify_eigenvalue_tolerance = 1e-6;
  /// Override of every parameter's scaling (the problem file's when unset).
  std::optional<Scaling> scaling;
  /// Ipopt's own second-order derivative test at the starting point (slow beyond a few hundred
  /// unknowns; check-derivatives is the scalable check).
  bool ipopt_derivative_test = false;
  /// Ipopt print level (0 silent, 5 its usual table). Range: [0, 12].
  int print_level = 0;
  /// Called after every Newton iteration (progress display).
  std::function<void(const struct KktRecord&)> progress;
  bool IsValid(std::string* error) const;
};

/// One Newton iteration (Ipopt's, or the block solver's: there complementarity and mu are 0, the
/// bounds being handled by an active set).
struct MODALCAL_EXPORT KktRecord {
  int iteration = 0;             ///< cumulative over restarts
  double objective = 0;
  double primal_infeasibility = 0;  ///< max |constraint| (scaled rows)
  double dual_infeasibility = 0;    ///< max |gradient of the Lagrangian|
  double complementarity = 0;       ///< max |z (x - bound)|, bounds on p only
  double mu = 0;                    ///< barrier parameter
  /// Step length of the step that led here (0 at the start of an attempt): 1 is a full Newton
  /// step; less means the line search (or Ipopt's fraction to the boundary) cut it.
  double step_length = 0;
  /// Shift added to the Hessian for that step because it lacked the right inertia, in the scaled
  /// unknowns: Ipopt's regularization of W, the block solver's of the reduced Hessian. 0: a pure
  /// Newton step.
  double hessian_shift = 0;
  /// KKT error max(primal, dual, complementarity).
  double kkt_error() const;
  double parameter_error = NAN;     ///< max_j |p_j / p_true_j - 1| when the truth is known
  double min_mac = NAN;             ///< the guard's smallest MAC (NaN when not guarded)
  Vector p;
};

/// The end-of-run check of the eigenpairs against a forward solve at the final parameters.
struct MODALCAL_EXPORT ModeCheck {
  bool passed = false;
  std::string reason;            ///< why not, naming the measured mode
  std::vector<double> mac;       ///< per full-space mode, M-weighted, with its paired forward mode
  std::vector<double> eigenvalue_error;  ///< relative, same pairing
};

enum class FullSpaceStatus {
  Converged,           ///< the Newton phase converged and the mode check passed
  WrongModes,          ///< the Newton phase converged, but not on the paired modes
  MaxIterations,
  Failed,              ///< the Newton solver failed (Ipopt: restoration, ...; block: singular mode block, ...)
  ForwardSolveFailed,  ///< the start could not be evaluated
};
MODALCAL_EXPORT std::string to_string(FullSpaceStatus status);
/// "ipopt" or "block", as the CLI's --newton-solver spells them.
MODALCAL_EXPORT std::string to_string(FullSpaceOptions::NewtonSolver solver);
/// "structured" or "mumps", as the CLI's --kkt-solver spells them.
MODALCAL_EXPORT std::string to_string(FullSpaceOptions::KktSolver solver);

/// One escape from a minimum where paired modes cross (FullSpaceOptions::max_crossing_escapes).
struct MODALCAL_EXPORT CrossingEscape {
  std::string crossing;               ///< the measured modes and the model modes they pair with
  double objective_at_minimum = NAN;  ///< J where the pairs crossed
  double objective_after = NAN;       ///< J where the escape's Newton phase ended
  bool converged = false;             ///< the escape's Newton phase converged and passed the mode check
  bool kept = false;                  ///< its end point (the lower J) replaced the minimum's
  std::string ToString() const;
};

struct MODALCAL_EXPORT FullSpaceSummary {
  FullSpaceStatus status = FullSpaceStatus::ForwardSolveFailed;
  std::string message;
  std::string newton_solver;     ///< to_string(FullSpaceOptions::newton_solver)
  /// Who solved the KKT systems: "structured" (block elimination: the block solver, or Ipopt
  /// with KktSolver::Structured) or "mumps" (Ipopt with KktSolver::Mumps).
  std::string kkt_solver;
  /// Factorizations by block elimination, and by MUMPS on the whole matrix (with "structured":
  /// the fallbacks, e.g. in Ipopt's restoration phase; with "mumps" not counted).
  int structured_factorizations = 0, mumps_factorizations = 0;
  /// "per-mode" or "shared" (FullSpaceOptions::bordered_solves as it applied to this model;
  /// empty for KktSolver::Mumps); with "shared", the mode eliminations done through the shared
  /// factorization and the modes it failed (factored instead).
  std::string bordered_solves;
  int shared_eliminations = 0, shared_failures = 0;
  /// Status of the Newton phase's last attempt: Ipopt's return status (e.g. Solve_Succeeded), or
  /// the block solver's (Converged, Maximum_Iterations_Exceeded, Outside_Newton_Region,
  /// Singular_Mode_Block, User_Requested_Stop), or Stopped_At_Rounding_Floor (see tolerance).
  std::string newton_status;
  Vector initial, final;         ///< physical parameters
  double initial_objective = NAN, final_objective = NAN;
  int iterations = 0;            ///< Newton iterations over all attempts
  int globalization_iterations = 0;
  int restarts = 0;
  std::vector<CrossingEscape> crossing_escapes;  ///< FullSpaceOptions::max_crossing_escapes
  int forward_solves = 0;        ///< reduced phase, starts, guard and final check
  int kkt_solves = 0;            ///< Hessian evaluations = Newton (KKT) systems
  int num_unknowns = 0, num_constraints = 0;
  double seconds = 0, newton_seconds = 0, guard_seconds = 0;
  std::vector<IterationRecord> globalization_history;
  std::vector<KktRecord> kkt_history;
  /// Estimated order q of e_{k+1} ~ e_k^q from the primal-dual infeasibility of the last
  /// iterations above the noise floor; NaN when too few.
  double convergence_order = NAN;
  ModeCheck mode_check;
  /// Final multipliers, physical: w_i of (K - lambda_i M)u_i = 0 (columns) and eta_i of
  /// u_i^T M u_i = 1, comparable with Evaluation::adjoint.
  Matrix multipliers;
  Vector normalization_multipliers;
  /// Final eigenpairs (physical), one per full-space mode.
  Vector eigenvalues;
  Matrix modes;
  std::vector<int> measured_of_mode;  ///< measured mode of each full-space mode
  bool converged() const { return status == FullSpaceStatus::Converged; }
  std::string BriefReport() const;
  std::string FullReport() const;
};

MODALCAL_EXPORT FullSpaceSummary minimize_fullspace(Objective& objective, const Vector& p0,
                                                    const FullSpaceOptions& options);

/// Directional finite-difference check of the full-space derivatives at the forward solution
/// of p (multipliers random): per block of unknowns (modes, eigenvalues, parameters), the
/// relative error of J d, H d and the objective gradient against central differences of the
/// constraints, of the Lagrangian gradient and of the objective.
struct MODALCAL_EXPORT FullSpaceDerivativeCheck {
  double gradient_error = 0, jacobian_error = 0, hessian_error = 0;
  std::vector<std::string> lines;  ///< one per block and quantity, for printing
};
MODALCAL_EXPORT FullSpaceDerivativeCheck check_fullspace_derivatives(Objective& objective, const Vector& p,
                                                                     double relative_step = 1e-6, unsigned seed = 1);

}  // namespace modalcal
