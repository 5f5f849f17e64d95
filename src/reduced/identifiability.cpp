#include "modalcal/identifiability.hpp"

#include <Eigen/SVD>

#include <cstdio>
#include <stdexcept>

namespace modalcal {

Identifiability analyze_identifiability(Objective& objective, const Vector& p, const ParameterScaling& scaling,
                                        double relative_threshold) {
  objective.require_parameters(p, "analyze_identifiability");
  const Evaluation e = objective.evaluate(p, Need::Jacobian);
  if (!e.ok) throw std::runtime_error("identifiability: evaluation failed: " + e.message);
  const int n = static_cast<int>(p.size());
  const Matrix S = e.jacobian * scaling.first_derivative(scaling.to_scaled(p)).asDiagonal();
  Eigen::JacobiSVD<Matrix> svd(S, Eigen::ComputeFullV);
  Identifiability out;
  out.singular_values = Vector::Zero(n);
  out.singular_values.head(svd.singularValues().size()) = svd.singularValues();
  out.directions = svd.matrixV();
  out.poorly_identified.assign(n, false);
  out.weak_share = Vector::Zero(n);
  const double largest = out.singular_values.size() ? out.singular_values[0] : 0.0;
  const Problem& problem = objective.problem();
  char line[256];
  out.report = "scaled sensitivity S = dr/dx: singular values and directions (rows: parameters)\n";
  std::snprintf(line, sizeof line, "%-16s", "sigma_k / sigma_1");
  out.report += line;
  for (int k = 0; k < n; ++k) {
    std::snprintf(line, sizeof line, " %10.2e", largest > 0 ? out.singular_values[k] / largest : 0.0);
    out.report += line;
  }
  out.report += "\n";
  for (int j = 0; j < n; ++j) {
    std::snprintf(line, sizeof line, "%-16s", problem.parameters[j].name.c_str());
    out.report += line;
    for (int k = 0; k < n; ++k) {
      std::snprintf(line, sizeof line, " %10.3f", out.directions(j, k));
      out.report += line;
      if (out.singular_values[k] < relative_threshold * largest) out.weak_share[j] += out.directions(j, k) * out.directions(j, k);
    }
    out.poorly_identified[j] = out.weak_share[j] >= 0.5;
    out.report += "\n";
  }
  for (int j = 0; j < n; ++j)
    if (out.poorly_identified[j]) {
      std::snprintf(line, sizeof line,
                    "poorly identified: %s (%.0f %% of it lies along directions with sigma < %.0e sigma_1; "
                    "the data barely constrain it, more or different modes are needed)\n",
                    problem.parameters[j].name.c_str(), 100 * out.weak_share[j], relative_threshold);
      out.report += line;
    }
  return out;
}

}  // namespace modalcal
