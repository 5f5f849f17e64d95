// The model-form diagnosis loop and its before/after report (diagnosis.hpp).
#include "modalcal/diagnosis.hpp"
#include "support/text_util.hpp"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <deque>
#include <functional>
#include <future>
#include <limits>
#include <memory>
#include <stdexcept>
#include <system_error>
#include <utility>

#include "objective/shape_misfit.hpp"
#include "path_join.hpp"
#include "refit_walk.hpp"
#include "same_change.hpp"
#include "verdict_text.hpp"

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

namespace {

/// evaluate_fit() with `objective`, of `problem`: no solve when it has solved its model at p.
FitState fit_of(Objective& objective, const Problem& problem, const Vector& p, const ResidualTestOptions& options) {
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

}  // namespace

FitState evaluate_fit(const Problem& problem, const Vector& p, const ResidualTestOptions& options) {
  if (p.size() != static_cast<int>(problem.parameters.size()))
    throw std::invalid_argument("evaluate_fit: " + std::to_string(p.size()) + " values for " +
                                std::to_string(problem.parameters.size()) + " parameters");
  Objective objective(problem);
  return fit_of(objective, problem, p, options);
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
  // L-BFGS lowers J by less per iteration than Gauss-Newton does near its minimum, so the
  // refits' function tolerance would end it early: a change of the chi-square below about
  // 0.01 (1e-5 of it) means nothing, and it starts every refit.
  options.function_tolerance = 1e-5;
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
  if (max_steps < 0) {
    if (error) *error = "max_steps = " + detail::option_text(max_steps) + ": must be >= 0";
    return false;
  }
  if (first_step_alternatives < 0) {
    if (error) *error = "first_step_alternatives = " + detail::option_text(first_step_alternatives) + ": must be >= 0";
    return false;
  }
  if (pair_exchanges < 0 || pair_exchanges > 100) {
    if (error) *error = "pair_exchanges = " + detail::option_text(pair_exchanges) + ": must be in [0, 100]";
    return false;
  }
  if (!(other_data_margin >= 0)) {
    if (error) *error = "other_data_margin = " + detail::option_text(other_data_margin) + ": must be >= 0";
    return false;
  }
  if (calibration_starts < 0 || calibration_starts > 1000) {
    if (error) *error = "calibration_starts = " + detail::option_text(calibration_starts) + ": must be in [0, 1000]";
    return false;
  }
  return true;
}

namespace {

/// A model of the loop: the weighted problem with some effects as parameters after the problem's
/// own, and its objective (the ranking's options; its misfit is the ranking's too), which the
/// state's fit solved. The screen of that state starts from the same solve and then lets the
/// objective go, so that no factorization outlives its use: the loop keeps many states.
struct LoopModel {
  LoopModel(Problem with_effects, const ObjectiveOptions& options)
      : problem(std::move(with_effects)), objective(std::make_unique<Objective>(problem, options)) {}
  const Problem problem;
  std::unique_ptr<Objective> objective;  // refers to `problem`, declared before it
};

/// Where the loop stands: the model with the effects so far, their values, and the residual there.
struct LoopState {
  std::shared_ptr<LoopModel> model;
  std::vector<EffectCandidate> effects;
  Vector parameters;
  FitState fit;
  const Problem& problem() const { return model->problem; }
};

LoopState make_state(const Problem& fitted, const std::vector<EffectCandidate>& effects, const Vector& p,
                     const DiagnosisOptions& options) {
  const int np = static_cast<int>(fitted.parameters.size());
  std::vector<double> values(p.data() + np, p.data() + p.size());
  LoopState state{std::make_shared<LoopModel>(problem_with_effects(fitted, effects, values), options.ranking.objective),
                  effects, p, {}};
  state.fit = fit_of(*state.model->objective, state.problem(), p, options.test);
  return state;
}

/// Calibrates `fitted` with `effects` added, from `p` (the problem's parameters, then each
/// effect's value): the calibrated values, or nullopt when the calibration cannot start or the
/// effects do not apply (one sets a property of what another adds, a joint a step added, and the
/// backward pass or an exchange took that other out).
std::optional<Vector> calibrate_with(const Problem& fitted, const std::vector<EffectCandidate>& effects,
                                     const Vector& p, const DiagnosisOptions& options) {
  const int np = static_cast<int>(fitted.parameters.size());
  std::vector<double> values(p.data() + np, p.data() + p.size());
  Problem with;
  try {
    with = problem_with_effects(fitted, effects, values);
  } catch (const std::invalid_argument&) {
    return std::nullopt;
  }
  Objective objective(with, options.ranking.refit_objective());
  const ReducedSummary summary = detail::refit_walk(objective, p, options.ranking);
  if (summary.final.size() != p.size()) return std::nullopt;
  return summary.final;
}

/// The same, with the state after it (one more evaluation of the fit).
std::optional<LoopState> refit_with(const Problem& fitted, const std::vector<EffectCandidate>& effects,
                                    const Vector& p, const DiagnosisOptions& options) {
  const std::optional<Vector> calibrated = calibrate_with(fitted, effects, p, options);
  if (!calibrated) return std::nullopt;
  return make_state(fitted, effects, *calibrated, options);
}

/// The effects the model has from the start, with their first-order values at the calibration
/// (declared starts where given), calibrated with the parameters.
LoopState starting_state(const Problem& fitted, const std::vector<EffectCandidate>& effects, const Vector& calibrated,
                         const DiagnosisOptions& options) {
  if (effects.empty()) return make_state(fitted, {}, calibrated, options);
  RankingOptions screen = options.ranking;
  screen.refits = 0;
  const EffectRanking first_order = rank_effects(fitted, calibrated, effects, screen);
  Vector p(calibrated.size() + static_cast<Eigen::Index>(effects.size()));
  p.head(calibrated.size()) = calibrated;
  for (size_t k = 0; k < effects.size(); ++k) {
    const EffectCandidate& c = effects[k];
    double start = c.variable == EffectCandidate::Variable::Compliance ? c.upper : c.screen_value;
    for (const RankedEffect& r : first_order.effects)
      if (r.candidate.name == c.name && r.predicted_reduction > 0) start = r.predicted_value;
    p[calibrated.size() + static_cast<Eigen::Index>(k)] = std::clamp(c.initial.value_or(start), c.lower, c.upper);
  }
  std::optional<LoopState> state = refit_with(fitted, effects, p, options);
  if (!state) throw std::runtime_error("diagnose: the calibration with the problem's effects could not start");
  return *state;
}

void localize(const Problem& problem, const Vector& calibrated, const DiagnosisOptions& options, Diagnosis* d) {
  if (!options.localize) {
    d->localization_note = "localization switched off";
  } else if (!has_shapes(problem)) {
    d->localization_note = "no measured shapes: nothing to localize";
  } else {
    try {
      d->localization = localize_model_error(problem, calibrated, options.localization);
    } catch (const std::invalid_argument& e) {
      d->localization_note = std::string("no localization: ") + e.what();
    }
  }
}

bool consistent_with_noise(const FitState& fit) { return fit.test && !fit.test->model_form_error; }

/// Without a stated noise: every paired frequency within `resolution` (relative) of the measured
/// one and every MAC within it of 1. Such a fit cannot be told from exact agreement, so neither can
/// any effect's change to it.
bool at_resolution(const FitState& fit, double resolution) {
  if (fit.test) return false;
  for (const PairedMode& pair : fit.pairs) {
    if (!(std::abs(pair.model_hz - pair.measured_hz) <= resolution * pair.measured_hz)) return false;
    if (pair.mac >= 0 && !(1 - pair.mac <= resolution)) return false;
  }
  return true;
}

/// The ranking's effect to accept, or null: its best refit when that is significant and inside
/// its range (the ranking puts those first).
const RankedEffect* acceptable(const EffectRanking& ranking) {
  if (ranking.effects.empty() || !ranking.effects.front().acceptable()) return nullptr;
  return &ranking.effects.front();
}

/// The last step's significant refit that ended on a bound of its range, when that step accepted
/// nothing: the data still ask for a change, one no candidate makes within its range.
const RankedEffect* bound_limited(const Diagnosis& d) {
  if (d.rankings.empty() || d.rankings.back().effects.empty() || d.rankings.back().effects.front().acceptable())
    return nullptr;
  for (const RankedEffect& r : d.rankings.back().effects)
    if (r.refitted && r.significant && r.at_bound) return &r;
  return nullptr;
}

/// True when `other` is an acceptable refit whose likelihood-ratio statistic is within
/// DiagnosisStep::kAlternativeMargin of `best`'s or above it: the data alone hardly tell the two
/// apart (a likelihood ratio below about 20 : 1).
bool hardly_told_apart(const RankedEffect& other, const RankedEffect& best) {
  return other.acceptable() && other.statistic > best.statistic - DiagnosisStep::kAlternativeMargin;
}

/// Sets step->place_spread and places (DiagnosisStep) from `ranking`, whose effect `index` it
/// accepts.
void set_place_spread(const EffectRanking& ranking, const Model& model, size_t index, DiagnosisStep* step) {
  if (!step->location) return;
  const RankedEffect& best = ranking.effects[index];
  step->place_spread = 0;
  step->places = 1;
  for (size_t k = 0; k < ranking.effects.size(); ++k) {
    const RankedEffect& other = ranking.effects[k];
    if (k == index || !hardly_told_apart(other, best) || !detail::same_change(other.candidate, best.candidate))
      continue;
    const std::optional<Vec3> place = effect_location(model, other.candidate);
    if (!place) continue;
    step->place_spread = std::max(step->place_spread, (*place - *step->location).norm());
    ++step->places;
  }
}

/// The record of accepting `ranking`'s best effect (acceptable()) as step `number`: its test, its
/// place in `model` and the alternatives the data hardly tell from it.
DiagnosisStep step_accepting(const EffectRanking& ranking, const Model& model, int number, size_t index = 0) {
  const RankedEffect& best = ranking.effects[index];
  DiagnosisStep step;
  step.step = number;
  step.effect = best;
  step.chi2_before = ranking.chi2_before;
  step.screened = ranking.screened;
  step.critical_value = ranking.critical_value;
  step.location = effect_location(model, best.candidate);
  set_place_spread(ranking, model, index, &step);
  for (size_t k = 0; k < ranking.effects.size(); ++k) {
    const RankedEffect& other = ranking.effects[k];
    if (k == index) continue;
    // The data's verdict alone, without the prior over kinds: a likelihood ratio below 20 : 1,
    // or one in the other's favour that the prior overruled. Not the same effect a node or two
    // away (the neighbour refits), which says where, not what.
    if (hardly_told_apart(other, best) && !other.candidate.neighbour_of(best.candidate))
      step.alternatives.push_back(other);
  }
  return step;
}

/// How a further measurement would tell the step's effect from each alternative (with a stated
/// noise), on `fitted` with `effects` (at `values`), the model before the step. Advice only: when
/// even the accepted effect's model cannot be made or solved, every entry names no reading and no
/// mode.
void add_tell_apart(const Problem& fitted, const std::vector<EffectCandidate>& effects,
                    const std::vector<double>& values, DiagnosisStep* step) {
  if (!fitted.measurement_noise || step->alternatives.empty()) return;
  try {
    step->tell_apart = tell_apart(problem_with_effects(fitted, effects, values), step->effect, step->alternatives);
  } catch (const std::exception&) {
    for (const RankedEffect& alternative : step->alternatives) {
      TellApart none;
      none.alternative = alternative.candidate.name;
      step->tell_apart.push_back(none);
    }
  }
}

/// The names of `effects`, in order.
std::vector<std::string> names_of(const std::vector<EffectCandidate>& effects) {
  std::vector<std::string> names;
  for (const EffectCandidate& c : effects) names.push_back(c.name);
  return names;
}

/// The screens one diagnosis ran, by the state they screened. An exchange screens the model without
/// one effect, and without the last one taken that is the model the step before screened; another
/// path's exchange often screens a model the first path's steps did. A state with the same effects
/// in the same order at the same fit (detail::same_fit, as joins() judges paths)
/// gets that screen again: a new screen there would repeat it to within the refits' tolerance.
class ScreenMemo {
 public:
  ScreenMemo() = default;
  /// A memo that also finds the screens of `earlier`, which must outlive it and take no screen
  /// meanwhile: an other path's, which may run beside its sibling paths (walk_other_paths).
  explicit ScreenMemo(const ScreenMemo* earlier) : earlier_(earlier) {}

  /// The ranking of the candidates in `state`'s model, screened now (from the solve of its fit) or
  /// taken from an earlier screen; then the model's objective is let go. `candidates`, when not
  /// null, receives the candidates of `state`'s model (generated once: the diagnosis keeps the
  /// first screen's).
  const EffectRanking& rank(const LoopState& state, const DiagnosisOptions& options,
                            std::vector<EffectCandidate>* candidates = nullptr) {
    const std::vector<std::string> names = names_of(state.effects);
    std::unique_ptr<Objective> objective = std::move(state.model->objective);
    if (const EffectRanking* screened = find(names, state.fit.statistic)) {
      ++reused_;
      if (candidates) *candidates = generate_candidates(state.problem(), options.candidates);
      return *screened;
    }
    if (!objective) objective = std::make_unique<Objective>(state.problem(), options.ranking.objective);
    std::vector<EffectCandidate> screened = generate_candidates(state.problem(), options.candidates);
    entries_.push_back({names, state.fit.statistic,
                        detail::rank_effects_with(*objective, state.parameters, screened, options.ranking)});
    if (candidates) *candidates = std::move(screened);
    return entries_.back().ranking;
  }
  /// Takes in the screens and the count of reuses of `path`, a memo made on this one.
  void absorb(ScreenMemo&& path) {
    for (Entry& e : path.entries_) entries_.push_back(std::move(e));
    reused_ += path.reused_;
  }
  int screened() const { return static_cast<int>(entries_.size()); }
  int reused() const { return reused_; }

 private:
  struct Entry {
    std::vector<std::string> names;  ///< the state's effects, in order (the parameters' layout)
    double chi2;
    EffectRanking ranking;
  };
  const EffectRanking* find(const std::vector<std::string>& names, double chi2) const {
    for (const Entry& e : entries_)
      if (e.names == names && detail::same_fit(chi2, e.chi2)) return &e.ranking;
    return earlier_ ? earlier_->find(names, chi2) : nullptr;
  }
  std::deque<Entry> entries_;  // a deque, so that the references rank() returns stay valid
  int reused_ = 0;
  const ScreenMemo* earlier_ = nullptr;
};

/// Accepts the effect `index` of d's last ranking (an acceptable refit) as the next step.
void accept_effect(const Problem& fitted, size_t index, const DiagnosisOptions& options, LoopState* state,
                   Diagnosis* d) {
  const EffectRanking& ranking = d->rankings.back();
  d->steps.push_back(step_accepting(ranking, state->problem().model, static_cast<int>(d->steps.size()) + 1, index));
  std::vector<EffectCandidate> effects = state->effects;
  effects.push_back(ranking.effects[index].candidate);
  *state = make_state(fitted, effects, ranking.effects[index].parameters, options);
}

/// One forward step: screens the candidates of the model as it now is and accepts the best
/// refit when it is significant. Returns false when nothing was accepted.
bool forward_step(const Problem& fitted, LoopState* state, const DiagnosisOptions& options, bool may_accept,
                  ScreenMemo* memo, Diagnosis* d) {
  d->rankings.push_back(memo->rank(*state, options, d->rankings.empty() ? &d->candidates : nullptr));
  const EffectRanking& ranking = d->rankings.back();
  if (!may_accept || !acceptable(ranking)) return false;
  accept_effect(fitted, 0, options, state, d);
  return true;
}

/// `state`'s effects without effect `k`.
std::vector<EffectCandidate> effects_without(const LoopState& state, size_t k) {
  std::vector<EffectCandidate> effects = state.effects;
  effects.erase(effects.begin() + static_cast<std::ptrdiff_t>(k));
  return effects;
}

/// The parameters of `state` without its effect `k`, refitted from where they are (as a TaskMap
/// result: empty when the calibration cannot start).
std::string calibrate_without(const Problem& fitted, const LoopState& state, size_t k, const DiagnosisOptions& options) {
  const int np = static_cast<int>(fitted.parameters.size());
  Vector p(state.parameters.size() - 1);
  const Eigen::Index removed = np + static_cast<Eigen::Index>(k);
  p << state.parameters.head(removed), state.parameters.tail(state.parameters.size() - removed - 1);
  TaskCodec outcome;
  outcome.put(calibrate_with(fitted, effects_without(state, k), p, options).value_or(Vector()));
  return outcome.str();
}

/// The likelihood-ratio statistic of `with` against `without` (one effect fewer): the chi-square
/// it gains, or without a stated noise the F statistic, the gain over `with`'s residual per
/// degree of freedom (the residual with every effect estimates the noise).
double lr_statistic(const Diagnosis& d, double chi2_without, const LoopState& with) {
  const double increase = chi2_without - with.fit.statistic;
  if (d.noise_known) return increase;
  const int dof = d.rankings.front().num_data - static_cast<int>(with.parameters.size());
  return increase / std::max(with.fit.statistic / std::max(1, dof), d.rankings.front().resolution_variance);
}

double lr_statistic(const Diagnosis& d, const LoopState& without, const LoopState& with) {
  return lr_statistic(d, without.fit.statistic, with);
}

/// `state` without its effect `k` from calibrate_without()'s result `refit`; nullopt when that
/// calibration could not start.
std::optional<LoopState> state_without(const Problem& fitted, const LoopState& state, size_t k, const std::string& refit,
                                       const DiagnosisOptions& options) {
  const Vector calibrated = TaskCodec(refit).get_vector();
  if (calibrated.size() == 0) return std::nullopt;
  return make_state(fitted, effects_without(state, k), calibrated, options);
}

/// One state without each of its effects in turn, the rest refitted: those made so far.
struct StatesWithout {
  explicit StatesWithout(size_t effects = 0) : states(effects), known(effects, false) {}
  std::vector<std::optional<LoopState>> states;  ///< nullopt where the calibration could not start
  std::vector<bool> known;                       ///< states[k] is made
};

/// `state` without each of its effects in turn, the rest refitted (through the task map), but for
/// those `made` already holds.
std::vector<std::optional<LoopState>> states_without_each(const Problem& fitted, const LoopState& state,
                                                          const DiagnosisOptions& options, StatesWithout made) {
  if (made.states.size() != state.effects.size()) made = StatesWithout(state.effects.size());
  std::vector<size_t> missing;
  for (size_t k = 0; k < state.effects.size(); ++k)
    if (!made.known[k]) missing.push_back(k);
  const TaskMap& map = options.ranking.task_map ? options.ranking.task_map : TaskMap(run_in_turn);
  const std::vector<std::string> refits =
      map(missing.size(), [&](size_t i) { return calibrate_without(fitted, state, missing[i], options); });
  for (size_t i = 0; i < missing.size(); ++i)
    made.states[missing[i]] = state_without(fitted, state, missing[i], refits[i], options);
  return std::move(made.states);
}

/// The value of `state`'s effect `k`.
double effect_value(const LoopState& state, size_t k) {
  return state.parameters[state.parameters.size() - static_cast<Eigen::Index>(state.effects.size() - k)];
}

const DiagnosisStep* step_that_added(const Diagnosis& d, const std::string& name);

/// The first effect a step accepted (not one the model started with) that the later refits moved
/// onto a bound of its range; effects.size() when none is.
size_t accepted_on_bound(const Diagnosis& d, const LoopState& state) {
  for (size_t k = 0; k < state.effects.size(); ++k)
    if (step_that_added(d, state.effects[k].name) && state.effects[k].on_bound(effect_value(state, k))) return k;
  return state.effects.size();
}

/// The backward pass: an accepted effect the later refits moved onto a bound of its range is
/// dropped first, as a step would not have accepted it there; then, while the weakest effect in
/// the model (the one whose removal raises the misfit least; the problem's own enabled effects
/// included) is below the critical value at the stated level, it is dropped and the rest refitted.
/// `made`: the states without each effect of `*state` made already (by the exchange pass).
void backward_pass(const Problem& fitted, LoopState* state, const DiagnosisOptions& options, StatesWithout made,
                   Diagnosis* d) {
  while (!state->effects.empty()) {
    const double critical = gain_critical_value(d->rankings.front(), options.ranking.significance,
                                                static_cast<int>(state->parameters.size()));
    std::vector<std::optional<LoopState>> without = states_without_each(fitted, *state, options, std::move(made));
    made = StatesWithout();
    size_t weakest = without.size();
    double weakest_increase = INFINITY;
    for (size_t k = 0; k < without.size(); ++k) {
      if (!without[k]) continue;
      const double statistic = lr_statistic(*d, *without[k], *state);
      if (statistic < weakest_increase) {
        weakest_increase = statistic;
        weakest = k;
      }
    }
    const size_t on_bound = accepted_on_bound(*d, *state);
    const bool stand_in = on_bound < without.size() && without[on_bound];
    if (stand_in) {
      weakest = on_bound;
      weakest_increase = lr_statistic(*d, *without[on_bound], *state);
    } else if (weakest == without.size() || weakest_increase >= critical) {
      return;
    }
    d->dropped.push_back(
        {state->effects[weakest].name, weakest_increase, critical, stand_in, effect_value(*state, weakest)});
    *state = std::move(*without[weakest]);
  }
}

/// The step (forward or exchange) that put the effect named `name` into the model, or null.
const DiagnosisStep* step_that_added(const Diagnosis& d, const std::string& name) {
  for (auto it = d.exchanges.rbegin(); it != d.exchanges.rend(); ++it)
    if (it->effect.candidate.name == name) return &*it;
  for (const DiagnosisStep& s : d.steps)
    if (s.effect.candidate.name == name) return &s;
  return nullptr;
}

/// Whether a walk has reached a path walked before (joins()), asked after each change of its model
/// past the forward steps as well: an exchange can bring it there as a step can, and from there it
/// would only retrace that path. Always false on the first path.
using Joined = std::function<bool(const LoopState&)>;

/// The exchange pass. Each forward step chose its effect with the later ones missing from the
/// model, and with several effects at once the first often stands in for them together (one
/// region's mass scale for two point masses). With two or more accepted, each in turn is taken out,
/// the rest refitted, and the candidates screened again with the others in the model; the best
/// significant refit there replaces it when its score S beats what the accepted effect scores
/// there (its own likelihood-ratio statistic less its kind's penalty), or whenever it has gone to a
/// bound of its range. An exchange that reaches the path walked before (`joined`) ends the pass.
/// Returns the states without each effect it made of the state it leaves, for the backward pass.
StatesWithout exchange_pass(const Problem& fitted, LoopState* state, const DiagnosisOptions& options,
                            ScreenMemo* memo, const Joined& joined, Diagnosis* d) {
  const size_t first = d->started_with.size();
  if (state->effects.size() < first + 2) return StatesWithout();
  StatesWithout made(state->effects.size());
  const Eigen::Index np = static_cast<Eigen::Index>(fitted.parameters.size());
  for (size_t k = first; k < state->effects.size(); ++k) {
    const DiagnosisStep* incumbent = step_that_added(*d, state->effects[k].name);
    if (!incumbent) continue;
    made.states[k] = state_without(fitted, *state, k, calibrate_without(fitted, *state, k, options), options);
    made.known[k] = true;
    if (!made.states[k]) continue;
    const LoopState& without = *made.states[k];
    const EffectRanking& ranking = memo->rank(without, options);
    const RankedEffect* best = acceptable(ranking);
    // One the later refits moved onto a bound stands in for something else: any acceptable
    // effect replaces it.
    const bool on_bound = state->effects[k].on_bound(effect_value(*state, k));
    const double incumbent_score = lr_statistic(*d, without, *state) - incumbent->effect.kind_penalty;
    if (!best || best->candidate.name == state->effects[k].name || !(on_bound || best->score() > incumbent_score))
      continue;
    DiagnosisStep exchange = step_accepting(ranking, without.problem().model, incumbent->step);
    exchange.replaces = state->effects[k].name;
    exchange.replaced_score = incumbent_score;
    exchange.replaced_on_bound = on_bound;
    exchange.after_step = static_cast<int>(d->steps.size());
    // best->parameters are without's, then the new effect's value: it takes effect k's place.
    std::vector<EffectCandidate> effects = state->effects;
    effects[k] = best->candidate;
    Vector p(state->parameters.size());
    p.head(np) = best->parameters.head(np);
    for (size_t i = 0, j = static_cast<size_t>(np); i < effects.size(); ++i)
      p[np + static_cast<Eigen::Index>(i)] = best->parameters[static_cast<Eigen::Index>(i == k ? without.parameters.size() : j++)];
    d->exchanges.push_back(std::move(exchange));
    *state = make_state(fitted, effects, p, options);
    made = StatesWithout(state->effects.size());  // those were of the state before the exchange
    if (joined(*state)) break;
  }
  return made;
}

std::string chi2_text(bool noise_known) { return noise_known ? "chi-square" : "2J"; }

std::string format_number(double v) {
  char b[32];
  std::snprintf(b, sizeof b, "%.3g", v);
  return b;
}

std::string effects_text(const Diagnosis& d, double resolution);

std::string discretization_text(const Diagnosis& d) {
  if (!d.discretization || !d.discretization->significant) return "";
  const DiscretizationEstimate& est = *d.discretization;
  double largest = 0;
  for (const DiscretizationEstimate::Mode& m : est.per_mode)
    largest = std::max(largest, std::abs(m.shift_percent));
  char text[600];
  if (!est.corrected && std::isfinite(est.score_as_measured) && !std::isfinite(est.score_corrected)) {
    std::snprintf(text, sizeof text,
                  "The mesh's discretization error (up to %.3g %% in frequency) would account for %.4g of the "
                  "chi-square (more than %.3g), but the loop on the data corrected for it could not run; the "
                  "diagnosis is of the data as measured. ",
                  largest, est.chi2_explained, est.critical_value);
    return text;
  }
  if (!est.corrected && std::isfinite(est.score_as_measured)) {
    std::snprintf(text, sizeof text,
                  "The mesh's discretization error (up to %.3g %% in frequency) would account for %.4g of the "
                  "chi-square (more than %.3g), but the data as measured are explained %s than corrected for the "
                  "mesh (-2 ln L plus %.3g per effect: %.4g against %.4g); the diagnosis is of the data as measured. ",
                  largest, est.chi2_explained, est.critical_value,
                  d.accepted().empty() ? "at least as well" : "better with the effects below", d.ranking.critical_value,
                  est.score_as_measured, est.score_corrected);
    return text;
  }
  std::snprintf(text, sizeof text,
                "Refine the mesh first: its discretization error (up to %.3g %% in frequency) accounts for %.4g of "
                "the chi-square (more than %.3g). %s",
                largest, est.chi2_explained, est.critical_value,
                est.corrected ? "The diagnosis below is of the data corrected for it. " : "");
  return text;
}

/// The calibration parameters of `problem` that `p` holds on a bound of their range (within
/// 1e-6 of the range, in the optimizer's variables), each as "name (lower|upper bound V)".
std::vector<std::string> held_on_bounds(const Problem& problem, const Vector& p) {
  const ParameterScaling scaling(problem.parameters);
  const Vector x = scaling.to_scaled(p), lo = scaling.to_scaled(problem.lower_bounds()),
               hi = scaling.to_scaled(problem.upper_bounds());
  std::vector<std::string> held;
  for (Eigen::Index j = 0; j < x.size(); ++j) {
    const double near = 1e-6 * (hi[j] - lo[j]);
    const bool lower = std::abs(x[j] - lo[j]) <= near, upper = std::abs(x[j] - hi[j]) <= near;
    if (!lower && !upper) continue;
    const Parameter& q = problem.parameters[static_cast<size_t>(j)];
    held.push_back(q.name + " (" + (lower ? "lower" : "upper") + " bound " +
                   detail::number_text(lower ? q.lower : q.upper, 4) + ")");
  }
  return held;
}

/// "The calibration ends with A (upper bound 100) and B (...) on a bound of their range: ..." or "".
std::string held_on_bounds_text(const Diagnosis& d) {
  if (d.calibration_on_bounds.empty() || !d.model_form_error) return "";
  std::string names;
  for (size_t k = 0; k < d.calibration_on_bounds.size(); ++k)
    names += (k == 0 ? "" : k + 1 == d.calibration_on_bounds.size() ? " and " : ", ") + d.calibration_on_bounds[k];
  return "The calibration ends with " + names +
         " on a bound of the range you gave: the data ask for values beyond it. Unless those bounds are physical "
         "limits, widen them and diagnose again: what a wider range removes is no model-form error. ";
}

std::string recommendation_text(const Diagnosis& d, double resolution) {
  std::string restarted = held_on_bounds_text(d);
  if (std::isfinite(d.first_calibration_local_minimum)) {
    char text[300];
    std::snprintf(text, sizeof text,
                  "The first calibration stopped in a local minimum (%s %.4g); %s found a lower one with the same "
                  "model (%.4g), and the diagnosis %s there. ",
                  chi2_text(d.noise_known).c_str(), d.first_calibration_local_minimum,
                  d.calibration_start > 0 ? "a calibration from another start in the parameters' bounds"
                                          : "the loop's refits",
                  d.before.statistic, d.calibration_start > 0 ? "starts" : "was run again from");
    restarted += text;
  }
  return restarted + discretization_text(d) + effects_text(d, resolution);
}

/// " X, significant, ends on a bound of its range (value V): the data ask for more change than any
/// candidate makes within its range, so it is not added." or "".
std::string bound_limited_text(const Diagnosis& d) {
  const RankedEffect* limited = bound_limited(d);
  if (!limited) return "";
  return " " + limited->candidate.name + " explains a significant part of " +
         (d.accepted().empty() ? "the residual" : "what remains") + " but ends on a bound of its range (" +
         format_number(limited->value) + "): the data ask for more change than it can make, so it is not added.";
}

/// "every measured frequency within 0.01 % and every MAC within 0.0001 of 1, the data's resolution"
std::string resolution_text(double resolution) {
  char text[160];
  std::snprintf(text, sizeof text,
                "every measured frequency within %.3g %% and every MAC within %.3g of 1, the data's resolution",
                100 * resolution, resolution);
  return text;
}

/// "No model-form error can be shown: with 2 data for 3 parameters ..." when the calibration has as
/// many parameters as data or more, else "": then any model meets the data, and no residual can
/// show what is missing.
std::string too_few_data_text(const Diagnosis& d) {
  if (d.rankings.empty() || d.rankings.front().num_data > d.calibration.final.size()) return "";
  return "No model-form error can be shown: with " + std::to_string(d.rankings.front().num_data) + " data for " +
         std::to_string(d.calibration.final.size()) +
         " parameters the calibration can meet any data. Measure more modes or shapes to test the model's form.";
}

}  // namespace

namespace detail {

// The recommendation is what a user acts on, and there the effect's name alone would read as
// more certain than the data are.
std::string hardly_told_apart_text(const Diagnosis& d) {
  std::string text;
  bool readings = false;
  for (const std::string& name : d.accepted()) {
    const DiagnosisStep& s = *step_that_added(d, name);
    std::vector<std::string> others;
    for (const RankedEffect& a : s.alternatives)
      if (!s.data_favour(a)) others.push_back(a.candidate.name);
    if (others.empty()) continue;
    const size_t shown = std::min<size_t>(others.size(), 3);
    std::string list;
    for (size_t k = 0; k < shown; ++k)
      list += (k == 0 ? "" : k + 1 == shown && others.size() == shown ? " and " : ", ") + others[k];
    if (others.size() > shown) list += " and " + std::to_string(others.size() - shown) + " more";
    text += " The data hardly tell " + name + " from " + list + ".";
    readings = readings || !s.tell_apart.empty();
  }
  if (readings) text += " The stepwise loop lists the readings that would tell them apart.";
  return text;
}

}  // namespace detail

namespace {

std::string effects_text(const Diagnosis& d, double resolution) {
  char numbers[200];
  if (d.accepted().empty()) {
    if (bound_limited(d))
      return "Model-form error." + bound_limited_text(d) +
             " The missing physics is not among the candidates as they are bounded (declare your own under "
             "effects: in the problem file).";
    if (!d.model_form_error && !too_few_data_text(d).empty()) return too_few_data_text(d);
    if (!d.model_form_error && !d.noise_known)
      return "No model-form error: with no stated noise, the calibrated model meets " + resolution_text(resolution) +
             "; nothing smaller can be told apart, and nothing needs adding.";
    if (!d.model_form_error)
      return "No model-form error: the calibrated residual is consistent with the stated noise and no candidate "
             "effect explains a significant part of it; nothing needs adding.";
    if (!d.noise_known)
      return "Model-form error, or noise: the calibrated model does not meet the data to their resolution, and no "
             "candidate effect explains the residual significantly. With no stated noise it is not known whether "
             "what remains is noise (state it under measured: noise:) or physics not among the " +
             std::to_string(d.ranking.screened) + " candidates (declare your own under effects: in the problem file).";
    return "Model-form error, but no candidate effect explains the residual significantly: the missing physics is "
           "not among the " +
           std::to_string(d.ranking.screened) + " candidates (declare your own under effects: in the problem file).";
  }
  std::string text = "Model-form error. Add";
  bool first = true;
  for (const std::string& name : d.accepted()) {
    const DiagnosisStep& s = *step_that_added(d, name);
    std::snprintf(numbers, sizeof numbers, " (%s %.4g -> %.4g)", chi2_text(d.noise_known).c_str(), s.chi2_before,
                  s.effect.chi2_after);
    text += std::string(first ? " " : "; then ") + s.effect.candidate.name + ": " + s.effect.summary() + numbers;
    first = false;
  }
  text += ". ";
  for (const DroppedEffect& x : d.dropped)
    text += x.name + (x.on_bound ? " was dropped again: refitted with the later effects it went to a bound of its range (" +
                                       format_number(x.value) + "), where it stands in for something else. "
                                 : " was dropped again: the others explain it. ");
  if (d.at_resolution)
    text += "With them the model meets " + resolution_text(resolution) + ".";
  else if (!d.final_fit.test)
    text += "Without a stated noise it is not known whether anything else is missing.";
  else if (d.final_fit.test->model_form_error)
    text += "The residual is still larger than the noise (" + d.final_fit.test->verdict +
            "): what remains is not among the candidates.";
  else
    text += "With them the residual is consistent with the noise.";
  return text + detail::hardly_told_apart_text(d) + bound_limited_text(d);
}

}  // namespace

namespace {

/// r²/(r² − 1): the continuum's change over that of a mesh r times finer, for an O(h²) error.
double extrapolation_factor(double r) { return r * r / (r * r - 1); }

/// Per sensor, 1 where the finer mesh reads it at the node's place on this mesh, else 0; the
/// others are counted in `est`, with the farthest one's distance. A sensor snapped to another
/// place on the finer mesh reads another point, and that change of shape is not the mesh's error.
Vector sensors_held(const Problem& problem, const Problem& finer, DiscretizationEstimate* est) {
  const double tolerance = 1e-6 * bounding_box_diagonal(problem.model);
  Vector held = Vector::Zero(static_cast<Eigen::Index>(problem.sensors.size()));
  for (size_t s = 0; s < problem.sensors.size() && s < finer.sensors.size(); ++s) {
    const double moved = (finer.model.coordinates[finer.sensors[s].node] -
                          problem.model.coordinates[problem.sensors[s].node]).norm();
    if (moved <= tolerance) {
      held[static_cast<Eigen::Index>(s)] = 1;
      continue;
    }
    ++est->sensors_moved;
    est->sensor_offset = std::max(est->sensor_offset, moved);
  }
  return held;
}

DiscretizationEstimate estimate_discretization(const Problem& problem, const Problem& finer, const Vector& p,
                                               double significance) {
  if (finer.parameters.size() != problem.parameters.size() || finer.measured.size() != problem.measured.size())
    throw std::invalid_argument("diagnose: the finer-mesh problem has other parameters or measured modes");
  Objective coarse(problem), fine(finer);
  const Evaluation ec = coarse.evaluate(p, Need::Value), ef = fine.evaluate(p, Need::Value);
  if (!ec.ok || !ef.ok)
    throw std::runtime_error("diagnose: the discretization estimate failed: " + (ec.ok ? ef.message : ec.message));
  DiscretizationEstimate est;
  est.dofs = coarse.system().num_dofs();
  est.finer_dofs = fine.system().num_dofs();
  // The ratio of element sizes: the meshes' refinement factors where both were generated from an
  // element size, since a slender member keeps its one or two elements across and refines only
  // along its length (the portal frame: 1.5 along, 1.13 from the DOF counts); else from the DOF
  // counts of a 3D mesh.
  const double from_dofs = std::cbrt(static_cast<double>(est.finer_dofs) / est.dofs);
  est.refinement = problem.mesh_refinement > 0 && finer.mesh_refinement > 0
                       ? finer.mesh_refinement / problem.mesh_refinement
                       : from_dofs;
  if (!(from_dofs > 1.01 && est.refinement > 1.05))
    throw std::invalid_argument("diagnose: the finer-mesh problem is not finer (" + std::to_string(est.finer_dofs) +
                                " DOFs against " + std::to_string(est.dofs) + ")");
  const double richardson = extrapolation_factor(est.refinement);
  const SparseMatrix sensors_c = detail::sensor_matrix(problem, coarse.system().dof_map());
  const SparseMatrix sensors_f = detail::sensor_matrix(finer, fine.system().dof_map());
  const Vector held = sensors_held(problem, finer, &est);
  for (const PairedMode& c : ec.pairs)
    for (const PairedMode& f : ef.pairs)
      if (f.measured == c.measured) {
        const double shift = f.model_hz / c.model_hz - 1;
        DiscretizationEstimate::Mode mode{c.measured, mode_label(problem, c.measured), 100 * shift,
                                          100 * shift * richardson, {}, {}};
        if (sensors_c.rows() == sensors_f.rows() && sensors_c.rows() > 0) {
          // The finer mesh's shape at the sensors, scaled (and signed) onto this mesh's where both
          // read the same places.
          mode.shape = sensors_c * ec.modal.modes.col(c.model);
          const Vector finer_shape = sensors_f * ef.modal.modes.col(f.model);
          const Vector finer_held = finer_shape.cwiseProduct(held);
          const double fit = finer_held.dot(mode.shape) / std::max(finer_held.squaredNorm(), 1e-300);
          mode.shape_change = (fit * finer_shape - mode.shape).cwiseProduct(held);
        }
        est.per_mode.push_back(std::move(mode));
      }
  est.critical_value = chi_square_critical_value(significance, 1);
  return est;
}

/// `problem` as this mesh would see it: each measured frequency moved by the mode's change on the
/// finer mesh, and what extrapolation says even the finer mesh still misses allowed as model error
/// in the mode's frequency (MeasuredMode::model_error).
Problem corrected_for_mesh(const Problem& problem, const DiscretizationEstimate& est, bool allow_the_rest) {
  Problem corrected = problem;
  for (const DiscretizationEstimate::Mode& m : est.per_mode) {
    MeasuredMode& measured = corrected.measured[m.measured];
    measured.frequency_hz /= 1 + m.shift_percent / 100;
    // The shape: moved by the change at the sensors, in the measured shape's own scale, so that this
    // mesh's mode meets it as the finer mesh's meets the data.
    if (measured.shape.size() > 0 && measured.shape.size() == m.shape.size()) {
      const double scale = measured.shape.dot(m.shape) / std::max(m.shape.squaredNorm(), 1e-300);
      measured.shape -= scale * m.shape_change;
    }
    if (allow_the_rest) measured.model_error = std::abs(m.extrapolated_percent - m.shift_percent) / 100;
  }
  return corrected;
}

Problem weighted_if(bool noise_known, const Problem& problem) {
  return noise_known ? noise_weighted(problem, *problem.measurement_noise) : problem;
}

/// One line for the caller's progress display, when it has one.
void say(const DiagnosisOptions& options, const std::string& line) {
  if (options.progress) options.progress(line);
}

/// The lowest of the calibrations of `weighted` from options.calibration_starts further starts
/// (spread_start() 1, 2, ...), walked as `walk` says through the task map and judged with
/// `objective` (the first calibration's, on the whole model): its start's number when
/// it ends lower than `fit` by more than what tells two minima apart (summary and fit replaced,
/// but for the summary's initial values), else 0: 0.1 in X² with a stated noise, a likelihood
/// ratio of 1.05 and far below any test's critical value, so that two runs ending in the same
/// minimum at a calibration's tolerance apart do not make the first "a local minimum"; without
/// one, the rounding of 2J.
int calibrate_from_further_starts(Objective& objective, const Problem& weighted, const DiagnosisOptions& options,
                                  RankingOptions walk, ReducedSummary* summary, FitState* fit) {
  walk.refit.progress = nullptr;  // the caller's display follows one calibration, and these may run at once
  const TaskMap& map = options.ranking.task_map ? options.ranking.task_map : TaskMap(run_in_turn);
  const std::vector<std::string> outcomes = map(static_cast<size_t>(options.calibration_starts), [&](size_t k) {
    Objective own(weighted, options.ranking.objective);  // one per start: they may run at once
    const ReducedSummary from_k = detail::refit_walk(own, spread_start(weighted.parameters, int(k) + 1), walk);
    TaskCodec outcome;
    outcome.put(from_k.final.size() == summary->final.size() ? from_k.final : Vector());
    outcome.put(static_cast<double>(from_k.iterations));
    outcome.put(static_cast<double>(from_k.forward_solves));
    return outcome.str();
  });
  int kept = 0;
  for (size_t k = 0; k < outcomes.size(); ++k) {
    TaskCodec outcome(outcomes[k]);
    const Vector p = outcome.get_vector();
    const int iterations = static_cast<int>(outcome.get_number()), solves = static_cast<int>(outcome.get_number());
    summary->forward_solves += solves;
    if (p.size() == 0) {
      say(options, "  start " + std::to_string(k + 1) + ": the calibration could not start there");
      continue;
    }
    FitState other = fit_of(objective, weighted, p, options.test);
    say(options, "  start " + std::to_string(k + 1) + " ends at " + chi2_text(has_noise(weighted)) + " " +
                     format_number(other.statistic));
    const double apart = has_noise(weighted) ? 0.1 : 1e-9 * fit->statistic;
    if (!(other.statistic < fit->statistic - apart)) continue;
    *fit = std::move(other);
    summary->final = p;
    summary->iterations = iterations;
    kept = static_cast<int>(k) + 1;
  }
  return kept;
}

/// Where the nominal calibration's kept run started, and what the caller's start came to when
/// that was a further start.
struct StartKept {
  int start = 0;             ///< 0: the caller's; k: spread_start(parameters, k)
  double given_end = NAN;    ///< X² (2J without a stated noise) of the run from the caller's start
};

/// The nominal calibration of `weighted` from `from`, and the fit at its result. With
/// `further_starts`, when that fit is a model-form error (its residual more than the stated noise,
/// or without one, than the data's resolution), calibrations from
/// DiagnosisOptions::calibration_starts further starts too, the lowest kept: a local minimum of
/// the calibration looks exactly like a model-form error.
StartKept calibrate_nominal(const Problem& weighted, const Vector& from, const DiagnosisOptions& options,
                            ReducedSummary* summary, FitState* fit, bool further_starts = false) {
  Objective objective(weighted, options.ranking.objective);
  RankingOptions walk = options.ranking;  // in a span, as the refits, with the calibration's own settings
  walk.refit = options.calibration;
  *summary = detail::refit_walk(objective, from, walk);
  if (summary->final.size() != from.size())
    throw std::runtime_error("diagnose: the calibration could not start: " + summary->message);
  *fit = fit_of(objective, weighted, summary->final, options.test);  // the walk's check solved it there
  const bool too_far = fit->test ? fit->test->model_form_error : !at_resolution(*fit, options.ranking.resolution);
  if (!further_starts || !too_far || options.calibration_starts == 0) return {};
  const double given_end = fit->statistic;
  say(options, "calibrating again from " + std::to_string(options.calibration_starts) +
                   " further starts spread over the bounds: the given start ended at " +
                   chi2_text(has_noise(weighted)) + " " + format_number(given_end) +
                   (has_noise(weighted) ? ", more than the noise" : ", more than the data's resolution"));
  const int start = calibrate_from_further_starts(objective, weighted, options, walk, summary, fit);
  return start == 0 ? StartKept{} : StartKept{start, given_end};
}

/// The data moved by the finer mesh's change, with the allowance, and the calibration to start
/// their loop from, when the mesh accounts for a significant part of the residual; else nullopt.
std::optional<std::pair<Problem, Vector>> check_the_mesh(const Problem& problem, const DiagnosisOptions& options,
                                                         Diagnosis* d) {
  // The parameters absorb what the mesh does alike in every mode (a uniformly softer mesh is a
  // lower modulus), so the mesh's share is what recalibrating on the corrected data gains.
  DiscretizationEstimate& est = d->discretization.emplace(
      estimate_discretization(problem, *options.finer_mesh, d->calibration.final, options.ranking.significance));
  // The statistic compares the data moved by the finer mesh's change (no free parameter) with
  // the data as they are; an allowance for model error would lower any chi-square, so it
  // enters only the loop, once the mesh is found to matter.
  ReducedSummary summary;
  FitState fit;
  calibrate_nominal(weighted_if(d->noise_known, corrected_for_mesh(problem, est, false)), d->calibration.final,
                    options, &summary, &fit);
  est.chi2_explained = d->before.statistic - fit.statistic;
  est.significant = d->noise_known && est.chi2_explained > est.critical_value;
  if (!est.significant || !options.correct_for_discretization) return std::nullopt;
  return std::make_pair(corrected_for_mesh(problem, est, true), summary.final);
}

/// What a path through the loop ends at: -2 ln L (the chi-square) plus, per accepted effect kept,
/// the first step's critical value (the price the mesh check puts on an effect) and its kind's
/// penalty, 2 ln n_kind: the prior over kinds each step's choice was made with, so that a path
/// does not win on a better fit that prior gave away (a point mass against its column's scale).
double path_score(const Diagnosis& d) {
  double score = d.final_fit.statistic;
  for (const std::string& name : d.accepted())
    score += d.rankings.front().critical_value + step_that_added(d, name)->effect.kind_penalty;
  return score;
}

/// True when `state` holds the effects the `earlier` path ended with and one more, which the data
/// do not need there (detail::holds_the_end_and_one_unneeded): without it, the chi-square would
/// rise only to that path's end, by less than the backward pass's critical value at `significance`.
/// The backward pass would drop it and end where that path did; the screen, exchange and drops on
/// the way there would find nothing new.
bool holds_the_end_and_one_unneeded(const LoopState& state, const Diagnosis& earlier, double significance) {
  if (state.effects.size() != earlier.effects.size() + 1) return false;
  const EffectRanking& first = earlier.rankings.front();
  const double critical = gain_critical_value(first, significance, static_cast<int>(state.parameters.size()));
  return detail::holds_the_end_and_one_unneeded(names_of(state.effects), names_of(earlier.effects),
                                                lr_statistic(earlier, earlier.final_fit.statistic, state), critical);
}

/// True when `state`, after `steps` forward steps, holds the effects the `earlier` path held after
/// as many, or those it ended with, at the same fit (detail::same_effects_and_fit), or those it ended
/// with and one the data do not need (holds_the_end_and_one_unneeded). From the first both paths
/// take the same steps, exchanges and drops; from the second, the walk would screen once more where
/// the earlier path's exchange and backward pass left it, as that path did not.
bool joins(const LoopState& state, const Diagnosis& earlier, size_t steps, double significance) {
  const std::vector<std::string> here = names_of(state.effects);
  const double chi2 = state.fit.statistic;
  if (detail::same_effects_and_fit(here, chi2, names_of(earlier.effects), earlier.final_fit.statistic)) return true;
  if (holds_the_end_and_one_unneeded(state, earlier, significance)) return true;
  if (steps == 0 || steps > earlier.steps.size()) return false;
  std::vector<EffectCandidate> there = earlier.started_with;
  for (size_t k = 0; k < steps; ++k) there.push_back(earlier.steps[k].effect.candidate);
  return detail::same_effects_and_fit(here, chi2, names_of(there), earlier.steps[steps - 1].effect.chi2_after);
}

/// Forward steps while another may be taken (max_steps, the data's resolution,
/// stop_when_consistent, not `joined`) and one is significant. Returns true when one was taken.
bool step_on(const Problem& fitted, LoopState* state, const DiagnosisOptions& options, ScreenMemo* memo,
             const Joined& joined, Diagnosis* d) {
  bool stepped = false;
  while (static_cast<int>(state->effects.size() - d->started_with.size()) < options.max_steps && !joined(*state) &&
         !at_resolution(state->fit, options.ranking.resolution) &&
         !(options.stop_when_consistent && consistent_with_noise(state->fit)) &&
         forward_step(fitted, state, options, true, memo, d))
    stepped = true;
  return stepped;
}

/// The exchange pass, and while it changes the model, forward steps on the model it leaves and
/// the exchange pass again (at most kExchangeRounds times). An exchange that trades a stand-in
/// (a block's scale for the region that carried two effects' change) changes what the residual
/// still holds, so a step screened before it may have missed what the trade uncovers. Stops where
/// the walk reaches the path walked before (`joined`). Returns the exchange pass's states without
/// each effect when the model is still the one it left.
StatesWithout exchange_and_step_again(const Problem& fitted, LoopState* state, const DiagnosisOptions& options,
                                      ScreenMemo* memo, const Joined& joined, Diagnosis* d) {
  constexpr int kExchangeRounds = 3;
  StatesWithout made;
  if (!options.exchange) return made;
  for (int round = 0; round < kExchangeRounds; ++round) {
    const size_t exchanged = d->exchanges.size();
    made = exchange_pass(fitted, state, options, memo, joined, d);
    if (d->exchanges.size() == exchanged || round + 1 == kExchangeRounds || joined(*state)) break;
    if (!step_on(fitted, state, options, memo, joined, d) || joined(*state)) break;
    made = StatesWithout();
  }
  return made;
}

/// One try of two effects for one (pair_exchange): `without` (the state with one effect taken
/// out) with the refit `replacement` of its screen in that effect's place, then the best
/// significant step from there, and the score of the two (path_score's terms).
struct PairTry {
  size_t replacement = 0;                ///< the index of the refit in the screen without
  LoopState with;                        ///< `without` with the replacement
  const EffectRanking* next = nullptr;   ///< the screen of `with`
  std::optional<LoopState> pair;         ///< `with` and its best significant step
  double score = INFINITY;               ///< chi-square plus the two effects' critical values and penalties
};

/// The try of `screened`'s refit `replacement` (an acceptable one) in `without`, `critical` the
/// first step's critical value.
PairTry try_pair(const Problem& fitted, const LoopState& without, const EffectRanking& screened, size_t replacement,
                 double critical, const DiagnosisOptions& options, ScreenMemo* memo) {
  const RankedEffect& first = screened.effects[replacement];
  std::vector<EffectCandidate> effects = without.effects;
  effects.push_back(first.candidate);
  PairTry t{replacement, make_state(fitted, effects, first.parameters, options), nullptr, std::nullopt, INFINITY};
  t.next = &memo->rank(t.with, options);
  const RankedEffect* second = acceptable(*t.next);
  if (!second) return t;
  effects.push_back(second->candidate);
  t.pair = make_state(fitted, effects, second->parameters, options);
  t.score = t.pair->fit.statistic + 2 * critical + first.kind_penalty + second->kind_penalty;
  return t;
}

/// Two effects for one (DiagnosisOptions::pair_exchanges): when the residual is still larger than
/// the noise, each accepted effect in turn is taken out, each of the best significant refits in
/// its place followed by the best significant step from there, and the best such pair replaces it
/// when the model scores lower (path_score's terms). An exchange and a step record the change.
/// `made`: the states without each effect, as the exchange pass left them (taken, and given back
/// when nothing changes). Returns true when the model changed.
bool pair_exchange(const Problem& fitted, LoopState* state, const DiagnosisOptions& options, StatesWithout* made,
                   ScreenMemo* memo, Diagnosis* d) {
  const size_t first = d->started_with.size();
  if (options.pair_exchanges == 0 || !state->fit.test || consistent_with_noise(state->fit) ||
      state->effects.size() <= first || static_cast<int>(state->effects.size() - first) >= options.max_steps)
    return false;
  const double critical = d->rankings.front().critical_value;
  std::vector<std::optional<LoopState>> without = states_without_each(fitted, *state, options, std::move(*made));
  std::optional<PairTry> best;
  size_t replaced = 0;
  double best_change = 0;  // in score: a pair must lower it
  for (size_t k = first; k < state->effects.size(); ++k) {
    const DiagnosisStep* incumbent = step_that_added(*d, state->effects[k].name);
    if (!incumbent || !without[k]) continue;
    const double score_now = state->fit.statistic + critical + incumbent->effect.kind_penalty;
    const EffectRanking& screened = memo->rank(*without[k], options);
    int tried = 0;
    for (size_t i = 0; i < screened.effects.size() && tried < options.pair_exchanges; ++i) {
      if (!screened.effects[i].acceptable()) break;  // the acceptable refits come first
      if (screened.effects[i].candidate.name == state->effects[k].name) continue;
      ++tried;
      PairTry t = try_pair(fitted, *without[k], screened, i, critical, options, memo);
      if (t.score - score_now < best_change) {
        best_change = t.score - score_now;
        best = std::move(t);
        replaced = k;
      }
    }
  }
  if (!best) {
    made->states = std::move(without);
    made->known.assign(made->states.size(), true);
    return false;
  }
  const LoopState& out = *without[replaced];
  DiagnosisStep exchange = step_accepting(memo->rank(out, options), out.problem().model,
                                          step_that_added(*d, state->effects[replaced].name)->step, best->replacement);
  exchange.replaces = state->effects[replaced].name;
  exchange.replaced_score = lr_statistic(*d, out, *state) - step_that_added(*d, exchange.replaces)->effect.kind_penalty;
  exchange.after_step = static_cast<int>(d->steps.size());
  exchange.pair_score_change = best_change;
  d->exchanges.push_back(std::move(exchange));
  d->rankings.push_back(*best->next);
  d->steps.push_back(step_accepting(*best->next, best->with.problem().model, static_cast<int>(d->steps.size()) + 1));
  *state = std::move(*best->pair);
  *made = StatesWithout();
  return true;
}

/// What a path's walk ended at, when given a path walked before (walk()).
enum class WalkEnd {
  kEnd,          ///< walked to the end: forward steps, exchange and backward pass
  kJoined,       ///< reached the earlier path's effects (joins())
  kNoSecondStep  ///< took no step after its first and fits no better than the earlier path's first
};

/// Records `state` as where d's path ends.
void end_at(const LoopState& state, Diagnosis* d) {
  d->effects = state.effects;
  d->final_parameters = state.parameters;
  d->final_fit = state.fit;
}

/// walk()'s test that a walk reached the `earlier` path (joins()); never true without one.
Joined joined_to(const Diagnosis* earlier, const Diagnosis& d, const DiagnosisOptions& options) {
  return [earlier, &d, &options](const LoopState& s) {
    return earlier && joins(s, *earlier, d.steps.size(), options.ranking.significance);
  };
}

/// walk()'s forward steps from `state` (after the `first` already taken); d records them and
/// where they end. Returns how the walk ended when it ends there (WalkEnd::kJoined,
/// WalkEnd::kNoSecondStep), else nullopt: the exchange and the backward pass follow (walk_on()).
std::optional<WalkEnd> walk_forward(const Problem& fitted, LoopState* state, int first, const DiagnosisOptions& options,
                                    ScreenMemo* memo, Diagnosis* d, const Diagnosis* earlier = nullptr) {
  const Joined joined = joined_to(earlier, *d, options);
  for (int k = first; k < std::max(1, options.max_steps); ++k) {
    if (joined(*state)) return WalkEnd::kJoined;
    if (k > 0 && options.stop_when_consistent && consistent_with_noise(state->fit)) break;
    const bool may_accept = k < options.max_steps && !at_resolution(state->fit, options.ranking.resolution);
    if (!forward_step(fitted, state, options, may_accept, memo, d)) break;
  }
  if (joined(*state)) return WalkEnd::kJoined;
  end_at(*state, d);
  if (earlier && d->steps.size() == 1 && state->fit.statistic >= earlier->steps.front().effect.chi2_after &&
      path_score(*d) >= path_score(*earlier))
    return WalkEnd::kNoSecondStep;
  return std::nullopt;
}

/// walk() after its forward steps (walk_forward(), which left `state`): the exchange pass, the
/// pair exchange and the backward pass; d records them and the end.
WalkEnd walk_on(const Problem& fitted, LoopState state, const DiagnosisOptions& options, ScreenMemo* memo, Diagnosis* d,
                const Diagnosis* earlier = nullptr) {
  const Joined joined = joined_to(earlier, *d, options);
  StatesWithout made = exchange_and_step_again(fitted, &state, options, memo, joined, d);
  if (joined(state)) return WalkEnd::kJoined;
  if (pair_exchange(fitted, &state, options, &made, memo, d)) {
    step_on(fitted, &state, options, memo, joined, d);
    if (joined(state)) return WalkEnd::kJoined;
    made = exchange_and_step_again(fitted, &state, options, memo, joined, d);
    if (joined(state)) return WalkEnd::kJoined;
  }
  if (options.backward) backward_pass(fitted, &state, options, std::move(made), d);
  end_at(state, d);
  return WalkEnd::kEnd;
}

/// The forward steps from `state` (after the `first` already taken), then the exchange and the
/// backward pass; d records them and the end. Given the `earlier` path, a walk stops when nothing
/// new lies ahead: when it reaches that path's effects (joins()), or when it took no step after
/// its first and fits no better than that path's first step, at no lower a score (its exchange
/// could at best trade its effect for that one, where that path went on from). The test for the
/// first is made after every change of the model, exchanges included.
WalkEnd walk(const Problem& fitted, LoopState state, int first, const DiagnosisOptions& options, ScreenMemo* memo,
             Diagnosis* d, const Diagnosis* earlier = nullptr) {
  if (const std::optional<WalkEnd> end = walk_forward(fitted, &state, first, options, memo, d, earlier)) return *end;
  return walk_on(fitted, std::move(state), options, memo, d, earlier);
}

/// True when a and b kept the same effects: paths that end there differ only in rounding, and
/// the first one walked (the greedy path) stays.
bool same_effects(const Diagnosis& a, const Diagnosis& b) {
  std::vector<std::string> x = a.accepted(), y = b.accepted();
  std::sort(x.begin(), x.end());
  std::sort(y.begin(), y.end());
  return x == y;
}

/// The record of d's path for Diagnosis::paths.
DiagnosisPath path_of(const Diagnosis& d) {
  return {d.steps.front().effect.candidate.name, d.accepted(), d.final_fit.statistic, path_score(d), false, "", 0, false};
}

/// The first ranking's acceptable refits, other than its first, to start another path from: at
/// most `count`, by score, none the hypothesis of one taken before at its place
/// (detail::one_hypothesis: a neighbour, or mass at the same place as a point mass or a region's
/// scale), whose path would retrace that one's.
std::vector<size_t> other_first_steps(const EffectRanking& ranking, int count) {
  std::vector<size_t> chosen;
  for (size_t k = 1; k < ranking.effects.size() && static_cast<int>(chosen.size()) < count; ++k) {
    const RankedEffect& r = ranking.effects[k];
    if (!r.acceptable() || detail::one_hypothesis(r.candidate, ranking.effects.front().candidate)) continue;
    if (std::none_of(chosen.begin(), chosen.end(),
                     [&](size_t c) { return detail::one_hypothesis(ranking.effects[c].candidate, r.candidate); }))
      chosen.push_back(k);
  }
  return chosen;
}

/// An other path (walk_other_paths): its diagnosis, how its walk ended, and the screens it took.
struct OtherPath {
  Diagnosis d;
  WalkEnd end = WalkEnd::kEnd;
  ScreenMemo memo;
};

/// The path from the first ranking's effect `index`, walked from `start` as walk() walks given the
/// greedy path `greedy` (`before_the_loop`: greedy as it was before), with the screens of
/// `screened` (the greedy path's) and its own.
OtherPath walk_other_path(const Problem& fitted, const LoopState& start, const Diagnosis& before_the_loop, size_t index,
                          const DiagnosisOptions& options, const ScreenMemo& screened, const Diagnosis& greedy) {
  OtherPath path{before_the_loop, WalkEnd::kEnd, ScreenMemo(&screened)};
  path.d.rankings = {greedy.ranking};
  path.d.ranking = greedy.ranking;
  path.d.map = greedy.map;
  LoopState state = start;
  accept_effect(fitted, index, options, &state, &path.d);
  path.end = walk(fitted, std::move(state), 1, options, &path.memo, &path.d, &greedy);
  return path;
}

/// The paths from the first ranking's effects `others` (walk_other_path), in their order: side by
/// side, all but the first in threads of their own, with DiagnosisOptions::walk_side_by_side; else
/// one after the other. Each is judged against the greedy path only and takes no screen of
/// another's, so they come out the same either way.
std::vector<OtherPath> walk_each(const Problem& fitted, const LoopState& start, const Diagnosis& before_the_loop,
                                 const std::vector<size_t>& others, const DiagnosisOptions& options,
                                 const ScreenMemo& screened, const Diagnosis& greedy) {
  auto walk_one = [&](size_t i) {
    return walk_other_path(fitted, start, before_the_loop, others[i], options, screened, greedy);
  };
  std::vector<std::future<OtherPath>> beside;  // an exception below waits for these, then goes on
  for (size_t i = 1; i < others.size() && options.walk_side_by_side; ++i) try {
      beside.push_back(std::async(std::launch::async, walk_one, i));
    } catch (const std::system_error&) {  // no thread to be had: the rest in this one
      break;
    }
  std::vector<OtherPath> walked;
  walked.push_back(walk_one(0));
  for (size_t i = 1; i < others.size(); ++i) walked.push_back(i <= beside.size() ? beside[i - 1].get() : walk_one(i));
  return walked;
}

/// The paths from the first ranking's next-best effects (DiagnosisOptions::first_step_alternatives),
/// after the greedy path `d` walked from `start`; `before_the_loop` is d as it was before. The path
/// that ends with the lowest score (path_score) is kept; on a tie, or with the same effects as a
/// path before it, the earlier path.
void walk_other_paths(const Problem& fitted, const LoopState& start, const Diagnosis& before_the_loop,
                      const DiagnosisOptions& options, ScreenMemo* memo, Diagnosis* d) {
  const bool any_end = d->steps.size() >= 2 && options.alternatives_after_consistent_end;
  if (d->steps.empty() || !d->final_fit.test || (!any_end && consistent_with_noise(d->final_fit))) return;
  const std::vector<size_t> others = other_first_steps(d->ranking, options.first_step_alternatives);
  if (others.empty()) return;
  std::vector<OtherPath> walked = walk_each(fitted, start, before_the_loop, others, options, *memo, *d);
  const DiagnosisPath greedy = path_of(*d);
  std::vector<DiagnosisPath> paths = {greedy};
  for (OtherPath& path : walked) {
    memo->absorb(std::move(path.memo));
    if (path.end == WalkEnd::kJoined) {
      paths.push_back(greedy);
      paths.back().joined = greedy.first;
      paths.back().first = path.d.steps.front().effect.candidate.name;
      paths.back().joined_after = static_cast<int>(path.d.steps.size());
      paths.back().joined_after_exchanges = static_cast<int>(path.d.exchanges.size());
      continue;
    }
    paths.push_back(path_of(path.d));
    paths.back().no_second_step = path.end == WalkEnd::kNoSecondStep;
    if (path.end == WalkEnd::kEnd && paths.back().score < path_score(*d) && !same_effects(path.d, *d))
      *d = std::move(path.d);
  }
  for (DiagnosisPath& path : paths) path.kept = path.first == d->steps.front().effect.candidate.name;
  d->paths = std::move(paths);
}

/// Each step's advice on telling its effect from the alternatives (add_tell_apart), on the model
/// as it stood before the step: the effects the loop started with and the earlier steps'. Given
/// once the diagnosis has chosen its path, as only that path's steps are reported.
void advise_measurements(const Problem& fitted, Diagnosis* d) {
  std::vector<EffectCandidate> effects = d->started_with;
  const size_t np = fitted.parameters.size();
  for (DiagnosisStep& step : d->steps) {
    const Vector& p = step.effect.parameters;  // the parameters before the step, then its effect's value
    add_tell_apart(fitted, effects, std::vector<double>(p.data() + np, p.data() + p.size() - 1), &step);
    effects.push_back(step.effect.candidate);
  }
}

/// A loop between its first path and the others: where it started and the screens it ran, which
/// the other paths take again where they reach a model screened before; between the first path's
/// forward steps and the rest of it, where those steps left the model.
struct Loop {
  Problem fitted;
  LoopState start;
  Diagnosis before_the_loop;
  ScreenMemo memo;
  LoopState at_forward_end;
};

/// d's count of the screens its loop ran so far (Diagnosis::screens, screens_reused).
void count_screens(const Loop& loop, Diagnosis* d) {
  d->screens = loop.memo.screened();
  d->screens_reused = loop.memo.reused();
}

/// The loop's first path on `fitted` from d's calibration up to the end of its forward steps,
/// with the first step's localization and map; finish_first_path() walks the rest.
Loop walk_first_path_forward(const Problem& problem, const Problem& fitted, const DiagnosisOptions& options,
                             Diagnosis* d) {
  localize(problem, d->calibration.final, options, d);
  d->started_with = enabled_candidates(problem, options.candidates);
  d->started_with.insert(d->started_with.end(), options.added.begin(), options.added.end());
  Loop loop{fitted, starting_state(fitted, d->started_with, d->calibration.final, options), {}, {}, {}};
  if (!d->started_with.empty()) d->before = loop.start.fit;
  loop.before_the_loop = *d;
  loop.at_forward_end = loop.start;
  walk_forward(loop.fitted, &loop.at_forward_end, 0, options, &loop.memo, d);
  d->ranking = d->rankings.front();
  d->map = screen_map(problem.model, d->ranking);
  count_screens(loop, d);
  return loop;
}

/// The rest of the loop's first path after walk_first_path_forward(): the exchange and the
/// backward pass.
void finish_first_path(Loop* loop, const DiagnosisOptions& options, Diagnosis* d) {
  walk_on(loop->fitted, loop->at_forward_end, options, &loop->memo, d);
  count_screens(*loop, d);
}

/// The loop's first path on `fitted` from d's calibration: the forward steps, the exchange and the
/// backward pass, with the first step's localization and map.
Loop walk_first_path(const Problem& problem, const Problem& fitted, const DiagnosisOptions& options, Diagnosis* d) {
  Loop loop = walk_first_path_forward(problem, fitted, options, d);
  finish_first_path(&loop, options, d);
  return loop;
}

/// The loop's other paths: when its first path ended with a residual larger than the noise (or
/// took two or more steps, DiagnosisOptions::alternatives_after_consistent_end), the loop is walked
/// again from each of the first ranking's next-best
/// effects (walk_other_paths): with several effects at once the best single effect may stand in
/// for them together, and no later step or exchange then leaves it.
void walk_other_paths(Loop* loop, const DiagnosisOptions& options, Diagnosis* d) {
  walk_other_paths(loop->fitted, loop->start, loop->before_the_loop, options, &loop->memo, d);
  count_screens(*loop, d);
}

/// The whole loop on `fitted` from d's calibration: its first path, then the others.
void run_loop(const Problem& problem, const Problem& fitted, const DiagnosisOptions& options, Diagnosis* d) {
  Loop loop = walk_first_path(problem, fitted, options, d);
  walk_other_paths(&loop, options, d);
  advise_measurements(fitted, d);
}

/// -2 ln L at the end of d's loop on `data` (unweighted, with a stated noise), up to a constant
/// common to the data corrected for the mesh and as measured, plus the critical value of a step
/// per kept effect (DiscretizationEstimate::score_corrected).
double loop_score(const Problem& data, const Diagnosis& d) {
  const double noise = data.measurement_noise->frequency;
  double score = d.final_fit.statistic;
  for (const MeasuredMode& m : data.measured)  // the frequencies the fit weighs
    if (m.weight > 0) score += std::log1p(m.model_error * m.model_error / (noise * noise));
  return score + d.ranking.critical_value * static_cast<double>(d.accepted().size());
}

/// Runs `beside` in a thread of its own (with DiagnosisOptions::walk_side_by_side) while `here`
/// runs in this one, and waits for both; without a thread to be had, one after the other.
template <typename Beside, typename Here>
void side_by_side(const DiagnosisOptions& options, Beside beside, Here here) {
  std::future<void> other;  // an exception of `here` waits for it before what it writes to goes
  if (options.walk_side_by_side) try {
      other = std::async(std::launch::async, beside);
    } catch (const std::system_error&) {  // no thread to be had: walked in turn below
    }
  here();
  if (other.valid())
    other.get();
  else
    beside();
}

/// True when two loops' forward steps end within DiagnosisOptions::other_data_margin of each other,
/// in critical values of `first_screen`'s step; false when a score is NaN (a loop that failed).
bool within_margin(double score, double other_score, const EffectRanking& first_screen,
                   const DiagnosisOptions& options) {
  const double gap = std::abs(score - other_score);
  return std::isfinite(gap) &&
         (std::isinf(options.other_data_margin) || gap < options.other_data_margin * first_screen.critical_value);
}

/// The loop on the data corrected for the mesh (`corrected`, from check_the_mesh()) and on the
/// data as measured; d becomes the one whose end scores lower, the data as measured on a tie or
/// when the corrected data's loop cannot run (its score is then NaN). Both loops take their first
/// path's forward steps. The rest of a first path (the exchange and the backward pass) is walked
/// for the data whose forward steps end lower, and for the other data only when theirs end within
/// DiagnosisOptions::other_data_margin of those (measured: docs/design.md, "The mesh's share").
/// The other paths, the most of a loop's cost, are walked first for the data whose first path
/// ends lower; for the other data only when their first path ends lower still than that loop's
/// end. Other paths replace a path only by one that ends lower, so what this gives up is the
/// other data's paths gaining more than the two ends differ by. The walks that do not depend on
/// one another run side by side with DiagnosisOptions::walk_side_by_side; when the first path on
/// the data as measured ends first, its other paths start while the other first path runs, and
/// are let go should they not be wanted: the same diagnosis, without the cores waiting on one walk.
void loop_with_and_without_the_mesh(const Problem& problem, const std::pair<Problem, Vector>& corrected,
                                    const DiagnosisOptions& options, Diagnosis* d) {
  Diagnosis as_measured = *d;
  const bool noise_known = d->noise_known;
  std::optional<Loop> corrected_loop, measured_loop;
  auto forward_corrected = [&] {
    try {  // a loop on the corrected data that cannot run leaves the one on the data as measured
      const Problem fitted = weighted_if(noise_known, corrected.first);
      calibrate_nominal(fitted, corrected.second, options, &d->calibration, &d->before);
      corrected_loop = walk_first_path_forward(problem, fitted, options, d);
    } catch (const std::runtime_error&) {
    }
  };
  side_by_side(options, forward_corrected, [&] {
    measured_loop = walk_first_path_forward(problem, weighted_if(noise_known, problem), options, &as_measured);
  });
  auto score_corrected = [&] { return corrected_loop ? loop_score(corrected.first, *d) : NAN; };
  auto score_as_measured = [&] { return loop_score(problem, as_measured); };
  using Walk = void (*)(Loop*, const DiagnosisOptions&, Diagnosis*);
  auto corrected_walks = [&](Walk walk) {  // as above: a failure leaves the data as measured
    try {
      walk(&*corrected_loop, options, d);
    } catch (const std::runtime_error&) {
      corrected_loop.reset();
    }
  };
  auto finish_corrected = [&] { corrected_walks(finish_first_path); };
  auto finish_measured = [&] { finish_first_path(&*measured_loop, options, &as_measured); };
  auto walk_corrected = [&] { corrected_walks(walk_other_paths); };
  auto walk_measured = [&] { walk_other_paths(&*measured_loop, options, &as_measured); };
  const bool finish_both = within_margin(score_corrected(), score_as_measured(), as_measured.ranking, options);
  // While the corrected data's first path still runs, the measured data's other paths are walked
  // already (the cores would otherwise wait on that one path): they are what follows below
  // whenever the data as measured lead, or come to lead; else the first path's end is taken back.
  std::optional<Diagnosis> measured_first_path;
  double measured_first_score = NAN;
  if (finish_both) {
    std::future<void> corrected_beside;  // declared after all it writes to (as side_by_side's)
    if (options.walk_side_by_side) try {
        corrected_beside = std::async(std::launch::async, finish_corrected);
      } catch (const std::system_error&) {
      }
    finish_measured();
    measured_first_score = score_as_measured();
    if (corrected_beside.valid() && corrected_beside.wait_for(std::chrono::seconds(0)) != std::future_status::ready) {
      measured_first_path = as_measured;
      walk_measured();
    }
    if (corrected_beside.valid())
      corrected_beside.get();
    else
      finish_corrected();
  } else {  // only the data whose forward steps end lower: the other's score stays those steps'
    if (score_corrected() < score_as_measured()) finish_corrected();
    if (!(score_corrected() < score_as_measured())) finish_measured();
    measured_first_score = score_as_measured();
  }
  const bool corrected_first = score_corrected() < measured_first_score;
  if (corrected_first)
    walk_corrected();
  else if (!measured_first_path)
    walk_measured();
  // The other data's first path ends lower than the end just walked (or the corrected loop failed).
  const bool other_leads =
      (score_corrected() < (corrected_first ? measured_first_score : score_as_measured())) != corrected_first;
  if (other_leads && !corrected_first) walk_corrected();
  if (other_leads && corrected_first && !measured_first_path) walk_measured();
  if (!other_leads && corrected_first && measured_first_path) as_measured = std::move(*measured_first_path);
  const double corrected_score = score_corrected(), as_measured_score = score_as_measured();
  const Problem& kept_fitted = corrected_score < as_measured_score ? corrected_loop->fitted : measured_loop->fitted;
  if (!(corrected_score < as_measured_score)) *d = std::move(as_measured);
  advise_measurements(kept_fitted, d);
  d->discretization->corrected = corrected_score < as_measured_score;
  d->discretization->score_corrected = corrected_score;
  d->discretization->score_as_measured = as_measured_score;
  d->discretization->other_data_first_path_only = corrected_loop && !other_leads;
  d->discretization->other_data_forward_steps_only = corrected_loop && !finish_both;
}

/// An effect to start from given twice is the caller's mistake: said before the first calibration,
/// where the loop's start would only find that the effects make no model.
void check_starting_effects(const Problem& problem, const DiagnosisOptions& options) {
  std::vector<EffectCandidate> effects = enabled_candidates(problem, options.candidates);
  effects.insert(effects.end(), options.added.begin(), options.added.end());
  for (size_t k = 0; k < effects.size(); ++k)
    for (size_t j = 0; j < k; ++j)
      if (effects[j].name == effects[k].name)
        throw std::invalid_argument("diagnose: the effect " + effects[k].name +
                                    " is given twice among the problem's enabled effects and DiagnosisOptions::added");
}

}  // namespace

namespace {

/// Without a stated noise the misfit is no chi-square, and the calibrations' absolute tolerances,
/// meant for one, would end them short of the data's resolution on data a model all but meets
/// (below 1, the function tolerance stops any step that gains less than a thousandth): they are
/// taken in units of the resolution's variance per datum instead.
DiagnosisOptions in_misfit_units(const Problem& problem, DiagnosisOptions options) {
  if (has_noise(problem)) return options;
  const double unit = resolution_variance(problem, options.ranking.resolution);
  for (ReducedOptions* walk : {&options.calibration, &options.ranking.refit}) {
    walk->gradient_tolerance *= unit;
    walk->function_scale = unit;
  }
  return options;
}

/// The diagnosis from the nominal calibration started at `start`.
Diagnosis diagnose_from(const Problem& problem, const Vector& start, const DiagnosisOptions& options) {
  Diagnosis d;
  d.noise_known = has_noise(problem);
  const StartKept kept =
      calibrate_nominal(weighted_if(d.noise_known, problem), start, options, &d.calibration, &d.before, true);
  d.calibration_start = kept.start;
  d.first_calibration_local_minimum = kept.given_end;
  const std::optional<std::pair<Problem, Vector>> corrected =
      options.finer_mesh ? check_the_mesh(problem, options, &d) : std::nullopt;
  if (corrected)
    loop_with_and_without_the_mesh(problem, *corrected, options, &d);
  else
    run_loop(problem, weighted_if(d.noise_known, problem), options, &d);
  // What the backward pass kept decides, not the forward steps: a step whose refit only escaped
  // a local minimum of the calibration is dropped again, and the residual at the end is noise.
  d.at_resolution = at_resolution(d.final_fit, options.ranking.resolution);
  d.model_form_error = !d.accepted().empty() ||
                       (d.final_fit.test ? d.final_fit.test->model_form_error : !d.at_resolution) ||
                       bound_limited(d) != nullptr;
  if (!d.accepted().empty()) {
    d.recommended = rank_of(d.ranking, d.steps.front().effect.candidate.name) - 1;
    d.after = d.final_fit;
  }
  d.calibration.initial = start;  // the caller's, whichever run the kept calibration is
  return d;
}

/// True when the loop ended with the problem's model as it is (no effect kept, the data as
/// measured) at a calibration lower than the first by more than a step's critical value: the
/// first stopped in a local minimum, which a refit with some effect left before the backward
/// pass dropped the effect again, and every screen was made from there.
bool left_a_local_minimum(const Diagnosis& d) {
  return d.effects.empty() && !(d.discretization && d.discretization->corrected) && !d.rankings.empty() &&
         d.final_fit.statistic < d.before.statistic - d.rankings.front().critical_value;
}

}  // namespace

Diagnosis diagnose(const Problem& problem, const Vector& start, const DiagnosisOptions& given) {
  std::string error;
  if (!given.IsValid(&error)) throw std::invalid_argument("DiagnosisOptions: " + error);
  const DiagnosisOptions options = in_misfit_units(problem, given);
  if (start.size() != static_cast<int>(problem.parameters.size()))
    throw std::invalid_argument("diagnose: " + std::to_string(start.size()) + " start values for " +
                                std::to_string(problem.parameters.size()) + " parameters");
  check_starting_effects(problem, options);
  Diagnosis d = diagnose_from(problem, start, options);
  if (left_a_local_minimum(d)) {  // once: from the lower minimum, the screens are the model's
    const double first = std::isfinite(d.first_calibration_local_minimum) ? d.first_calibration_local_minimum
                                                                           : d.before.statistic;
    d = diagnose_from(problem, d.final_parameters, options);
    d.calibration.initial = start;
    d.calibration_start = -1;
    d.first_calibration_local_minimum = first;
  }
  d.calibration_on_bounds = held_on_bounds(problem, d.calibration.final);
  d.recommendation = recommendation_text(d, options.ranking.resolution);
  return d;
}

std::vector<std::string> Diagnosis::accepted() const {
  std::vector<std::string> names;
  for (const EffectCandidate& c : effects)
    if (step_that_added(*this, c.name)) names.push_back(c.name);
  return names;
}

std::string format_diagnosis(const Problem& problem, const Diagnosis& d) {
  std::string text;
  char line[320];
  std::snprintf(line, sizeof line, "calibration: %s after %d iterations, %d forward solves%s\n",
                to_string(d.calibration.status).c_str(), d.calibration.iterations, d.calibration.forward_solves,
                d.calibration_start > 0 ? (" (from start " + std::to_string(d.calibration_start) +
                                           " in the parameters' bounds; the given start ended higher)").c_str()
                                        : "");
  text += line;
  for (size_t j = 0; j < problem.parameters.size(); ++j) {
    std::snprintf(line, sizeof line, "  %-20s %13.5g\n", problem.parameters[j].name.c_str(), d.calibration.final[j]);
    text += line;
  }
  text += "\nresidual test: " + verdict(d.before) + "\n";
  if (d.discretization) text += "\n" + format_discretization(*d.discretization);
  std::snprintf(line, sizeof line,
                "\nwhere the model fails (the first step's screen: -log10 p of the best effect at each place; noise "
                "alone stays below about %.1f):\n",
                std::log10(std::max<size_t>(1, d.map.places.size())) + 2);
  text += line + format_screen_map(d.map, 5);
  text += "a second view, the residual forces of the expanded measured shapes:\n";
  text += d.localization ? format_ranking(*d.localization, 5) : d.localization_note + "\n";
  text += "\nwhich effect is missing (the first step's screen):\n" + format_effect_ranking(d.ranking, 10);
  text += "\n" + format_steps(problem, d);
  text += "\n" + d.recommendation + "\n";
  if (d.after) {
    const Problem with = problem_with_diagnosed_effects(problem, d);
    if (d.discretization && d.discretization->corrected)
      text += "\n(measured: the data corrected for the mesh, each frequency moved by its change on the finer mesh)";
    text += "\n" + format_before_after(with, d.before, *d.after, "nominal", "with effects");
  }
  return text;
}

std::string format_discretization(const DiscretizationEstimate& est) {
  char line[256];
  std::snprintf(line, sizeof line,
                "discretization (a mesh %.3g times finer, %d DOFs against %d): each mode's frequency change there\n",
                est.refinement, est.finer_dofs, est.dofs);
  std::string text = line;
  for (const DiscretizationEstimate::Mode& m : est.per_mode) {
    std::snprintf(line, sizeof line, "  %-14s %+9.4f %% (extrapolated %+9.4f %%)\n", m.label.c_str(), m.shift_percent,
                  m.extrapolated_percent);
    text += line;
  }
  if (est.sensors_moved > 0) {
    std::snprintf(line, sizeof line,
                  "  sensor readings the finer mesh takes elsewhere: %d, at its nearest nodes up to %.3g away, "
                  "their shapes not corrected; mesh planes through the sensors hold them in place\n",
                  est.sensors_moved, est.sensor_offset);
    text += line;
  }
  if (est.chi2_explained < 0) {
    // The finer mesh moves the model away from the data: what misfits is not the mesh.
    std::snprintf(line, sizeof line,
                  "  explains none of the chi-square: the data corrected for it fit worse (by %.4g)\n",
                  -est.chi2_explained);
    return text + line;
  }
  std::snprintf(line, sizeof line, "  explains %.4g of the chi-square (%s %.3g)%s\n", est.chi2_explained,
                est.significant ? "more than" : "not more than", est.critical_value,
                est.corrected ? "; the diagnosis below is of the data corrected for it" : "");
  text += line;
  if (std::isfinite(est.score_corrected) && std::isfinite(est.score_as_measured)) {
    std::snprintf(line, sizeof line,
                  "  the loop on both: -2 ln L plus a step's critical value per effect %.4g corrected, %.4g as "
                  "measured; the diagnosis below is of the data %s\n",
                  est.score_corrected, est.score_as_measured, est.corrected ? "corrected" : "as measured");
    text += line;
    const std::string other = est.corrected ? "the data as measured" : "the corrected data";
    if (est.other_data_forward_steps_only)
      text += "  the loop on " + other + " took its first path's forward steps only: they ended higher than the "
              "other loop's by more than the margin (--other-data-margin)\n";
    else if (est.other_data_first_path_only)
      text += "  the loop on " + other + " walked its first path only: that ended higher than the other loop's end\n";
  }
  return text;
}

/// The reading and the unmeasured mode that would tell a step's effect from an alternative.
std::string tell_apart_text(const Problem& problem, const TellApart& t) {
  std::string text;
  char b[320];
  if (t.node >= 0 && t.measured >= 0 && static_cast<size_t>(t.measured) < problem.measured.size()) {
    std::snprintf(b, sizeof b, "a reading at node %ld [%.4g, %.4g, %.4g] along %c in %s (%.2g noise sd apart)",
                  problem.model.node_ids[static_cast<size_t>(t.node)], t.location[0], t.location[1], t.location[2],
                  "xyz"[t.component], problem.measured[static_cast<size_t>(t.measured)].label.c_str(), t.shape_separation);
    text += b;
  }
  if (t.model_mode >= 0) {
    std::snprintf(b, sizeof b, "%smodel mode %d at %.4g Hz, not measured (%.2g noise sd apart)", text.empty() ? "" : "; ",
                  t.model_mode + 1, t.model_hz, t.frequency_separation);
    text += b;
  }
  if (text.empty()) return "              nothing this model computes tells them apart\n";
  return "              to tell them apart: " + text + "\n";
}

/// The paths walked from the first step's alternatives, the kept one marked.
std::string paths_text(const Diagnosis& d) {
  if (d.paths.size() < 2) return "";
  char line[200];
  std::snprintf(line, sizeof line,
                "the loop walked from the first step's next-best effects too; kept the path that ends lowest in %s "
                "plus %.3g and its kind's prior penalty per effect:\n",
                chi2_text(d.noise_known).c_str(), d.ranking.critical_value);
  std::string text = line;
  for (const DiagnosisPath& path : d.paths) {
    std::string kept;
    for (const std::string& name : path.accepted) kept += (kept.empty() ? "" : ", ") + name;
    std::snprintf(line, sizeof line, "  %s from %s: %.4g + %zu effects = %.4g (", path.kept ? "*" : " ",
                  path.first.c_str(), path.chi2_final, path.accepted.size(), path.score);
    text += line + (kept.empty() ? std::string("nothing kept") : kept) + ")";
    if (!path.joined.empty())
      text += ", joined the path from " + path.joined + " after " + std::to_string(path.joined_after) + " steps" +
              (path.joined_after_exchanges > 0
                   ? " and " + std::to_string(path.joined_after_exchanges) +
                         (path.joined_after_exchanges > 1 ? " exchanges" : " exchange")
                   : "");
    if (path.no_second_step) text += ", no second step: walked no further";
    text += "\n";
  }
  std::snprintf(line, sizeof line, "  (%d screens of the candidates; %d more were a model screened before, at the same fit)\n",
                d.screens, d.screens_reused);
  return text + line;
}

namespace {

/// One of step `s`'s alternatives. Where the data favour it by more than 20 : 1 the line says so,
/// and what chose the step's effect instead: the prior over kinds, or (`first_of_kept_path`) the
/// path the loop kept, which began with it. "Hardly tell" would hide that the data, alone, point
/// elsewhere.
std::string alternative_text(const DiagnosisStep& s, const RankedEffect& a, bool first_of_kept_path) {
  char line[400];
  if (!s.data_favour(a)) {
    std::snprintf(line, sizeof line, "            the data hardly tell it from %s = %.4g (%.4g -> %.4g)\n",
                  a.candidate.name.c_str(), a.value, s.chi2_before, a.chi2_after);
    return line;
  }
  char why[160] = "";
  if (s.prior_overruled(a))
    std::snprintf(why, sizeof why, "; the prior over kinds chose the step's effect (kind penalty 2 ln n %.3g against %.3g)",
                  s.effect.kind_penalty, a.kind_penalty);
  else if (first_of_kept_path)
    std::snprintf(why, sizeof why, "; the path kept, which ends lowest (below), began with the step's effect");
  std::snprintf(line, sizeof line, "            the data favour %s = %.4g (%.4g -> %.4g) by more than 20 : 1%s\n",
                a.candidate.name.c_str(), a.value, s.chi2_before, a.chi2_after, why);
  return line;
}

/// The line of a fit in the stepwise text: its statistic, and with a stated noise the test.
std::string fit_line_text(const FitState& fit) {
  char b[160];
  if (fit.test)
    std::snprintf(b, sizeof b, "%.4g on %d dof, p = %.3g%s", fit.statistic, fit.test->dof, fit.test->p_value,
                  fit.test->model_form_error ? " (more than the noise)" : " (consistent with the noise)");
  else
    std::snprintf(b, sizeof b, "%.4g", fit.statistic);
  return b;
}

/// A forward step's lines in the stepwise text: the effect, its place and test, its alternatives.
std::string forward_step_text(const Problem& problem, const Diagnosis& d, const DiagnosisStep& s) {
  std::string where = "block-wide";
  if (s.location) {
    char b[160];
    std::snprintf(b, sizeof b, "at [%.4g, %.4g, %.4g]", (*s.location)[0], (*s.location)[1], (*s.location)[2]);
    where = b;
    if (s.places > 1) {
      std::snprintf(b, sizeof b, ", or within %.3g of there: %d places fit alike", s.place_spread, s.places);
      where += b;
    }
  }
  char line[400];
  std::snprintf(line, sizeof line, "  step %-3d  + %s = %.4g%s (%s): %.4g -> %.4g (%s %.4g > %.4g, %d screened)\n",
                s.step, s.effect.candidate.name.c_str(), s.effect.value,
                std::isfinite(s.effect.standard_error) ? (" +/- " + format_number(s.effect.standard_error)).c_str() : "",
                where.c_str(), s.chi2_before, s.effect.chi2_after, d.noise_known ? "dX2" : "F", s.effect.statistic,
                s.critical_value, s.screened);
  std::string text = line;
  for (size_t k = 0; k < s.alternatives.size(); ++k) {
    text += alternative_text(s, s.alternatives[k], s.step == 1 && d.paths.size() > 1);
    if (k < s.tell_apart.size()) text += tell_apart_text(problem, s.tell_apart[k]);
  }
  return text;
}

/// An exchange's line in the stepwise text.
std::string exchange_text(const DiagnosisStep& x) {
  char line[400];
  if (x.replaced_on_bound)
    std::snprintf(line, sizeof line, "  exchange  %s -> %s = %.4g: with the others in, the first ends on a bound\n",
                  x.replaces.c_str(), x.effect.candidate.name.c_str(), x.effect.value);
  else if (std::isfinite(x.pair_score_change))
    std::snprintf(line, sizeof line,
                  "  exchange  %s -> %s = %.4g and the next step: with the others in, the two score %.4g lower than the first alone\n",
                  x.replaces.c_str(), x.effect.candidate.name.c_str(), x.effect.value, -x.pair_score_change);
  else
    std::snprintf(line, sizeof line, "  exchange  %s -> %s = %.4g: with the others in, S %.4g beats %.4g\n",
                  x.replaces.c_str(), x.effect.candidate.name.c_str(), x.effect.value, x.effect.score(),
                  x.replaced_score);
  return line;
}

}  // namespace

std::string format_steps(const Problem& problem, const Diagnosis& d) {
  std::string text = "the stepwise loop (" + chi2_text(d.noise_known) + " after each accepted effect):\n";
  text += "  start     " + fit_line_text(d.before) + "\n";
  // In the order the loop made them: an exchange that changed the model can be followed by steps.
  size_t next_exchange = 0;
  auto exchanges_after = [&](int steps) {
    for (; next_exchange < d.exchanges.size() && d.exchanges[next_exchange].after_step <= steps; ++next_exchange)
      text += exchange_text(d.exchanges[next_exchange]);
  };
  for (const DiagnosisStep& s : d.steps) {
    exchanges_after(s.step - 1);
    text += forward_step_text(problem, d, s);
  }
  exchanges_after(std::numeric_limits<int>::max());
  char line[400];
  for (const DroppedEffect& x : d.dropped) {
    if (x.on_bound)
      std::snprintf(line, sizeof line, "  backward  - %s: refitted with the later effects it ends on a bound (%.4g)\n",
                    x.name.c_str(), x.value);
    else
      std::snprintf(line, sizeof line, "  backward  - %s: without it %s only %.4g (< %.4g)\n", x.name.c_str(),
                    d.noise_known ? "the chi-square rises by" : "the F statistic is", x.chi2_increase, x.critical_value);
    text += line;
  }
  if (d.steps.empty()) text += "  no effect accepted\n";
  else text += "  end       " + fit_line_text(d.final_fit) + "\n";
  return text + paths_text(d);
}

Problem problem_with_diagnosed_effects(const Problem& problem, const Diagnosis& d) {
  const Eigen::Index np = static_cast<Eigen::Index>(problem.parameters.size());
  std::vector<double> values(d.final_parameters.data() + np, d.final_parameters.data() + d.final_parameters.size());
  Problem with = problem_with_effects(problem, d.effects, values);
  for (Eigen::Index j = 0; j < np; ++j) with.parameters[j].initial = d.final_parameters[j];
  return with;
}

int rank_of(const EffectRanking& ranking, const std::string& name) {
  for (size_t k = 0; k < ranking.effects.size(); ++k)
    if (ranking.effects[k].candidate.name == name) return static_cast<int>(k) + 1;
  return 0;
}

}  // namespace modalcal
