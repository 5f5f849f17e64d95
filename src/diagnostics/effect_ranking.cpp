// The effect ranking: a first-order screen of every candidate from one Jacobian, then refits of
// the best (formulas in effects.hpp).
#include <Eigen/QR>
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <functional>
#include <limits>
#include <map>
#include <numeric>
#include <optional>
#include <set>
#include <stdexcept>

#include "modalcal/effects.hpp"
#include "modalcal/task_map.hpp"
#include "refit_walk.hpp"
#include "same_change.hpp"
#include "support/text_util.hpp"

namespace modalcal {

namespace {

using Clock = std::chrono::steady_clock;

double seconds_since(Clock::time_point start) { return std::chrono::duration<double>(Clock::now() - start).count(); }

/// The screening variable of a value, and back.
double to_variable(const EffectCandidate& c, double value) {
  switch (c.variable) {
    case EffectCandidate::Variable::Log:
      return std::log10(value);
    case EffectCandidate::Variable::Linear:
      return value;
    case EffectCandidate::Variable::Compliance:
      return 1 / value;  // 0 for +infinity
  }
  return value;
}
double from_variable(const EffectCandidate& c, double x) {
  switch (c.variable) {
    case EffectCandidate::Variable::Log:
      return std::pow(10.0, x);
    case EffectCandidate::Variable::Linear:
      return x;
    case EffectCandidate::Variable::Compliance:
      return x > 0 ? 1 / x : std::numeric_limits<double>::infinity();
  }
  return x;
}
/// d value / d variable at `value`.
double value_per_variable(const EffectCandidate& c, double value) {
  switch (c.variable) {
    case EffectCandidate::Variable::Log:
      return value * std::log(10.0);
    case EffectCandidate::Variable::Linear:
      return 1;
    case EffectCandidate::Variable::Compliance:
      return -value * value;  // k = 1/c
  }
  return 1;
}

/// The misfit statistic at an evaluation: X^2 against the stated noise, or without one 2J
/// (the objective's own weights), with its degrees of freedom and number of data.
struct Misfit {
  double statistic = 0;
  int dof = 1, data = 0;
  double p_value = NAN;
  bool model_form_error = false;
};

Misfit misfit_of(const Objective& objective, const Evaluation& e, int num_parameters, double significance) {
  const Problem& problem = objective.problem();
  Misfit m;
  if (problem.measurement_noise && problem.measurement_noise->frequency > 0) {
    ResidualTestOptions options;
    options.significance = significance;
    const ResidualTest t = test_residual(objective, e, *problem.measurement_noise, num_parameters, options);
    m.statistic = t.statistic;
    m.dof = t.dof;
    m.p_value = t.p_value;
    m.model_form_error = t.model_form_error;
    for (const ModeResidual& r : t.modes) m.data += r.dof;
    return m;
  }
  m.statistic = e.residuals.squaredNorm();
  m.data = count_data(problem, e);
  m.dof = std::max(1, m.data - num_parameters);
  return m;
}

}  // namespace

double gain_critical_value(const EffectRanking& ranking, double alpha, int num_parameters) {
  if (ranking.noise_known) return chi_square_critical_value(alpha, 1);
  const int dof = ranking.num_data - num_parameters;
  return dof >= 1 ? f_critical_value(alpha, 1, dof) : INFINITY;
}

namespace {

std::string format_value(double v) {
  char buffer[32];
  std::snprintf(buffer, sizeof buffer, "%.3g", v);
  return buffer;
}

/// A candidate's kind for the prior of effects.hpp ("Which effect"): its change's kind and
/// property, except that added point masses and the mass scales of block regions are one kind,
/// mass added (or missing) at a place: two parametrizations of one physical hypothesis, which the
/// fit, not their numbers, should choose between. A declared candidate is a kind of its own.
std::string kind_of(const EffectCandidate& c) {
  if (c.declared) return "declared " + c.name;
  if (detail::local_mass(c)) return "local mass";
  return std::to_string(static_cast<int>(c.change.kind)) + " " + c.change.property;
}

/// Sets every screened candidate's kind size and penalty.
void set_kind_penalties(std::vector<RankedEffect>* screened, bool equal_kind_prior) {
  std::map<std::string, int> sizes;
  for (const RankedEffect& r : *screened) ++sizes[kind_of(r.candidate)];
  for (RankedEffect& r : *screened) {
    r.kind_size = sizes[kind_of(r.candidate)];
    r.kind_penalty = equal_kind_prior ? 2 * std::log(static_cast<double>(r.kind_size)) : 0.0;
  }
}

/// How many of the best predictions to refit (RankingOptions::refits, weak_refits): more when
/// the best prediction, as the test's statistic, lies within `weak_prediction` critical values,
/// where the first-order ranking of places is flat. Without a stated noise the statistic divides
/// by the calibrated point's residual per degree of freedom, as a refit's does by its own.
int refit_count(const std::vector<RankedEffect>& screened, const RankingOptions& options, const EffectRanking& ranking) {
  if (screened.empty()) return options.refits;
  const double noise_variance =
      ranking.noise_known ? 1.0 : std::max(ranking.chi2_before / std::max(1, ranking.dof_before), ranking.resolution_variance);
  const bool weak = screened.front().predicted_reduction / noise_variance < options.weak_prediction * ranking.critical_value;
  return weak ? std::max(options.refits, options.weak_refits) : options.refits;
}

/// The `refits` candidates to refit from `screened` (in order of prediction): the best
/// prediction, then by predicted score (prediction less the kind's penalty), at most one of each
/// group of neighbours (the best of it).
std::vector<size_t> refit_choices(const std::vector<RankedEffect>& screened, int refits) {
  std::vector<size_t> order(screened.size());
  std::iota(order.begin(), order.end(), size_t{0});
  if (!order.empty())
    std::stable_sort(order.begin() + 1, order.end(),
                     [&](size_t a, size_t b) { return screened[a].score() > screened[b].score(); });
  std::vector<size_t> chosen;
  for (size_t k : order) {
    if (static_cast<int>(chosen.size()) >= refits) break;
    if (std::none_of(chosen.begin(), chosen.end(),
                     [&](size_t c) { return screened[c].candidate.neighbour_of(screened[k].candidate); }))
      chosen.push_back(k);
  }
  return chosen;
}

/// Adds to `chosen` up to RankingOptions::place_refits candidates of `screened` (in order of
/// prediction) that act apart from every one chosen before: farther than a quarter of the
/// model's size, with a prediction at least place_refit_share of the best.
void add_place_refits(const Model& model, const std::vector<RankedEffect>& screened, const RankingOptions& options,
                      std::vector<size_t>* chosen) {
  if (screened.empty() || options.place_refits == 0) return;
  const double apart = bounding_box_diagonal(model) / 4, least = options.place_refit_share * screened.front().predicted_reduction;
  std::vector<Vec3> places;
  for (size_t c : *chosen)
    if (std::optional<Vec3> at = effect_place(model, screened[c].candidate)) places.push_back(*at);
  int added = 0;
  for (size_t k = 0; k < screened.size() && added < options.place_refits; ++k) {
    if (!(screened[k].predicted_reduction >= least)) break;
    if (std::find(chosen->begin(), chosen->end(), k) != chosen->end()) continue;
    const std::optional<Vec3> at = effect_place(model, screened[k].candidate);
    if (!at || std::any_of(places.begin(), places.end(), [&](const Vec3& p) { return (p - *at).norm() <= apart; }))
      continue;
    chosen->push_back(k);
    places.push_back(*at);
    ++added;
  }
}

/// Adds to `chosen` the best candidate of up to RankingOptions::kind_refits kinds that no
/// candidate in it has, best score first, with a prediction at least kind_refit_share of the
/// best. A kind's candidates share its penalty, so its best score is its best prediction.
void add_kind_refits(const std::vector<RankedEffect>& screened, const RankingOptions& options,
                     std::vector<size_t>* chosen) {
  if (screened.empty() || options.kind_refits == 0) return;
  const double least = options.kind_refit_share * screened.front().predicted_reduction;
  std::set<std::string> kinds;
  for (size_t c : *chosen) kinds.insert(kind_of(screened[c].candidate));
  std::vector<size_t> best_of_kinds;
  for (size_t k = 0; k < screened.size() && screened[k].predicted_reduction >= least; ++k)
    if (kinds.insert(kind_of(screened[k].candidate)).second) best_of_kinds.push_back(k);
  std::stable_sort(best_of_kinds.begin(), best_of_kinds.end(),
                   [&](size_t a, size_t b) { return screened[a].score() > screened[b].score(); });
  const size_t count = std::min(best_of_kinds.size(), static_cast<size_t>(options.kind_refits));
  chosen->insert(chosen->end(), best_of_kinds.begin(), best_of_kinds.begin() + static_cast<std::ptrdiff_t>(count));
}

/// Two walks' counts as one.
/// `then` as the summary of both walks: it started where `first` did, and counts the work of both.
void add_counts(const ReducedSummary& first, ReducedSummary* then) {
  if (first.initial.size() > 0) then->initial = first.initial;
  then->seconds += first.seconds;
  then->iterations += first.iterations;
  then->forward_solves += first.forward_solves;
  then->linear_solves += first.linear_solves;
  then->failed_evaluations += first.failed_evaluations;
}

/// Whether `end`, where a walk in the objective's span stopped, is where a Gauss-Newton walk on
/// the whole model would stop too: the whole model's misfit there agrees with the span's
/// (`span_value`) to the refit's function tolerance, and a Gauss-Newton step with the whole
/// model's gradient (the span's Jacobian standing in for the whole one's) would lower it by less
/// than that. Parameters on a bound that the gradient pushes against are left out of the step.
/// Leaves the objective on the whole model, with its value at `end` in `whole_value`.
bool ends_on_the_whole_model(Objective& objective, const Vector& end, double span_value, double tolerance,
                             double* whole_value) {
  const Evaluation in_span = objective.evaluate(end, Need::Jacobian);
  objective.set_span(Matrix());
  const Evaluation value = objective.evaluate(end, Need::Value);
  *whole_value = value.ok ? value.value : NAN;
  if (!in_span.ok || !value.ok || !(std::abs(value.value - span_value) <= tolerance * value.value)) return false;
  const Evaluation whole = objective.evaluate(end, Need::Gradient);  // the same solve, and its adjoint
  if (!whole.ok) return false;
  const std::vector<Parameter>& parameters = objective.problem().parameters;
  std::vector<Eigen::Index> free;
  for (Eigen::Index j = 0; j < end.size(); ++j) {
    const Parameter& q = parameters[static_cast<size_t>(j)];
    const double width = 1e-9 * (q.upper - q.lower);
    const bool held = (end[j] <= q.lower + width && whole.gradient[j] > 0) ||
                      (end[j] >= q.upper - width && whole.gradient[j] < 0);
    if (!held) free.push_back(j);
  }
  if (free.empty()) return true;  // every parameter held on a bound: no step is left to take
  Matrix J(in_span.jacobian.rows(), static_cast<Eigen::Index>(free.size()));
  Vector g(static_cast<Eigen::Index>(free.size()));
  for (size_t k = 0; k < free.size(); ++k) {
    J.col(static_cast<Eigen::Index>(k)) = in_span.jacobian.col(free[k]);
    g[static_cast<Eigen::Index>(k)] = whole.gradient[free[k]];
  }
  Matrix H = J.transpose() * J;
  H.diagonal().array() += 1e-12 * std::max(H.diagonal().maxCoeff(), 1e-300);
  const double predicted_decrease = 0.5 * g.dot(H.ldlt().solve(g));
  return predicted_decrease <= tolerance * whole.value;
}

/// One walk in a span from `*start` (`span`, else span_at(*start)), its end checked on the whole
/// model. True with the walk in `walk` when the end is kept. Otherwise `walk` holds what the walk
/// cost (nothing when no span was taken), `*start` moves to the walk's end if the whole model
/// could be evaluated there, and the objective is on the whole model.
bool walk_in_span(Objective& objective, Matrix span, const RankingOptions& options, Vector* start,
                  ReducedSummary* walk) {
  if (span.size() == 0) try {
      span = objective.span_at(*start);
    } catch (const std::runtime_error&) {
      return false;  // the whole model's walk fails there too, with its reason
    }
  if (span.cols() > options.refit_span_share * objective.system().num_dofs()) return false;
  objective.set_span(std::move(span));
  *walk = minimize_reduced(objective, *start, options.refit);
  double whole_value = NAN;
  if (walk->final.size() == start->size() && std::isfinite(walk->final_objective) &&
      ends_on_the_whole_model(objective, walk->final, walk->final_objective, options.refit.function_tolerance,
                              &whole_value)) {
    walk->final_objective = whole_value;
    ++walk->forward_solves;
    return true;
  }
  objective.set_span(Matrix());
  if (std::isfinite(whole_value)) *start = walk->final;
  return false;
}

}  // namespace

namespace detail {

ReducedSummary refit_walk(Objective& objective, const Vector& p0, const RankingOptions& options, Matrix span) {
  if (!(options.refit_span_share * objective.system().num_dofs() >= 1))
    return minimize_reduced(objective, p0, options.refit);
  // A span from far away (the step's, or the start's when the walk went far) can miss the whole
  // model's minimum by more than the tolerance; the span at the walk's end, where the check has
  // solved the whole model already, then costs only its block solves.
  Vector start = p0;
  ReducedSummary spent;
  for (int round = 0; round < 2; ++round) {
    ReducedSummary walk;
    const Vector before = start;
    const bool kept = walk_in_span(objective, round == 0 ? std::move(span) : Matrix(), options, &start, &walk);
    add_counts(spent, &walk);
    if (kept) return walk;
    spent = walk;
    if (start == before) break;  // no span, or no whole-model point to span from
  }
  ReducedSummary rest = minimize_reduced(objective, start, options.refit);
  add_counts(spent, &rest);
  return rest;
}

StepSpan::StepSpan(Objective& ranked, const Vector& calibrated, const RankingOptions& options)
    : ranked_(ranked), calibrated_(calibrated) {
  const double dofs = ranked.system().num_dofs();
  if (!(options.refit_span_share * dofs >= 1)) return;
  try {
    span_ = ranked.span_at(calibrated);
  } catch (const std::runtime_error&) {
    return;  // each refit tries its own
  }
  if (span_.cols() > options.refit_span_share * dofs) span_ = Matrix();
}

Matrix StepSpan::for_refit(const Objective& refit, const Vector& p0) {
  if (span_.size() == 0 || !(refit.system().dof_map() == ranked_.system().dof_map())) return Matrix();
  const std::lock_guard<std::mutex> one_at_a_time(turn_);
  try {
    return ranked_.extend_span(span_, calibrated_, refit.system(), p0);
  } catch (const std::runtime_error&) {
    return Matrix();
  }
}

}  // namespace detail

namespace {

/// One refit (every calibration parameter free, the effect started at its first-order value or
/// its declared start), as a TaskMap result: the optimizer's outcome, then whether the refitted
/// model could be evaluated, and its misfit.
std::string refit_candidate(const Problem& problem, const RankedEffect& ranked, const RankingOptions& options,
                            detail::StepSpan* step) {
  const Eigen::Index np = static_cast<Eigen::Index>(problem.parameters.size());
  const EffectCandidate& c = ranked.candidate;
  double start = c.initial.value_or(ranked.predicted_value);
  start = std::clamp(start, c.lower, c.upper);
  if (c.variable == EffectCandidate::Variable::Compliance && !std::isfinite(start)) start = c.upper;
  const Problem with = problem_with_effects(problem, {c}, {start});
  Objective refit_objective(with, options.refit_objective());
  Vector p0 = ranked.parameters;  // the first-order estimate of every parameter
  p0[np] = start;
  const ReducedSummary refit = detail::refit_walk(refit_objective, p0, options, step->for_refit(refit_objective, p0));
  TaskCodec outcome;
  outcome.put(static_cast<double>(static_cast<int>(refit.status)));
  outcome.put(static_cast<double>(refit.iterations));
  outcome.put(static_cast<double>(refit.forward_solves));
  outcome.put(static_cast<double>(refit.linear_solves));
  outcome.put(refit.message);
  outcome.put(refit.final);
  const Evaluation after = refit.final.size() == np + 1 ? refit_objective.evaluate(refit.final) : Evaluation();
  outcome.put(after.ok ? 1.0 : 0.0);
  if (!after.ok) return outcome.str();
  const Misfit m = misfit_of(refit_objective, after, static_cast<int>(np) + 1, options.significance);
  outcome.put(m.statistic);
  outcome.put(static_cast<double>(m.dof));
  outcome.put(m.p_value);
  outcome.put(m.model_form_error ? 1.0 : 0.0);
  return outcome.str();
}

/// The candidates that apply to the model (at their screen values, one after the other to the
/// same model, so each is checked with the ones before it: of two that clash, the later is set
/// aside), the others set aside with the reason.
std::vector<EffectCandidate> applicable(const Problem& problem, const std::vector<EffectCandidate>& candidates,
                                        EffectRanking* ranking) {
  std::vector<ModelChange> changes;
  for (const EffectCandidate& c : candidates) {
    changes.push_back(c.change);
    changes.back().value = c.screen_value;
  }
  std::vector<EffectCandidate> usable;
  Model trial = problem.model;
  for (size_t k = 0; k < candidates.size(); ++k) {
    try {
      apply_model_change(&trial, changes[k]);
      usable.push_back(candidates[k]);
    } catch (const std::invalid_argument& e) {
      ranking->set_aside.emplace_back(candidates[k].name, std::string("could not be applied: ") + e.what());
    }
  }
  return usable;
}

/// The screen's Jacobian: the calibration parameters' columns and each usable candidate's, at the
/// calibrated point with every candidate at its screen value.
struct ScreenJacobian {
  Matrix parameters, candidates;
  std::vector<bool> evaluated;  // per usable candidate
};

/// One evaluation for all. If that model cannot be solved (many stiff support springs can make
/// the eigen-solver take elastic modes for rigid ones), the other candidates and each support's
/// candidates are evaluated apart, and a group that still fails is set aside.
ScreenJacobian screen_jacobian(const Problem& problem, const Vector& calibrated, const std::vector<EffectCandidate>& usable,
                               Eigen::Index num_residuals, const RankingOptions& options, EffectRanking* ranking) {
  const int np = static_cast<int>(problem.parameters.size());
  // The Jacobian of the model with a group of candidates added, calibration parameters first.
  auto jacobian_with = [&](const std::vector<EffectCandidate>& group, Evaluation* e) {
    std::vector<double> values;
    for (const EffectCandidate& c : group) values.push_back(c.screen_value);
    const Problem augmented = problem_with_effects(problem, group, values);
    Objective objective(augmented, options.objective);
    Vector p(np + group.size());
    p << calibrated, Eigen::Map<const Vector>(values.data(), static_cast<Eigen::Index>(values.size()));
    *e = objective.evaluate(p, Need::Jacobian);
    ranking->linear_solves += e->linear_solves;
    return e->ok;
  };
  ScreenJacobian s{Matrix(), Matrix(num_residuals, static_cast<Eigen::Index>(usable.size())),
                   std::vector<bool>(usable.size(), false)};
  Evaluation e;
  if (jacobian_with(usable, &e)) {
    s.parameters = e.jacobian.leftCols(np);
    s.candidates = e.jacobian.rightCols(usable.size());
    s.evaluated.assign(usable.size(), true);
    return s;
  }
  std::vector<std::string> keys;  // "" for the other candidates, else the support's place
  std::vector<std::vector<size_t>> groups;
  for (size_t k = 0; k < usable.size(); ++k) {
    const ModelChange& change = usable[k].change;
    const std::string key = change.kind == ModelChange::Kind::FlexibleSupport
                                ? "support " + to_string(change).substr(0, to_string(change).find(':'))
                                : "";
    const auto at = std::find(keys.begin(), keys.end(), key);
    if (at == keys.end()) {
      keys.push_back(key);
      groups.push_back({k});
    } else {
      groups[at - keys.begin()].push_back(k);
    }
  }
  for (const std::vector<size_t>& group : groups) {
    std::vector<EffectCandidate> members;
    for (size_t k : group) members.push_back(usable[k]);
    if (!jacobian_with(members, &e)) {
      for (size_t k : group) ranking->set_aside.emplace_back(usable[k].name, "could not be evaluated: " + e.message);
      continue;
    }
    if (s.parameters.size() == 0) s.parameters = e.jacobian.leftCols(np);
    for (size_t a = 0; a < group.size(); ++a) {
      s.candidates.col(group[a]) = e.jacobian.col(np + a);
      s.evaluated[group[a]] = true;
    }
  }
  if (s.parameters.size() == 0 && np > 0)
    throw std::runtime_error("rank_effects: no model with candidates added can be evaluated: " + e.message);
  return s;
}

/// What the calibration parameters can already do, to first order at the calibrated point: an
/// orthonormal basis of their (scaled) columns, and where the linear model puts them.
class ParameterSpan {
 public:
  ParameterSpan(const Problem& problem, const Vector& calibrated, Matrix jacobian, Eigen::Index num_residuals)
      : problem_(problem), calibrated_(calibrated), np_(static_cast<int>(problem.parameters.size())) {
    if (jacobian.size() == 0) jacobian = Matrix(num_residuals, 0);
    column_norms_ = Vector::Ones(np_);
    for (int j = 0; j < np_; ++j)
      if (const double n = jacobian.col(j).norm(); n > 0) {
        column_norms_[j] = n;
        jacobian.col(j) /= n;
      }
    qr_.setThreshold(1e-10);
    qr_.compute(jacobian);
    Q_ = np_ > 0 ? Matrix(qr_.householderQ() * Matrix::Identity(num_residuals, qr_.rank()))
                 : Matrix(num_residuals, 0);
  }
  /// `column` less what the calibration parameters can do.
  Vector projected(const Vector& column) const { return column - Q_ * (Q_.transpose() * column); }
  /// Where the linear model puts the calibration parameters once an effect with residual
  /// column `column` has moved by `step`: p - J_p^+ (r + column step), each kept within a factor
  /// of two and its bounds (the refit's start).
  Vector shifted(const Vector& r, const Vector& column, double step) const {
    Vector p1 = calibrated_;
    if (np_ == 0) return p1;
    const Vector shift = qr_.solve(Vector(-(r + column * step))).cwiseQuotient(column_norms_);
    for (int j = 0; j < np_; ++j) {
      const Parameter& q = problem_.parameters[j];
      const double v = calibrated_[j] + shift[j];
      p1[j] = std::clamp(calibrated_[j] > 0 ? std::clamp(v, 0.5 * calibrated_[j], 2 * calibrated_[j]) : v, q.lower,
                         q.upper);
    }
    return p1;
  }

 private:
  const Problem& problem_;
  const Vector& calibrated_;
  int np_;
  Vector column_norms_;
  Eigen::ColPivHouseholderQR<Matrix> qr_;
  Matrix Q_;
};

/// A line through residual space along which a candidate's effect is modelled: r + column t for
/// t in [lo, hi] (the candidate's bounds), and the candidate's value at t.
struct ResidualLine {
  Vector column;
  double lo = 0, hi = 0;
  std::function<double(double)> value_at;
};

/// The tangent: the Jacobian column in the candidate's screening variable, from its screen value.
ResidualLine tangent(const EffectCandidate& c, const Vector& column_per_value) {
  const double x0 = to_variable(c, c.screen_value);
  double lo = to_variable(c, c.lower) - x0, hi = to_variable(c, c.upper) - x0;
  if (lo > hi) std::swap(lo, hi);  // compliance runs opposite to stiffness
  return {column_per_value * value_per_variable(c, c.screen_value), lo, hi,
          [&c, x0](double t) { return from_variable(c, x0 + t); }};
}

/// The 1-D Gauss-Newton step along `line`, projected off what the calibration parameters can do:
/// the chi-square reduction that step predicts, the value and where the parameters go. Empty,
/// with the reason, when the line does nothing the parameters cannot.
std::optional<RankedEffect> one_dimensional_step(const EffectCandidate& c, const ResidualLine& line, const Vector& r,
                                                 const ParameterSpan& span, std::string* why_not) {
  const double norm = line.column.norm();
  if (!(norm > 0) || !std::isfinite(norm)) {
    *why_not = "no effect on the measured modes";
    return std::nullopt;
  }
  const Vector projected = span.projected(line.column);
  const double h = projected.squaredNorm();
  if (!(h > 1e-10 * norm * norm)) {
    *why_not = "the calibration parameters already do this";
    return std::nullopt;
  }
  const double g = projected.dot(r);
  const double step = std::clamp(-g / h, line.lo, line.hi);
  RankedEffect ranked;
  ranked.candidate = c;
  ranked.predicted_reduction = std::max(0.0, -2 * step * g - step * step * h);
  ranked.predicted_value = line.value_at(step);
  ranked.value = ranked.predicted_value;
  const Vector p = span.shifted(r, line.column, step);
  ranked.parameters.resize(p.size() + 1);
  ranked.parameters << p, ranked.predicted_value;
  return ranked;
}

/// True for a joint's or spring's present stiffness component.
bool is_present_stiffness(const EffectCandidate& c) {
  return c.variable == EffectCandidate::Variable::Log && c.change.kind == ModelChange::Kind::SetProperty &&
         std::find(kStiffnessComponentNames.begin(), kStiffnessComponentNames.end(), c.change.property) !=
             kStiffnessComponentNames.end();
}

/// The tangent of a present stiffness k0 in its compliance 1/k, over the same range. Near rigid a
/// joint acts in series with the structure and the modes move in proportion to its compliance, so
/// along this tangent the step reaches a softening of a decade or more, where in log10 k the
/// slope is small and the step stops on the range's bound, its prediction cut short.
ResidualLine compliance_tangent(const EffectCandidate& c, const Vector& column_per_value) {
  const double k0 = c.screen_value;
  return {column_per_value * (-k0 * k0), 1 / c.upper - 1 / k0, 1 / c.lower - 1 / k0,
          [k0](double t) { return 1 / (1 / k0 + t); }};
}

/// Each evaluated candidate's first-order prediction: the 1-D Gauss-Newton step along its
/// tangent; for a present stiffness component also along its tangent in compliance, the larger
/// prediction kept (the refit decides).
std::vector<RankedEffect> predict(const Problem& problem, const Vector& calibrated, const Vector& r,
                                  const std::vector<EffectCandidate>& usable, const ScreenJacobian& jacobian,
                                  EffectRanking* ranking) {
  const ParameterSpan span(problem, calibrated, jacobian.parameters, r.size());
  std::vector<RankedEffect> screened;
  for (size_t k = 0; k < usable.size(); ++k) {
    if (!jacobian.evaluated[k]) continue;
    const EffectCandidate& c = usable[k];
    std::string why_not;
    std::optional<RankedEffect> ranked =
        one_dimensional_step(c, tangent(c, jacobian.candidates.col(k)), r, span, &why_not);
    if (!ranked) {
      ranking->set_aside.emplace_back(c.name, why_not);
      continue;
    }
    if (is_present_stiffness(c))
      if (std::optional<RankedEffect> in_compliance =
              one_dimensional_step(c, compliance_tangent(c, jacobian.candidates.col(k)), r, span, &why_not);
          in_compliance && in_compliance->predicted_reduction > ranked->predicted_reduction)
        ranked = std::move(in_compliance);
    screened.push_back(std::move(*ranked));
  }
  return screened;
}

/// Refits of the screened candidates `choices` (those with a positive prediction or a declared
/// start), through the options' TaskMap, each judged by its likelihood-ratio test against the
/// critical value.
void refit_chosen(const Problem& problem, const RankingOptions& options, const EffectRanking& ranking,
                  const std::vector<size_t>& choices, detail::StepSpan* step, std::vector<RankedEffect>* screened) {
  const Eigen::Index np = static_cast<Eigen::Index>(problem.parameters.size());
  std::vector<size_t> chosen;
  for (size_t k : choices)
    if ((*screened)[k].predicted_reduction > 0 || (*screened)[k].candidate.initial) chosen.push_back(k);
  const TaskMap& map = options.task_map ? options.task_map : TaskMap(run_in_turn);
  const std::vector<std::string> outcomes =
      map(chosen.size(), [&](size_t i) { return refit_candidate(problem, (*screened)[chosen[i]], options, step); });
  for (size_t i = 0; i < chosen.size(); ++i) {
    RankedEffect& ranked = (*screened)[chosen[i]];
    TaskCodec outcome(outcomes[i]);
    ranked.refit.status = static_cast<ReducedStatus>(static_cast<int>(outcome.get_number()));
    ranked.refit.iterations = static_cast<int>(outcome.get_number());
    ranked.refit.forward_solves = static_cast<int>(outcome.get_number());
    ranked.refit.linear_solves = static_cast<int>(outcome.get_number());
    ranked.refit.message = outcome.get_text();
    ranked.refit.final = outcome.get_vector();
    if (ranked.refit.final.size() != np + 1 || !(outcome.get_number() > 0)) continue;  // no usable refit
    Misfit m;
    m.statistic = outcome.get_number();
    m.dof = static_cast<int>(outcome.get_number());
    m.p_value = outcome.get_number();
    m.model_form_error = outcome.get_number() > 0;
    ranked.refitted = true;
    ranked.parameters = ranked.refit.final;
    ranked.value = ranked.refit.final[np];
    ranked.chi2_after = m.statistic;
    ranked.dof_after = m.dof;
    ranked.p_value_after = m.p_value;
    ranked.model_form_error_after = m.model_form_error;
    ranked.achieved_reduction = ranking.chi2_before - m.statistic;
    // Without a stated noise the refit's residual estimates it (F-test with 1 and dof degrees),
    // though never below the data's resolution.
    const double statistic =
        ranking.noise_known ? ranked.achieved_reduction
                            : ranked.achieved_reduction / std::max(m.statistic / m.dof, ranking.resolution_variance);
    ranked.statistic = statistic;
    ranked.significant = statistic > ranking.critical_value;
    ranked.at_bound = ranked.candidate.on_bound(ranked.value);
    ranked.delta_bic = statistic - std::log(static_cast<double>(std::max(1, ranking.num_data)));
    ranked.delta_aic = statistic - 2;
  }
}

/// Where the neighbour refits start: the best-scoring acceptable refit of each kind with
/// neighbours (a place), while its score lies within the critical value of the best one's, or
/// within `window_share` of the best score when that is wider: of kinds that close, the data
/// hardly tell which, and the first refits' places are only first-order guesses. Those in
/// `climbed` are left out.
std::vector<size_t> climb_starts(const std::vector<RankedEffect>& screened, double critical_value,
                                 double window_share, const std::vector<size_t>& climbed) {
  std::vector<size_t> best_of_kind;  // the best acceptable refit of each kind, by score
  for (size_t k = 0; k < screened.size(); ++k) {
    if (!screened[k].acceptable() || !screened[k].candidate.location) continue;
    auto same = std::find_if(best_of_kind.begin(), best_of_kind.end(),
                             [&](size_t b) { return detail::same_change(screened[b].candidate, screened[k].candidate); });
    if (same == best_of_kind.end())
      best_of_kind.push_back(k);
    else if (screened[k].score() > screened[*same].score())
      *same = k;
  }
  double best = -INFINITY;
  for (const RankedEffect& r : screened)
    if (r.acceptable()) best = std::max(best, r.score());
  const double window = std::max(critical_value, window_share * best);
  std::vector<size_t> starts;
  for (size_t b : best_of_kind)
    if (screened[b].score() >= best - window && std::find(climbed.begin(), climbed.end(), b) == climbed.end())
      starts.push_back(b);
  return starts;
}

/// Up to `neighbour_refits` neighbours of `start` not refitted yet and not in `chosen`, best
/// predicted first, appended to `chosen`.
void add_neighbours(const std::vector<RankedEffect>& screened, size_t start, int neighbour_refits,
                    std::vector<size_t>* chosen) {
  int added = 0;
  for (size_t k = 0; k < screened.size() && added < neighbour_refits; ++k)
    if (!screened[k].refitted && screened[start].candidate.neighbour_of(screened[k].candidate) &&
        std::find(chosen->begin(), chosen->end(), k) == chosen->end()) {
      chosen->push_back(k);
      ++added;
    }
}

/// The neighbour refits (RankingOptions::neighbour_refits, neighbour_rounds): rounds of refits of
/// the neighbours of each kind's best refit (climb_starts), until no kind's best moves. For a large
/// effect the first-order prediction does not rank the places of one kind reliably, so each
/// round lets a kind's best walk one neighbourhood on towards where the refits fit best.
void climb_neighbours(const Problem& problem, const RankingOptions& options, const EffectRanking& ranking,
                      detail::StepSpan* step, std::vector<RankedEffect>* screened) {
  std::vector<size_t> climbed;
  for (int round = 0; round < options.neighbour_rounds; ++round) {
    std::vector<size_t> chosen;
    for (size_t start : climb_starts(*screened, ranking.critical_value, options.neighbour_window_share, climbed)) {
      add_neighbours(*screened, start, options.neighbour_refits, &chosen);
      climbed.push_back(start);
    }
    if (chosen.empty()) return;
    refit_chosen(problem, options, ranking, chosen, step, screened);
  }
}

/// Refits of the best predictions (refit_choices, add_place_refits, add_kind_refits), then of
/// the best refits' neighbours (climb_neighbours), each judged by its likelihood-ratio test.
void refit_best(const Problem& problem, const RankingOptions& options, const EffectRanking& ranking,
                detail::StepSpan* step, std::vector<RankedEffect>* screened) {
  std::vector<size_t> choices = refit_choices(*screened, refit_count(*screened, options, ranking));
  add_place_refits(problem.model, *screened, options, &choices);
  add_kind_refits(*screened, options, &choices);
  refit_chosen(problem, options, ranking, choices, step, screened);
  climb_neighbours(problem, options, ranking, step, screened);
}
/// The standard error of the effect's value in `best`'s refit: the covariance of a noise-weighted
/// least-squares estimate, (J^T J)^-1; NaN when its Jacobian cannot be had or is singular.
double standard_error_of(const Problem& problem, const RankedEffect& best, const RankingOptions& options) {
  const Eigen::Index np = static_cast<Eigen::Index>(problem.parameters.size());
  const Problem with = problem_with_effects(problem, {best.candidate}, {best.value});
  Objective best_objective(with, options.objective);
  const Evaluation at = best_objective.evaluate(best.parameters, Need::Jacobian);
  if (!at.ok) return NAN;
  // In relative units (columns times the values), which are all of order one.
  Vector scale = best.parameters.cwiseAbs();
  for (int j = 0; j < scale.size(); ++j)
    if (!(scale[j] > 0)) scale[j] = 1;
  const Matrix scaled = at.jacobian * scale.asDiagonal();
  Eigen::ColPivHouseholderQR<Matrix> information(scaled.transpose() * scaled);
  if (!information.isInvertible()) return NAN;
  return scale[np] * std::sqrt(std::max(0.0, information.inverse()(np, np)));
}

}  // namespace

bool EffectCandidate::on_bound(double value) const {
  if (variable == Variable::Linear && lower == 0) return false;
  if (variable == Variable::Compliance) return false;
  const double lo = to_variable(*this, lower), hi = to_variable(*this, upper), x = to_variable(*this, value);
  const double tolerance = 1e-4 * std::abs(hi - lo);
  return std::abs(x - lo) <= tolerance || std::abs(x - hi) <= tolerance;
}

ReducedOptions RankingOptions::default_refit_options() {
  ReducedOptions options;
  options.method = ReducedOptions::Method::GaussNewton;
  options.max_iterations = 60;
  options.gradient_tolerance = 1e-4;
  options.relative_gradient_tolerance = 1e-8;
  // An iteration that lowers the chi-square by under a thousandth of it (about 0.4 at 400) ends
  // the refit: a fiftieth of the critical value, a fifteenth of the margin within which the data
  // hardly tell two effects apart. 1e-5 took a sixth more CPU on LFU for the same effects, their
  // final chi-squares within 0.003 (docs/design.md, "Refits and significance").
  options.function_tolerance = 1e-3;
  // A refit starts where the screen's linear model put it, one Gauss-Newton step from the
  // calibrated point: the next step is short and the model good, and a first step damped by 1
  // would only halve it (a fifth fewer solves per refit, the same minima on the seeds measured).
  options.initial_damping = 1e-2;
  return options;
}

ObjectiveOptions RankingOptions::default_objective_options() {
  ObjectiveOptions options;
  options.linear_tolerance = 1e-8;
  return options;
}

ObjectiveOptions RankingOptions::refit_objective() const {
  ObjectiveOptions options = objective;
  options.linear_tolerance = refit_linear_tolerance;
  return options;
}

bool RankingOptions::IsValid(std::string* error) const {
  auto bad = [&](const std::string& message) {
    if (error) *error = message;
    return false;
  };
  if (refits < 0) return bad("refits = " + detail::option_text(refits) + ": must be >= 0");
  if (weak_refits < 0) return bad("weak_refits = " + detail::option_text(weak_refits) + ": must be >= 0");
  if (!(weak_prediction >= 0) || !std::isfinite(weak_prediction))
    return bad("weak_prediction = " + detail::option_text(weak_prediction) + ": must be finite and >= 0");
  if (place_refits < 0) return bad("place_refits = " + detail::option_text(place_refits) + ": must be >= 0");
  if (neighbour_refits < 0) return bad("neighbour_refits = " + detail::option_text(neighbour_refits) + ": must be >= 0");
  if (neighbour_rounds < 0) return bad("neighbour_rounds = " + detail::option_text(neighbour_rounds) + ": must be >= 0");
  if (!(neighbour_window_share >= 0 && neighbour_window_share < 1))
    return bad("neighbour_window_share = " + detail::option_text(neighbour_window_share) + ": must be in [0, 1)");
  if (!(place_refit_share > 0 && place_refit_share <= 1))
    return bad("place_refit_share = " + detail::option_text(place_refit_share) + ": must be in (0, 1]");
  if (kind_refits < 0) return bad("kind_refits = " + detail::option_text(kind_refits) + ": must be >= 0");
  if (!(kind_refit_share > 0 && kind_refit_share <= 1))
    return bad("kind_refit_share = " + detail::option_text(kind_refit_share) + ": must be in (0, 1]");
  if (!(significance > 0 && significance < 0.5))
    return bad("significance = " + detail::option_text(significance) + ": must be in (0, 0.5)");
  if (!(resolution > 0 && resolution <= 0.01))
    return bad("resolution = " + detail::option_text(resolution) + ": must be in (0, 0.01]");
  if (!(refit_span_share >= 0 && refit_span_share <= 1))
    return bad("refit_span_share = " + detail::option_text(refit_span_share) + ": must be in [0, 1]");
  if (!(refit_linear_tolerance > 0 && refit_linear_tolerance <= 1e-4))
    return bad("refit_linear_tolerance = " + detail::option_text(refit_linear_tolerance) + ": must be in (0, 1e-4]");
  std::string inner;
  if (!refit.IsValid(&inner)) return bad("refit." + inner);
  if (!objective.IsValid(&inner)) return bad("objective." + inner);
  return true;
}

std::string RankedEffect::summary() const {
  const double v = refitted ? value : predicted_value;
  std::string text = candidate.description + (refitted ? ", identified " : ", predicted ") + format_value(v);
  if (std::isfinite(standard_error)) text += " +/- " + format_value(standard_error);
  return text;
}

namespace {

void require_valid(const Problem& problem, const Vector& calibrated, const RankingOptions& options) {
  std::string error;
  if (!options.IsValid(&error)) throw std::invalid_argument("RankingOptions: " + error);
  if (calibrated.size() != static_cast<Eigen::Index>(problem.parameters.size()))
    throw std::invalid_argument("rank_effects: " + std::to_string(calibrated.size()) + " calibrated values for " +
                                std::to_string(problem.parameters.size()) + " parameters");
}

}  // namespace

EffectRanking rank_effects(const Problem& problem, const Vector& calibrated,
                           const std::vector<EffectCandidate>& candidates, const RankingOptions& options) {
  require_valid(problem, calibrated, options);
  Objective objective(problem, options.objective);
  return detail::rank_effects_with(objective, calibrated, candidates, options);
}

EffectRanking detail::rank_effects_with(Objective& objective, const Vector& calibrated,
                                        const std::vector<EffectCandidate>& candidates, const RankingOptions& options) {
  const Problem& problem = objective.problem();
  require_valid(problem, calibrated, options);
  const int np = static_cast<int>(problem.parameters.size());
  const Clock::time_point screen_start = Clock::now();
  EffectRanking ranking;
  ranking.noise_known = problem.measurement_noise && problem.measurement_noise->frequency > 0;
  Misfit before;
  Vector r;  // the residual at the calibrated point, of the model as it is (supports rigid)
  {  // the objective's solve there, when it has made it, also starts every refit's span
    const Evaluation e = objective.evaluate(calibrated);
    if (!e.ok) throw std::runtime_error("rank_effects: the calibrated point cannot be evaluated: " + e.message);
    before = misfit_of(objective, e, np, options.significance);
    r = e.residuals;
  }
  ranking.chi2_before = before.statistic;
  ranking.dof_before = before.dof;
  ranking.num_data = before.data;
  if (!ranking.noise_known) ranking.resolution_variance = resolution_variance(problem, options.resolution);

  // The screen: every candidate's first-order prediction from one Jacobian.
  // Usually every candidate applies, and the screen's model is the one check; when one does not,
  // the candidates are tried apart and those that fail set aside.
  std::vector<EffectCandidate> usable = candidates;
  ScreenJacobian jacobian;
  const size_t set_aside_before = ranking.set_aside.size();
  const int solves_before = ranking.linear_solves;
  try {
    jacobian = screen_jacobian(problem, calibrated, usable, r.size(), options, &ranking);
  } catch (const std::invalid_argument&) {  // other errors come back from the second try
    ranking.set_aside.resize(set_aside_before);
    ranking.linear_solves = solves_before;
    usable = applicable(problem, candidates, &ranking);
    jacobian = screen_jacobian(problem, calibrated, usable, r.size(), options, &ranking);
  }
  std::vector<RankedEffect> screened = predict(problem, calibrated, r, usable, jacobian, &ranking);
  ranking.screened = static_cast<int>(screened.size());
  set_kind_penalties(&screened, options.equal_kind_prior);
  std::stable_sort(screened.begin(), screened.end(), [](const RankedEffect& a, const RankedEffect& b) {
    return a.predicted_reduction > b.predicted_reduction;
  });
  ranking.screen_seconds = seconds_since(screen_start);

  // Refits of the best predictions: every calibration parameter free, the effect started at its
  // first-order value (or its declared start).
  const Clock::time_point refit_start = Clock::now();
  ranking.critical_value = gain_critical_value(ranking, options.significance / std::max(1, ranking.screened), np + 1);
  detail::StepSpan step(objective, calibrated, options);
  refit_best(problem, options, ranking, &step, &screened);
  // Refitted first, the significant ones before the others, each by score; then the rest by
  // prediction.
  std::stable_sort(screened.begin(), screened.end(), [](const RankedEffect& a, const RankedEffect& b) {
    if (a.refitted != b.refitted) return a.refitted;
    if (!a.refitted) return false;
    if (a.acceptable() != b.acceptable()) return a.acceptable();
    return a.score() > b.score();
  });
  if (!screened.empty() && screened.front().refitted && ranking.noise_known)
    screened.front().standard_error = standard_error_of(problem, screened.front(), options);
  ranking.refit_seconds = seconds_since(refit_start);
  ranking.effects = std::move(screened);
  return ranking;
}

std::string format_effect_ranking(const EffectRanking& ranking, int max_rows) {
  std::string text;
  char line[400];
  const char* unit = ranking.noise_known ? "chi-square" : "2J (no stated noise)";
  std::snprintf(line, sizeof line, "%s before: %.4g on %d degrees of freedom (%d data); %d candidates screened\n", unit,
                ranking.chi2_before, ranking.dof_before, ranking.num_data, ranking.screened);
  text += line;
  std::snprintf(line, sizeof line, "%4s  %-34s %11s %11s %11s %9s  %s\n", "rank", "effect", "predicted", "achieved",
                "value", "dBIC", "significant");
  text += line;
  const int rows = std::min<int>(max_rows, static_cast<int>(ranking.effects.size()));
  for (int k = 0; k < rows; ++k) {
    const RankedEffect& r = ranking.effects[k];
    const std::string achieved = r.refitted ? format_value(r.achieved_reduction) : "-";
    const std::string bic = r.refitted ? format_value(r.delta_bic) : "-";
    std::snprintf(line, sizeof line, "%4d  %-34s %11s %11s %11s %9s  %s\n", k + 1, r.candidate.name.c_str(),
                  format_value(r.predicted_reduction).c_str(), achieved.c_str(),
                  format_value(r.refitted ? r.value : r.predicted_value).c_str(), bic.c_str(),
                  r.refitted ? (r.significant ? (r.at_bound ? "at bound" : "yes") : "no") : "-");
    text += line;
  }
  const std::string test = ranking.noise_known ? "chi-square(1)"
                                                : "F(1, " + std::to_string(ranking.dof_before - 1) + ") of the refit's gain";
  std::snprintf(line, sizeof line,
                "(predicted: first-order reduction of the %s; achieved: by a refit with every parameter free; "
                "significant: above %.3g, the %s value at the significance level / %d candidates)\n",
                unit, ranking.critical_value, test.c_str(), ranking.screened);
  text += line;
  for (int k = 0; k < rows; ++k) {
    const RankedEffect& r = ranking.effects[k];
    if (!r.refitted) continue;
    std::snprintf(line, sizeof line, "%4d  %s: %s; %s %.4g -> %.4g", k + 1, r.candidate.name.c_str(),
                  r.summary().c_str(), unit, ranking.chi2_before, r.chi2_after);
    text += line;
    if (ranking.noise_known)
      text += r.model_form_error_after ? " (still more than the noise)" : " (consistent with the noise)";
    text += "\n";
  }
  return text;
}

}  // namespace modalcal
