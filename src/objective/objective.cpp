#include "modalcal/objective.hpp"

#include <algorithm>
#include <cmath>
#include <sstream>

#include "modalcal/mode_description.hpp"
#include "objective/deflated_solve.hpp"

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

// Rows of T for the sensor DOFs: the sensor reading of a free-DOF vector u is P u.
SparseMatrix sensor_matrix(const Problem& problem, const DofMap& dofs) {
  std::vector<Eigen::Triplet<double, int>> entries;
  for (size_t s = 0; s < problem.sensors.size(); ++s) {
    const int f = dofs.full_index(problem.sensors[s].node, problem.sensors[s].component);
    for (DofMap::RowSparseMatrix::InnerIterator it(dofs.transformation_rows(), f); it; ++it)
      entries.emplace_back(static_cast<int>(s), static_cast<int>(it.col()), it.value());
  }
  SparseMatrix P(problem.sensors.size(), dofs.num_free());
  P.setFromTriplets(entries.begin(), entries.end());
  return P;
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
  system_ = std::make_unique<ParametricSystem>(problem.model, problem.parameter_targets());
  workspace_ = std::make_unique<Workspace>();
  workspace_->sensors = sensor_matrix(problem, system_->dof_map());
  int highest = problem.options.num_modes;
  for (const MeasuredMode& m : problem.measured) {
    if (m.pairing.kind == PairingRule::Kind::ModelIndex) highest = std::max(highest, m.pairing.model_index);
    num_residuals_ += 1 + static_cast<int>(m.shape.size());
  }
  workspace_->modes_needed = highest + options_.extra_modes;
  ModalOptions modal;
  modal.num_modes = workspace_->modes_needed;
  modal.max_rigid_modes = problem.expected_rigid_modes();
  modal.tolerance = problem.options.tolerance;
  solver_ = std::make_unique<ModalSolver>(system_->pattern(), modal);
}

Objective::~Objective() = default;

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
    e.message = "forward solve failed: " + e.modal.message;
    return e;
  }
  const Matrix& U = e.modal.modes;
  const Vector& lambda = e.modal.eigenvalues;
  const int num_model = static_cast<int>(lambda.size());

  // --- Pairing: fixed rules first, then MAC greedily (largest MAC first, one-to-one).
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
  while (true) {
    int best_i = -1, best_k = -1;
    double best = -1;
    for (int i = 0; i < num_measured; ++i) {
      if (model_of[i] >= 0 || problem_.measured[i].pairing.kind != PairingRule::Kind::Mac) continue;
      for (int k = 0; k < num_model; ++k)
        if (!taken[k] && mac_table(i, k) > best) {
          best = mac_table(i, k);
          best_i = i;
          best_k = k;
        }
    }
    if (best_i < 0) break;
    model_of[best_i] = best_k;
    taken[best_k] = true;
  }
  for (int i = 0; i < num_measured; ++i)
    if (model_of[i] < 0) {
      e.message = describe_measured(problem_.measured[i], i) + ": no model mode left to pair with";
      return e;
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
    e.residuals[row++] = std::sqrt(m.weight) * pair.relative_error;
    e.eigenvalue_term += 0.5 * m.weight * pair.relative_error * pair.relative_error;
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

  // --- Gradient (adjoint) and, on request, the residual Jacobian (direct sensitivities).
  const int np = num_parameters();
  e.gradient = options_.regularization * (x - x0).cwiseQuotient(regularization_scaling_.first_derivative(x));
  if (need == Need::Jacobian) e.jacobian = Matrix::Zero(num_residuals_, np);

  detail::DeflationBasis basis;
  const int nr = static_cast<int>(e.modal.rigid_eigenvalues.size());
  basis.modes.resize(U.rows(), nr + num_model);
  basis.modes << e.modal.rigid_modes, U;
  basis.eigenvalues.resize(nr + num_model);
  basis.eigenvalues << e.modal.rigid_eigenvalues, lambda;
  basis.mass_modes = ws.M * basis.modes;
  auto precondition = [&](const Matrix& B) { return solver_->solve_factorized(B); };

  // Eigenvalue sensitivities of every paired mode: dlambda/dp_j = u^T (K_j - lambda M_j) u.
  std::vector<Vector> dlambda(num_measured), umu(num_measured);
  for (int i = 0; i < num_measured; ++i) {
    const int k = model_of[i];
    Vector a, b;
    system_->derivative_forms(p, U.col(k), U.col(k), &a, &b);
    dlambda[i] = a - lambda[k] * b;
    umu[i] = b;
    const MeasuredMode& m = problem_.measured[i];
    const double target = eigenvalue_of_hz(m.frequency_hz);
    e.gradient += m.weight * e.pairs[i].relative_error / target * dlambda[i];
    if (need == Need::Jacobian) e.jacobian.row(i) = std::sqrt(m.weight) / target * dlambda[i].transpose();
  }

  // Shape terms: adjoint right-hand sides (M u u^T - I) J_u, one column per measured shape.
  std::vector<int> shape_modes, own;
  Matrix rhs(U.rows(), 0);
  for (int i = 0; i < num_measured; ++i) {
    const MeasuredMode& m = problem_.measured[i];
    if (m.shape.size() == 0 || m.shape_weight == 0) continue;
    const Vector u = U.col(model_of[i]);
    const Vector y = ws.sensors * u;
    const Vector phi = m.shape.normalized();
    const Vector res = shape_residual(y, phi);
    // J_y = kappa (de/dy)^T e; de/dy is symmetric-projector based: (de/dy)^T e = de/dy applied to e.
    const double norm = y.norm();
    const Vector yhat = y / norm;
    const Vector Pe = res - phi * phi.dot(res);
    const Vector Jy = m.shape_weight * (Pe - yhat * yhat.dot(Pe)) / norm;
    const Vector Ju = ws.sensors.transpose() * Jy;
    rhs.conservativeResize(Eigen::NoChange, rhs.cols() + 1);
    rhs.col(rhs.cols() - 1) = ws.M * u * u.dot(Ju) - Ju;
    shape_modes.push_back(i);
    own.push_back(nr + model_of[i]);
    // eta_i u^T M_j u with eta_i = -u^T J_u / 2.
    e.gradient += -0.5 * u.dot(Ju) * umu[i];
  }
  if (!shape_modes.empty()) {
    const detail::DeflatedSolveResult adjoint =
        detail::solve_deflated(ws.K, ws.M, basis, own, rhs, precondition, options_.linear_tolerance,
                               options_.max_linear_iterations);
    e.linear_solves += adjoint.column_solves;
    if (!adjoint.converged) {
      e.ok = false;
      e.message = "adjoint solve: " + adjoint.message;
      return e;
    }
    for (size_t s = 0; s < shape_modes.size(); ++s) {
      const int k = model_of[shape_modes[s]];
      Vector a, b;
      system_->derivative_forms(p, adjoint.solution.col(s), U.col(k), &a, &b);
      e.gradient += a - lambda[k] * b;
    }
  }

  if (need == Need::Jacobian) {
    // du/dp_j = x_j - (u^T M_j u / 2) u, (K - lambda M) x_j = -(K_j - lambda M_j) u + dlambda_j M u.
    Matrix sensitivity_rhs(U.rows(), 0);
    std::vector<int> own_columns;
    std::vector<int> column_mode;
    for (int i : shape_modes) {
      const int k = model_of[i];
      const Vector u = U.col(k);
      const Vector Mu = ws.M * u;
      for (int j = 0; j < np; ++j) {
        Vector dKu, dMu;
        system_->derivative_times(p, j, u, &dKu, &dMu);
        sensitivity_rhs.conservativeResize(Eigen::NoChange, sensitivity_rhs.cols() + 1);
        sensitivity_rhs.col(sensitivity_rhs.cols() - 1) = -(dKu - lambda[k] * dMu) + dlambda[i][j] * Mu;
        own_columns.push_back(nr + k);
        column_mode.push_back(i);
      }
    }
    if (!own_columns.empty()) {
      const detail::DeflatedSolveResult direct =
          detail::solve_deflated(ws.K, ws.M, basis, own_columns, sensitivity_rhs, precondition,
                                 options_.linear_tolerance, options_.max_linear_iterations);
      e.linear_solves += direct.column_solves;
      if (!direct.converged) {
        e.ok = false;
        e.message = "sensitivity solve: " + direct.message;
        return e;
      }
      // Shape rows start after the eigenvalue rows, in measured order.
      std::vector<int> first_row(num_measured, -1);
      int r = num_measured;
      for (int i = 0; i < num_measured; ++i)
        if (problem_.measured[i].shape.size()) {
          first_row[i] = r;
          r += ns;
        }
      for (size_t c = 0; c < own_columns.size(); ++c) {
        const int i = column_mode[c];
        const int j = static_cast<int>(c % np);
        const MeasuredMode& m = problem_.measured[i];
        const Vector u = U.col(model_of[i]);
        const Vector du = direct.solution.col(c) - 0.5 * umu[i][j] * u;
        const Vector y = ws.sensors * u;
        e.jacobian.block(first_row[i], j, ns, 1) =
            std::sqrt(m.shape_weight) * shape_residual_derivative(y, m.shape.normalized(), ws.sensors * du);
      }
    }
  }
  linear_solves_ += e.linear_solves;
  return e;
}

}  // namespace modalcal
