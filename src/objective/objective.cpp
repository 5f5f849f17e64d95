#include "modalcal/objective.hpp"
#include "support/text_util.hpp"

#include <Eigen/Eigenvalues>
#include <algorithm>
#include <cmath>
#include <optional>
#include <sstream>

#include "eigen/block_lanczos.hpp"  // symmetric_times
#include "modalcal/mode_description.hpp"
#include "objective/assignment.hpp"
#include "objective/deflated_solve.hpp"
#include "objective/mode_pairing.hpp"
#include "objective/shape_misfit.hpp"

namespace modalcal {

double mac(const Vector& a, const Vector& b) {
  // MAC does not depend on scale, but the squares of entries near 1e-160 underflow and those near
  // 1e+160 overflow: each vector is taken at a largest entry of 1 first.
  const double scale_a = a.size() ? a.cwiseAbs().maxCoeff() : 0, scale_b = b.size() ? b.cwiseAbs().maxCoeff() : 0;
  if (scale_a == 0 || scale_b == 0) return 0;
  const Vector unit_a = a / scale_a, unit_b = b / scale_b;
  const double ab = unit_a.dot(unit_b);
  return ab * ab / (unit_a.squaredNorm() * unit_b.squaredNorm());
}

bool ObjectiveOptions::IsValid(std::string* error) const {
  auto bad = [&](const std::string& message) {
    if (error) *error = message;
    return false;
  };
  if (!(regularization >= 0) || !std::isfinite(regularization))
    return bad("regularization = " + detail::option_text(regularization) + ": must be finite and >= 0");
  if (extra_modes < 1) return bad("extra_modes = " + detail::option_text(extra_modes) + ": must be >= 1");
  if (!(linear_tolerance > 0 && linear_tolerance <= 1e-4))
    return bad("linear_tolerance = " + detail::option_text(linear_tolerance) + ": must be in (0, 1e-4]");
  if (max_linear_iterations < 1)
    return bad("max_linear_iterations = " + detail::option_text(max_linear_iterations) + ": must be >= 1");
  if (!(difference_step > 0 && difference_step < 0.1))
    return bad("difference_step = " + detail::option_text(difference_step) + ": must be in (0, 0.1)");
  if (!(close_eigenvalue_tolerance > 0 && close_eigenvalue_tolerance < 1))
    return bad("close_eigenvalue_tolerance = " + detail::option_text(close_eigenvalue_tolerance) + ": must be in (0, 1)");
  return true;
}

struct Objective::Workspace {
  SparseMatrix K, M;     // at the last forward solve
  SparseMatrix sensors;  // P: free DOFs -> sensor readings
  int modes_needed = 0;
  // The last successful forward solve: where, and its result. K, M and the solver's factorization
  // are that point's as long as it is the last solve.
  bool has_solved = false;
  Vector solved_at;
  ModalResult solved;
  // Objective::set_span: the span the evaluations solve in (empty: the whole model), and every
  // Ritz pair of the last solve there, the deflation basis that makes its linear solves exact.
  Matrix span;
  std::vector<Matrix> span_terms;  // the system's terms projected on it
  ModalResult span_pairs;
};

namespace {

// The rigid-body modes and the first `elastic` elastic ones of `all`.
ModalResult first_modes(const ModalResult& all, int elastic) {
  ModalResult first = all;
  const int n = std::min(elastic, static_cast<int>(all.eigenvalues.size()));
  first.eigenvalues = all.eigenvalues.head(n);
  first.modes = all.modes.leftCols(n);
  first.residuals = all.residuals.head(n);
  return first;
}

// [U, C] with C made M-orthogonal to U (M-orthonormal columns) and M-orthonormal itself, its
// columns dependent on the rest (below 1e-10 of its largest direction, each first scaled to unit
// M-norm) dropped: U's span is kept exactly.
Matrix extend_m_orthonormal(const SparseMatrix& M, const Matrix& U, Matrix C) {
  const Matrix MU = detail::symmetric_times(M, U);
  for (int pass = 0; pass < 2; ++pass) C -= U * (MU.transpose() * C);  // twice: once loses digits
  const Matrix MC = detail::symmetric_times(M, C);
  for (Eigen::Index c = 0; c < C.cols(); ++c) {
    const double norm = std::sqrt(std::max(C.col(c).dot(MC.col(c)), 0.0));
    if (norm > 0) C.col(c) /= norm;
  }
  Matrix G = C.transpose() * detail::symmetric_times(M, C);
  G = 0.5 * (G + G.transpose()).eval();
  Eigen::SelfAdjointEigenSolver<Matrix> es(G);
  const Vector& d = es.eigenvalues();
  Eigen::Index first = 0;
  while (first < d.size() && !(d[first] > 1e-10 * d[d.size() - 1])) ++first;
  const Eigen::Index kept = d.size() - first;
  Matrix V(U.rows(), U.cols() + kept);
  V << U, C * (es.eigenvectors().rightCols(kept) * d.tail(kept).cwiseSqrt().cwiseInverse().asDiagonal());
  return V;
}

// The eigenvalue residual r(lambda) of one measured mode with its first two derivatives.
struct EigenvalueResidual {
  double r, dr, d2r;
};

EigenvalueResidual eigenvalue_residual(double lambda, double target, ObjectiveOptions::EigenvalueMisfit form) {
  if (form == ObjectiveOptions::EigenvalueMisfit::Logarithmic)
    return {std::log(lambda / target), 1 / lambda, -1 / (lambda * lambda)};
  return {(lambda - target) / target, 1 / target, 0};
}

// e = (I - phi phi^T) y / |y| for unit phi, and de/dy = (I - phi phi^T)(I - yhat yhat^T)/|y|.
Vector shape_residual(const Vector& y, const Vector& phi_unit) {
  const Vector yhat = y / y.norm();
  return yhat - phi_unit * phi_unit.dot(yhat);
}
Vector shape_residual_derivative(const Vector& y, const Vector& phi_unit, const Vector& dy) {
  const double norm = y.norm();
  const Vector yhat = y / norm;
  const Vector t = (dy - yhat * yhat.dot(dy)) / norm;
  return t - phi_unit * phi_unit.dot(t);
}


}  // namespace

Objective::Objective(const Problem& problem, ObjectiveOptions options)
    : problem_(problem), options_(options), regularization_scaling_(problem.parameters) {
  check_problem();
  system_ = std::make_shared<ParametricSystem>(problem.model, problem.parameter_targets());
  workspace_ = std::make_shared<Workspace>();
  workspace_->sensors = detail::sensor_matrix(problem, system_->dof_map());
  workspace_->modes_needed = count_modes_and_residuals();
  ModalOptions modal;
  modal.num_modes = workspace_->modes_needed;
  modal.max_rigid_modes = problem.expected_rigid_modes();
  modal.tolerance = problem.options.tolerance;
  solver_ = std::make_shared<ModalSolver>(system_->pattern(), modal);
}

Objective::Objective(const Problem& problem, ObjectiveOptions options, const Objective& same_model)
    : problem_(problem),
      options_(options),
      regularization_scaling_(problem.parameters),
      system_(same_model.system_),
      solver_(same_model.solver_),
      workspace_(same_model.workspace_) {
  check_problem();
  const Problem& other = same_model.problem_;
  if (problem.model.num_nodes() != other.model.num_nodes() || problem.parameter_targets() != other.parameter_targets() ||
      problem.sensors.size() != other.sensors.size() || count_modes_and_residuals() != workspace_->modes_needed)
    throw std::logic_error("Objective: sharing the forward model of a different problem");
}

// The problem and options make an objective: measured modes, and frequency order without shapes.
void Objective::check_problem() const {
  std::string error;
  if (!options_.IsValid(&error)) throw std::invalid_argument("ObjectiveOptions: " + error);
  if (problem_.measured.empty())
    throw std::invalid_argument(problem_.path + ": no measured modes to calibrate against" +
                                (problem_.synthetic ? std::string(" (its synthetic modes are computed by "
                                                                  "synthesize_measured(), modalcal/synthesis.hpp)")
                                                    : std::string()));
  if (options_.eigenvalues_in_frequency_order)
    for (size_t i = 0; i < problem_.measured.size(); ++i)
      if (problem_.measured[i].has_shape_term())
        throw std::invalid_argument("ObjectiveOptions::eigenvalues_in_frequency_order needs an objective without shape "
                                    "terms, but " + detail::describe_measured(problem_.measured[i], static_cast<int>(i)) +
                                    " has a weighted shape");
}

// Sets num_residuals_; returns the modes the forward solve computes: the highest the pairing can
// need, plus extra_modes as far as a small model has them.
int Objective::count_modes_and_residuals() {
  num_residuals_ = 0;
  for (const MeasuredMode& m : problem_.measured) num_residuals_ += 1 + static_cast<int>(m.shape.size());
  return detail::modes_to_compute(problem_, options_.extra_modes, system_->num_dofs());
}

Objective::~Objective() = default;

// Exact Hessian contribution of measured mode i (paired with eigenvalue lambda, mode u).
// Eigenvalue term 1/2 beta r(lambda)^2 (r = (lambda - lambda_m)/lambda_m, or ln(lambda/lambda_m)):
//   H += beta (r'^2 + r r'') grad(lambda) grad(lambda)^T + beta r r' d2lambda,
//   d2lambda_jk = -2 x_k^T (K - lambda M) x_j - lambda_j m_k - lambda_k m_j + u^T (K_jk - lambda M_jk) u,
// with m_j = u^T M_j u (differentiate lambda_j = u^T (K_j - lambda M_j) u once more).
// Shape term g(y) = kappa/2 (1 - MAC(y, phi)), y = P u:
//   H += y_j^T grad2 g y_k + J_u^T u_jk, and J_u^T u_jk = w0^T Q'_jk + c_jk u^T J_u, where
//   Q'_jk = (K_j - lambda_j M - lambda M_j) u_k + (j <-> k) + (K_jk - lambda_j M_k - lambda_k M_j - lambda M_jk) u
//   c_jk = u^T M u_jk = -(u_j^T M u_k + u_j^T M_k u + u_k^T M_j u + u^T M_jk u / 2)
// from the twice-differentiated eigenproblem and normalization: the adjoint w0 stands in for
// the second eigenvector derivatives, so no further solve is needed.
void Objective::add_mode_hessian(const Vector& p, int i, double lambda, const Vector& u, const Matrix& X,
                                 const Matrix& dU, const Vector& dlambda, const Vector& m, const Vector& Ju,
                                 const Vector& w0, Matrix* H) const {
  const MeasuredMode& measured = problem_.measured[i];
  const SparseMatrix& K = workspace_->K;
  const SparseMatrix& M = workspace_->M;
  const int np = num_parameters();
  Matrix A2, B2;
  system_->second_derivative_forms(p, u, u, &A2, &B2);
  if (measured.weight > 0) {
    const EigenvalueResidual e =
        eigenvalue_residual(lambda, eigenvalue_of_hz(measured.frequency_hz), options_.eigenvalue_misfit);
    const Matrix KX = K * X - lambda * (M * X);
    Matrix d2lambda = -2 * X.transpose() * KX + A2 - lambda * B2;
    d2lambda -= dlambda * m.transpose() + m * dlambda.transpose();
    *H += measured.weight * (e.dr * e.dr + e.r * e.d2r) * dlambda * dlambda.transpose() +
          measured.weight * e.r * e.dr * 0.5 * (d2lambda + d2lambda.transpose());
  }
  if (Ju.size() == 0) return;
  const Matrix Hy = detail::ShapeMisfit(measured.shape, measured.shape_weight).hessian(workspace_->sensors * u);
  const Matrix Y = workspace_->sensors * dU;
  *H += Y.transpose() * Hy * Y;
  // w0^T Q'_jk.
  Vector aw, bw;
  system_->derivative_forms(p, w0, u, &aw, &bw);
  Matrix A0, B0;
  system_->second_derivative_forms(p, w0, u, &A0, &B0);
  const Vector wMdu = dU.transpose() * (M * w0);
  Matrix WQ = A0 - lambda * B0 - dlambda * bw.transpose() - bw * dlambda.transpose();
  Matrix Bu(np, np);  // Bu(j, k) = u_j^T M_k u
  // All k at once, one pass over the assembly terms each: w0^T K_j u_k, w0^T M_j u_k and u_k^T M_j u.
  Matrix AK, BK, AU, BU;
  system_->derivative_forms(p, w0.replicate(1, np), dU, &AK, &BK);
  system_->derivative_forms(p, dU, u.replicate(1, np), &AU, &BU);
  for (int k = 0; k < np; ++k) {
    const Vector column = AK.col(k) - dlambda * wMdu[k] - lambda * BK.col(k);
    WQ.col(k) += column;
    WQ.row(k) += column.transpose();
    Bu.row(k) = BU.col(k).transpose();
  }
  const Matrix c = -(dU.transpose() * M * dU + Bu + Bu.transpose() + 0.5 * B2);
  *H += 0.5 * (WQ + WQ.transpose()) + c * u.dot(Ju);
}

void Objective::require_parameters(const Vector& p, const std::string& caller) const {
  if (num_parameters() == 0)
    throw std::invalid_argument(caller + ": " + problem_.path +
                                " has no calibration parameters (no 'parameters' section)");
  if (p.size() != num_parameters())
    throw std::invalid_argument(caller + ": " + std::to_string(p.size()) + " parameter values for " +
                                std::to_string(num_parameters()) + " parameters");
}

/// One evaluation's steps, in order: the forward solve, the pairing, the residuals and value, then
/// on request the adjoint gradient and the Jacobian (sensor adjoints or eigenvector sensitivities)
/// with the Hessian. Each step that can fail marks the evaluation failed with its reason and
/// returns false; the evaluation then goes no further.
class Objective::Evaluator {
 public:
  Evaluator(Objective& objective, const Vector& p, Evaluation* e)
      : o_(objective), problem_(objective.problem_), ws_(*objective.workspace_), p_(p), e_(*e) {}

  bool forward_solve();
  bool pair_modes();
  void residuals_and_value();
  void central_difference_gradient();
  bool gradient();
  bool sensor_adjoint_jacobian();
  bool sensitivities(Need need);

 private:
  const detail::DeflationBasis& deflation_basis();
  std::optional<Matrix> deflated_solve(const char* what, const std::vector<int>& own_columns, const Matrix& B);
  std::optional<Matrix> deflated_solve_shared(const char* what, const std::vector<int>& own, const Matrix& B);
  int num_measured() const { return static_cast<int>(problem_.measured.size()); }
  int num_model() const { return static_cast<int>(e_.modal.eigenvalues.size()); }
  int num_sensors() const { return static_cast<int>(problem_.sensors.size()); }
  int rigid() const { return static_cast<int>(e_.modal.rigid_eigenvalues.size()); }
  const Matrix& U() const { return e_.modal.modes; }
  const Vector& lambda() const { return e_.modal.eigenvalues; }

  Objective& o_;
  const Problem& problem_;
  Workspace& ws_;
  const Vector& p_;
  Evaluation& e_;
  std::vector<int> model_of_;  // the model mode paired with each measured mode
  std::vector<int> mac_rows_;  // the measured modes paired by MAC
  Matrix mac_table_;           // MAC of each measured shape with each model mode (-1: no shape)
  Vector x_, x0_;              // the regularization's variables at p and at the start
  detail::DeflationBasis basis_;
  std::vector<Vector> dlambda_, umu_;  // per measured mode: dlambda/dp and u^T M_j u
  std::vector<int> shape_modes_;       // measured modes with a shape term, in order
  std::vector<Vector> shape_gradient_; // J_u of each measured mode's shape term
  Matrix adjoint_solution_;            // one column per shape mode
};

bool Objective::Evaluator::forward_solve() {
  if (ws_.has_solved && ws_.solved_at.size() == p_.size() && ws_.solved_at == p_) {
    e_.modal = ws_.solved;  // the last solve, of this objective or one sharing its model
    return true;
  }
  o_.system_->assemble(p_, &ws_.K, &ws_.M);
  if (ws_.span.size() == 0) {
    e_.modal = o_.solver_->solve(ws_.K, ws_.M);
  } else {
    Matrix Kr, Mr;
    o_.system_->assemble_projected(p_, ws_.span_terms, &Kr, &Mr);
    // No residuals: nothing reads a span's, and the walk's end is checked on the whole model.
    ws_.span_pairs = o_.solver_->solve_in_span(Kr, Mr, ws_.span, ws_.K, ws_.M, /*residuals=*/false);
    e_.modal = first_modes(ws_.span_pairs, ws_.modes_needed);
  }
  ++o_.forward_solves_;
  ws_.has_solved = e_.modal.status == EigenStatus::Successful;
  if (ws_.has_solved) {
    ws_.solved_at = p_;
    ws_.solved = e_.modal;
    return true;
  }
  e_.message = "forward solve failed: " + o_.system_->failure_message(p_, e_.modal.message);
  return false;
}

// The pairing of objective/mode_pairing.hpp, its tables kept for the residuals and derivatives.
bool Objective::Evaluator::pair_modes() {
  detail::ModePairing pairing =
      detail::pair_modes(problem_, e_.modal, ws_.sensors, o_.options_.eigenvalues_in_frequency_order,
                         [&] { return describe_modes(*o_.system_, p_, ws_.M, e_.modal); });
  if (!pairing.ok()) {
    e_.message = pairing.message;
    return false;
  }
  model_of_ = std::move(pairing.model_of);
  mac_rows_ = std::move(pairing.mac_rows);
  mac_table_ = std::move(pairing.mac_table);
  return true;
}

void Objective::Evaluator::residuals_and_value() {
  const ObjectiveOptions& options = o_.options_;
  const int ns = num_sensors();
  e_.residuals = Vector::Zero(o_.num_residuals_);
  e_.pairs = detail::paired_modes(problem_, e_.modal, model_of_, mac_table_);
  for (std::string& warning :
       detail::close_eigenvalue_warnings(problem_, e_.modal, model_of_, options.close_eigenvalue_tolerance))
    e_.warnings.push_back(std::move(warning) + ": its derivatives are ill defined there");
  int row = 0;
  for (int i = 0; i < num_measured(); ++i) {
    const MeasuredMode& m = problem_.measured[i];
    const double r = eigenvalue_residual(lambda()[model_of_[i]], eigenvalue_of_hz(m.frequency_hz), options.eigenvalue_misfit).r;
    e_.residuals[row++] = std::sqrt(m.weight) * r;
    e_.eigenvalue_term += 0.5 * m.weight * r * r;
  }
  for (int i = 0; i < num_measured(); ++i) {
    const MeasuredMode& m = problem_.measured[i];
    if (m.shape.size() == 0) continue;
    const Vector y = ws_.sensors * U().col(model_of_[i]);
    const Vector res = shape_residual(y, m.shape.normalized());
    e_.residuals.segment(row, ns) = std::sqrt(m.shape_weight) * res;
    e_.shape_term += 0.5 * m.shape_weight * res.squaredNorm();
    row += ns;
  }
  x_ = o_.regularization_scaling_.to_scaled(p_);
  x0_ = o_.regularization_scaling_.to_scaled(problem_.initial_values());
  e_.regularization_term = 0.5 * options.regularization * (x_ - x0_).squaredNorm();
  e_.value = e_.eigenvalue_term + e_.shape_term + e_.regularization_term;
  e_.ok = true;
}

void Objective::Evaluator::central_difference_gradient() {
  const int np = o_.num_parameters();
  e_.gradient.resize(np);
  for (int j = 0; j < np; ++j) {
    const double h = o_.options_.difference_step * std::max(std::abs(p_[j]), 1e-300);
    Vector plus = p_, minus = p_;
    plus[j] += h;
    minus[j] -= h;
    const Evaluation ep = o_.evaluate(plus), em = o_.evaluate(minus);
    if (!ep.ok || !em.ok) {
      e_.ok = false;
      e_.message = "finite-difference gradient: " + (ep.ok ? em.message : ep.message);
      return;
    }
    e_.gradient[j] = (ep.value - em.value) / (2 * h);
  }
}

// The deflation basis only for the linear solves (shape adjoints, sensitivities): its product
// M U alone costs about 3 % of a forward solve, more than the whole eigenvalue-only gradient.
const detail::DeflationBasis& Objective::Evaluator::deflation_basis() {
  if (basis_.modes.size() == 0 && ws_.span.size() != 0) {
    const ModalResult& all = ws_.span_pairs;  // in a span, every Ritz pair
    basis_.modes.resize(all.modes.rows(), all.rigid_modes.cols() + all.modes.cols());
    basis_.modes << all.rigid_modes, all.modes;
    basis_.eigenvalues.resize(basis_.modes.cols());
    basis_.eigenvalues << all.rigid_eigenvalues, all.eigenvalues;  // no M U: solve_in_basis needs none
  } else if (basis_.modes.size() == 0) {
    basis_.modes.resize(U().rows(), rigid() + num_model());
    basis_.modes << e_.modal.rigid_modes, U();
    basis_.eigenvalues.resize(rigid() + num_model());
    basis_.eigenvalues << e_.modal.rigid_eigenvalues, lambda();
    basis_.mass_modes = ws_.M * basis_.modes;
  }
  return basis_;
}

namespace {

// A solve's solution, its column solves counted in `e`; on failure `e` is marked failed with
// `what` and the solver's reason, and nullopt is returned.
std::optional<Matrix> counted(const char* what, detail::DeflatedSolveResult solve, Evaluation* e) {
  e->linear_solves += solve.column_solves;
  if (solve.converged) return std::move(solve.solution);
  e->ok = false;
  e->message = std::string(what) + ": " + solve.message;
  return std::nullopt;
}

}  // namespace

// A deflated solve (K - lambda_own M) X = B (counted()).
std::optional<Matrix> Objective::Evaluator::deflated_solve(const char* what, const std::vector<int>& own_columns,
                                                           const Matrix& B) {
  if (ws_.span.size() != 0) {  // the Ritz pairs span the whole space solved in: no iteration
    e_.linear_solves += static_cast<int>(B.cols());
    return detail::solve_in_basis(deflation_basis(), own_columns, B);
  }
  auto precondition = [&](const Matrix& rhs) { return o_.solver_->solve_factorized(rhs); };
  return counted(what,
                 detail::solve_deflated(ws_.K, ws_.M, deflation_basis(), own_columns, B, precondition,
                                        o_.options_.linear_tolerance, o_.options_.max_linear_iterations),
                 &e_);
}

// As deflated_solve for B once per mode in `own` (the columns B's solves for own[0], then own[1],
// ...), the right-hand sides' Krylov space shared by the modes (detail::solve_deflated_shared).
std::optional<Matrix> Objective::Evaluator::deflated_solve_shared(const char* what, const std::vector<int>& own,
                                                                  const Matrix& B) {
  if (ws_.span.size() != 0) {
    std::vector<int> own_columns;
    for (int mode : own) own_columns.insert(own_columns.end(), static_cast<size_t>(B.cols()), mode);
    return deflated_solve(what, own_columns, B.replicate(1, static_cast<Eigen::Index>(own.size())));
  }
  // The space's Q, M Q and K Q at most 2^23 doubles each (64 MiB): beyond, each mode on its own.
  const Eigen::Index max_columns = (Eigen::Index{1} << 23) / std::max<Eigen::Index>(1, B.rows());
  auto precondition = [&](const Matrix& rhs) { return o_.solver_->solve_factorized(rhs); };
  return counted(what,
                 detail::solve_deflated_shared(ws_.K, ws_.M, deflation_basis(), own, B, precondition,
                                               o_.options_.linear_tolerance, o_.options_.max_linear_iterations,
                                               max_columns),
                 &e_);
}

// The adjoint gradient; with Need::Jacobian or more also the eigenvalue rows of the Jacobian.
bool Objective::Evaluator::gradient() {
  const int n = num_measured();
  e_.gradient = o_.options_.regularization * (x_ - x0_).cwiseQuotient(o_.regularization_scaling_.first_derivative(x_));
  // Eigenvalue sensitivities of every paired mode: dlambda/dp_j = u^T (K_j - lambda M_j) u, all
  // modes in one pass over the assembly terms instead of one pass per mode.
  dlambda_.resize(n);
  umu_.resize(n);
  e_.adjoint = Matrix::Zero(U().rows(), n);
  e_.adjoint_eta = Vector::Zero(n);
  Matrix paired_modes(U().rows(), n);
  for (int i = 0; i < n; ++i) paired_modes.col(i) = U().col(model_of_[i]);
  Matrix mode_a, mode_b;
  o_.system_->derivative_forms(p_, paired_modes, paired_modes, &mode_a, &mode_b);
  const bool jacobian = e_.jacobian.size() > 0;
  for (int i = 0; i < n; ++i) {
    const int k = model_of_[i];
    dlambda_[i] = mode_a.col(i) - lambda()[k] * mode_b.col(i);
    umu_[i] = mode_b.col(i);
    const MeasuredMode& m = problem_.measured[i];
    const EigenvalueResidual r =
        eigenvalue_residual(lambda()[k], eigenvalue_of_hz(m.frequency_hz), o_.options_.eigenvalue_misfit);
    e_.gradient += m.weight * r.r * r.dr * dlambda_[i];
    e_.adjoint.col(i) = m.weight * r.r * r.dr * U().col(k);  // J_lambda u
    if (jacobian) e_.jacobian.row(i) = std::sqrt(m.weight) * r.dr * dlambda_[i].transpose();
  }

  // Shape terms: adjoint right-hand sides (M u u^T - I) J_u, one column per measured shape.
  std::vector<int> own;
  shape_gradient_.assign(n, Vector());
  Matrix rhs(U().rows(), 0);
  for (int i = 0; i < n; ++i) {
    const MeasuredMode& m = problem_.measured[i];
    if (m.shape.size() == 0 || m.shape_weight == 0) continue;
    const Vector u = U().col(model_of_[i]);
    const Vector y = ws_.sensors * u;
    const Vector Ju = ws_.sensors.transpose() * detail::ShapeMisfit(m.shape, m.shape_weight).gradient(y);
    shape_gradient_[i] = Ju;
    rhs.conservativeResize(Eigen::NoChange, rhs.cols() + 1);
    rhs.col(rhs.cols() - 1) = ws_.M * u * u.dot(Ju) - Ju;
    shape_modes_.push_back(i);
    own.push_back(rigid() + model_of_[i]);
    // eta_i u^T M_j u with eta_i = -u^T J_u / 2.
    e_.adjoint_eta[i] = -0.5 * u.dot(Ju);
    e_.gradient += e_.adjoint_eta[i] * umu_[i];
  }
  adjoint_solution_.resize(U().rows(), 0);
  if (shape_modes_.empty()) return true;
  std::optional<Matrix> adjoint = deflated_solve("adjoint solve", own, rhs);
  if (!adjoint) return false;
  // w_s^T (K_j - lambda M_j) u for every shape at once.
  Matrix shape_u(U().rows(), static_cast<Eigen::Index>(shape_modes_.size()));
  for (size_t s = 0; s < shape_modes_.size(); ++s) shape_u.col(s) = U().col(model_of_[shape_modes_[s]]);
  Matrix shape_a, shape_b;
  o_.system_->derivative_forms(p_, *adjoint, shape_u, &shape_a, &shape_b);
  for (size_t s = 0; s < shape_modes_.size(); ++s) {
    const int k = model_of_[shape_modes_[s]];
    e_.gradient += shape_a.col(s) - lambda()[k] * shape_b.col(s);
    e_.adjoint.col(shape_modes_[s]) += adjoint->col(s);
  }
  adjoint_solution_ = std::move(*adjoint);
  return true;
}

namespace {

// The first Jacobian row of each measured mode's shape term (they follow the eigenvalue rows), or
// -1 for a mode without one.
std::vector<int> shape_rows(const Problem& problem) {
  const int n = static_cast<int>(problem.measured.size());
  const int ns = static_cast<int>(problem.sensors.size());
  std::vector<int> first_row(n, -1);
  for (int i = 0, r = n; i < n; ++i)
    if (problem.measured[i].shape.size()) {
      first_row[i] = r;
      r += ns;
    }
  return first_row;
}

}  // namespace

// The shape rows of the Jacobian from sensor adjoints: P du/dp_j = P x_j - (u^T M_j u / 2) P u,
// and P x_j = P S b_j = Z^T b_j with Z = S P^T (S the deflated inverse, symmetric) and
// b_j = -(K_j - lambda M_j) u + dlambda_j M u, whose second part Z^T M u vanishes (S M u = 0).
// One solve per sensor reading instead of per parameter, and the modes' solves of the same
// readings share one Krylov space (deflated_solve_shared).
bool Objective::Evaluator::sensor_adjoint_jacobian() {
  const int np = o_.num_parameters();
  const int ns = num_sensors();
  const std::vector<int> first_row = shape_rows(problem_);
  std::vector<int> rows_of, own_modes;
  for (int i = 0; i < num_measured(); ++i)
    if (problem_.measured[i].has_shape_term()) rows_of.push_back(i);
  for (int i : rows_of) own_modes.push_back(rigid() + model_of_[i]);
  const std::optional<Matrix> sensor_solve =
      deflated_solve_shared("sensor adjoint solve", own_modes, Matrix(ws_.sensors.transpose()));
  if (!sensor_solve) return false;
  for (size_t a = 0; a < rows_of.size(); ++a) {
    const int i = rows_of[a];
    const MeasuredMode& m = problem_.measured[i];
    const int k = model_of_[i];
    const Vector y = ws_.sensors * U().col(k);
    Matrix A, B;  // np x ns: z_s^T K_j u and z_s^T M_j u
    o_.system_->derivative_forms(p_, sensor_solve->middleCols(a * ns, ns), U().col(k).replicate(1, ns), &A, &B);
    const Matrix dy = -(A - lambda()[k] * B).transpose() - 0.5 * y * umu_[i].transpose();  // ns x np
    for (int j = 0; j < np; ++j)
      e_.jacobian.block(first_row[i], j, ns, 1) =
          std::sqrt(m.shape_weight) * shape_residual_derivative(y, m.shape.normalized(), dy.col(j));
  }
  return true;
}

// Eigenvector sensitivities du/dp_j = x_j - (u^T M_j u / 2) u with
// (K - lambda M) x_j = -(K_j - lambda M_j) u + dlambda_j M u, x_j M-orthogonal to u: for the shape
// rows of the Jacobian, and for every paired mode when the Hessian is wanted.
bool Objective::Evaluator::sensitivities(Need need) {
  const int np = o_.num_parameters();
  const int ns = num_sensors();
  const std::vector<int> first_row = shape_rows(problem_);
  std::vector<int> modes_needed;
  for (int i = 0; i < num_measured(); ++i)
    if (need == Need::Hessian || problem_.measured[i].has_shape_term()) modes_needed.push_back(i);
  Matrix sensitivity_rhs(U().rows(), static_cast<Eigen::Index>(modes_needed.size()) * np);
  std::vector<int> own_columns;
  for (size_t a = 0; a < modes_needed.size(); ++a) {
    const int i = modes_needed[a];
    const int k = model_of_[i];
    const Vector Mu = ws_.M * U().col(k);
    for (int j = 0; j < np; ++j) {
      Vector dKu, dMu;
      o_.system_->derivative_times(p_, j, U().col(k), &dKu, &dMu);
      sensitivity_rhs.col(a * np + j) = -(dKu - lambda()[k] * dMu) + dlambda_[i][j] * Mu;
      own_columns.push_back(rigid() + k);
    }
  }
  const std::optional<Matrix> direct = deflated_solve("sensitivity solve", own_columns, sensitivity_rhs);
  if (!direct) return false;
  if (need == Need::Hessian) {
    e_.hessian = Matrix::Zero(np, np);
    // Regularization: R = alpha/2 |x_r(p) - x_r0|^2, dx/dp = 1/p'(x), d2x/dp2 = -p''(x)/p'(x)^3.
    const ParameterScaling& scaling = o_.regularization_scaling_;
    const Vector dp = scaling.first_derivative(x_), d2p = scaling.second_derivative(x_);
    for (int j = 0; j < np; ++j)
      e_.hessian(j, j) = o_.options_.regularization *
                         (1 / (dp[j] * dp[j]) - (x_[j] - x0_[j]) * d2p[j] / (dp[j] * dp[j] * dp[j]));
  }
  for (size_t a = 0; a < modes_needed.size(); ++a) {
    const int i = modes_needed[a];
    const MeasuredMode& m = problem_.measured[i];
    const int k = model_of_[i];
    const Vector u = U().col(k);
    const Matrix X = direct->middleCols(a * np, np);
    Matrix dU = X;
    for (int j = 0; j < np; ++j) dU.col(j) -= 0.5 * umu_[i][j] * u;
    const bool has_shape = m.has_shape_term();
    if (has_shape) {
      const Vector y = ws_.sensors * u;
      for (int j = 0; j < np; ++j)
        e_.jacobian.block(first_row[i], j, ns, 1) =
            std::sqrt(m.shape_weight) * shape_residual_derivative(y, m.shape.normalized(), ws_.sensors * dU.col(j));
    }
    if (need != Need::Hessian) continue;
    const auto shape = std::find(shape_modes_.begin(), shape_modes_.end(), i) - shape_modes_.begin();
    o_.add_mode_hessian(p_, i, lambda()[k], u, X, dU, dlambda_[i], umu_[i], has_shape ? shape_gradient_[i] : Vector(),
                        has_shape ? adjoint_solution_.col(shape) : Vector(), &e_.hessian);
  }
  return true;
}

void Objective::set_span(Matrix basis) {
  if (basis.size() != 0 && basis.rows() != system_->num_dofs())
    throw std::invalid_argument("Objective::set_span: columns of length " + std::to_string(basis.rows()) + " for " +
                                std::to_string(system_->num_dofs()) + " DOFs");
  if (basis.size() == 0 && workspace_->span.size() == 0) return;  // on the whole model already
  workspace_->span_terms = basis.size() != 0 ? system_->project_terms(basis) : std::vector<Matrix>();
  workspace_->span = std::move(basis);
  workspace_->has_solved = false;  // the last solve was in the other space
}

bool Objective::in_span() const { return workspace_->span.size() != 0; }

Matrix Objective::mode_directions(const Evaluation& e, const ParametricSystem& system, const Vector& at,
                                  int first) const {
  // (dK_q - lambda dM_q) u of each paired mode and parameter q: their images under the
  // factorization of K - sigma M at e's point, the last solve's, are the sensitivities but for
  // the part in the modes computed and a factor near 1 on the rest (lambda << the modes beyond).
  const int count = system.num_parameters() - first;
  Matrix rhs(system_->num_dofs(), static_cast<Eigen::Index>(e.pairs.size()) * count);
  Eigen::Index column = 0;
  for (const PairedMode& pair : e.pairs)
    for (int q = first; q < system.num_parameters(); ++q) {
      Vector dKu, dMu;
      system.derivative_times(at, q, e.modal.modes.col(pair.model), &dKu, &dMu);
      rhs.col(column++) = dKu - e.modal.eigenvalues[pair.model] * dMu;
    }
  const Matrix corrections = solver_->solve_factorized(rhs);
  Matrix C(system_->num_dofs(), 2 * corrections.cols());
  C << corrections, solver_->solve_factorized(detail::symmetric_times(workspace_->M, corrections));
  return C;
}

Evaluation Objective::whole_model_evaluation(const Vector& p, const char* caller) {
  set_span(Matrix());
  Evaluation e = evaluate(p, Need::Value);
  if (!e.ok) throw std::runtime_error(std::string("Objective::") + caller + ": " + e.message);
  return e;
}

Matrix Objective::span_at(const Vector& p) {
  const Evaluation e = whole_model_evaluation(p, "span_at");
  Matrix U(system_->num_dofs(), e.modal.rigid_modes.cols() + e.modal.modes.cols());
  U << e.modal.rigid_modes, e.modal.modes;
  return extend_m_orthonormal(workspace_->M, U, mode_directions(e, *system_, p, 0));
}

Matrix Objective::extend_span(const Matrix& span, const Vector& p, const ParametricSystem& wider,
                              const Vector& wider_p) {
  if (span.rows() != system_->num_dofs() || !(wider.dof_map() == system_->dof_map()) ||
      wider.num_parameters() <= num_parameters() || wider_p.size() != wider.num_parameters())
    throw std::invalid_argument("Objective::extend_span: the wider model needs this model's DOFs, more parameters "
                                "and a value for each, and the span columns of the model's size");
  const Evaluation e = whole_model_evaluation(p, "extend_span");
  return extend_m_orthonormal(workspace_->M, span, mode_directions(e, wider, wider_p, num_parameters()));
}

Evaluation Objective::evaluate(const Vector& p, Need need) {
  Evaluation e;
  if (p.size() != num_parameters() || !p.allFinite()) {
    e.message = "parameter vector has wrong size or non-finite entries";
    return e;
  }
  Evaluator run(*this, p, &e);
  if (!run.forward_solve() || !run.pair_modes()) return e;
  run.residuals_and_value();
  if (need == Need::Value) return e;
  if (need == Need::Gradient && options_.gradient == ObjectiveOptions::Gradient::CentralDifferences) {
    run.central_difference_gradient();
    return e;
  }
  if (need >= Need::Jacobian) e.jacobian = Matrix::Zero(num_residuals_, num_parameters());
  if (!run.gradient()) return e;
  // The shape rows: sensor adjoints when they are fewer solves than the parameters' sensitivities
  // (and no Hessian needs the sensitivities anyway).
  const bool sensor_adjoint =
      need == Need::Jacobian && (options_.jacobian == ObjectiveOptions::Jacobian::SensorAdjoint ||
                                 (options_.jacobian == ObjectiveOptions::Jacobian::Automatic &&
                                  num_parameters() > static_cast<int>(problem_.sensors.size())));
  if (sensor_adjoint ? !run.sensor_adjoint_jacobian() : need >= Need::Jacobian && !run.sensitivities(need)) return e;
  linear_solves_ += e.linear_solves;
  return e;
}

}  // namespace modalcal
