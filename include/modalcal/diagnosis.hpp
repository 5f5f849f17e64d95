#pragma once
/// \file diagnosis.hpp
/// The model-form diagnosis loop, stepwise: calibrate, test the residual against the noise
/// (residual_test.hpp), localize it (localization.hpp), then repeat: rank candidate effects
/// (effects.hpp), refit the best, and accept the best when its likelihood-ratio test is
/// significant at the stated level divided by the number of candidates screened in that step;
/// screen again with the accepted effects in the model, until no candidate is significant (or,
/// with DiagnosisOptions::stop_when_consistent, the residual is consistent with the noise). An
/// exchange pass then revisits each accepted effect with the others in the model, and a backward
/// pass then drops any
/// accepted effect whose own likelihood-ratio test, with the others in the model, is no longer
/// significant at the stated level. The verdict is one: a model-form error when an accepted
/// effect is kept or the residual test rejects.
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
/// for (const modalcal::DiagnosisStep& s : d.steps) std::cout << s.effect.summary() << "\n";
/// \endcode

#include <cmath>
#include <functional>
#include <optional>
#include <string>
#include <vector>

#include "modalcal/effects.hpp"
#include "modalcal/export.hpp"
#include "modalcal/localization.hpp"
#include "modalcal/reduced.hpp"
#include "modalcal/residual_test.hpp"

namespace modalcal {

/// A calibrated state: parameter values and how the model then meets the measured modes.
struct MODALCAL_EXPORT FitState {
  std::vector<std::string> parameter_names;  ///< calibration parameters, then added effects
  Vector parameters;
  std::vector<PairedMode> pairs;  ///< measured and model modes, paired
  /// The residual test against the stated noise (absent without one).
  std::optional<ResidualTest> test;
  /// \f$X^2\f$ of the test, or 2J of the problem's objective without a stated noise (in a
  /// diagnosis, the objective with DiagnosisOptions::ranking.objective's settings, as the screens').
  double statistic = 0;
};

/// Evaluates `problem` at `p` and tests its residual (with `p.size()` fitted parameters).
/// \throws std::runtime_error if the evaluation fails; std::invalid_argument for a wrong size.
MODALCAL_EXPORT FitState evaluate_fit(const Problem& problem, const Vector& p, const ResidualTestOptions& options = {});

/// Side by side, per measured mode: measured Hz, model Hz and error % before and after, MAC before
/// and after; then the parameters before and after (added effects with their words) and the
/// residual test's verdict before and after.
MODALCAL_EXPORT std::string format_before_after(const Problem& after_problem, const FitState& before,
                                                const FitState& after, const std::string& before_title = "before",
                                                const std::string& after_title = "after");

struct MODALCAL_EXPORT DiagnosisOptions {
  /// Effects in the model from the start, beside the problem's enabled ones (`effects:` with
  /// `enable: true`); their values are calibrated with the parameters before the first screen.
  std::vector<EffectCandidate> added;
  /// At most this many effects are accepted by the forward steps. Range: >= 0 (0: screen and
  /// refit once, accept nothing).
  int max_steps = 4;
  /// Stop the forward steps once the residual is consistent with the noise, even when a candidate
  /// would still pass its own test. Off by default: one candidate's likelihood-ratio test has far
  /// more power than the omnibus test on every datum, and with several effects at once the first
  /// accepted one often leaves a residual the omnibus test cannot tell from noise while the next
  /// effect is still plain to its own test. Each step's test is corrected for what it screens, so
  /// continuing adds a false acceptance with probability at most the stated level per step.
  bool stop_when_consistent = false;
  /// The same problem on a finer mesh (same parameters and measured modes), for the
  /// discretization estimate; null: no estimate. The caller loads it (e.g. load_problem with
  /// LoadOptions::refinement 1.5 times the problem's mesh_refinement).
  const Problem* finer_mesh = nullptr;
  /// When the mesh explains a significant part of the residual, run the loop on the data corrected
  /// for it (DiscretizationEstimate), so that no physical effect is accepted for what the mesh
  /// accounts for.
  bool correct_for_discretization = true;
  /// Walk side by side, in threads of this process: the first paths of the loops on the data as
  /// measured and corrected for the mesh (correct_for_discretization), and a loop's other paths
  /// (first_step_alternatives). The same diagnosis as one after the other, sooner on two or more
  /// cores: those walks share nothing but what was there before them. Only with a
  /// ranking.task_map that may be called from several threads at once (run_in_turn,
  /// run_in_threads; not an MPI job's, whose processes must reach every map in the same order),
  /// and a BLAS whose thread count no one changes meanwhile. Off by default; `diagnose` turns it
  /// on when it runs alone with more than one thread.
  bool walk_side_by_side = false;
  /// The exchange pass, after the forward steps: with two or more accepted effects, take each out
  /// in turn, screen again with the others in the model, and replace it by the best significant
  /// refit there when that scores higher. A forward step chooses with the later effects missing,
  /// and with several effects at once the first accepted often stands in for several.
  bool exchange = true;
  /// Two effects for one, when the residual is still larger than the noise after the forward
  /// steps and the exchange pass (and fewer than max_steps effects were accepted): each accepted
  /// effect in turn is taken out, and each of this many best significant refits in its place is
  /// followed by the best significant step from there; the pair replaces the effect when the model
  /// then scores lower in chi-square plus the first step's critical value and the kind penalty per
  /// effect (as Diagnosis::paths are judged). Two effects near one another can each hide the other
  /// from a screen: a point mass fitted at one end of a beam takes up part of what a mass at the
  /// other end would explain, so no screen with it in ranks the second mass, and no replacement of
  /// it alone fits better; with the first replaced, the second fits plainly.
  /// Each try costs a screen. Range: [0, 100] (0: none).
  int pair_exchanges = 2;
  /// The backward pass: drop effects (accepted ones and the problem's own) that are no longer
  /// significant at the stated level once the others are in the model.
  bool backward = true;
  /// When the loop ends with a residual larger than the noise (or, with
  /// alternatives_after_consistent_end, took two or more steps), walk it again from each of the
  /// first step's next-best significant refits (at most this many, none a neighbour of the first
  /// or of another, nor mass at the place of one as a point mass or a
  /// region's mass scale: the same hypothesis), and keep the path that ends lowest in chi-square plus
  /// the first step's critical value and the effect's kind penalty (RankedEffect::kind_penalty)
  /// per kept effect (Diagnosis::paths). With several effects at once the best single effect may
  /// stand in for them together, and one exchange at a time does not undo that. Each path is
  /// walked as the greedy path's alternative: it stops where it reaches the greedy path's effects,
  /// and takes again the greedy path's screens, not another alternative's. Each costs up to a
  /// loop. Range: >= 0 (0: the greedy path only).
  int first_step_alternatives = 2;
  /// Walk those other paths also when the first path took two or more steps and ends with a
  /// residual consistent with the noise. Off by default: they are walked where the first path ends
  /// with a residual larger than the noise, where the data still hold what its effects do not
  /// explain (as the pair exchanges are). After a consistent end they took 40-50 % of a
  /// multi-effect diagnosis's time and changed 6 of 26 multi-effect answers on the tuning sets,
  /// one of them from wrong to right (docs/benchmarks.md, round forty-two).
  bool alternatives_after_consistent_end = false;
  /// When the mesh check is significant and the loop runs on the data corrected for the mesh and
  /// on the data as measured (correct_for_discretization), both take their first path's forward
  /// steps; the exchange and the backward pass follow for the data whose steps end lower in score
  /// (DiscretizationEstimate::score_corrected), and for the other data only when theirs end within
  /// this many of the first step's critical value of those. The exchange and backward passes
  /// only lower a path's score, so data whose forward steps end far above the others' rarely come
  /// to lead, and on a multi-effect loser those passes (a screen per accepted effect, then steps
  /// again) cost much: on LFU case 27502, half the diagnosis, for the same answer (docs/
  /// benchmarks.md, round forty-three). Range: >= 0 (infinity: always both; 0: only the lower
  /// data's).
  double other_data_margin = 1.0;
  /// When the first calibration's residual is more than the noise (or, without a stated noise,
  /// the data's resolution), it is run again from this many further starts spread over the
  /// parameters' bounds (spread_start()), through ranking.task_map, and the lowest end is kept. A
  /// local minimum of the calibration looks exactly like a model-form error, and with few data
  /// (frequencies only, or few sensors) a start far from the truth often ends in one. The
  /// calibrations of the data corrected for the mesh start from the kept end. Each start costs up
  /// to a calibration. Range: [0, 1000] (0: the caller's start only).
  int calibration_starts = 4;
  /// Called with one line of text when a stage that can take long begins or ends (the further
  /// calibration starts, each with its end), for a progress display; null: nothing is said.
  /// Called from the caller's thread only.
  std::function<void(const std::string&)> progress;
  /// The first calibration: reduced L-BFGS (the robust choice from a far start) with the refits'
  /// tolerances (RankingOptions::default_refit_options), but for the function tolerance, 1e-5.
  /// It walks in a span of the model, its end checked on the whole model, as the refits do
  /// (RankingOptions::refit_span_share).
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

/// What further measurement would tell two explanations of the same data apart: the sensor
/// reading not yet taken, and the mode not yet measured, where the models of the two refits
/// differ most, each in units of the stated noise.
///
/// A reading's separation: each model's shape of a measured mode, scaled so that its largest
/// value at the present sensors is 1 (the scale the shape noise σ_φ refers to) and signed alike
/// at the sensors, differs at the reading by d; separation = d / σ_φ. A mode's: the relative
/// difference of the two models' frequencies of an elastic mode paired with no measured one,
/// over σ_f. Only free translational DOFs of surface and interface nodes that no sensor reads
/// already are considered.
struct MODALCAL_EXPORT TellApart {
  std::string alternative;  ///< the alternative's candidate name
  int node = -1;            ///< 0-based model node of the best reading; -1 if none
  int component = 0;        ///< 0..2 = x, y, z
  Vec3 location = Vec3::Zero();
  int measured = -1;              ///< 0-based index of the measured mode whose shape differs there
  double shape_separation = 0;    ///< in noise standard deviations
  int model_mode = -1;            ///< 0-based elastic mode of the best unmeasured frequency; -1 if none
  double model_hz = 0;            ///< its frequency with the accepted effect
  double frequency_separation = 0;  ///< in noise standard deviations
};

/// How to tell `accepted` from `alternative`, two refits of one ranking of `problem` (their
/// `parameters`: `problem`'s, then the effect's value). Needs a stated noise
/// (`problem.measurement_noise`, σ_f and σ_φ > 0 for the respective part).
/// \throws std::invalid_argument without a stated noise, or if either refit's parameters do not
///   fit `problem`; std::runtime_error if either model cannot be solved.
MODALCAL_EXPORT TellApart tell_apart(const Problem& problem, const RankedEffect& accepted,
                                     const RankedEffect& alternative);
/// The same for each of `alternatives`, with `accepted`'s model solved once. Advice only: an
/// alternative whose model cannot be solved gets an entry that names no reading and no mode.
/// \throws std::invalid_argument without a stated noise or if `accepted`'s parameters do not fit
///   `problem`; std::runtime_error if `accepted`'s model cannot be solved.
MODALCAL_EXPORT std::vector<TellApart> tell_apart(const Problem& problem, const RankedEffect& accepted,
                                                  const std::vector<RankedEffect>& alternatives);

/// One effect accepted by a forward step of the loop.
struct MODALCAL_EXPORT DiagnosisStep {
  int step = 0;        ///< 1-based
  RankedEffect effect;  ///< its refit in that step: value, standard error, X^2 after, p-value, dBIC
  double chi2_before = 0;       ///< X^2 (or 2J without noise) before the step
  int screened = 0;             ///< candidates screened in the step
  double critical_value = 0;    ///< of the step's likelihood-ratio test
  std::optional<Vec3> location;  ///< effect_location(); none for a block-wide effect
  /// How far the data let the place move: the largest distance from `location` to the place of
  /// another acceptable refit of the step's that makes the same change (kind and property) and
  /// whose likelihood-ratio statistic is within kAlternativeMargin of the effect's or above it;
  /// `places` counts those places, its own included. Among the places the step refitted (the
  /// best predictions and the neighbours the refits climbed to), so at least this. A mass on a
  /// slender member, say, is placed along it far better than across it. NaN and 0 for a
  /// block-wide effect.
  double place_spread = NAN;
  int places = 0;
  /// The step's other significant refits whose likelihood-ratio statistic (ΔX²) is within
  /// DiagnosisStep::kAlternativeMargin of the accepted one's, or above it: effects these data
  /// hardly tell from it (a likelihood ratio below about 20 to 1), the prior over kinds
  /// (effects.hpp, "Which effect") left aside, since it is what chose between them.
  std::vector<RankedEffect> alternatives;
  /// One per alternative, in the same order (tell_apart()); empty without a stated noise and for
  /// an exchange.
  std::vector<TellApart> tell_apart;
  static constexpr double kAlternativeMargin = 6;  ///< 2 ln 20
  /// True when the data alone favour `alternative` over the step's effect by more than 20 : 1:
  /// its statistic exceeds the effect's by more than kAlternativeMargin.
  bool data_favour(const RankedEffect& alternative) const {
    return alternative.statistic - effect.statistic > kAlternativeMargin;
  }
  /// True when the data favour `alternative` (data_favour()) and the prior over kinds chose the
  /// step's effect: its score S, the statistic less its kind's penalty, is no lower.
  bool prior_overruled(const RankedEffect& alternative) const {
    return data_favour(alternative) && effect.score() >= alternative.score();
  }
  /// For an exchange (Diagnosis::exchanges): the accepted effect this one replaced, and that
  /// effect's score S in the same screen; empty and NaN for a forward step.
  std::string replaces;
  double replaced_score = NAN;
  /// The replaced effect had gone to a bound of its range (EffectCandidate::on_bound): any
  /// acceptable effect replaces it, whatever the scores.
  bool replaced_on_bound = false;
  /// For an exchange: how many forward steps the loop had taken when it was made. A forward step
  /// may follow an exchange that changed the model (its number is then larger than this).
  int after_step = 0;
  /// For an exchange of two effects for one (DiagnosisOptions::pair_exchanges): the change in
  /// score (chi-square plus the first step's critical value and the kind penalty per effect) of
  /// this effect with the forward step that follows it (step `after_step + 1`) against the
  /// replaced effect alone; negative, as only a lower score is taken. NaN for every other exchange.
  double pair_score_change = NAN;
};

/// How much of the residual the mesh accounts for. Both meshes are solved at the calibrated
/// parameters; each measured frequency is moved by its mode's relative change on the finer mesh
/// (what this mesh would show of it), each measured shape by the mode's change at the sensors (in
/// the shape's own scale), and the parameters are recalibrated: the chi-square this
/// gains, with no free parameter added, tests "the residual is the mesh's". When it is
/// significant the loop runs on the moved data, with the part extrapolation says even the finer
/// mesh misses (r²/(r² − 1) − 1 times the change, for a frequency error of order h², r the
/// ratio of element sizes: the ratio of the problems' mesh_refinement where both have one, else
/// (n_fine/n)^(1/3) from the DOF counts) allowed as model error in each frequency
/// (MeasuredMode::model_error).
struct MODALCAL_EXPORT DiscretizationEstimate {
  struct Mode {
    int measured = 0;  ///< 0-based
    std::string label;
    double shift_percent = 0;         ///< (finer mesh - this mesh) / this mesh, in %
    double extrapolated_percent = 0;  ///< (continuum - this mesh) / this mesh by extrapolation, in %
    /// This mesh's mode at the sensors, and the finer mesh's (scaled onto it) less it; empty when
    /// the two meshes' sensor readings differ in number.
    Vector shape, shape_change;
  };
  double refinement = 0;  ///< r, the element-size ratio of the two meshes
  int dofs = 0, finer_dofs = 0;
  /// Sensors the finer mesh reads at another place than this mesh's node (snapped to its nearest
  /// node there), and the farthest one's distance: their shape change is left out (Mode::
  /// shape_change is 0 there), since it is a change of place, not the mesh's error. Mesh planes
  /// through the sensors (docs/problem-format.md) keep every mesh's node on them.
  int sensors_moved = 0;
  double sensor_offset = 0;
  std::vector<Mode> per_mode;
  /// X^2 at the calibration minus X^2 of the recalibration on the moved data. Negative when the
  /// finer mesh moves the model away from the data (the misfit is not the mesh's).
  double chi2_explained = 0;
  double critical_value = 0;  ///< chi-square(1) at the significance level
  bool significant = false;   ///< chi2_explained above it: refine the mesh first
  /// When significant, the loop runs twice, on the data corrected for the mesh and on the data as
  /// measured, and the one whose end explains the data better is kept: each end's score is
  /// -2 ln L up to a common constant (its X² plus the log of the variance the allowance adds to
  /// each weighted frequency, sum ln(1 + allowance²/noise²), on the corrected data) plus the
  /// step's critical value per kept effect. A physical effect that moves the modes as the mesh
  /// does is thus not taken for the mesh when the data say otherwise, and the mesh not for a
  /// physical effect. Both NaN when the loop ran once; score_corrected NaN when the loop on the
  /// corrected data could not run (the data as measured are then kept).
  double score_corrected = NAN, score_as_measured = NAN;
  bool corrected = false;     ///< the loop ran on the corrected data (and its end was kept)
  /// The data not kept had only their loop's first path walked (DiagnosisOptions::
  /// first_step_alternatives): it ended above the other loop's end, and the other paths only
  /// replace a path by one that ends lower; its score is that first path's.
  bool other_data_first_path_only = false;
  /// Of that first path the data not kept walked only the forward steps (DiagnosisOptions::
  /// other_data_margin): they ended higher than the kept data's forward steps by more than the
  /// margin; their score is those steps' end.
  bool other_data_forward_steps_only = false;
};

/// An accepted effect the backward pass removed: one the others make redundant, or one that
/// the later effects' refits moved onto a bound of its range (EffectCandidate::on_bound), where it
/// stands in for something else, as a step would not have accepted it.
struct MODALCAL_EXPORT DroppedEffect {
  std::string name;
  double chi2_increase = 0;   ///< X^2 refitted without it, minus X^2 with it (without a stated noise: the F statistic)
  double critical_value = 0;  ///< chi-square(1) at the significance level
  bool on_bound = false;      ///< dropped for ending on a bound, whatever its chi2_increase
  double value = NAN;         ///< its value when dropped
};

/// One path through the loop (DiagnosisOptions::first_step_alternatives): the effect its first
/// step took, what its backward pass kept, and where it ended.
struct MODALCAL_EXPORT DiagnosisPath {
  std::string first;                  ///< the first step's effect
  std::vector<std::string> accepted;  ///< the effects kept at its end
  double chi2_final = 0;              ///< X^2 at its end
  /// chi2_final plus, per kept effect, the first step's critical value and the effect's kind
  /// penalty 2 ln n_kind (the prior the ranking orders by): the paths' common measure.
  double score = 0;
  bool kept = false;  ///< the diagnosis is this path's
  /// Not empty when, after `joined_after` forward steps and `joined_after_exchanges` exchanges,
  /// the path held the effects that the path from `joined` (the one kept at the time) held after
  /// as many steps or at its end, at the same fit, or those it ended with and one more whose gain
  /// is below the backward pass's critical value (the backward pass would drop it): it was walked
  /// no further and ends where that path ends (accepted, chi2_final and score are that path's).
  std::string joined;
  int joined_after = 0;
  int joined_after_exchanges = 0;
  /// The path took no step after its first, fitted no better than the kept path's first step and
  /// scored no lower than the kept path, so it was walked no further (its exchange could at best
  /// trade its effect for that one): accepted, chi2_final and score are where it stood.
  bool no_second_step = false;
};

struct MODALCAL_EXPORT Diagnosis {
  bool noise_known = false;
  ReducedSummary calibration;  ///< the nominal calibration
  FitState before;             ///< at its result
  /// When the first calibration from the caller's start stopped in a local minimum: that
  /// calibration's X² (2J without a stated noise); NaN otherwise. Either a calibration from a
  /// further start ended lower (calibration_start > 0), or the loop left it: its end, with no
  /// effect kept, fitted the data lower by more than a step's critical value, and the diagnosis
  /// was run again from there (calibration_start = -1). `calibration` and `before` are then of
  /// the lower minimum; calibration.initial stays the caller's start.
  double first_calibration_local_minimum = NAN;
  /// Where the kept nominal calibration started: 0 the caller's start, k >= 1
  /// spread_start(problem.parameters, k) (DiagnosisOptions::calibration_starts), -1 the end of a
  /// loop that left the first calibration's local minimum.
  int calibration_start = 0;
  /// The calibration parameters the nominal calibration holds on a bound of their range, each as
  /// "name (lower|upper bound V)": the data ask for values beyond the range given, and a residual
  /// that a wider range removes is no model-form error (the recommendation says so).
  std::vector<std::string> calibration_on_bounds;
  std::optional<DiscretizationEstimate> discretization;  ///< with options.finer_mesh
  std::optional<Localization> localization;
  std::string localization_note;  ///< why there is none, when there is none
  std::vector<EffectCandidate> candidates;
  EffectRanking ranking;
  /// Where the model fails: the first step's screen as a map (ScreenMap, effects.hpp).
  ScreenMap map;
  /// Index into ranking.effects (the first step's ranking) of the first effect to add: 0 when the
  /// first step accepted one, -1 otherwise.
  int recommended = -1;
  std::optional<FitState> after;  ///< with the accepted effects, when any
  std::string recommendation;     ///< in words
  /// The effects the model had from the start (enabled in the problem, or options.added).
  std::vector<EffectCandidate> started_with;
  std::vector<DiagnosisStep> steps;       ///< forward steps, in order
  std::vector<EffectRanking> rankings;    ///< each step's ranking (rankings[0] is `ranking`)
  /// By the exchange pass, in order: each replaced an accepted effect (DiagnosisStep::replaces);
  /// `step` is the forward step whose effect it replaced, its test is against the model with
  /// every other effect in.
  std::vector<DiagnosisStep> exchanges;
  std::vector<DroppedEffect> dropped;     ///< by the backward pass
  /// The paths walked when the first step's alternatives were tried, the first ranking's best
  /// effect's first; empty when only that one was.
  std::vector<DiagnosisPath> paths;
  /// The screens (rank_effects()) the loop ran over every path, steps and exchanges, and how many
  /// times it took an earlier screen of the same model at the same fit instead of screening again.
  int screens = 0;
  int screens_reused = 0;
  /// The effects kept by the backward pass: started_with's, then the accepted ones.
  std::vector<EffectCandidate> effects;
  /// The final parameters: the problem's, then one value per entry of `effects`.
  Vector final_parameters;
  FitState final_fit;  ///< the residual at the end
  /// Without a stated noise: the final fit meets every measured frequency within
  /// RankingOptions::resolution (relative) and every MAC within it of 1, the data's resolution;
  /// no step is taken from such a fit. Always false with a stated noise (the test decides there).
  bool at_resolution = false;
  /// The one verdict: an accepted effect survived the backward pass, or the residual at the end
  /// still fails the test against the noise (without a stated noise: is not at the data's
  /// resolution, at_resolution).
  bool model_form_error = false;
  /// Names of the accepted effects the backward pass kept.
  std::vector<std::string> accepted() const;
};

/// Runs the loop on `problem` from the parameter values `start`.
/// \throws std::invalid_argument for invalid options, a start of the wrong size or an effect to
///   start from given twice (among the problem's enabled effects and DiagnosisOptions::added);
///   std::runtime_error if the start cannot be evaluated.
MODALCAL_EXPORT Diagnosis diagnose(const Problem& problem, const Vector& start, const DiagnosisOptions& options = {});

/// The report: calibration, residual test, localization (first rows), ranking, recommendation
/// and the before/after table of the recommended effect.
MODALCAL_EXPORT std::string format_diagnosis(const Problem& problem, const Diagnosis& diagnosis);

/// The discretization estimate as text: each mode's estimated error and the chi-square it explains.
MODALCAL_EXPORT std::string format_discretization(const DiscretizationEstimate& estimate);

/// The stepwise loop as text: the misfit at the start, after each accepted effect (its value,
/// standard error, place, test, the alternatives and what would tell them apart), the effects
/// the backward pass dropped, and at the end. `problem` names the nodes and the measured modes.
MODALCAL_EXPORT std::string format_steps(const Problem& problem, const Diagnosis& diagnosis);

/// `problem` (unweighted) with the diagnosis's kept effects as parameters after its own, every
/// parameter starting at the diagnosis's final value: what `calibrate` continues from.
/// \throws std::invalid_argument if `diagnosis` was not made from `problem`.
MODALCAL_EXPORT Problem problem_with_diagnosed_effects(const Problem& problem, const Diagnosis& diagnosis);

/// 1-based rank of the effect called `name` in `ranking`, 0 if it is not ranked.
MODALCAL_EXPORT int rank_of(const EffectRanking& ranking, const std::string& name);

}  // namespace modalcal
