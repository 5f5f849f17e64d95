// The uncertainty of a calibrated point: Laplace (sandwich) intervals and profile intervals
// (formulas in uncertainty.hpp).
#include "modalcal/uncertainty.hpp"
#include "support/text_util.hpp"

#include <Eigen/Eigenvalues>
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <limits>
#include <stdexcept>

#include "modalcal/effects.hpp"
#include "modalcal/objective.hpp"
#include "modalcal/residual_test.hpp"

namespace modalcal {

namespace {

constexpr double kInfinity = std::numeric_limits<double>::infinity();

bool has_noise(const Problem& problem) { return problem.measurement_noise && problem.measurement_noise->frequency > 0; }

/// The residuals and their Jacobian in the optimizer's variables at p.
struct Linearization {
  Vector residuals;
  Matrix jacobian;  // d residuals / dx
  int data = 0;     // count_data() of the evaluation
};

Linearization linearize(const Problem& problem, const Vector& p, const ParameterScaling& scaling) {
  Objective objective(problem);
  const Evaluation e = objective.evaluate(p, Need::Jacobian);
  if (!e.ok) throw std::runtime_error("estimate_uncertainty: the model cannot be evaluated at the calibrated point: " + e.message);
  return {e.residuals, e.jacobian * scaling.first_derivative(scaling.to_scaled(p)).asDiagonal(),
          count_data(problem, e)};
}

/// Each residual's variance under the stated noise, from the ratio of the noise-weighted rows to
/// the objective's: the two problems differ only in the weights of whole terms.
Vector residual_variances(const Linearization& own, const Linearization& weighted) {
  Vector variance = Vector::Ones(own.residuals.size());
  for (Eigen::Index k = 0; k < variance.size(); ++k) {
    const double own_norm = own.jacobian.row(k).norm(), weighted_norm = weighted.jacobian.row(k).norm();
    double ratio = 0;  // sqrt(noise weight / own weight)
    if (own_norm > 0) ratio = weighted_norm / own_norm;
    else if (own.residuals[k] != 0) ratio = std::abs(weighted.residuals[k] / own.residuals[k]);
    variance[k] = ratio > 0 ? 1 / (ratio * ratio) : 0;
  }
  return variance;
}

/// C = A^+ B A^+ with A = J^T J, B = J^T diag(variance) J; a parameter with a part in a direction
/// A does not see gets an infinite variance.
Matrix sandwich_covariance(const Matrix& J, const Vector& variance) {
  const Matrix A = J.transpose() * J;
  const Matrix B = J.transpose() * variance.asDiagonal() * J;
  Eigen::SelfAdjointEigenSolver<Matrix> eigen(A);
  const Vector& values = eigen.eigenvalues();
  const Matrix& V = eigen.eigenvectors();
  const double largest = values.size() ? values.maxCoeff() : 0;
  Vector inverse = Vector::Zero(values.size());
  std::vector<bool> blind(values.size(), false);
  for (Eigen::Index k = 0; k < values.size(); ++k) {
    if (values[k] > 1e-12 * largest && values[k] > 0) inverse[k] = 1 / values[k];
    else blind[k] = true;
  }
  const Matrix A_plus = V * inverse.asDiagonal() * V.transpose();
  Matrix C = A_plus * B * A_plus;
  for (Eigen::Index j = 0; j < C.rows(); ++j)
    for (Eigen::Index k = 0; k < values.size(); ++k)
      if (blind[k] && V(j, k) * V(j, k) > 1e-8) C(j, j) = kInfinity;
  return C;
}

Matrix correlation_of(const Matrix& C) {
  Matrix R(C.rows(), C.cols());
  for (Eigen::Index i = 0; i < C.rows(); ++i)
    for (Eigen::Index j = 0; j < C.cols(); ++j) {
      const double d = std::sqrt(C(i, i) * C(j, j));
      R(i, j) = std::isfinite(d) && d > 0 ? C(i, j) / d : (i == j ? 1.0 : NAN);
    }
  return R;
}

/// The likelihood the profiles follow: its problem (noise-weighted, or the objective's own) and
/// the factor that turns |r|^2 into a chi-square.
struct Likelihood {
  Problem problem;
  double factor = 1;
};

/// The covariance of the calibrated point in the optimizer's variables (the sandwich of
/// uncertainty.hpp), with what `u` records of it (data, statistic, noise, note), and the
/// likelihood the profiles follow.
Matrix laplace_covariance(const Problem& problem, const Vector& p, const ParameterScaling& scaling, Uncertainty* u,
                          Likelihood* likelihood) {
  const int np = static_cast<int>(problem.parameters.size());
  u->noise_stated = has_noise(problem);
  const Linearization own = linearize(problem, p, scaling);
  u->num_data = own.data;
  if (u->noise_stated) {
    likelihood->problem = noise_weighted(problem, *problem.measurement_noise);
    const Linearization weighted = linearize(likelihood->problem, p, scaling);
    u->statistic = weighted.residuals.squaredNorm();
    u->note = "noise as stated in the problem";
    if (weighted.residuals.size() != own.residuals.size())  // not the same rows: the Fisher information
      return sandwich_covariance(weighted.jacobian, Vector::Ones(weighted.residuals.size()));
    return sandwich_covariance(own.jacobian, residual_variances(own, weighted));
  }
  const int dof = u->num_data - np;
  if (dof <= 0) {
    u->sigma2 = kInfinity;
    likelihood->factor = 0;
    u->note = "no stated noise, and no more data (" + std::to_string(u->num_data) + ") than parameters (" +
              std::to_string(np) + "): the noise cannot be estimated, so nothing bounds the parameters; state the "
              "measurement noise (measured: noise:) to get intervals";
    Matrix C = Matrix::Constant(np, np, NAN);
    C.diagonal().setConstant(kInfinity);
    return C;
  }
  u->sigma2 = own.residuals.squaredNorm() / dof;
  likelihood->factor = 1 / u->sigma2;
  u->statistic = likelihood->factor * own.residuals.squaredNorm();
  u->note = "no stated noise: one noise variance for every weighted residual, estimated from the residual (" +
            std::to_string(u->num_data) + " data, " + std::to_string(np) + " parameters)";
  return sandwich_covariance(own.jacobian, Vector::Constant(own.residuals.size(), u->sigma2));
}

/// `likelihood` with parameter j fixed at `value`: its targets set in the model, the parameter
/// removed.
Problem with_fixed(const Problem& problem, size_t j, double value) {
  Problem fixed = problem;
  for (PropertyId t : fixed.parameters[j].targets) fixed.model.properties[t].value = value;
  fixed.parameters.erase(fixed.parameters.begin() + static_cast<std::ptrdiff_t>(j));
  return fixed;
}

Vector without(const Vector& v, size_t j) {
  Vector out(v.size() - 1);
  const Eigen::Index J = static_cast<Eigen::Index>(j);
  out << v.head(J), v.tail(v.size() - J - 1);
  return out;
}

/// The chi-square of `problem` at `p` (NaN when it cannot be evaluated).
double chi_square(const Likelihood& l, const Problem& problem, const Vector& p) {
  Objective objective(problem);
  const Evaluation e = objective.evaluate(p, Need::Value);
  return e.ok ? l.factor * e.residuals.squaredNorm() : NAN;
}

/// The chi-square at the end of a recalibration of the likelihood: its misfit is |r|^2 / 2, so no
/// further evaluation is needed (NaN when it could not start).
double chi_square(const Likelihood& l, const ReducedSummary& fit, Eigen::Index size) {
  return fit.final.size() == size ? 2 * l.factor * fit.final_objective : NAN;
}

/// The rise of the likelihood above `minimum` with parameter j fixed at `value`, the others
/// recalibrated from `others` (updated to where they went); NaN when the model fails there.
double recalibrated_rise(const Likelihood& l, double minimum, size_t j, double value, Vector* others,
                         const UncertaintyOptions& options, ParameterUncertainty* pu) {
  const Problem fixed = with_fixed(l.problem, j, value);
  if (fixed.parameters.empty()) return chi_square(l, fixed, Vector(0)) - minimum;
  Objective objective(fixed);
  const ReducedSummary fit = minimize_reduced(objective, *others, options.recalibration);
  ++pu->profile_calibrations;
  if (fit.final.size() == others->size()) *others = fit.final;
  return chi_square(l, fit, others->size()) - minimum;
}

/// One side (`direction` ±1) of parameter j's profile from the calibrated point `best` (where
/// the likelihood is at its minimum `minimum`): the end point in p, and whether it is open.
/// Steps grow by 1.5 from `step` (in the optimizer's variable) until the rise reaches the
/// chi-square quantile; the crossing is then bisected until the rise across the bracket is at
/// most the quantile, and interpolated: a steep or jumping rise (a far step past where the others
/// can still compensate) must not put the end anywhere in a long step.
std::pair<double, bool> profile_side(const Likelihood& l, const Vector& best, double minimum, size_t j,
                                     double step, int direction, const UncertaintyOptions& options,
                                     ParameterUncertainty* pu) {
  const ParameterScaling scaling(l.problem.parameters);
  const Eigen::Index J = static_cast<Eigen::Index>(j);
  const Parameter& q = l.problem.parameters[j];
  const double x_end = scaling.to_scaled(direction > 0 ? l.problem.upper_bounds() : l.problem.lower_bounds())[J];
  const double quantile = chi_square_critical_value(1 - options.confidence, 1);
  Vector x = scaling.to_scaled(best);
  auto physical = [&](double xj) {
    x[J] = xj;
    return scaling.to_physical(x)[J];
  };
  double x_prev = x[J], rise_prev = 0;
  Vector others = without(best, j);
  for (int k = 0; k < options.profile_steps; ++k, step *= 1.5) {
    double x_try = x_prev + direction * step;
    const bool at_end = direction > 0 ? x_try >= x_end : x_try <= x_end;
    if (at_end) x_try = x_end;
    const double value = physical(x_try);
    Vector others_try = others;
    const double rise = recalibrated_rise(l, minimum, j, value, &others_try, options, pu);
    if (!std::isfinite(rise)) break;  // the model fails here: end the profile where it still held
    pu->profile_points.emplace_back(value, rise);
    if (rise >= quantile) {
      double a = x_prev, ra = rise_prev, b = x_try, rb = rise;
      for (int bisection = 0; bisection < 10 && rb - ra > quantile; ++bisection) {
        const double mid = 0.5 * (a + b);
        Vector others_mid = others;
        const double rise_mid = recalibrated_rise(l, minimum, j, physical(mid), &others_mid, options, pu);
        if (std::isfinite(rise_mid)) pu->profile_points.emplace_back(physical(mid), rise_mid);
        if (std::isfinite(rise_mid) && rise_mid < quantile) {
          a = mid;
          ra = std::max(0.0, rise_mid);
          others = others_mid;
        } else {
          b = mid;
          rb = std::isfinite(rise_mid) ? rise_mid : INFINITY;
        }
      }
      const double t = std::isfinite(rb) ? (quantile - ra) / (rb - ra) : 0.5;
      return {physical(a + t * (b - a)), false};
    }
    if (at_end) return {direction > 0 ? q.upper : q.lower, true};
    x_prev = x_try;
    rise_prev = std::max(0.0, rise);
    others = others_try;
  }
  return {physical(x_prev), true};
}

std::string format_value(double v) {
  char b[32];
  std::snprintf(b, sizeof b, "%.4g", v);
  return b;
}

}  // namespace

// The same fits as the effect ranking's refits: a chi-square misfit, recalibrated from nearby.
ReducedOptions UncertaintyOptions::default_recalibration_options() {
  ReducedOptions options = RankingOptions::default_refit_options();
  // A profile's interval ends where the chi-square has risen by a few units (3.84 at 95 %), so
  // its recalibrations keep 1e-5 (a change below about 0.01), not the refits' 1e-3, which may
  // leave a few tenths and move the ends.
  options.function_tolerance = 1e-5;
  return options;
}

bool UncertaintyOptions::IsValid(std::string* error) const {
  auto bad = [&](const std::string& message) {
    if (error) *error = message;
    return false;
  };
  if (!(confidence > 0 && confidence < 1)) return bad("confidence = " + format_value(confidence) + ": must be in (0, 1)");
  if (!(profile_half_width > 0)) return bad("profile_half_width = " + format_value(profile_half_width) + ": must be > 0");
  if (profile_steps < 1 || profile_steps > 1000)
    return bad("profile_steps = " + detail::option_text(profile_steps) + ": must be in [1, 1000]");
  std::string inner;
  if (!recalibration.IsValid(&inner)) return bad("recalibration." + inner);
  return true;
}

Uncertainty estimate_uncertainty(const Problem& problem, const Vector& p, const UncertaintyOptions& options) {
  std::string error;
  if (!options.IsValid(&error)) throw std::invalid_argument("UncertaintyOptions: " + error);
  const size_t np = problem.parameters.size();
  if (p.size() != static_cast<Eigen::Index>(np))
    throw std::invalid_argument("estimate_uncertainty: " + std::to_string(p.size()) + " values for " +
                                std::to_string(np) + " parameters");
  Uncertainty u;
  u.confidence = options.confidence;
  Likelihood likelihood{problem, 1};
  const ParameterScaling scaling(problem.parameters);
  const Matrix C = laplace_covariance(problem, p, scaling, &u, &likelihood);
  u.correlation = correlation_of(C);
  const double z = std::sqrt(chi_square_critical_value(1 - options.confidence, 1));
  const Vector x = scaling.to_scaled(p), dp_dx = scaling.first_derivative(x);
  std::vector<size_t> to_profile;
  for (size_t j = 0; j < np; ++j) {
    const Eigen::Index J = static_cast<Eigen::Index>(j);
    const Parameter& q = problem.parameters[j];
    ParameterUncertainty pu;
    pu.name = q.name;
    pu.value = p[J];
    pu.scaled_standard_error = std::sqrt(C(J, J));
    pu.standard_error = std::abs(dp_dx[J]) * pu.scaled_standard_error;
    Vector lo = x, hi = x;
    lo[J] -= z * pu.scaled_standard_error;
    hi[J] += z * pu.scaled_standard_error;
    const double a = std::isfinite(lo[J]) ? scaling.to_physical(lo)[J] : -kInfinity;
    const double b = std::isfinite(hi[J]) ? scaling.to_physical(hi)[J] : kInfinity;
    pu.lower = std::max(std::min(a, b), q.lower);
    pu.upper = std::min(std::max(a, b), q.upper);
    pu.at_bound = std::min(a, b) < q.lower || std::max(a, b) > q.upper;
    if (pu.at_bound || !(z * pu.scaled_standard_error <= options.profile_half_width)) to_profile.push_back(j);
    u.parameters.push_back(pu);
  }
  if (!options.profiles || to_profile.empty() || !(likelihood.factor > 0)) {
    u.likelihood_minimum = u.statistic;
    return u;
  }
  // The profiles' reference is the likelihood's own minimum, which the calibration (with the
  // objective's weights) need not have reached.
  Vector best = p;
  {
    Objective objective(likelihood.problem);
    const ReducedSummary fit = minimize_reduced(objective, p, options.recalibration);
    const double at_fit = chi_square(likelihood, fit, p.size());
    u.likelihood_minimum = u.statistic;
    if (at_fit < u.statistic) {
      u.likelihood_minimum = at_fit;
      best = fit.final;
    }
  }
  for (size_t j : to_profile) {
    ParameterUncertainty& pu = u.parameters[j];
    const double step = std::clamp(std::isfinite(pu.scaled_standard_error) ? pu.scaled_standard_error : 0.25, 0.02, 0.25);
    pu.profile_points.emplace_back(best[static_cast<Eigen::Index>(j)], 0.0);
    const auto [low, open_low] = profile_side(likelihood, best, u.likelihood_minimum, j, step, -1, options, &pu);
    const auto [high, open_high] = profile_side(likelihood, best, u.likelihood_minimum, j, step, +1, options, &pu);
    std::sort(pu.profile_points.begin(), pu.profile_points.end());
    pu.profile = {low, high};
    pu.profile_open_below = open_low;
    pu.profile_open_above = open_high;
  }
  return u;
}

std::string Uncertainty::BriefReport() const {
  std::string text;
  char line[240];
  for (const ParameterUncertainty& pu : parameters) {
    std::snprintf(line, sizeof line, "%s = %.4g +/- %.3g, %.0f %% interval [%.4g, %.4g]%s\n", pu.name.c_str(), pu.value,
                  pu.standard_error, 100 * confidence, pu.lower, pu.upper, pu.at_bound ? " (clipped to the bounds)" : "");
    text += line;
  }
  return text;
}

std::string Uncertainty::FullReport() const {
  char line[320];
  std::snprintf(line, sizeof line, "parameter uncertainty (%.0f %%; %s):\n", 100 * confidence, note.c_str());
  std::string text = line;
  std::snprintf(line, sizeof line, "%-16s %12s %12s %12s %12s   %s\n", "parameter", "value", "std. error", "lower",
                "upper", "profile interval");
  text += line;
  for (const ParameterUncertainty& pu : parameters) {
    std::string profile = "-";
    if (pu.profile)
      profile = (pu.profile_open_below ? "open below " : "[") + format_value(pu.profile->first) + ", " +
                format_value(pu.profile->second) + (pu.profile_open_above ? " open above" : "]");
    std::snprintf(line, sizeof line, "%-16s %12.4g %12.3g %12.4g %12.4g%s %s\n", pu.name.c_str(), pu.value,
                  pu.standard_error, pu.lower, pu.upper, pu.at_bound ? "*" : " ", profile.c_str());
    text += line;
  }
  text += "(lower, upper: the Laplace interval, * where clipped to the bounds; profile interval where that interval "
          "cannot be trusted: a side is open when the misfit never rises enough before the bound)\n";
  if (parameters.size() > 1) {
    text += "correlation:\n";
    for (Eigen::Index i = 0; i < correlation.rows(); ++i) {
      std::snprintf(line, sizeof line, "  %-16s", parameters[static_cast<size_t>(i)].name.c_str());
      text += line;
      for (Eigen::Index j = 0; j < correlation.cols(); ++j) {
        std::snprintf(line, sizeof line, " %6.2f", correlation(i, j));
        text += line;
      }
      text += "\n";
    }
  }
  return text;
}

}  // namespace modalcal
