#pragma once
/// \file effects.hpp
/// Model-form diagnosis, "which effect is missing": candidate effects generated from the model's
/// structure (and declared in the problem file), ranked by how much of the calibrated misfit each
/// one removes on top of the calibration parameters.
///
/// **Candidates.** A candidate is a model change (model_change.hpp) whose value is free: its name
/// is the change's canonical `<entity>.<property>` (the name synthetic data give their hidden
/// effects), its description the change's words. generate_candidates() takes them from the model:
///
/// | where | candidates | variable | bounds |
/// |---|---|---|---|
/// | each block | `stiffness_scale`, `mass_scale` | log | ×/÷ 10 |
/// | each region of a block (a grid of cells `region_elements` elements across, and the grid shifted by half a cell) | `stiffness_scale`, `mass_scale` | log | ×/÷ 10 |
/// | each joint, spring | its six components: present ones | log | ×/÷ 100 |
/// | | absent ones (the rotational ones a nominal model leaves out) | linear from 0 | [0, 100 k_ref] |
/// | each point mass | `mass` | log | ×/÷ 10 |
/// | each free node set | a spring to ground along x, y, z on each node | linear from 0 | [0, 100 k_ref] |
/// | | an added mass on each of its n nodes | linear from 0 | [0, m_ref / 2n] |
/// | each fixed node set | support flexibility per direction (`support@SET:kx`) | compliance | [k_ref/1000, k₀] |
/// | each sensor node | an added point mass (a sensor's or cable's mass loading) | linear from 0 | [0, m_ref / 2] |
/// | blocks sharing no node, < 2 elements apart | a joint along x, y, z at nearest nodes | from 0 | [0, 100 k_ref] |
/// | every free node of a surface or interface (spatial) | an added point mass | linear from 0 | [0, m_ref / 2] |
/// | | a spring to ground along each free direction | linear from 0 | [0, 100 k_ref] |
///
/// k_ref is the stiffness of a node in the adjoining block, \f$E h\f$ (E Young's modulus, h the
/// element size), or for a joint's absent rotational component its translational stiffness (the
/// geometric mean of the present components) times the squared radius of the patch its nodes
/// couple; m_ref the mass of the blocks the nodes belong to. Candidates whose property a
/// calibration parameter already sets are left out.
///
/// **Screen** (rank_effects). With the residual vector r and its Jacobian
/// \f$J_p\f$ in the calibration parameters at the calibrated point (noise-weighted, so that
/// \f$\|r\|^2 = X^2\f$ of residual_test.hpp: see noise_weighted()), candidate j's column j in its
/// screening variable (log10 of the value, the value, or the compliance \f$c = 1/k\f$ of a support,
/// where the first-order effect of a rigid support's flexibility does not vanish) is projected off
/// what the calibration parameters can already do, \f$j_\perp = (I - J_p J_p^+)\,j\f$, and the
/// Gauss-Newton (score-test) prediction of the chi-square it removes is
/// \f[ \Delta X^2_{pred} = \max_{\delta \in [\delta_-, \delta_+]} -2\delta\, j_\perp^T r - \delta^2 \|j_\perp\|^2
///     \;=\; \frac{(j_\perp^T r)^2}{\|j_\perp\|^2} \text{ when the bounds do not bind,} \f]
/// the bounds keeping one-sided effects (an added mass, a softer support) from "helping" by a
/// negative value and tiny effects from helping by an absurd one. One evaluation of the model with
/// every candidate added (at the value meaning "no effect"; a support at a stiff k₀ = 10³ k_ref)
/// gives all columns at once; its shape rows come from one adjoint solve per sensor reading
/// (ObjectiveOptions::Jacobian), not per candidate. Should that model fail to solve, the
/// supports' candidates are evaluated apart, per support. A joint's or spring's present stiffness
/// component is also stepped along the same tangent in its compliance \f$1/k\f$, over the same
/// range, the larger prediction kept: near rigid, the modes move in proportion to a joint's
/// compliance, while in log10 k the slope is small and the step stops on the range's bound.
///
/// **Refit.** The best few by prediction are recalibrated with all calibration parameters free
/// (reduced L-BFGS from the calibrated point, the candidate started at its first-order value);
/// the achieved reduction \f$\Delta X^2 = X^2_{before} - X^2_{after}\f$ is a likelihood-ratio
/// statistic, \f$\chi^2_1\f$ under "the effect is absent". It is *significant* above the
/// \f$\chi^2_1\f$ critical value at the significance level divided by the number of candidates
/// screened (Bonferroni: the best of many is tested). \f$\Delta BIC = \Delta X^2 - \ln n\f$ (n data)
/// is reported beside it; positive favours the effect. Without a stated noise the objective's own
/// weights stand in and significance uses the residual of the refit as the noise estimate
/// (an F-test).
///
/// **Which effect.** Significance says that something is missing; which candidate is named is a
/// second question. Among the significant refits the ranking puts first the largest
/// \f[ S = \Delta X^2 - 2 \ln n_{kind}, \f]
/// \f$n_{kind}\f$ the number of candidates of its kind screened (a kind: the change's kind and
/// property, e.g. "a spring to ground along x" or "a block's stiffness scale"; added point masses
/// and block regions' mass scales are one kind, mass at a place; a declared candidate is a kind of
/// its own). S is twice the log posterior odds of the candidate against "no effect" when
/// every kind is a priori equally likely and a kind's members share its prior (up to a constant
/// common to all): a point mass at one of 2,000 nodes must fit better by \f$2\ln(2000/4) \approx 12\f$
/// than a scale of one of 4 blocks to be preferred, since one of 2,000 places fits well by chance
/// more easily. Effects the data do not tell apart (the same fit to within the noise) are thus
/// named by the simpler hypothesis; the refits' order of choice uses the same penalty on the
/// predictions (after the best prediction itself).
///
/// \code
/// modalcal::Problem weighted = modalcal::noise_weighted(problem, *problem.measurement_noise);
/// std::vector<modalcal::EffectCandidate> candidates = modalcal::generate_candidates(weighted);
/// modalcal::EffectRanking ranking = modalcal::rank_effects(weighted, calibrated_p, candidates);
/// std::cout << modalcal::format_effect_ranking(ranking, 10);
/// \endcode

#include <optional>
#include <string>
#include <vector>

#include "modalcal/export.hpp"
#include "modalcal/model_change.hpp"
#include "modalcal/problem.hpp"
#include "modalcal/reduced.hpp"
#include "modalcal/residual_test.hpp"
#include "modalcal/task_map.hpp"

namespace modalcal {

/// A parameterized model change: the unit the ranking talks in.
struct MODALCAL_EXPORT EffectCandidate {
  /// How the screen linearizes the effect and the refit scales it.
  enum class Variable {
    Log,         ///< log10 of a positive value with a nonzero nominal (scale factors, present stiffness)
    Linear,      ///< the value itself, from a nominal of 0 (absent components, added masses and springs)
    Compliance,  ///< 1/k of a flexible support, from 0 (rigid); the refit works in log10 k
  };
  std::string name;         ///< canonical `<entity>.<property>`, e.g. "joint2.kry"
  std::string description;  ///< in words, e.g. "rotational stiffness about y of joint joint2"
  ModelChange change;       ///< its value is set to the candidate's value when applied
  Variable variable = Variable::Log;
  double nominal = 1;             ///< the value that means "no effect": 1, 0, or +infinity (rigid support)
  double screen_value = 1;        ///< where the screen linearizes: the nominal, or k₀ for a support
  double reference = 1;           ///< a typical magnitude (physical units), for scaling
  double lower = 0, upper = 0;    ///< bounds of the value, lower < upper
  std::optional<double> initial;  ///< a declared start (else the first-order estimate)
  bool declared = false;          ///< from the problem file's `effects:` or the command line
  /// Where it acts: the centroid of its nodes (none for a block's property, which acts on the
  /// whole block).
  std::optional<Vec3> location;
  /// Two candidates of one kind (change kind and property) closer than this are neighbours: the
  /// refits take the best of each group (two element sizes at its nodes).
  double neighbourhood = 0;
  /// True when `other` is of this one's kind (change kind and property) and acts within the
  /// larger of their neighbourhoods: one effect seen from two neighbouring places.
  bool neighbour_of(const EffectCandidate& other) const;
  /// True when `value` lies on a bound of the range, to 1e-4 of the range in the screening
  /// variable, and that bound is not a physical limit: a refit that ends there asks for more
  /// change than the candidate makes, and stands in for something else. Exempt are the effects
  /// added from zero (a spring or a mass: at its upper bound a spring holds its node, the truth may
  /// be stiffer still) and a support's flexibility (at its softest, a thousandth of the
  /// structure's own stiffness there, the support is released in that direction).
  bool on_bound(double value) const;
};

/// Which automatic candidates to generate (all by default).
struct MODALCAL_EXPORT CandidateOptions {
  bool blocks = true;         ///< stiffness and mass scale per block, Poisson's ratio of an (E, nu) block
  bool joints = true;         ///< six components per joint and spring, mass per point mass
  bool node_sets = true;      ///< springs to ground and added masses per free node set
  bool supports = true;       ///< flexibility of each fixed node set, per fixed component
  bool sensor_masses = true;  ///< an added mass at each sensor node
  bool between_parts = true;  ///< springs between blocks that share no node but nearly touch
  /// A point mass and springs to ground along x, y and z at every free node of the model's
  /// surfaces and of the interfaces between its blocks: effects outside any list of parts.
  bool spatial = true;
  /// Stiffness and mass scales of the regions of every block: the block's element centroids
  /// binned in a grid of cubes `region_elements` element sizes across (aligned with the block's
  /// lowest corner), one region per non-empty cube, for blocks that span more than one cube; and
  /// the same on grids twice, four times, ... as coarse (`region_levels` grids in all), since a
  /// changed part of a block has no given size. A coarse cube holding the same elements as a finer
  /// one is not screened twice.
  bool regions = true;
  /// The finest regions' size in element sizes. Range: [1, 1000].
  double region_elements = 3;
  /// How many grids of regions, each twice as coarse as the one before. Range: [1, 6].
  int region_levels = 3;
  /// Each grid also shifted along every axis by half a cube, rounded to whole element sizes (a
  /// body-centred second grid). A changed part of a block rarely lines up with one grid: a part
  /// centred on a face of its cubes is split between two regions, neither of which acts as it
  /// does. With the shifted grid every part has a region centred within about a quarter cube of
  /// its centre along each axis.
  bool region_stagger = true;
  /// Two blocks "nearly touch" when their nearest nodes are closer than this times the larger
  /// element size of the two. Range: > 0.
  double gap_factor = 2.0;
  /// The screen's stand-in for a rigid support: springs of this many k_ref (a support's screen
  /// value k₀). The screen's columns are taken at c₀ = 1/k₀ instead of 0 (an error of about
  /// 1/this, relative; the residual itself is the rigid model's). Much stiffer springs inflate
  /// tr(K), by which the eigen-solver judges what is a rigid-body mode, until an elastic mode may
  /// look rigid (docs/design.md, "Candidates"). Range: [10, 1e8].
  double rigid_support_factor = 1e3;
  /// Returns false and names the field, its value and the violated condition.
  bool IsValid(std::string* error) const;
};

/// The candidates of `problem`'s model (table above), then the declared ones (Problem::effects),
/// without those whose property a calibration parameter sets; unique names, declared ones
/// replacing automatic ones of the same name.
/// \throws std::invalid_argument for invalid options.
MODALCAL_EXPORT std::vector<EffectCandidate> generate_candidates(const Problem& problem,
                                                                 const CandidateOptions& options = {});

/// One candidate from a change text without its value ("joint2.kry", "point_mass@top:mass",
/// "support@post_bottom:kx") or with a start value ("joint2.kry=1e5"), with the defaults of the
/// table above; or the candidate of that name among generate_candidates() (e.g.
/// "added_mass_node123.mass"). Marked declared.
/// \throws std::invalid_argument naming the text and why it does not apply to the model, or
/// that its start value lies outside the candidate's bounds.
MODALCAL_EXPORT EffectCandidate make_candidate(const Problem& problem, const std::string& text,
                                               const CandidateOptions& options = {});

/// The declared effects of `problem` that are enabled (`enable: true`), as candidates.
MODALCAL_EXPORT std::vector<EffectCandidate> enabled_candidates(const Problem& problem,
                                                                const CandidateOptions& options = {});

/// `problem` with each candidate applied to its model at `values[k]` and added as a parameter
/// after the problem's own (name = candidate name, initial value `values[k]`, bounds of the
/// candidate). Log scaling where the value is positive (an effect from 0 then searched down to a
/// thousandth of `values[k]`, its lower bound), linear scaling with the candidate's reference
/// where it is 0 (the screen's point) or the bounds include negative values.
/// \throws std::invalid_argument if a change cannot be applied (naming it) or the sizes differ.
MODALCAL_EXPORT Problem problem_with_effects(const Problem& problem, const std::vector<EffectCandidate>& candidates,
                                             const std::vector<double>& values);

/// Where `candidate` acts on `model`: the centroid of the nodes of the joint, springs or point
/// mass it sets or adds (a joint's two nodes, a support's or node set's nodes); none for a
/// block's property, which acts on the whole block.
/// \throws std::invalid_argument if its change does not apply to `model`.
MODALCAL_EXPORT std::optional<Vec3> effect_location(const Model& model, const EffectCandidate& candidate);
/// Where a candidate acts, block-wide ones included: effect_location(), or the centroid of the
/// block's nodes for a block's property.
MODALCAL_EXPORT std::optional<Vec3> effect_place(const Model& model, const EffectCandidate& candidate);

struct MODALCAL_EXPORT RankingOptions {
  /// How many of the best-predicted candidates are refitted. Range: >= 0.
  int refits = 3;
  /// Refits for a weak effect: while the best prediction is below `weak_prediction` critical
  /// values, max(refits, weak_refits) of the best-predicted candidates (one per group of
  /// neighbours) are refitted. Near the critical value many places predict alike, and a refit's
  /// gain over its first-order prediction differs between them by more than the predictions do:
  /// a point mass at a sensor's node gains about twice its prediction, one a few nodes away a
  /// quarter more (docs/design.md, "Refits and significance"). A weak effect's refits are short,
  /// and a strong one's ranking is not flat, so only weak steps refit more. 0: `refits` always.
  /// Range: >= 0.
  int weak_refits = 6;
  /// Range: >= 0 (0: no step counts as weak).
  double weak_prediction = 2;
  /// Further refits for hypotheses elsewhere: the best-predicted candidates whose place lies
  /// farther than a quarter of the model's size from every candidate chosen before, while their
  /// prediction is at least `place_refit_share` of the best one's. Mirror-image parts of a
  /// symmetric structure predict alike to first order and part only in the refit. Range: >= 0.
  int place_refits = 2;
  /// Range: (0, 1].
  double place_refit_share = 0.7;
  /// Further refits for other physics: the best-scored candidate of each kind that no candidate
  /// chosen before has, best score first, while its prediction is at least `kind_refit_share` of
  /// the best one's. Different physics at one place (a support's flexibility, the stiffness of
  /// the part it holds) predict alike to first order; the refits above, chosen by score, can all
  /// go to one kind's variants of one place. Range: >= 0.
  int kind_refits = 4;
  /// Range: (0, 1].
  double kind_refit_share = 0.8;
  /// Refits of the best refit's neighbours (its kind, within its neighbourhood), best predicted
  /// first, after the refits above; as many again for each other kind's best refit that scores
  /// within the critical value of it (or neighbour_window_share of its score). The choice above refits one candidate per neighbourhood,
  /// and for a large effect the first-order prediction does not rank the nodes of one
  /// neighbourhood reliably: a point mass refitted one node from the truth's leaves a residual
  /// that later steps fill with spurious effects. Range: >= 0.
  int neighbour_refits = 3;
  /// Rounds of neighbour refits. The first refits the best refit's neighbours and those of every
  /// kind's best scoring close to it (neighbour_window_share); each further round refits the
  /// neighbours of a kind's best that moved in the round before, so that it can walk on to the
  /// place the data favour. 1: the first round only; 0: no neighbour refits. Range: >= 0.
  int neighbour_rounds = 3;
  /// A kind's best refit starts neighbour refits while its score lies within the critical value
  /// of the best one's, or within this share of the best score when that is wider. For a large
  /// effect (a ΔX² of thousands) one neighbourhood's places part by more than the critical value
  /// and the first-order prediction ranks them no better than that, so a kind a few tens behind
  /// after the first refits can still fit best once it has walked to its best place.
  /// Range: [0, 1).
  double neighbour_window_share = 0.01;
  /// Name the effect by S = ΔX² − 2 ln(candidates of its kind) (see "Which effect" above); false:
  /// by ΔX² alone (every candidate equally likely a priori).
  bool equal_kind_prior = true;
  /// Significance level of the likelihood-ratio test, before the Bonferroni division by the
  /// number of candidates screened. Range: (0, 0.5).
  double significance = 0.01;
  /// Without a stated noise, the data's resolution: a model frequency within this relative error
  /// of the measured one, and a MAC within it of 1, cannot be told from exact agreement (no modal
  /// test repeats to 0.01 % in frequency). The F test, which estimates the noise from the refit's
  /// own residual, never takes that estimate below the residual such a fit leaves per datum
  /// (resolution_variance()): otherwise, on noise-free data from the right model, a
  /// refit that merely converges further than the calibration did would be "significant".
  /// Unused with a stated noise. Range: (0, 0.01].
  double resolution = 1e-4;
  /// The refits: Gauss-Newton from the first-order start (why not L-BFGS: docs/design.md,
  /// "Refits and significance"). Tolerances suit a
  /// noise-weighted misfit (values of the order of the number of data): the projected gradient in
  /// scaled variables to 1e-4, or 1e-8 of its start, or an iteration that lowers the misfit by at
  /// most 1e-3 of it (a change of the chi-square below about 0.4, a fiftieth of a critical
  /// value); at most 60 iterations.
  ReducedOptions refit = default_refit_options();
  /// Deflated solves to 1e-8: the default 1e-11 buys nothing a ranking can see and costs more
  /// solves (docs/design.md, "Screen").
  ObjectiveOptions objective = default_objective_options();
  /// The refits' deflated solves (their Jacobians and gradients; `objective`'s other settings
  /// hold): a Gauss-Newton step needs a few digits of its Jacobian, and a refit's chi-square
  /// comes from its forward solve, which this does not touch. 1e-6 costs a fifth fewer solves
  /// than 1e-8 and leaves every refit's chi-square the same to 1e-5 (docs/design.md, "Refits and
  /// significance"). Range: (0, 1e-4].
  double refit_linear_tolerance = 1e-6;
  /// Walk a refit (and the diagnosis's calibrations: the first, and the loop's with its accepted
  /// effects) in a span of the model (Objective::set_span: a refit's from the ranked model's span
  /// at the calibrated point, Objective::extend_span; a calibration's from Objective::span_at at
  /// its start) when that span
  /// has at most `refit_span_share` of the model's DOFs, then check its end on the whole model:
  /// kept when the two chi-squares agree to the walk's function tolerance and a Gauss-Newton step
  /// there would gain less than that, else the walk goes on in the span at that end, checked
  /// again, and then on the whole model. The span's
  /// steps need no factorization and no iterative solve, but cost products with its columns: a
  /// twentieth keeps them well below a whole-model step (LFU 0.7's span is a hundredth of its
  /// DOFs; on the portal frame, where it would be a thirteenth, it gained nothing; docs/design.md,
  /// "Refits in a span"). 0: every refit on the whole model. Range: [0, 1].
  double refit_span_share = 0.05;
  /// `objective` with the refits' linear tolerance.
  ObjectiveOptions refit_objective() const;
  /// How the refits, independent of each other, are run: in turn here when empty; the
  /// command-line tool passes one that spreads them over the processes of an MPI job.
  TaskMap task_map;
  /// Returns false and names the field, its value and the violated condition.
  bool IsValid(std::string* error) const;
  static ReducedOptions default_refit_options();
  static ObjectiveOptions default_objective_options();
};

struct MODALCAL_EXPORT RankedEffect {
  EffectCandidate candidate;
  double predicted_reduction = 0;  ///< the screen's \f$\Delta X^2_{pred}\f$ (bounded)
  double predicted_value = 0;      ///< the value at the screen's optimum
  bool refitted = false;
  double achieved_reduction = NAN;  ///< \f$X^2_{before} - X^2_{after}\f$ of the refit
  double value = NAN;               ///< identified by the refit (else the predicted value)
  double chi2_after = NAN;          ///< \f$X^2\f$ with the effect (refitted only)
  int dof_after = 0;
  double p_value_after = NAN;
  bool model_form_error_after = false;  ///< the residual test still fails with the effect
  double delta_bic = NAN;               ///< \f$\Delta X^2 - \ln n\f$
  double delta_aic = NAN;               ///< \f$\Delta X^2 - 2\f$
  /// The likelihood-ratio statistic of the refit in chi-square units: ΔX² with a stated noise,
  /// else the F statistic (the reduction over the refit's residual per degree of freedom).
  double statistic = NAN;
  int kind_size = 1;        ///< \f$n_{kind}\f$: candidates of its kind screened (1 if declared)
  double kind_penalty = 0;  ///< \f$2 \ln n_{kind}\f$ (0 without RankingOptions::equal_kind_prior)
  /// S = statistic − kind_penalty after a refit, the predicted ΔX² − kind_penalty before.
  double score() const { return (refitted ? statistic : predicted_reduction) - kind_penalty; }
  /// One standard deviation of the identified value, \f$\sqrt{((J^T J)^{-1})_{\theta\theta}}\f$ with
  /// the noise-weighted Jacobian at the refit (the first-ranked effect only; NaN otherwise or
  /// without a stated noise).
  double standard_error = NAN;
  bool significant = false;  ///< likelihood-ratio test passed (refitted only)
  /// The refit's value ended on a bound of the candidate's range (EffectCandidate::lower,
  /// upper): the data ask for more change than this effect can make, so what it gains stands in
  /// for something else (a foam's stiffness at a tenth, a block's mass at a tenth). Listed, but
  /// never accepted by a step nor named as an alternative. Effects whose bound is a physical
  /// limit are exempt: those added from zero (springs, masses; a spring at its upper bound holds
  /// its node) and a support's flexibility (at its softest the support is released).
  bool at_bound = false;
  /// What a step may accept: significant, and inside its range.
  bool acceptable() const { return refitted && significant && !at_bound; }
  /// The refit's calibration parameters, then the effect's value; before a refit, the
  /// first-order estimate of them (its start).
  Vector parameters;
  ReducedSummary refit;  ///< the refit's optimizer summary
  /// "rotational stiffness about y of joint joint2, identified 3.1e+05" (or "predicted ...").
  std::string summary() const;
};

struct MODALCAL_EXPORT EffectRanking {
  /// Refitted candidates, the significant ones first, each group by score() (S, "Which effect"
  /// above); then the others by predicted reduction.
  std::vector<RankedEffect> effects;
  double chi2_before = 0;  ///< \f$X^2\f$ at the calibrated point (or 2J without noise)
  int dof_before = 0;
  int num_data = 0;          ///< n: one per frequency, s - 1 per shape of s values
  bool noise_known = false;  ///< the residuals were weighted by a stated noise
  int screened = 0;          ///< candidates with a usable column
  /// Candidates the screen set aside, with the reason ("no effect on the measured modes", "the
  /// calibration parameters already do this", "could not be applied: ...").
  std::vector<std::pair<std::string, std::string>> set_aside;
  double critical_value = 0;  ///< of the likelihood-ratio test
  /// Without a stated noise: the least noise variance per datum the F test assumes, that of a fit
  /// whose every frequency is off by RankingOptions::resolution and every MAC short of 1 by it
  /// (resolution_variance()). 0 with a stated noise.
  double resolution_variance = 0;
  double screen_seconds = 0, refit_seconds = 0;
  int linear_solves = 0;  ///< of the screen's Jacobian
};

/// Where the model fails, read off the screen: every candidate's predicted chi-square reduction
/// put where it acts. Under noise alone a candidate's prediction is (at most) a chi-square(1)
/// variable, its score statistic, wherever it acts: each family's map is flat up to noise, and a
/// missing effect shows as a peak. The scores combine a place's candidates as
/// \f$-\log_{10} p\f$ of the best one, p Šidák-corrected for their number
/// (\f$p = 1 - (1 - p_1)^k\f$), so they too are flat in distribution under noise. Without a stated
/// noise the predictions (in 2J) are first divided by the noise variance the residual estimates,
/// 2J / dof, at least EffectRanking::resolution_variance.
struct MODALCAL_EXPORT ScreenMap {
  Vector node_mass;     ///< per model node: an added point mass (NaN where none was screened)
  Matrix node_spring;   ///< per node, 3 columns: a spring to ground along x, y, z (NaN likewise)
  /// Per node: \f$-\log_{10} p\f$ of its best candidate (0 where none): the additions at the
  /// node, and the candidates acting at a place (a joint, a node set, a support) whose nearest
  /// node it is.
  Vector node_score;
  /// Per element (blocks in model order, elements in block order): the stiffness and mass scales
  /// of its regions and its block (the largest prediction; NaN where none was screened), and the
  /// score of all of them.
  Vector element_stiffness, element_mass, element_score;
  int node_candidates = 0, region_candidates = 0;  ///< how many of each the map shows
  /// A node or region of the map with its score: the map read as a list.
  struct Place {
    /// "node 17 (added mass)", "region base_region_0p75_0p5_0p75_n18.stiffness_scale",
    /// "block foam.stiffness_scale", "joint2.kry"
    std::string what;
    Vec3 location = Vec3::Zero();  ///< the node, or the centroid of the nodes of the region, block or entity
    double score = 0;   ///< -log10 p as above
  };
  std::vector<Place> places;  ///< every scored node and region, highest score first
};

/// The map of the screen `ranking` made on `model` (the model it screened; see ScreenMap).
/// \throws std::invalid_argument if a region candidate does not apply to `model`.
MODALCAL_EXPORT ScreenMap screen_map(const Model& model, const EffectRanking& ranking);

/// The map's first `rows` places as a table: score, place, location.
MODALCAL_EXPORT std::string format_screen_map(const ScreenMap& map, int rows = 5);

/// The critical value an effect's gain must pass at level `alpha`, a model with `num_parameters`
/// fitted: with a stated noise the chi-square(1) value; without one the F(1, n - num_parameters)
/// value, the noise estimated from the refit's residual (infinite when no degree of freedom is
/// left, n = ranking.num_data: no gain can then be told from noise).
MODALCAL_EXPORT double gain_critical_value(const EffectRanking& ranking, double alpha, int num_parameters);

/// Screens `candidates` at the calibrated parameters `calibrated` of `problem` (weighted by its
/// measurement noise when it has one, see noise_weighted) and refits the best ones.
/// `problem` must be the weighted problem the calibration minimized.
/// \throws std::invalid_argument for invalid options or sizes; std::runtime_error if the
///   calibrated point cannot be evaluated.
MODALCAL_EXPORT EffectRanking rank_effects(const Problem& problem, const Vector& calibrated,
                                           const std::vector<EffectCandidate>& candidates,
                                           const RankingOptions& options = {});

/// The ranking as a table: rank, name, predicted and achieved reduction, value, ΔBIC,
/// significant; its first `max_rows` rows, then the description of each refitted one.
MODALCAL_EXPORT std::string format_effect_ranking(const EffectRanking& ranking, int max_rows = 10);

}  // namespace modalcal
