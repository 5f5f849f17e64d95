#pragma once
/// \file residual_test.hpp
/// Is the misfit left after calibration physics or noise? A chi-square test of the residual
/// against the stated measurement noise, overall and per mode.
///
/// Noise model (the one `fullspace_calib synth` draws from): a measured frequency is
/// \f$f_m = f\,(1 + \sigma_f z)\f$ and each sensor value of a measured shape is
/// \f$\phi_{m,k} = \phi_k + \sigma_s \max_k|\phi_{m,k}|\, z_k\f$, with independent standard normal z.
/// If the model is right and calibrated, the noise-normalized residual
/// \f[ X^2 = \sum_i \Big(\frac{f_i - f_{m,i}}{\sigma_f f_{m,i}}\Big)^2
///        + \sum_i \frac{\|\phi_{m,i} - \psi_i\|^2}{(\sigma_s \max_k|\psi_{i,k}|)^2},
///   \qquad \psi_i = \frac{y_i^T \phi_{m,i}}{y_i^T y_i}\, y_i \f]
/// is \f$\chi^2\f$ with \f$\nu = \sum_i (1 + (s_i - 1)) - n_p\f$ degrees of freedom (one per frequency,
/// s − 1 per shape of s sensor values since its scale is fitted, minus the calibrated parameters).
/// \f$\psi_i\f$ is the best multiple of the paired model mode's sensor readings \f$y_i\f$, so
/// \f$\|\phi_m - \psi\|^2 = \|\phi_m\|^2(1-\mathrm{MAC})\f$; the noise scale is taken from it and not
/// from the measured shape, whose largest entry is biased upward by the noise itself. A large \f$X^2\f$ (p-value below the significance level) says the model
/// cannot reach the data within its noise: a model-form error is likely. Each mode is also tested
/// alone (Bonferroni: level / number of modes) to say which modes carry it.
///
/// \code
/// modalcal::Objective objective(problem);
/// modalcal::Evaluation e = objective.evaluate(calibrated_p);
/// modalcal::ResidualTest t = modalcal::test_residual(objective, e, {0.002, 0.02}, calibrated_p.size());
/// std::cout << t.verdict;
/// \endcode

#include <string>
#include <vector>

#include "modalcal/export.hpp"
#include "modalcal/objective.hpp"
#include "modalcal/problem.hpp"

namespace modalcal {

struct MODALCAL_EXPORT ResidualTestOptions {
  /// Significance level of the overall test; a mode is flagged at level / number of modes.
  /// Range: (0, 0.5). Default 0.01.
  double significance = 0.01;
  bool IsValid(std::string* error) const;
};

/// One measured mode's share of the residual.
struct MODALCAL_EXPORT ModeResidual {
  int measured = 0;          ///< 0-based index into Problem::measured
  std::string label;
  int model = 0;             ///< 0-based elastic model mode it was paired with
  double frequency_error = 0;  ///< (f - f_m) / f_m
  double frequency_chi2 = 0;   ///< its noise-normalized square (0 if the eigenvalue term is off)
  double shape_chi2 = 0;       ///< 0 without a measured shape or with the shape term off
  int dof = 0;                 ///< 1 for the frequency, s - 1 for a shape of s values
  double p_value = 1;          ///< of this mode's chi-square alone
  bool flagged = false;        ///< p_value < significance / number of tested modes
};

struct MODALCAL_EXPORT ResidualTest {
  double statistic = 0;      ///< X^2
  int dof = 0;               ///< nu (at least 1)
  /// P(chi2_nu > X^2); NaN when there are no more data than calibrated parameters: the
  /// calibration can then meet any data, nothing is tested, and model_form_error is false.
  double p_value = 1;
  /// X^2 / nu: about 1 when the residual is noise.
  double reduced_chi2 = 0;
  bool model_form_error = false;  ///< p_value < significance
  std::vector<ModeResidual> modes;
  std::string verdict;       ///< one plain sentence or two, naming the modes that carry the misfit
};

/// Tests the residual of `evaluation` (`objective` evaluated at the calibrated parameters)
/// against `noise`. `num_parameters` calibrated parameters are subtracted from the degrees of
/// freedom; shapes are tested only when noise.shape > 0.
/// \throws std::invalid_argument if noise.frequency is not positive, the evaluation failed, or
///         the options are invalid.
MODALCAL_EXPORT ResidualTest test_residual(const Objective& objective, const Evaluation& evaluation,
                                           const MeasurementNoise& noise, int num_parameters,
                                           const ResidualTestOptions& options = {});

/// Without a stated noise, the misfit a fit at the data's resolution leaves per datum: 2J over
/// count_data() when every frequency is off by `resolution` (relative; its eigenvalue by twice
/// that) and every MAC short of 1 by it, under the problem's own weights:
/// \f$\big(\sum_i \beta_i (2\epsilon)^2 + \sum_i \kappa_i \epsilon\big) / n\f$. A diagnosis's F test
/// takes no noise variance below it (RankingOptions::resolution).
/// \throws std::invalid_argument unless resolution > 0.
MODALCAL_EXPORT double resolution_variance(const Problem& problem, double resolution);

/// The number of data n the residual holds: one per weighted frequency, s − 1 per weighted shape
/// of s values (a shape's scale is not a datum).
MODALCAL_EXPORT int count_data(const Problem& problem, const Evaluation& evaluation);

/// A copy of `problem` whose objective weights make twice its misfit the statistic \f$X^2\f$ above
/// (to first order), so that calibrating it is a maximum-likelihood fit under `noise`, as the
/// likelihood-ratio tests of the effect ranking (effects.hpp) assume:
/// \f$\beta_i = 1/(4\sigma_f^2)\f$ for a frequency, since
/// \f$(\lambda - \lambda_m)/\lambda_m \approx 2(f - f_m)/f_m\f$, and
/// \f$\kappa_i = \|\phi_{m,i}\|^2/(\sigma_s \max_k|\phi_{m,i,k}|)^2\f$ for a shape, since
/// \f$\|e_i\|^2 = 1 - \mathrm{MAC}\f$ (the measured shape's largest entry stands in for the fitted
/// one's). Terms switched off (weight 0) stay off; shape weights are kept when noise.shape is 0.
/// \throws std::invalid_argument if noise.frequency is not positive or noise is invalid.
MODALCAL_EXPORT Problem noise_weighted(const Problem& problem, const MeasurementNoise& noise);

/// The critical value c with \f$P(\chi^2_\nu > c) = \alpha\f$ (bisection on
/// chi_square_upper_tail). Range: nu >= 1, alpha in (0, 1).
MODALCAL_EXPORT double chi_square_critical_value(double alpha, int nu);

/// Upper tail of the chi-square distribution, \f$P(\chi^2_\nu > x) = Q(\nu/2, x/2)\f$ (regularized
/// upper incomplete gamma function). Range: nu >= 1, x >= 0.
MODALCAL_EXPORT double chi_square_upper_tail(double x, int nu);

/// Upper tail of the F distribution, \f$P(F_{\nu_1,\nu_2} > f) = I_{\nu_2/(\nu_2+\nu_1 f)}(\nu_2/2, \nu_1/2)\f$
/// (regularized incomplete beta function). The test of an effect's gain without a stated noise,
/// where the noise variance is estimated from \f$\nu_2\f$ degrees of freedom of residual.
/// Range: nu1, nu2 >= 1, f >= 0.
MODALCAL_EXPORT double f_upper_tail(double f, int nu1, int nu2);

/// The critical value c with \f$P(F_{\nu_1,\nu_2} > c) = \alpha\f$ (bisection on f_upper_tail); tends
/// to chi_square_critical_value(alpha, nu1) / nu1 as nu2 grows. Range: nu1, nu2 >= 1, alpha in (0, 1).
MODALCAL_EXPORT double f_critical_value(double alpha, int nu1, int nu2);

}  // namespace modalcal
