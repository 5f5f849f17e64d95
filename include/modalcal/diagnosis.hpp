#pragma once
/// \file diagnosis.hpp
/// The model-form diagnosis loop: calibrate, test the residual against the noise
/// (residual_test.hpp), localize it (localization.hpp), rank candidate effects (effects.hpp),
/// refit the best, and say what to add, with the residual before and after.
///
/// When the measured data state their noise, every fit here minimizes the chi-square
/// (noise_weighted()): the calibration is then a maximum-likelihood fit and the ranking's
/// likelihood-ratio tests hold. Without a stated noise the problem's own weights are used, the
/// residual test is skipped and significance comes from the refits' residuals.
///
/// \code
/// modalcal::Problem problem = modalcal::load_problem("problems/lfu-hidden/joint-rotation.yaml");
/// modalcal::Diagnosis d = modalcal::diagnose(problem, problem.initial_values());
/// std::cout << modalcal::format_diagnosis(problem, d);
/// if (d.recommended >= 0) std::cout << d.ranking.effects[d.recommended].summary();
/// \endcode

#include <optional>
#include <string>
#include <vector>

#include "modalcal/effects.hpp"
#include "modalcal/localization.hpp"
#include "modalcal/reduced.hpp"
#include "modalcal/residual_test.hpp"

namespace modalcal {

/// A calibrated state: parameter values and how the model then meets the measured modes.
struct FitState {
  std::vector<std::string> parameter_names;  ///< calibration parameters, then added effects
  Vector parameters;
  std::vector<PairedMode> pairs;  ///< measured and model modes, paired
  /// The residual test against the stated noise (absent without one).
  std::optional<ResidualTest> test;
  /// \f$X^2\f$ of the test, or 2J of the problem's objective without a stated noise.
  double statistic = 0;
};

/// Evaluates `problem` at `p` and tests its residual (with `p.size()` fitted parameters).
/// \throws std::runtime_error if the evaluation fails; std::invalid_argument for a wrong size.
FitState evaluate_fit(const Problem& problem, const Vector& p, const ResidualTestOptions& options = {});

/// Side by side, per measured mode: measured Hz, model Hz and error % before and after, MAC before
/// and after; then the parameters before and after (added effects with their words) and the
/// residual test's verdict before and after.
std::string format_before_after(const Problem& after_problem, const FitState& before, const FitState& after,
                                const std::string& before_title = "before", const std::string& after_title = "after");

struct DiagnosisOptions {
  /// The first calibration: reduced L-BFGS (the robust choice from a far start) with the refits'
  /// tolerances (RankingOptions::default_refit_options).
  ReducedOptions calibration = default_calibration_options();
  ResidualTestOptions test;
  bool localize = true;  ///< needs measured shapes; skipped (with a note) without
  LocalizationOptions localization;
  CandidateOptions candidates;
  RankingOptions ranking;
  /// Returns false and names the field, its value and the violated condition.
  bool IsValid(std::string* error) const;
  static ReducedOptions default_calibration_options();
};

struct Diagnosis {
  bool noise_known = false;
  ReducedSummary calibration;  ///< the nominal calibration
  FitState before;             ///< at its result
  std::optional<Localization> localization;
  std::string localization_note;  ///< why there is none, when there is none
  std::vector<EffectCandidate> candidates;
  EffectRanking ranking;
  /// Index into ranking.effects of the effect to add: the first, when the residual test flags a
  /// model-form error (or without noise) and its refit is significant; -1 otherwise.
  int recommended = -1;
  std::optional<FitState> after;  ///< with the recommended effect
  std::string recommendation;     ///< in words
};

/// Runs the loop on `problem` from the parameter values `start`.
/// \throws std::invalid_argument for invalid options or a start of the wrong size;
///   std::runtime_error if the start cannot be evaluated.
Diagnosis diagnose(const Problem& problem, const Vector& start, const DiagnosisOptions& options = {});

/// The report: calibration, residual test, localization (first rows), ranking, recommendation
/// and the before/after table of the recommended effect.
std::string format_diagnosis(const Problem& problem, const Diagnosis& diagnosis);

/// 1-based rank of the effect called `name` in `ranking`, 0 if it is not ranked.
int rank_of(const EffectRanking& ranking, const std::string& name);

}  // namespace modalcal
