#pragma once
/// \file reduced.hpp
/// Reduced-space calibration: minimize \f$\hat J(p) = J(\lambda(p), u(p), p)\f$ subject to
/// \f$\underline p \le p \le \overline p\f$ (SAND2015-11101 eq. 6), every evaluation a forward
/// modal solve and every gradient an adjoint (see objective.hpp).
///
/// The optimizers work in dimensionless variables x (ParameterScaling: none, linear p/p_ref, or
/// log10 p) because parameters of very different magnitude (foam moduli ~1e4, joint stiffness
/// ~1e6) otherwise make the problem badly conditioned (the report's Figures 3-4).
///
/// - `Method::Lbfgs`: projected line-search limited-memory BFGS, the report's algorithm: the
///   quasi-Newton step acts on the variables not held at a bound, the step is projected onto the
///   bounds, and a backtracking Armijo search along the projected path accepts it.
/// - `Method::GaussNewton`: the same projected search along a Levenberg-damped Gauss-Newton step
///   \f$(J_r^T J_r + \alpha I + \mu D)\, d = -g\f$ from the residual Jacobian \f$J_r\f$
///   (eigenvector sensitivities for shape terms).
/// - `Method::Newton`: the exact reduced Hessian (eigenvector sensitivities for every paired mode
///   and the adjoint in place of second eigenvector derivatives, see objective.hpp), made
///   positive definite where it is not by reflecting and flooring its eigenvalues
///   (\f$|\mu_k| \ge 10^{-8}\max|\mu|\f$), with the same damping and projected search. As in
///   Fletcher & Xu (1987) it takes Gauss-Newton steps while they reduce J by 20 % or more (pure
///   Newton from far starts finds spurious local minima of this nonconvex problem) and the exact
///   Hessian afterwards, which keeps quadratic convergence when the residual at the solution is
///   not zero (model-form error, noise), where Gauss-Newton is only linear.
///
/// A forward solve that fails at a trial point (e.g. a negative modulus without bounds) counts
/// as an infinite objective: the search backtracks instead of aborting. Every run ends with a
/// status (ReducedStatus), the best iterate and the reason.
///
/// \code
/// modalcal::Objective objective(problem);
/// modalcal::ReducedOptions options;          // L-BFGS, bounds on, scaling from the problem file
/// modalcal::ReducedSummary s = modalcal::minimize_reduced(objective, problem.initial_values(), options);
/// std::cout << s.FullReport();
/// \endcode

#include <functional>
#include <optional>
#include <string>
#include <vector>

#include "modalcal/export.hpp"
#include "modalcal/objective.hpp"

namespace modalcal {

/// How a reduced-space run ended; the words are FullSpaceStatus's where the two share a case, and
/// `to_string` gives both in one vocabulary (Converged, MaxIterations, ForwardSolveFailed, ...).
enum class ReducedStatus {
  Converged,           ///< projected gradient below tolerance
  MaxIterations,
  LineSearchFailed,    ///< no decrease along the search direction (at the best point found)
  ForwardSolveFailed,  ///< the initial point could not be evaluated
};
MODALCAL_EXPORT std::string to_string(ReducedStatus status);

struct MODALCAL_EXPORT IterationRecord {
  int iteration = 0;
  double objective = 0;
  double gradient_norm = 0;     ///< projected gradient norm in the optimizer's variables
  double step_norm = 0;         ///< |x_k - x_{k-1}|
  double parameter_error = NAN; ///< max_j |p_j / p_true_j - 1| when the truth is known
  int forward_solves = 0;       ///< cumulative
  Vector p;
};

struct MODALCAL_EXPORT ReducedOptions {
  enum class Method { Lbfgs, GaussNewton, Newton };
  Method method = Method::Lbfgs;
  /// Range: >= 0 (0 only evaluates the start).
  int max_iterations = 100;
  /// Stop when the projected gradient norm (scaled variables) falls below this. Range: >= 0.
  double gradient_tolerance = 1e-10;
  /// ... or below this times its initial value. Range: [0, 1).
  double relative_gradient_tolerance = 1e-12;
  /// ... or when an iteration lowers J by at most this times max(|J|, 1) (as Ceres'
  /// function_tolerance): the misfit has stopped moving even if its gradient has not reached the
  /// tolerance (rounding in J, or a flat valley). 0 switches it off. Range: [0, 1).
  double function_tolerance = 0;
  /// The misfit below which function_tolerance is absolute: an iteration's decrease is compared
  /// with function_tolerance × max(|J|, function_scale). 1 suits a noise-weighted misfit (a
  /// chi-square); one in other units, e.g. relative errors without a stated noise, needs its own
  /// unit, or a misfit far below 1 stops after any step. Range: > 0.
  double function_scale = 1;
  /// L-BFGS memory. Range: >= 1.
  int memory = 10;
  /// Use the parameters' bounds; without them only log scaling keeps p positive. 
  bool use_bounds = true;
  /// Override of every parameter's scaling (the problem file's when unset).
  std::optional<Scaling> scaling;
  /// Armijo sufficient-decrease constant. Range: (0, 0.5).
  double armijo = 1e-4;
  /// Largest number of backtracking steps per iteration. Range: >= 1.
  int max_line_search_steps = 30;
  /// Longest step per variable, in scaled units (a decade for log scaling), or relative to the
  /// starting value for unscaled variables. Range: > 0.
  double max_step = 1.0;
  /// Gauss-Newton and Newton: the Levenberg parameter of the first step, relative to the model
  /// matrix's diagonal (it falls by 10 after every full step and rises by 10, to at most 1, after
  /// a backtracking one). 1 keeps the first steps from a far start gradient-like; a start that
  /// a linear model already put near the minimum can take its first step nearly undamped.
  /// Range: (0, 1].
  double initial_damping = 1.0;
  /// Called after every iteration (progress display).
  std::function<void(const IterationRecord&)> progress;
  bool IsValid(std::string* error) const;
};

struct MODALCAL_EXPORT ReducedSummary {
  ReducedStatus status = ReducedStatus::ForwardSolveFailed;
  std::string message;
  std::string method;
  Vector initial, final;            ///< physical parameters; final is the best iterate
  double initial_objective = NAN, final_objective = NAN;
  int iterations = 0;
  int forward_solves = 0, linear_solves = 0;
  /// Trial points whose evaluation failed (e.g. K indefinite) and were backtracked from.
  int failed_evaluations = 0;
  double seconds = 0;
  std::vector<IterationRecord> history;
  /// Order of convergence of the projected-gradient norm in the last iterations
  /// (estimate_convergence_order); NaN when too few iterations show a rate.
  double convergence_order = NAN;
  bool converged() const { return status == ReducedStatus::Converged; }
  std::string BriefReport() const;
  std::string FullReport() const;
};

/// Order q of e_{k+1} ~ C e_k^q, \f$ q = \log(e_{k+1}/e_k) / \log(e_k/e_{k-1}) \f$, from the last
/// three errors that each fall at least 2x and lie above both `floor` and twice the smallest
/// error (the rounding floor the run reached, where the rate is no longer visible); NaN if there
/// are none.
MODALCAL_EXPORT double estimate_convergence_order(const std::vector<double>& errors, double floor = 1e-14);

MODALCAL_EXPORT ReducedSummary minimize_reduced(Objective& objective, const Vector& p0, const ReducedOptions& options);

/// The k-th of a sequence of starts spread over the parameters' box [lower, upper], for
/// calibrations from several starts: point k of the Halton sequence, the radical inverse of k in
/// base 2 for the first parameter, 3 for the second, 5, 7, ... (a fraction u in [0, 1) of the
/// range), uniform in log10 of the value for a parameter with Scaling::Log and a positive lower
/// bound, else in the value; a parameter without a finite box keeps its initial value. Point 1
/// lies at u = 1/2, 1/3, 1/5, ...; the first points fill the box evenly in every projection, and
/// the same on every machine (no random draws). Range: k >= 1. With many parameters the bases
/// grow and the first points cover the last parameters' ranges only coarsely (k below the base
/// puts u = k / base).
/// Example: `spread_start(problem.parameters, 1)`.
/// \throws std::invalid_argument for k < 1.
MODALCAL_EXPORT Vector spread_start(const std::vector<Parameter>& parameters, int k);

}  // namespace modalcal
