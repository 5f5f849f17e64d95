#include "modalcal/gradient_check.hpp"

#include <cmath>
#include <cstdio>

namespace modalcal {

GradientCheck check_gradient(Objective& objective, const Vector& p, const GradientCheckOptions& options) {
  objective.require_parameters(p, "check_gradient");
  GradientCheck check;
  const Evaluation base = objective.evaluate(p, Need::Gradient);
  if (!base.ok) {
    check.report = "evaluation at p failed: " + base.message + "\n";
    return check;
  }
  const int n = static_cast<int>(p.size());
  check.analytic = base.gradient;
  check.finite_difference.resize(n);
  check.relative_error.resize(n);
  const double floor = 1e-8 * check.analytic.cwiseAbs().maxCoeff();
  check.ok = true;
  char line[256];
  std::snprintf(line, sizeof line, "%-16s %14s %14s %14s %10s\n", "parameter", "value", "adjoint", "central FD",
                "rel. error");
  check.report = line;
  for (int j = 0; j < n; ++j) {
    const double h = options.relative_step * std::max(std::abs(p[j]), 1e-300);
    Vector plus = p, minus = p;
    plus[j] += h;
    minus[j] -= h;
    const Evaluation ep = objective.evaluate(plus), em = objective.evaluate(minus);
    if (!ep.ok || !em.ok) {
      check.ok = false;
      check.report += objective.problem().parameters[j].name + ": evaluation failed: " + (ep.ok ? em.message : ep.message) + "\n";
      check.finite_difference[j] = check.relative_error[j] = NAN;
      continue;
    }
    check.finite_difference[j] = (ep.value - em.value) / (2 * h);
    const double scale = std::max({std::abs(check.analytic[j]), std::abs(check.finite_difference[j]), floor});
    check.relative_error[j] = scale > 0 ? std::abs(check.analytic[j] - check.finite_difference[j]) / scale : 0.0;
    check.max_relative_error = std::max(check.max_relative_error, check.relative_error[j]);
    check.ok = check.ok && check.relative_error[j] <= options.tolerance;
    std::snprintf(line, sizeof line, "%-16s %14.6e %14.6e %14.6e %10.2e\n",
                  objective.problem().parameters[j].name.c_str(), p[j], check.analytic[j],
                  check.finite_difference[j], check.relative_error[j]);
    check.report += line;
  }
  std::snprintf(line, sizeof line, "maximum relative error: %.3e (%s)\n", check.max_relative_error,
                check.ok ? "passed" : "FAILED");
  check.report += line;
  return check;
}

}  // namespace modalcal
