#include "reduced/scaled_problem.hpp"

#include <cmath>

namespace modalcal::detail {

ScaledProblem::ScaledProblem(Objective& objective, const ReducedOptions& options)
    : objective_(objective),
      options_(options),
      scaling_(options.scaling ? ParameterScaling(objective.problem().parameters, *options.scaling)
                               : ParameterScaling(objective.problem().parameters)) {
  const Problem& problem = objective.problem();
  const int n = objective.num_parameters();
  lower_ = Vector::Constant(n, -INFINITY);
  upper_ = Vector::Constant(n, INFINITY);
  if (options.use_bounds) {
    lower_ = scaling_.to_scaled(problem.lower_bounds());
    upper_ = scaling_.to_scaled(problem.upper_bounds());
  }
}

ScaledProblem::Point ScaledProblem::evaluate(const Vector& x, Need need) {
  Point point;
  point.x = x;
  point.p = scaling_.to_physical(x);
  const Evaluation e = objective_.evaluate(point.p, need);
  if (!e.ok) {
    ++failed_evaluations_;
    point.message = e.message;
    return point;
  }
  point.ok = true;
  point.value = e.value;
  point.residuals = e.residuals;
  if (need != Need::Value) {
    const Vector dpdx = scaling_.first_derivative(x);
    point.gradient = e.gradient.cwiseProduct(dpdx);
    if (need >= Need::Jacobian) point.jacobian = e.jacobian * dpdx.asDiagonal();
    // Chain rule: d2J/dx2 = D (d2J/dp2) D + diag(dJ/dp * d2p/dx2), D = diag(dp/dx).
    if (need == Need::Hessian)
      point.hessian = dpdx.asDiagonal() * e.hessian * dpdx.asDiagonal() +
                      Matrix(e.gradient.cwiseProduct(scaling_.second_derivative(x)).asDiagonal());
  }
  return point;
}

Vector ScaledProblem::project(const Vector& x) const { return x.cwiseMax(lower_).cwiseMin(upper_); }

Vector ScaledProblem::projected_gradient(const Point& point) const {
  return project(point.x - point.gradient) - point.x;
}

std::vector<bool> ScaledProblem::active_set(const Point& point) const {
  // A variable within epsilon of a bound with the gradient pushing it outward is held there;
  // epsilon shrinks with the projected gradient so that the set settles near the solution.
  const double epsilon = std::min(1e-3, projected_gradient(point).norm());
  std::vector<bool> active(point.x.size(), false);
  for (int j = 0; j < point.x.size(); ++j)
    active[j] = (point.x[j] <= lower_[j] + epsilon && point.gradient[j] > 0) ||
                (point.x[j] >= upper_[j] - epsilon && point.gradient[j] < 0);
  return active;
}

Vector ScaledProblem::regularization_hessian(const Vector& x) const {
  const double alpha = objective_.options().regularization;
  if (alpha == 0) return Vector::Zero(x.size());
  const Vector p = scaling_.to_physical(x);
  const ParameterScaling& r = objective_.regularization_scaling();
  // d x_r / d x = (dp/dx) / (dp/dx_r).
  const Vector ratio = scaling_.first_derivative(x).cwiseQuotient(r.first_derivative(r.to_scaled(p)));
  return alpha * ratio.cwiseAbs2();
}

ScaledProblem::Point ScaledProblem::line_search(const Point& from, const Vector& direction, Need need,
                                                double initial_step) {
  double step = initial_step;
  std::string last_failure;
  for (int k = 0; k < options_.max_line_search_steps; ++k, step *= 0.5) {
    const Vector x = project(from.x + step * direction);
    const Vector change = x - from.x;
    if (change.norm() == 0) break;
    // First-order derivatives come with the value (the first trial is usually accepted and an
    // adjoint costs less than a second forward solve); sensitivities and Hessians are only
    // worth computing at the accepted point, by the caller.
    Point trial = evaluate(x, need >= Need::Jacobian ? Need::Value : need);
    if (!trial.ok) {
      last_failure = trial.message;  // e.g. an indefinite K: treat as +infinity and backtrack
      continue;
    }
    if (trial.value <= from.value + options_.armijo * from.gradient.dot(change)) return trial;
  }
  Point failed;
  failed.message = "no decrease along the search direction after " +
                   std::to_string(options_.max_line_search_steps) + " backtracking steps" +
                   (last_failure.empty() ? "" : " (last failure: " + last_failure + ")");
  return failed;
}

}  // namespace modalcal::detail
