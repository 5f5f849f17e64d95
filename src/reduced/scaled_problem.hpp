#pragma once
// Internal: the objective seen in scaled variables x with (optional) bounds, the projection onto
// the bounds, the projected gradient, and the projected backtracking line search shared by the
// reduced-space methods.

#include "modalcal/reduced.hpp"

namespace modalcal::detail {

class ScaledProblem {
 public:
  ScaledProblem(Objective& objective, const ReducedOptions& options);
  /// It keeps a reference to its options: a temporary would dangle.
  ScaledProblem(Objective& objective, ReducedOptions&& options) = delete;

  struct Point {
    bool ok = false;
    Vector x, p;
    double value = INFINITY;
    Vector gradient;    // d value / dx
    Matrix jacobian;    // d residuals / dx (Gauss-Newton)
    Matrix hessian;     // d2 value / dx2 (Newton)
    Vector residuals;
    std::string message;
  };
  Point evaluate(const Vector& x, Need need);
  Vector project(const Vector& x) const;
  /// P(x - g) - x: zero exactly at a first-order (KKT) point of the bound-constrained problem.
  Vector projected_gradient(const Point& point) const;
  /// Variables held at a bound by a gradient pushing outward.
  std::vector<bool> active_set(const Point& point) const;
  /// Projected backtracking (Armijo) along x(a) = P(x + a d); returns the accepted point, or
  /// one with ok = false and the reason if no step decreased the objective. The accepted point
  /// carries derivatives up to `need`, but never beyond the gradient.
  Point line_search(const Point& from, const Vector& direction, Need need, double initial_step);
  /// Gauss-Newton Hessian of the regularization term in x (diagonal).
  Vector regularization_hessian(const Vector& x) const;
  const ParameterScaling& scaling() const { return scaling_; }
  Objective& objective() { return objective_; }
  const Vector& lower() const { return lower_; }
  const Vector& upper() const { return upper_; }
  int failed_evaluations() const { return failed_evaluations_; }

 private:
  Objective& objective_;
  const ReducedOptions& options_;
  ParameterScaling scaling_;
  Vector lower_, upper_;
  int failed_evaluations_ = 0;
};

}  // namespace modalcal::detail
