// The model-form diagnosis loop and its before/after report (diagnosis.hpp).
#include "modalcal/diagnosis.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <stdexcept>

namespace modalcal {

namespace {

bool has_noise(const Problem& problem) { return problem.measurement_noise && problem.measurement_noise->frequency > 0; }

bool has_shapes(const Problem& problem) {
  for (const MeasuredMode& m : problem.measured)
    if (m.shape.size() > 0) return true;
  return false;
}

std::string mode_label(const Problem& problem, int measured) {
  const std::string& label = problem.measured[measured].label;
  return label.empty() ? "mode " + std::to_string(measured + 1) : label;
}

std::string verdict(const FitState& fit) {
  if (fit.test) return fit.test->verdict;
  char line[160];
  std::snprintf(line, sizeof line, "2J = %.4g (no stated noise: not tested against it)", fit.statistic);
  return line;
}

}  // namespace

FitState evaluate_fit(const Problem& problem, const Vector& p, const ResidualTestOptions& options) {
  if (p.size() != static_cast<int>(problem.parameters.size()))
    throw std::invalid_argument("evaluate_fit: " + std::to_string(p.size()) + " values for " +
                                std::to_string(problem.parameters.size()) + " parameters");
  Objective objective(problem);
  const Evaluation e = objective.evaluate(p);
  if (!e.ok) throw std::runtime_error("evaluate_fit: " + e.message);
  FitState fit;
  for (const Parameter& q : problem.parameters) fit.parameter_names.push_back(q.name);
  fit.parameters = p;
  fit.pairs = e.pairs;
  if (has_noise(problem)) {
    fit.test = test_residual(objective, e, *problem.measurement_noise, static_cast<int>(p.size()), options);
    fit.statistic = fit.test->statistic;
  } else {
    fit.statistic = e.residuals.squaredNorm();
  }
  return fit;
}

std::string format_before_after(const Problem& after_problem, const FitState& before, const FitState& after,
                                const std::string& before_title, const std::string& after_title) {
  std::string text;
  char line[320];
  std::snprintf(line, sizeof line, "%-14s %13s | %12s %9s %7s | %12s %9s %7s\n", "measured", "measured [Hz]",
                (before_title + " [Hz]").c_str(), "error %", "MAC", (after_title + " [Hz]").c_str(), "error %", "MAC");
  text += line;
  auto mac_text = [](double mac) {
    char b[16];
    if (mac < 0) return std::string("-");
    std::snprintf(b, sizeof b, "%.4f", mac);
    return std::string(b);
  };
  for (const PairedMode& a : after.pairs) {
    const auto b = std::find_if(before.pairs.begin(), before.pairs.end(),
                                [&](const PairedMode& x) { return x.measured == a.measured; });
    if (b == before.pairs.end()) continue;
    std::snprintf(line, sizeof line, "%-14s %13.3f | %12.3f %9.4f %7s | %12.3f %9.4f %7s\n",
                  mode_label(after_problem, a.measured).c_str(), a.measured_hz, b->model_hz,
                  100 * (b->model_hz / b->measured_hz - 1), mac_text(b->mac).c_str(), a.model_hz,
                  100 * (a.model_hz / a.measured_hz - 1), mac_text(a.mac).c_str());
    text += line;
  }
  text += "\n";
  std::snprintf(line, sizeof line, "%-24s %13s %13s\n", "parameter", before_title.c_str(), after_title.c_str());
  text += line;
  for (size_t j = 0; j < after.parameter_names.size(); ++j) {
    const std::string& name = after.parameter_names[j];
    const auto at = std::find(before.parameter_names.begin(), before.parameter_names.end(), name);
    char before_value[32] = "-";
    if (at != before.parameter_names.end())
      std::snprintf(before_value, sizeof before_value, "%.5g", before.parameters[at - before.parameter_names.begin()]);
    std::snprintf(line, sizeof line, "%-24s %13s %13.5g", name.c_str(), before_value, after.parameters[j]);
    text += line;
    if (at == before.parameter_names.end()) text += "  (added: " + describe_property(after_problem.model, name) + ")";
    text += "\n";
  }
  text += "\n" + before_title + ": " + verdict(before) + "\n" + after_title + ": " + verdict(after) + "\n";
  return text;
}

ReducedOptions DiagnosisOptions::default_calibration_options() {
  ReducedOptions options = RankingOptions::default_refit_options();
  options.method = ReducedOptions::Method::Lbfgs;
  return options;
}

bool DiagnosisOptions::IsValid(std::string* error) const {
  std::string inner;
  auto bad = [&](const std::string& field) {
    if (error) *error = field + "." + inner;
    return false;
  };
  if (!calibration.IsValid(&inner)) return bad("calibration");
  if (!test.IsValid(&inner)) return bad("test");
  if (!localization.IsValid(&inner)) return bad("localization");
  if (!candidates.IsValid(&inner)) return bad("candidates");
  if (!ranking.IsValid(&inner)) return bad("ranking");
  return true;
}

Diagnosis diagnose(const Problem& problem, const Vector& start, const DiagnosisOptions& options) {
  std::string error;
  if (!options.IsValid(&error)) throw std::invalid_argument("DiagnosisOptions: " + error);
  if (start.size() != static_cast<int>(problem.parameters.size()))
    throw std::invalid_argument("diagnose: " + std::to_string(start.size()) + " start values for " +
                                std::to_string(problem.parameters.size()) + " parameters");
  Diagnosis d;
  d.noise_known = has_noise(problem);
  const Problem fitted = d.noise_known ? noise_weighted(problem, *problem.measurement_noise) : problem;

  Objective objective(fitted, options.ranking.objective);
  d.calibration = minimize_reduced(objective, start, options.calibration);
  if (d.calibration.final.size() != start.size())
    throw std::runtime_error("diagnose: the calibration could not start: " + d.calibration.message);
  const Vector& calibrated = d.calibration.final;
  d.before = evaluate_fit(fitted, calibrated, options.test);

  if (!options.localize) {
    d.localization_note = "localization switched off";
  } else if (!has_shapes(problem)) {
    d.localization_note = "no measured shapes: nothing to localize";
  } else {
    try {
      d.localization = localize_model_error(problem, calibrated, options.localization);
    } catch (const std::invalid_argument& e) {
      d.localization_note = std::string("no localization: ") + e.what();
    }
  }

  d.candidates = generate_candidates(fitted, options.candidates);
  d.ranking = rank_effects(fitted, calibrated, d.candidates, options.ranking);

  const bool flagged = !d.before.test || d.before.test->model_form_error;
  const bool have_best = !d.ranking.effects.empty() && d.ranking.effects.front().refitted;
  if (!flagged) {
    d.recommendation =
        "No model-form error: the calibrated residual is consistent with the stated noise; nothing "
        "needs adding.";
  } else if (!have_best || !d.ranking.effects.front().significant) {
    d.recommendation =
        "No candidate effect explains the residual significantly: the missing physics is not among "
        "the " +
        std::to_string(d.ranking.screened) + " candidates (declare your own under effects: in the problem file).";
  } else {
    d.recommended = 0;
    const RankedEffect& best = d.ranking.effects.front();
    const Problem with = problem_with_effects(fitted, {best.candidate}, {best.value});
    d.after = evaluate_fit(with, best.parameters, options.test);
    char numbers[200];
    std::snprintf(numbers, sizeof numbers, " (%s %.4g -> %.4g)", d.noise_known ? "chi-square" : "2J",
                  d.ranking.chi2_before, best.chi2_after);
    d.recommendation = "Add " + best.candidate.name + ": " + best.summary() + numbers + ". ";
    if (!d.after->test)
      d.recommendation += "Without a stated noise it is not known whether anything else is missing.";
    else if (d.after->test->model_form_error)
      d.recommendation +=
          "The residual is still larger than the noise: diagnose again with it added "
          "(fullspace_calib calibrate --add " +
          best.candidate.name + ").";
    else
      d.recommendation += "With it the residual is consistent with the noise.";
  }
  return d;
}

std::string format_diagnosis(const Problem& problem, const Diagnosis& d) {
  std::string text;
  char line[320];
  std::snprintf(line, sizeof line, "calibration: %s after %d iterations, %d forward solves\n",
                to_string(d.calibration.termination).c_str(), d.calibration.iterations, d.calibration.forward_solves);
  text += line;
  for (size_t j = 0; j < problem.parameters.size(); ++j) {
    std::snprintf(line, sizeof line, "  %-20s %13.5g\n", problem.parameters[j].name.c_str(), d.calibration.final[j]);
    text += line;
  }
  text += "\nresidual test: " + verdict(d.before) + "\n";
  text += "\nwhere the model fails (residual forces of the expanded measured shapes):\n";
  text += d.localization ? format_ranking(*d.localization, 5) : d.localization_note + "\n";
  text += "\nwhich effect is missing:\n" + format_effect_ranking(d.ranking, 10);
  text += "\n" + d.recommendation + "\n";
  if (d.after) {
    const RankedEffect& best = d.ranking.effects[d.recommended];
    const Problem with = problem_with_effects(problem, {best.candidate}, {best.value});
    text += "\n" + format_before_after(with, d.before, *d.after, "nominal", "with effect");
  }
  return text;
}

int rank_of(const EffectRanking& ranking, const std::string& name) {
  for (size_t k = 0; k < ranking.effects.size(); ++k)
    if (ranking.effects[k].candidate.name == name) return static_cast<int>(k) + 1;
  return 0;
}

}  // namespace modalcal
