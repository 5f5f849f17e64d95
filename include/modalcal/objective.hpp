#pragma once
/// \file objective.hpp
/// The calibration misfit (SAND2015-11101 eq. 4) as a function of the physical parameters p, with
/// its adjoint gradient (eqs. 12-21, extended to mass parameters), and its least-squares
/// residual form for Gauss-Newton.
///
/// \f[ J(p) = \sum_i \frac{\beta_i}{2}\, r_i^2 + \sum_i \frac{\kappa_i}{2}\, \|e_i\|^2 + \frac{\alpha}{2}\|x(p) - x_0\|^2,
///     \qquad r_i = \frac{\lambda_{m(i)} - \lambda_{m,i}}{\lambda_{m,i}},
///     \qquad e_i = (I - \hat\phi_i \hat\phi_i^T)\,\frac{P u_{m(i)}}{\|P u_{m(i)}\|} \f]
///
/// - \f$m(i)\f$ is the model mode paired with measured mode i, re-established at every evaluation
///   (by MAC at the sensors, by model index, or by mode family), so that modes swapping order as p
///   changes do not corrupt the objective. MAC pairing is the one-to-one assignment with the
///   largest total MAC (Hungarian method), not greedy.
/// - Shape misfit: \f$\|e_i\|^2 = 1 - \mathrm{MAC}(P u, \phi_i)\f$, with P the sensor selection and
///   \f$\hat\phi_i = \phi_i/\|\phi_i\|\f$. It is invariant to the sign and scale of the measured shape
///   (test data arrive in arbitrary units and signs) and of the model shape (whose amplitude at the
///   sensors changes with p even though \f$u^T M u = 1\f$, which would otherwise let the optimizer
///   trade shape for amplitude); it lies in [0, 1], is the MAC users already read, and is a
///   least-squares residual vector for Gauss-Newton.
/// - Regularization (Tikhonov) acts in the optimizer's scaled variables x (log10 p for log scaling,
///   p / reference for linear), toward the initial values.
///
/// Gradient, by the adjoint: with \f$g_i = (K - \lambda_i M) u_i\f$ and \f$b_i = u_i^T M u_i - 1\f$,
/// \f[ \nabla_p J = J_p + \sum_i w_i^T (K_{,j} - \lambda_i M_{,j}) u_i + \eta_i\, u_i^T M_{,j} u_i, \quad
///     w_i = w_{0i} + J_{\lambda_i} u_i,\quad \eta_i = -\tfrac12 u_i^T J_{u_i}, \f]
/// where \f$(K - \lambda_i M) w_{0i} = (M u_i u_i^T - I) J_{u_i}\f$, \f$u_i^T M w_{0i} = 0\f$. For the
/// eigenvalue-only objective \f$w_{0i} = 0\f$: no linear solve at all.
///
/// \code
/// modalcal::Objective objective(problem);
/// modalcal::Evaluation e = objective.evaluate(problem.initial_values(), modalcal::Need::Gradient);
/// if (e.ok) std::cout << e.value << " " << e.gradient.transpose();
/// \endcode

#include <memory>
#include <string>
#include <vector>

#include "modalcal/assembly.hpp"
#include "modalcal/eigen.hpp"
#include "modalcal/export.hpp"
#include "modalcal/problem.hpp"

namespace modalcal {

namespace detail {
class FullSpaceDriver;
}

/// Maps physical parameters p to the optimizer's dimensionless variables x and back:
/// none: x = p; linear: x = p / reference; log: x = log10 p.
class MODALCAL_EXPORT ParameterScaling {
 public:
  explicit ParameterScaling(const std::vector<Parameter>& parameters);
  /// Same parameters, every one with `scaling`.
  ParameterScaling(const std::vector<Parameter>& parameters, Scaling scaling);
  Vector to_scaled(const Vector& p) const;
  Vector to_physical(const Vector& x) const;
  /// dp_j / dx_j and d²p_j / dx_j² at x.
  Vector first_derivative(const Vector& x) const;
  Vector second_derivative(const Vector& x) const;
  Scaling scaling(int j) const { return scaling_[j]; }

 private:
  std::vector<Scaling> scaling_;
  Vector reference_;
};

struct MODALCAL_EXPORT ObjectiveOptions {
  /// How gradients are computed: by the adjoint (exact, at most one deflated solve per measured
  /// shape), or by central differences (2 forward solves per parameter, as a black-box tool
  /// would; for comparisons and cross-checks). Jacobians and Hessians are always analytic.
  enum class Gradient { Adjoint, CentralDifferences };
  Gradient gradient = Gradient::Adjoint;
  /// Relative step of the central differences. Range: (0, 0.1).
  double difference_step = 1e-5;
  /// Tikhonov weight alpha (in scaled variables, toward the initial values). Range: >= 0.
  double regularization = 0.0;
  /// Model modes computed beyond the highest one that could be paired; they make MAC pairing
  /// robust and deflate the adjoint solves. Range: >= 1.
  int extra_modes = 4;
  /// Relative residual at which the deflated adjoint/sensitivity solves stop. Range: (0, 1e-4].
  double linear_tolerance = 1e-11;
  /// Iteration limit of those solves. Range: >= 1.
  int max_linear_iterations = 300;
  /// Two model eigenvalues closer than this (relative) are reported as (nearly) repeated.
  /// Range: (0, 1).
  double close_eigenvalue_tolerance = 1e-4;
  /// How the shape rows of the residual Jacobian (Need::Jacobian) are computed. Both give the same
  /// matrix; they differ in the linear solves, one right-hand side per column of the deflated
  /// solve, per measured shape:
  /// - `DirectSensitivities`: the eigenvector sensitivity \f$\partial u/\partial p_j\f$ of every
  ///   parameter (n_p right-hand sides);
  /// - `SensorAdjoint`: \f$Z = S P^T\f$, S the deflated inverse of \f$K - \lambda M\f$ (symmetric),
  ///   one right-hand side per sensor reading, then
  ///   \f$P\,\partial u/\partial p_j = -Z^T(K_{,j} - \lambda M_{,j})u - \tfrac12 (u^T M_{,j} u)\, P u\f$
  ///   for all j in one pass over the assembly terms (n_s right-hand sides);
  /// - `Automatic`: the cheaper of the two (sensor adjoint when there are more parameters than
  ///   sensor readings, e.g. when ranking many candidate effects at once).
  /// The Hessian (Need::Hessian) always needs the full sensitivities.
  enum class Jacobian { Automatic, DirectSensitivities, SensorAdjoint };
  Jacobian jacobian = Jacobian::Automatic;
  /// Form of the eigenvalue residual of each measured mode:
  /// - `Relative`: \f$r_i = (\lambda_i - \lambda_{mi})/\lambda_{mi}\f$, the report's eq. 5 and
  ///   the calibration objective;
  /// - `Logarithmic`: \f$r_i = \ln(\lambda_i/\lambda_{mi})\f$, equal to first order near a fit.
  ///   The relative form saturates at -1 when a model is far too soft (\f$\lambda \ll
  ///   \lambda_m\f$, its slope in log-parameters \f$\lambda/\lambda_m\f$ vanishes), which
  ///   creates stationary points far from any fit; the logarithmic form has a slope of 1 for every
  ///   \f$\lambda\f$. The full-space globalization can use it (FullSpaceOptions::globalization_misfit).
  enum class EigenvalueMisfit { Relative, Logarithmic };
  EigenvalueMisfit eigenvalue_misfit = EigenvalueMisfit::Relative;
  /// Which MAC-paired model mode each measured eigenvalue is compared with:
  /// - `false`: its own pair's (the calibration objective);
  /// - `true`: the shapes choose the set of model modes, and within that set the k-th lowest
  ///   model eigenvalue is compared with the k-th lowest measured frequency. Where two paired
  ///   modes cross as p changes, their MAC pairs swap and the paired eigenvalue terms jump, which
  ///   leaves a barrier that a descent method cannot cross (docs/design.md, "Escape from crossed
  ///   pairs"); compared in order, the eigenvalue terms stay continuous. Only for an
  ///   objective without shape terms (the full-space escape from crossed pairs,
  ///   FullSpaceOptions::max_crossing_escapes): the Objective refuses it otherwise.
  bool eigenvalues_in_frequency_order = false;
  bool IsValid(std::string* error) const;
};

/// One measured mode and the model mode it was paired with at this evaluation.
struct MODALCAL_EXPORT PairedMode {
  int measured = 0;             ///< 0-based index into Problem::measured
  int model = 0;                ///< 0-based elastic model mode index
  double measured_hz = 0, model_hz = 0;
  double relative_error = 0;    ///< (lambda - lambda_m) / lambda_m, whatever the misfit form
  double mac = -1;              ///< MAC at the sensors, -1 without a measured shape
};

/// What an evaluation computes; each includes the ones before it.
enum class Need { Value, Gradient, Jacobian, Hessian };

struct MODALCAL_EXPORT Evaluation {
  bool ok = false;
  std::string message;               ///< why not ok (failed solve, pairing impossible)
  double value = 0;
  double eigenvalue_term = 0, shape_term = 0, regularization_term = 0;
  Vector gradient;                   ///< dJ/dp (physical), with Need::Gradient or Jacobian
  /// Least-squares residuals, J = 1/2 |residuals|^2 + regularization: sqrt(beta_i) r_i, then
  /// sqrt(kappa_i) e_i for each mode with a shape.
  Vector residuals;
  Matrix jacobian;                   ///< d residuals / dp, with Need::Jacobian
  /// d^2 J / dp^2, exact (second-order terms included), with Need::Hessian. See objective.cpp for
  /// the formulas: eigenvector sensitivities for every paired mode, and the adjoint w_0 in place
  /// of second eigenvector derivatives.
  Matrix hessian;
  /// Adjoint variables of the eigenproblem constraints at p (with Need::Gradient or more, adjoint
  /// gradient only): column i is \f$w_i = w_{0i} + J_{\lambda_i} u_i\f$ for measured mode i, the
  /// multiplier of \f$(K - \lambda_i M) u_i = 0\f$, and `adjoint_eta[i]` that of
  /// \f$u_i^T M u_i - 1 = 0\f$. They are the Lagrange multipliers the full-space method starts from.
  Matrix adjoint;
  Vector adjoint_eta;
  std::vector<PairedMode> pairs;
  std::vector<std::string> warnings; ///< e.g. nearly repeated eigenvalues, pairing changed
  ModalResult modal;
  int linear_solves = 0;             ///< right-hand sides solved with the factorization
};

class MODALCAL_EXPORT Objective {
 public:
  /// \throws std::invalid_argument for invalid options, or a problem without measured modes.
  explicit Objective(const Problem& problem, ObjectiveOptions options = {});
  /// The objective keeps a reference to its problem: a temporary would dangle.
  explicit Objective(Problem&& problem, ObjectiveOptions options = {}) = delete;
  ~Objective();
  Objective(const Objective&) = delete;
  Objective& operator=(const Objective&) = delete;

  /// The misfit and what `need` asks for at p. A point where the last forward solve of this
  /// objective (or one sharing its model) was made is not solved again.
  Evaluation evaluate(const Vector& p, Need need = Need::Value);
  /// Evaluations from now on solve the eigenproblem in the span of `basis`'s columns
  /// (Rayleigh-Ritz, ModalSolver::solve_in_span) instead of the whole model, and their
  /// derivatives are the exact ones of that reduced model: its linear solves are modal sums over
  /// every Ritz pair, with no factorization. An empty basis returns to the whole model. With a
  /// span from span_at(p) the reduced model agrees with the whole one near p (eigenvalues to
  /// second order in the eigenvector error), at a fraction of an evaluation's cost: for the many
  /// evaluations of a short walk from p, such as a refit, checked on the whole model at its end.
  /// Such an evaluation's `modal.residuals` are NaN: a check on the whole model says more, and
  /// their products with K and M would cost more than the rest of the span solve.
  /// Objectives sharing a model (the full-space driver's) share the span.
  /// \throws std::invalid_argument if the columns are not of the model's size.
  void set_span(Matrix basis);
  bool in_span() const;
  /// A span for set_span that holds, at p, the modes the objective computes and the directions
  /// their derivatives take: for each paired mode u (eigenvalue lambda) and parameter j,
  /// \f$A^{-1} (K_{,j} - \lambda M_{,j}) u\f$ and \f$A^{-1} M A^{-1} (K_{,j} - \lambda M_{,j}) u\f$
  /// with \f$A = K - \sigma M\f$ factorized by the forward solve; M-orthonormal, dependent
  /// columns dropped. One forward solve of the whole model and two block solves. Leaves the
  /// objective on the whole model (no span).
  /// \throws std::runtime_error if the forward solve at p fails.
  Matrix span_at(const Vector& p);
  /// `span` (span_at(p)'s, or one holding it) extended for a wider model on the same DOFs: this
  /// model with more parameters, such as a candidate effect. For each parameter q of `wider`
  /// beyond this objective's and each paired mode u of this model at p, the directions
  /// \f$A^{-1} (K_{,q} - \lambda M_{,q}) u\f$ and \f$A^{-1} M A^{-1} (K_{,q} - \lambda M_{,q}) u\f$,
  /// with wider's derivatives at wider_p and this model's factorization at p. No forward solve
  /// when p is where this objective last solved (as after span_at(p)): many wider models, the
  /// refits of one diagnosis step, then share one solve. Leaves the objective on the whole model.
  /// \throws std::invalid_argument if wider's DOFs differ, it has no further parameter or wider_p
  /// is not one value for each, or span's columns are not of the model's size;
  /// std::runtime_error if the forward solve at p fails.
  Matrix extend_span(const Matrix& span, const Vector& p, const ParametricSystem& wider, const Vector& wider_p);
  const Problem& problem() const { return problem_; }
  const ObjectiveOptions& options() const { return options_; }
  /// The variables the regularization acts in (the problem file's scaling).
  const ParameterScaling& regularization_scaling() const { return regularization_scaling_; }
  const ParametricSystem& system() const { return *system_; }
  int num_parameters() const { return system_->num_parameters(); }
  /// For the calibrations and checks, which need something to vary: \throws std::invalid_argument
  /// naming `caller` if the problem has no calibration parameters or `p` is not one value for each.
  void require_parameters(const Vector& p, const std::string& caller) const;
  int num_residuals() const { return num_residuals_; }
  /// Forward solves and linear solves (right-hand sides) since construction.
  int forward_solves() const { return forward_solves_; }
  int linear_solves() const { return linear_solves_; }

 private:
  struct Workspace;
  friend class detail::FullSpaceDriver;
  /// Another misfit of the model `same_model` evaluates: `problem` is a copy of same_model's
  /// with other measured weights, `options` may differ (the full-space driver's globalization
  /// misfits). The two share the assembled system and the modal solver, so a forward solve at
  /// the point where either last solved is not repeated.
  /// \throws std::logic_error if the problems differ in model size, parameters or sensors.
  Objective(const Problem& problem, ObjectiveOptions options, const Objective& same_model);
  void check_problem() const;
  int count_modes_and_residuals();
  class Evaluator;  // one evaluation's steps (objective.cpp)
  /// The evaluation at p on the whole model; \throws std::runtime_error naming `caller` if it fails.
  Evaluation whole_model_evaluation(const Vector& p, const char* caller);
  /// The span's directions (span_at) of e's paired modes for the parameters `first`.. of `system`
  /// at `at`, with the factorization of the last forward solve.
  Matrix mode_directions(const Evaluation& e, const ParametricSystem& system, const Vector& at, int first) const;
  void add_mode_hessian(const Vector& p, int i, double lambda, const Vector& u, const Matrix& X, const Matrix& dU,
                        const Vector& dlambda, const Vector& m, const Vector& Ju, const Vector& w0, Matrix* H) const;
  const Problem& problem_;
  ObjectiveOptions options_;
  ParameterScaling regularization_scaling_;
  // Shared with the objectives made with the same_model constructor.
  std::shared_ptr<ParametricSystem> system_;
  std::shared_ptr<ModalSolver> solver_;
  std::shared_ptr<Workspace> workspace_;
  int num_residuals_ = 0;
  int forward_solves_ = 0, linear_solves_ = 0;
};

/// Modal assurance criterion \f$ (a^T b)^2 / ((a^T a)(b^T b)) \f$ (0 if either is zero), in
/// [0, 1] and independent of the vectors' scales, from 1e-300 to 1e+300 alike.
MODALCAL_EXPORT double mac(const Vector& a, const Vector& b);

}  // namespace modalcal
