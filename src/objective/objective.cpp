#include "modalcal/objective.hpp"

#include <algorithm>
#include <cmath>
#include <optional>
#include <sstream>

#include "modalcal/mode_description.hpp"
#include "objective/assignment.hpp"
#include "objective/deflated_solve.hpp"
#include "objective/shape_misfit.hpp"

namespace modalcal {

double mac(const Vector& a, const Vector& b) {
  const double aa = a.squaredNorm(), bb = b.squaredNorm();
  if (aa == 0 || bb == 0) return 0;
  const double ab = a.dot(b);
  return ab * ab / (aa * bb);
}

bool ObjectiveOptions::IsValid(std::string* error) const {
  auto bad = [&](const std::string& message) {
    if (error) *error = message;
    return false;
  };
  if (!(regularization >= 0) || !std::isfinite(regularization))
    return bad("regularization = " + std::to_string(regularization) + ": must be finite and >= 0");
  if (extra_modes < 1) return bad("extra_modes = " + std::to_string(extra_modes) + ": must be >= 1");
  if (!(linear_tolerance > 0 && linear_tolerance <= 1e-4))
    return bad("linear_tolerance = " + std::to_string(linear_tolerance) + ": must be in (0, 1e-4]");
  if (max_linear_iterations < 1)
    return bad("max_linear_iterations = " + std::to_string(max_linear_iterations) + ": must be >= 1");
  if (!(difference_step > 0 && difference_step < 0.1))
    return bad("difference_step = " + std::to_string(difference_step) + ": must be in (0, 0.1)");
  if (!(close_eigenvalue_tolerance > 0 && close_eigenvalue_tolerance < 1))
    return bad("close_eigenvalue_tolerance = " + std::to_string(close_eigenvalue_tolerance) + ": must be in (0, 1)");
  return true;
}

struct Objective::Workspace {
  SparseMatrix K, M;
  SparseMatrix sensors;  // P: free DOFs -> sensor readings
  int modes_needed = 0;
};

namespace {

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

std::string describe_measured(const MeasuredMode& m, int index) {
  std::ostringstream s;
  s << "measured mode " << index + 1;
  if (!m.label.empty()) s << " ('" << m.label << "')";
  return s.str();
}

}  // namespace

Objective::Objective(const Problem& problem, ObjectiveOptions options)
    : problem_(problem), options_(options), regularization_scaling_(problem.parameters) {
  std::string error;
  if (!options_.IsValid(&error)) throw std::invalid_argument("ObjectiveOptions: " + error);
  if (problem.measured.empty())
    throw std::invalid_argument(problem.path + ": no measured modes to calibrate against");
  if (options_.eigenvalues_in_frequency_order)
    for (size_t i = 0; i < problem.measured.size(); ++i)
      if (problem.measured[i].has_shape_term())
        throw std::invalid_argument("ObjectiveOptions::eigenvalues_in_frequency_order needs an objective without shape "
                                    "terms, but " + describe_measured(problem.measured[i], static_cast<int>(i)) +
                                    " has a weighted shape");
  system_ = std::make_unique<ParametricSystem>(problem.model, problem.parameter_targets());
  workspace_ = std::make_unique<Workspace>();
  workspace_->sensors = detail::sensor_matrix(problem, system_->dof_map());
  int highest = problem.options.num_modes;
  for (const MeasuredMode& m : problem.measured) {
    if (m.pairing.kind == PairingRule::Kind::ModelIndex) highest = std::max(highest, m.pairing.model_index);
    num_residuals_ += 1 + static_cast<int>(m.shape.size());
  }
  // Extra modes only as far as a small model has them.
  workspace_->modes_needed =
      std::max(highest, std::min(highest + options_.extra_modes, system_->num_dofs() - problem.expected_rigid_modes()));
  ModalOptions modal;
  modal.num_modes = workspace_->modes_needed;
  modal.max_rigid_modes = problem.expected_rigid_modes();
  modal.tolerance = problem.options.tolerance;
  solver_ = std::make_unique<ModalSolver>(system_->pattern(), modal);
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

Evaluation Objective::evaluate(const Vector& p, Need need) {
  Evaluation e;
  if (p.size() != num_parameters() || !p.allFinite()) {
    e.message = "parameter vector has wrong size or non-finite entries";
    return e;
  }
  Workspace& ws = *workspace_;
  system_->assemble(p, &ws.K, &ws.M);
  e.modal = solver_->solve(ws.K, ws.M);
  ++forward_solves_;
  if (e.modal.status != EigenStatus::Successful) {
    e.message = "forward solve failed: " + system_->failure_message(p, e.modal.message);
    return e;
  }
  const Matrix& U = e.modal.modes;
  const Vector& lambda = e.modal.eigenvalues;
  const int num_model = static_cast<int>(lambda.size());

  // --- Pairing: fixed rules first, then by MAC (largest total MAC, one-to-one).
  const int num_measured = static_cast<int>(problem_.measured.size());
  std::vector<int> model_of(num_measured, -1);
  std::vector<bool> taken(num_model, false);
  std::vector<ModeDescription> described;
  for (int i = 0; i < num_measured; ++i) {
    const PairingRule& rule = problem_.measured[i].pairing;
    int k = -1;
    if (rule.kind == PairingRule::Kind::ModelIndex) {
      k = rule.model_index - 1;
    } else if (rule.kind == PairingRule::Kind::Family) {
      if (described.empty()) described = describe_modes(*system_, p, ws.M, e.modal);
      k = find_family_mode(described, rule.family, rule.family_index) - 1;
      if (k < 0) {
        e.message = describe_measured(problem_.measured[i], i) + ": the lowest " + std::to_string(num_model) +
                    " model modes have fewer than " + std::to_string(rule.family_index) + " '" + rule.family +
                    "' modes; raise options.num_modes or check the model";
        return e;
      }
    } else {
      continue;
    }
    if (k >= num_model || taken[k]) {
      e.message = describe_measured(problem_.measured[i], i) + ": model mode " + std::to_string(k + 1) +
                  (taken[k] ? " is already paired with another measured mode" : " was not computed");
      return e;
    }
    model_of[i] = k;
    taken[k] = true;
  }
  Matrix mac_table = Matrix::Constant(num_measured, num_model, -1.0);
  for (int i = 0; i < num_measured; ++i) {
    const MeasuredMode& m = problem_.measured[i];
    if (m.shape.size() == 0) continue;
    for (int k = 0; k < num_model; ++k) mac_table(i, k) = mac(ws.sensors * U.col(k), m.shape);
  }
  // MAC-paired modes: the assignment with the largest total MAC among the modes left free.
  std::vector<int> mac_rows, free_columns;
  for (int i = 0; i < num_measured; ++i)
    if (model_of[i] < 0 && problem_.measured[i].pairing.kind == PairingRule::Kind::Mac) mac_rows.push_back(i);
  for (int k = 0; k < num_model; ++k)
    if (!taken[k]) free_columns.push_back(k);
  if (!mac_rows.empty() && mac_rows.size() <= free_columns.size()) {
    // Sparse sensors can see two modes alike (on a test model, MAC 0.99999 with modes at 1.7 and
    // 3.2 Hz): rounding must not decide between them, or J jumps wherever the tie flips and a line
    // search stalls there. Each score loses kMacTieWeight |ln(lambda_k / lambda_m)|, so a tie
    // goes to the nearer eigenvalue while a MAC difference of more than ~1e-3 still decides.
    constexpr double kMacTieWeight = 1e-3;
    Matrix score(mac_rows.size(), free_columns.size());
    for (size_t a = 0; a < mac_rows.size(); ++a) {
      const double target = eigenvalue_of_hz(problem_.measured[mac_rows[a]].frequency_hz);
      for (size_t b = 0; b < free_columns.size(); ++b) {
        const double ratio = std::abs(lambda[free_columns[b]]) / target;
        score(a, b) = mac_table(mac_rows[a], free_columns[b]) - kMacTieWeight * std::abs(std::log(std::max(ratio, 1e-300)));
      }
    }
    const std::vector<int> assigned = detail::maximize_assignment(score);
    for (size_t a = 0; a < mac_rows.size(); ++a) model_of[mac_rows[a]] = free_columns[assigned[a]];
  }
  for (int i = 0; i < num_measured; ++i)
    if (model_of[i] < 0) {
      e.message = describe_measured(problem_.measured[i], i) + ": no model mode left to pair with";
      return e;
    }
  if (options_.eigenvalues_in_frequency_order && mac_rows.size() > 1) {
    // The shapes chose the set; frequency order assigns it (see the option's comment).
    std::vector<int> set;
    for (int i : mac_rows) set.push_back(model_of[i]);
    std::sort(set.begin(), set.end(), [&](int a, int b) { return lambda[a] < lambda[b]; });
    std::vector<int> rows = mac_rows;
    std::stable_sort(rows.begin(), rows.end(), [&](int a, int b) {
      return problem_.measured[a].frequency_hz < problem_.measured[b].frequency_hz;
    });
    for (size_t a = 0; a < rows.size(); ++a) model_of[rows[a]] = set[a];
  }

  // --- Residuals and value.
  const int ns = static_cast<int>(problem_.sensors.size());
  e.residuals = Vector::Zero(num_residuals_);
  int row = 0;
  for (int i = 0; i < num_measured; ++i) {
    const MeasuredMode& m = problem_.measured[i];
    const int k = model_of[i];
    const double target = eigenvalue_of_hz(m.frequency_hz);
    PairedMode pair;
    pair.measured = i;
    pair.model = k;
    pair.measured_hz = m.frequency_hz;
    pair.model_hz = frequency_hz(lambda[k]);
    pair.relative_error = (lambda[k] - target) / target;
    pair.mac = m.shape.size() ? mac_table(i, k) : -1;
    e.pairs.push_back(pair);
    const double r = eigenvalue_residual(lambda[k], target, options_.eigenvalue_misfit).r;
    e.residuals[row++] = std::sqrt(m.weight) * r;
    e.eigenvalue_term += 0.5 * m.weight * r * r;
    for (int n : {k - 1, k + 1})
      if (n >= 0 && n < num_model && std::abs(lambda[n] - lambda[k]) < options_.close_eigenvalue_tolerance * lambda[k])
        e.warnings.push_back(describe_measured(m, i) + " is paired with model mode " + std::to_string(k + 1) +
                             ", whose eigenvalue nearly repeats that of mode " + std::to_string(n + 1) +
                             ": its derivatives are ill defined there");
  }
  for (int i = 0; i < num_measured; ++i) {
    const MeasuredMode& m = problem_.measured[i];
    if (m.shape.size() == 0) continue;
    const Vector y = ws.sensors * U.col(model_of[i]);
    const Vector res = shape_residual(y, m.shape.normalized());
    e.residuals.segment(row, ns) = std::sqrt(m.shape_weight) * res;
    e.shape_term += 0.5 * m.shape_weight * res.squaredNorm();
    row += ns;
  }
  const Vector x = regularization_scaling_.to_scaled(p);
  const Vector x0 = regularization_scaling_.to_scaled(problem_.initial_values());
  e.regularization_term = 0.5 * options_.regularization * (x - x0).squaredNorm();
  e.value = e.eigenvalue_term + e.shape_term + e.regularization_term;
  e.ok = true;
  if (need == Need::Value) return e;

  // --- Gradient (adjoint) and, on request, the residual Jacobian (sensitivities or sensor adjoint).
  const int np = num_parameters();
  if (need == Need::Gradient && options_.gradient == ObjectiveOptions::Gradient::CentralDifferences) {
    e.gradient.resize(np);
    for (int j = 0; j < np; ++j) {
      const double h = options_.difference_step * std::max(std::abs(p[j]), 1e-300);
      Vector plus = p, minus = p;
      plus[j] += h;
      minus[j] -= h;
      const Evaluation ep = evaluate(plus), em = evaluate(minus);
      if (!ep.ok || !em.ok) {
        e.ok = false;
        e.message = "finite-difference gradient: " + (ep.ok ? em.message : ep.message);
        return e;
      }
      e.gradient[j] = (ep.value - em.value) / (2 * h);
    }
    return e;
  }
  e.gradient = options_.regularization * (x - x0).cwiseQuotient(regularization_scaling_.first_derivative(x));
  if (need >= Need::Jacobian) e.jacobian = Matrix::Zero(num_residuals_, np);

  // The deflation basis only for the linear solves (shape adjoints, sensitivities): its product
  // M U alone costs about 3 % of a forward solve, more than the whole eigenvalue-only gradient.
  const int nr = static_cast<int>(e.modal.rigid_eigenvalues.size());
  detail::DeflationBasis basis;
  auto deflation_basis = [&]() -> const detail::DeflationBasis& {
    if (basis.modes.size() == 0) {
      basis.modes.resize(U.rows(), nr + num_model);
      basis.modes << e.modal.rigid_modes, U;
      basis.eigenvalues.resize(nr + num_model);
      basis.eigenvalues << e.modal.rigid_eigenvalues, lambda;
      basis.mass_modes = ws.M * basis.modes;
    }
    return basis;
  };
  auto precondition = [&](const Matrix& B) { return solver_->solve_factorized(B); };
  // A deflated solve (K - lambda_own M) X = B, counted; on failure the evaluation is marked
  // failed with `what` and the solver's reason, and nullopt is returned.
  auto deflated_solve = [&](const char* what, const std::vector<int>& own_columns,
                            const Matrix& B) -> std::optional<Matrix> {
    detail::DeflatedSolveResult solve =
        detail::solve_deflated(ws.K, ws.M, deflation_basis(), own_columns, B, precondition,
                               options_.linear_tolerance, options_.max_linear_iterations);
    e.linear_solves += solve.column_solves;
    if (solve.converged) return std::move(solve.solution);
    e.ok = false;
    e.message = std::string(what) + ": " + solve.message;
    return std::nullopt;
  };

  // Eigenvalue sensitivities of every paired mode: dlambda/dp_j = u^T (K_j - lambda M_j) u, all
  // modes in one pass over the assembly terms instead of one pass per mode.
  std::vector<Vector> dlambda(num_measured), umu(num_measured);
  e.adjoint = Matrix::Zero(U.rows(), num_measured);
  e.adjoint_eta = Vector::Zero(num_measured);
  Matrix paired_modes(U.rows(), num_measured);
  for (int i = 0; i < num_measured; ++i) paired_modes.col(i) = U.col(model_of[i]);
  Matrix mode_a, mode_b;
  system_->derivative_forms(p, paired_modes, paired_modes, &mode_a, &mode_b);
  for (int i = 0; i < num_measured; ++i) {
    const int k = model_of[i];
    dlambda[i] = mode_a.col(i) - lambda[k] * mode_b.col(i);
    umu[i] = mode_b.col(i);
    const MeasuredMode& m = problem_.measured[i];
    const EigenvalueResidual r =
        eigenvalue_residual(lambda[k], eigenvalue_of_hz(m.frequency_hz), options_.eigenvalue_misfit);
    e.gradient += m.weight * r.r * r.dr * dlambda[i];
    e.adjoint.col(i) = m.weight * r.r * r.dr * U.col(k);  // J_lambda u
    if (need >= Need::Jacobian) e.jacobian.row(i) = std::sqrt(m.weight) * r.dr * dlambda[i].transpose();
  }

  // Shape terms: adjoint right-hand sides (M u u^T - I) J_u, one column per measured shape.
  std::vector<int> shape_modes, own;
  std::vector<Vector> shape_gradient(num_measured);  // J_u of each measured mode's shape term
  Matrix rhs(U.rows(), 0);
  for (int i = 0; i < num_measured; ++i) {
    const MeasuredMode& m = problem_.measured[i];
    if (m.shape.size() == 0 || m.shape_weight == 0) continue;
    const Vector u = U.col(model_of[i]);
    const Vector y = ws.sensors * u;
    const Vector Ju = ws.sensors.transpose() * detail::ShapeMisfit(m.shape, m.shape_weight).gradient(y);
    shape_gradient[i] = Ju;
    rhs.conservativeResize(Eigen::NoChange, rhs.cols() + 1);
    rhs.col(rhs.cols() - 1) = ws.M * u * u.dot(Ju) - Ju;
    shape_modes.push_back(i);
    own.push_back(nr + model_of[i]);
    // eta_i u^T M_j u with eta_i = -u^T J_u / 2.
    e.adjoint_eta[i] = -0.5 * u.dot(Ju);
    e.gradient += e.adjoint_eta[i] * umu[i];
  }
  Matrix adjoint_solution(U.rows(), 0);
  if (!shape_modes.empty()) {
    std::optional<Matrix> adjoint = deflated_solve("adjoint solve", own, rhs);
    if (!adjoint) return e;
    // w_s^T (K_j - lambda M_j) u for every shape at once.
    Matrix shape_u(U.rows(), static_cast<Eigen::Index>(shape_modes.size()));
    for (size_t s = 0; s < shape_modes.size(); ++s) shape_u.col(s) = U.col(model_of[shape_modes[s]]);
    Matrix shape_a, shape_b;
    system_->derivative_forms(p, *adjoint, shape_u, &shape_a, &shape_b);
    for (size_t s = 0; s < shape_modes.size(); ++s) {
      const int k = model_of[shape_modes[s]];
      e.gradient += shape_a.col(s) - lambda[k] * shape_b.col(s);
      e.adjoint.col(shape_modes[s]) += adjoint->col(s);
    }
    adjoint_solution = std::move(*adjoint);
  }

  std::vector<int> first_row(num_measured, -1);  // shape rows follow the eigenvalue rows
  for (int i = 0, r = num_measured; i < num_measured; ++i)
    if (problem_.measured[i].shape.size()) {
      first_row[i] = r;
      r += ns;
    }
  const bool sensor_adjoint =
      need == Need::Jacobian && (options_.jacobian == ObjectiveOptions::Jacobian::SensorAdjoint ||
                                 (options_.jacobian == ObjectiveOptions::Jacobian::Automatic && np > ns));
  if (sensor_adjoint) {
    // P du/dp_j = P x_j - (u^T M_j u / 2) P u, and P x_j = P S b_j = Z^T b_j with Z = S P^T (S the
    // deflated inverse, symmetric) and b_j = -(K_j - lambda M_j) u + dlambda_j M u, whose second
    // part Z^T M u vanishes (S M u = 0). One solve per sensor reading instead of per parameter.
    std::vector<int> rows_of, own_columns;
    for (int i = 0; i < num_measured; ++i)
      if (problem_.measured[i].has_shape_term()) rows_of.push_back(i);
    const Matrix sensor_columns = Matrix(ws.sensors.transpose());
    Matrix adjoint_rhs(U.rows(), static_cast<Eigen::Index>(rows_of.size()) * ns);
    for (size_t a = 0; a < rows_of.size(); ++a) {
      adjoint_rhs.middleCols(a * ns, ns) = sensor_columns;
      own_columns.insert(own_columns.end(), ns, nr + model_of[rows_of[a]]);
    }
    const std::optional<Matrix> sensor_solve = deflated_solve("sensor adjoint solve", own_columns, adjoint_rhs);
    if (!sensor_solve) return e;
    for (size_t a = 0; a < rows_of.size(); ++a) {
      const int i = rows_of[a];
      const MeasuredMode& m = problem_.measured[i];
      const int k = model_of[i];
      const Vector y = ws.sensors * U.col(k);
      Matrix A, B;  // np x ns: z_s^T K_j u and z_s^T M_j u
      system_->derivative_forms(p, sensor_solve->middleCols(a * ns, ns), U.col(k).replicate(1, ns), &A, &B);
      const Matrix dy = -(A - lambda[k] * B).transpose() - 0.5 * y * umu[i].transpose();  // ns x np
      for (int j = 0; j < np; ++j)
        e.jacobian.block(first_row[i], j, ns, 1) =
            std::sqrt(m.shape_weight) * shape_residual_derivative(y, m.shape.normalized(), dy.col(j));
    }
  } else if (need >= Need::Jacobian) {
    // Eigenvector sensitivities du/dp_j = x_j - (u^T M_j u / 2) u with
    // (K - lambda M) x_j = -(K_j - lambda M_j) u + dlambda_j M u, x_j M-orthogonal to u:
    // for the shape rows of the Jacobian, and for every paired mode when the Hessian is wanted.
    std::vector<int> modes_needed;
    for (int i = 0; i < num_measured; ++i)
      if (need == Need::Hessian || problem_.measured[i].has_shape_term())
        modes_needed.push_back(i);
    Matrix sensitivity_rhs(U.rows(), static_cast<Eigen::Index>(modes_needed.size()) * np);
    std::vector<int> own_columns;
    for (size_t a = 0; a < modes_needed.size(); ++a) {
      const int i = modes_needed[a];
      const int k = model_of[i];
      const Vector Mu = ws.M * U.col(k);
      for (int j = 0; j < np; ++j) {
        Vector dKu, dMu;
        system_->derivative_times(p, j, U.col(k), &dKu, &dMu);
        sensitivity_rhs.col(a * np + j) = -(dKu - lambda[k] * dMu) + dlambda[i][j] * Mu;
        own_columns.push_back(nr + k);
      }
    }
    const std::optional<Matrix> direct = deflated_solve("sensitivity solve", own_columns, sensitivity_rhs);
    if (!direct) return e;
    if (need == Need::Hessian) {
      e.hessian = Matrix::Zero(np, np);
      // Regularization: R = alpha/2 |x_r(p) - x_r0|^2, dx/dp = 1/p'(x), d2x/dp2 = -p''(x)/p'(x)^3.
      const Vector dp = regularization_scaling_.first_derivative(x), d2p = regularization_scaling_.second_derivative(x);
      for (int j = 0; j < np; ++j)
        e.hessian(j, j) = options_.regularization *
                          (1 / (dp[j] * dp[j]) - (x[j] - x0[j]) * d2p[j] / (dp[j] * dp[j] * dp[j]));
    }
    for (size_t a = 0; a < modes_needed.size(); ++a) {
      const int i = modes_needed[a];
      const MeasuredMode& m = problem_.measured[i];
      const int k = model_of[i];
      const Vector u = U.col(k);
      const Matrix X = direct->middleCols(a * np, np);
      Matrix dU = X;
      for (int j = 0; j < np; ++j) dU.col(j) -= 0.5 * umu[i][j] * u;
      const bool has_shape = m.has_shape_term();
      if (has_shape) {
        const Vector y = ws.sensors * u;
        for (int j = 0; j < np; ++j)
          e.jacobian.block(first_row[i], j, ns, 1) =
              std::sqrt(m.shape_weight) * shape_residual_derivative(y, m.shape.normalized(), ws.sensors * dU.col(j));
      }
      if (need != Need::Hessian) continue;
      add_mode_hessian(p, i, lambda[k], u, X, dU, dlambda[i], umu[i], has_shape ? shape_gradient[i] : Vector(),
                       has_shape ? adjoint_solution.col(std::find(shape_modes.begin(), shape_modes.end(), i) - shape_modes.begin())
                                 : Vector(),
                       &e.hessian);
    }
  }
  linear_solves_ += e.linear_solves;
  return e;
}

}  // namespace modalcal
