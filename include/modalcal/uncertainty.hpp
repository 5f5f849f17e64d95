#pragma once
/// \file uncertainty.hpp
/// How well the measured data pin each calibrated parameter.
///
/// **Laplace intervals.** In the optimizer's variables x (log10 p for log-scaled parameters,
/// p / reference for linear ones) the calibrated x̂ minimizes \f$\tfrac12|r_w(x)|^2\f$, r_w the
/// objective's weighted residuals. Near x̂ the estimator's covariance is the sandwich
/// \f[ C = A^{-1} B A^{-1},\quad A = J_w^T J_w,\quad B = J_w^T\,\mathrm{Cov}(r_w)\,J_w, \f]
/// with \f$J_w = \partial r_w / \partial x\f$. With a stated noise (Problem::measurement_noise),
/// \f$\mathrm{Cov}(r_w)\f$ is diagonal: each residual's weight relative to the noise-weighted one
/// (noise_weighted() in residual_test.hpp), so that C is the inverse Fisher information
/// \f$(J_n^T J_n)^{-1}\f$ when the objective's weights are the noise's, and otherwise the covariance
/// of the weighted least-squares estimate the calibration actually made. Without a stated noise
/// the residuals are taken to share one variance, estimated as \f$\hat\sigma^2 = |r_w|^2/(n - n_p)\f$
/// (n data: one per frequency, s − 1 per shape of s values), and \f$C = \hat\sigma^2 A^{-1}\f$.
/// The interval is \f$\hat x_j \pm z\sqrt{C_{jj}}\f$ (z = 1.96 at 95 %) mapped back to p, so a
/// log-scaled parameter's interval is asymmetric; it is clipped to the bounds. The standard error
/// in p is \f$|dp/dx|\sqrt{C_{jj}}\f$ (delta method). A regularization term is not counted.
///
/// **Profile intervals.** Where the Laplace interval cannot be trusted — a direction the data
/// hardly see (an infinite or very wide interval), or an interval reaching a bound — the
/// parameter is profiled: fixed at values stepped away from x̂_j, the others recalibrated on the
/// likelihood (the noise-weighted misfit, or the objective's scaled by \f$1/\hat\sigma^2\f$), until
/// the misfit has risen by the \f$\chi^2_1\f$ quantile at the confidence (3.84 at 95 %). A side
/// where it never rises that far before the bound is *open*: the data say nothing there.
///
/// \code
/// modalcal::Objective objective(problem);
/// const modalcal::ReducedSummary fit = modalcal::minimize_reduced(objective, problem.initial_values());
/// const modalcal::Uncertainty u = modalcal::estimate_uncertainty(problem, fit.final);
/// std::cout << u.Report();
/// \endcode

#include <optional>
#include <string>
#include <vector>

#include "modalcal/export.hpp"
#include "modalcal/problem.hpp"
#include "modalcal/reduced.hpp"

namespace modalcal {

struct MODALCAL_EXPORT UncertaintyOptions {
  /// Confidence level of the intervals. Range: (0, 1).
  double confidence = 0.95;
  /// Profile the parameters whose Laplace interval cannot be trusted (see above).
  bool profiles = true;
  /// A Laplace interval is "very wide" above this half-width in the optimizer's variable (a
  /// factor 10^0.5 ≈ 3 either way for a log-scaled parameter). Range: > 0.
  double profile_half_width = 0.5;
  /// Fixed values tried per side of a profile at most (steps grow by half each time).
  /// Range: [1, 1000].
  int profile_steps = 16;
  /// The recalibrations along a profile and the likelihood's own minimum: Gauss-Newton with the
  /// diagnosis' refit tolerances (a misfit of the order of the number of data), but for the
  /// function tolerance, 1e-5: an interval's ends lie a few units of chi-square up.
  ReducedOptions recalibration = default_recalibration_options();
  /// Returns false and names the field, its value and the violated condition.
  bool IsValid(std::string* error) const;
  static ReducedOptions default_recalibration_options();
};

/// One parameter's uncertainty (physical units unless said).
struct MODALCAL_EXPORT ParameterUncertainty {
  std::string name;
  double value = 0;
  double standard_error = 0;         ///< delta method; +infinity when the data do not see it
  double scaled_standard_error = 0;  ///< \f$\sqrt{C_{jj}}\f$ in the optimizer's variable
  double lower = 0, upper = 0;       ///< the Laplace interval, clipped to the bounds
  bool at_bound = false;             ///< the Laplace interval was clipped
  /// The profile interval (profiled parameters only); an open side holds the bound.
  std::optional<std::pair<double, double>> profile;
  bool profile_open_below = false, profile_open_above = false;
  int profile_calibrations = 0;
  /// The profile's points (value, rise of the chi-square over its minimum), in increasing value,
  /// the fit's own point (rise 0 at the likelihood's minimum) included.
  std::vector<std::pair<double, double>> profile_points;
};

/// The uncertainty of a calibrated point: the summary of estimate_uncertainty().
struct MODALCAL_EXPORT Uncertainty {
  bool noise_stated = false;  ///< false: the noise was estimated from the residual
  double confidence = 0.95;
  int num_data = 0;
  double statistic = 0;  ///< \f$X^2\f$ at the calibrated point, or \f$|r_w|^2/\hat\sigma^2\f$ = n − n_p
  double sigma2 = 1;     ///< \f$\hat\sigma^2\f$ without a stated noise (1 with one)
  double likelihood_minimum = 0;  ///< the profiles' reference: the misfit's minimum over all parameters
  std::vector<ParameterUncertainty> parameters;
  Matrix correlation;  ///< of the scaled variables; NaN where a variance is infinite
  std::string note;    ///< e.g. how the noise was obtained
  /// One line per parameter: value, standard error, interval.
  std::string BriefReport() const;
  /// The table, the profile intervals, the correlation matrix and the note.
  std::string FullReport() const;
  std::string Report() const { return FullReport(); }
};

/// The uncertainty of `p`, a calibration of `problem` with its own objective weights.
/// \throws std::invalid_argument for invalid options or a wrong size; std::runtime_error if the
///   model cannot be evaluated at `p`.
MODALCAL_EXPORT Uncertainty estimate_uncertainty(const Problem& problem, const Vector& p,
                                                 const UncertaintyOptions& options = {});

}  // namespace modalcal
