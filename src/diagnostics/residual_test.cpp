// The chi-square test of the calibrated residual against the stated noise (residual_test.hpp).

#include "modalcal/residual_test.hpp"
#include "support/text_util.hpp"

#include <algorithm>
#include <cmath>
#include <sstream>
#include <stdexcept>

#include "objective/shape_misfit.hpp"

namespace modalcal {

namespace {

/// ln Γ(a) for a > 0. Not std::lgamma: it also writes the global `signgam`, a data race when
/// refits in threads test their residuals at the same time; lgamma_r (POSIX) returns the sign.
double log_gamma(double a) {
  int sign = 0;
  return lgamma_r(a, &sign);
}

// Regularized lower incomplete gamma P(a, x) by its power series, for x < a + 1:
// P = e^{-x} x^a / Gamma(a + 1) * sum_n x^n / ((a + 1) ... (a + n)).
double lower_gamma_series(double a, double x) {
  double term = 1.0 / a, sum = term;
  for (int n = 1; n < 1000 && std::abs(term) > 1e-16 * std::abs(sum); ++n) {
    term *= x / (a + n);
    sum += term;
  }
  return std::exp(-x + a * std::log(x) - log_gamma(a)) * sum;
}

// Regularized upper incomplete gamma Q(a, x) by Legendre's continued fraction (modified Lentz),
// for x >= a + 1: Q = e^{-x} x^a / Gamma(a) / (x + 1 - a - 1(1 - a)/(x + 3 - a - 2(2 - a)/(...))).
double upper_gamma_fraction(double a, double x) {
  constexpr double tiny = 1e-300;
  double b = x + 1 - a, c = 1 / tiny, d = 1 / b, h = d;
  for (int n = 1; n < 1000; ++n) {
    const double an = -n * (n - a);
    b += 2;
    d = an * d + b;
    if (std::abs(d) < tiny) d = tiny;
    c = b + an / c;
    if (std::abs(c) < tiny) c = tiny;
    d = 1 / d;
    const double delta = d * c;
    h *= delta;
    if (std::abs(delta - 1) < 1e-16) break;
  }
  return std::exp(-x + a * std::log(x) - log_gamma(a)) * h;
}

// Regularized incomplete beta I_x(a, b) by its continued fraction (modified Lentz), which
// converges fast for x < (a + 1) / (a + b + 2); the other side by I_x(a, b) = 1 - I_{1-x}(b, a).
double incomplete_beta(double a, double b, double x) {
  if (x <= 0) return 0;
  if (x >= 1) return 1;
  if (x > (a + 1) / (a + b + 2)) return 1 - incomplete_beta(b, a, 1 - x);
  const double tiny = 1e-300;
  double c = 1, d = 1 - (a + b) * x / (a + 1);
  if (std::abs(d) < tiny) d = tiny;
  d = 1 / d;
  double h = d;
  for (int m = 1; m < 1000; ++m) {
    for (int half = 0; half < 2; ++half) {  // the even term, then the odd one
      const double num = half == 0 ? m * (b - m) * x / ((a + 2 * m - 1) * (a + 2 * m))
                                   : -(a + m) * (a + b + m) * x / ((a + 2 * m) * (a + 2 * m + 1));
      d = 1 + num * d;
      if (std::abs(d) < tiny) d = tiny;
      c = 1 + num / c;
      if (std::abs(c) < tiny) c = tiny;
      d = 1 / d;
      h *= d * c;
    }
    if (std::abs(d * c - 1) < 1e-16) break;
  }
  const double front = std::exp(log_gamma(a + b) - log_gamma(a) - log_gamma(b) + a * std::log(x) + b * std::log1p(-x));
  return front * h / a;
}

/// The x >= 0 where a decreasing upper tail falls to alpha, by bisection to 1e-12 relative, the
/// bracket grown from [0, hi] until it holds the point.
template <class Tail>
double upper_quantile(const Tail& tail, double alpha, double hi) {
  double lo = 0;
  while (tail(hi) > alpha) hi *= 2;
  for (int k = 0; k < 300 && hi - lo > 1e-12 * hi; ++k) {
    const double mid = 0.5 * (lo + hi);
    (tail(mid) > alpha ? lo : hi) = mid;
  }
  return 0.5 * (lo + hi);
}

std::string percent(double x) {
  std::ostringstream s;
  s.precision(3);
  s << 100 * x << " %";
  return s.str();
}

/// The relative variance of a measured frequency: the stated noise and the mode's allowance for
/// model error, independent.
double frequency_variance(const MeasurementNoise& noise, const MeasuredMode& mode) {
  return noise.frequency * noise.frequency + mode.model_error * mode.model_error;
}

}  // namespace

bool ResidualTestOptions::IsValid(std::string* error) const {
  if (!(significance > 0 && significance < 0.5)) {
    if (error) *error = "ResidualTestOptions::significance = " + detail::option_text(significance) + " must lie in (0, 0.5)";
    return false;
  }
  return true;
}

double chi_square_upper_tail(double x, int nu) {
  if (nu < 1) throw std::invalid_argument("chi_square_upper_tail: nu = " + std::to_string(nu) + " must be >= 1");
  if (!(x >= 0)) throw std::invalid_argument("chi_square_upper_tail: x must be >= 0 and not NaN");
  if (x == 0) return 1;
  const double a = 0.5 * nu, h = 0.5 * x;
  return h < a + 1 ? 1 - lower_gamma_series(a, h) : upper_gamma_fraction(a, h);
}

double chi_square_critical_value(double alpha, int nu) {
  if (nu < 1 || !(alpha > 0 && alpha < 1))
    throw std::invalid_argument("chi_square_critical_value: need nu >= 1 and alpha in (0, 1), got nu = " +
                                std::to_string(nu) + ", alpha = " + std::to_string(alpha));
  return upper_quantile([nu](double x) { return chi_square_upper_tail(x, nu); }, alpha, nu + 10.0);
}

double resolution_variance(const Problem& problem, double resolution) {
  if (!(resolution > 0)) throw std::invalid_argument("resolution_variance: resolution must be > 0");
  double two_j = 0;
  int data = 0;
  for (const MeasuredMode& m : problem.measured) {
    if (m.weight > 0) {
      two_j += m.weight * 4 * resolution * resolution;
      data += 1;
    }
    if (m.has_shape_term() && m.shape.size() > 1) {
      two_j += m.shape_weight * resolution;
      data += static_cast<int>(m.shape.size()) - 1;
    }
  }
  return two_j / std::max(1, data);
}

int count_data(const Problem& problem, const Evaluation& evaluation) {
  int data = 0;
  for (const PairedMode& pair : evaluation.pairs) {
    const MeasuredMode& measured = problem.measured[pair.measured];
    if (measured.weight > 0) data += 1;
    if (measured.has_shape_term() && measured.shape.size() > 1) data += static_cast<int>(measured.shape.size()) - 1;
  }
  return data;
}

Problem noise_weighted(const Problem& problem, const MeasurementNoise& noise) {
  std::string error;
  if (!noise.IsValid(&error)) throw std::invalid_argument("noise_weighted: " + error);
  if (!(noise.frequency > 0))
    throw std::invalid_argument("noise_weighted: the frequency noise must be > 0 (state it under measured: noise:)");
  Problem weighted = problem;
  for (MeasuredMode& m : weighted.measured) {
    if (m.weight > 0) m.weight = 1 / (4 * frequency_variance(noise, m));
    if (m.has_shape_term() && noise.shape > 0) {
      const double sigma = noise.shape * m.shape.cwiseAbs().maxCoeff();
      m.shape_weight = m.shape.squaredNorm() / (sigma * sigma);
    }
  }
  return weighted;
}

ResidualTest test_residual(const Objective& objective, const Evaluation& evaluation, const MeasurementNoise& noise,
                           int num_parameters, const ResidualTestOptions& options) {
  const Problem& problem = objective.problem();
  std::string error;
  if (!options.IsValid(&error)) throw std::invalid_argument(error);
  if (!evaluation.ok) throw std::invalid_argument("test_residual: the evaluation failed: " + evaluation.message);
  if (!(noise.frequency > 0))
    throw std::invalid_argument("test_residual: the frequency noise must be > 0 (state it under measured: noise:)");

  const SparseMatrix sensors = detail::sensor_matrix(problem, objective.system().dof_map());
  ResidualTest test;
  int dof = 0;
  for (const PairedMode& pair : evaluation.pairs) {
    const MeasuredMode& measured = problem.measured[pair.measured];
    ModeResidual m;
    m.measured = pair.measured;
    m.label = measured.label;
    m.model = pair.model;
    m.frequency_error = (pair.model_hz - pair.measured_hz) / pair.measured_hz;
    if (measured.weight > 0) {
      m.frequency_chi2 = m.frequency_error * m.frequency_error / frequency_variance(noise, measured);
      m.dof += 1;
    }
    const bool shape_tested = measured.has_shape_term() && measured.shape.size() > 1 && noise.shape > 0 && pair.mac >= 0;
    if (shape_tested) {
      const Vector y = sensors * evaluation.modal.modes.col(pair.model);
      const Vector fitted = (y.dot(measured.shape) / y.squaredNorm()) * y;
      const double sigma = noise.shape * fitted.cwiseAbs().maxCoeff();
      m.shape_chi2 = (measured.shape - fitted).squaredNorm() / (sigma * sigma);
      m.dof += static_cast<int>(measured.shape.size()) - 1;
    }
    if (m.dof == 0) continue;  // switched off: says nothing about the model
    dof += m.dof;
    test.statistic += m.frequency_chi2 + m.shape_chi2;
    m.p_value = chi_square_upper_tail(m.frequency_chi2 + m.shape_chi2, m.dof);
    test.modes.push_back(m);
  }
  if (test.modes.empty()) throw std::invalid_argument("test_residual: every measured mode is switched off");

  test.dof = std::max(1, dof - num_parameters);
  test.reduced_chi2 = test.statistic / test.dof;
  if (dof <= num_parameters) {  // the calibration can meet any data: there is nothing to test
    test.p_value = NAN;
    std::ostringstream v;
    v.precision(3);
    v << "chi-square " << test.statistic << " on " << dof << " data for " << num_parameters
      << " parameters: the calibration can meet any data, so the residual cannot show a model-form error.";
    test.verdict = v.str();
    return test;
  }
  test.p_value = chi_square_upper_tail(test.statistic, test.dof);
  test.model_form_error = test.p_value < options.significance;
  const double mode_level = options.significance / static_cast<double>(test.modes.size());
  std::vector<std::string> carriers;
  for (ModeResidual& m : test.modes) {
    m.flagged = m.p_value < mode_level;
    if (m.flagged) carriers.push_back(m.label + " (" + percent(m.frequency_error) + " in frequency)");
  }

  std::ostringstream v;
  v.precision(3);
  v << "chi-square " << test.statistic << " on " << test.dof << " degrees of freedom (" << test.reduced_chi2
    << " per degree of freedom, p = " << test.p_value << "): ";
  if (test.model_form_error) {
    v << "the residual is larger than the stated noise (frequency " << percent(noise.frequency);
    if (noise.shape > 0) v << ", shape " << percent(noise.shape);
    v << ") can explain; a model-form error is likely.";
    if (!carriers.empty()) {
      v << " Modes carrying it:";
      for (size_t k = 0; k < carriers.size(); ++k) v << (k ? ", " : " ") << carriers[k];
      v << ".";
    }
  } else {
    v << "the residual is consistent with the stated noise; no model-form error is detected.";
  }
  test.verdict = v.str();
  return test;
}

double f_upper_tail(double f, int nu1, int nu2) {
  if (nu1 < 1 || nu2 < 1)
    throw std::invalid_argument("f_upper_tail: need nu1, nu2 >= 1, got " + std::to_string(nu1) + ", " + std::to_string(nu2));
  if (!(f >= 0)) throw std::invalid_argument("f_upper_tail: f must be >= 0 and not NaN");
  if (std::isinf(f)) return 0;
  return incomplete_beta(0.5 * nu2, 0.5 * nu1, nu2 / (nu2 + nu1 * f));
}

double f_critical_value(double alpha, int nu1, int nu2) {
  if (nu1 < 1 || nu2 < 1 || !(alpha > 0 && alpha < 1))
    throw std::invalid_argument("f_critical_value: need nu1, nu2 >= 1 and alpha in (0, 1), got nu1 = " +
                                std::to_string(nu1) + ", nu2 = " + std::to_string(nu2) + ", alpha = " + std::to_string(alpha));
  return upper_quantile([nu1, nu2](double f) { return f_upper_tail(f, nu1, nu2); }, alpha, 10.0);
}

}  // namespace modalcal
