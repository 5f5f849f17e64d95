// `fullspace_calib diagnose PROBLEM`: the model-form diagnosis loop. Calibrates, tests the
// residual against the stated noise, localizes it, ranks candidate effects, refits the best and
// says what to add (diagnosis.hpp).

#include <CLI/CLI.hpp>
#include <cmath>
#include <cstdio>
#include <algorithm>
#include <filesystem>
#include <iostream>
#include <optional>

#include "cli/cli_common.hpp"
#include "cli/cli_validators.hpp"
#include "cli/commands.hpp"
#include "cli/work_farm.hpp"
#include "support/text_util.hpp"
#include "modalcal/diagnosis.hpp"
#include "modalcal/output.hpp"
#include "cli/plot.hpp"
#include "modalcal/problem_file.hpp"

namespace modalcal::cli {

namespace {

struct DiagnoseArgs {
  std::string problem;
  ParameterChoice start;
  double start_factor = 1;
  double refine = 0;
  int refits = RankingOptions().refits;
  int weak_refits = RankingOptions().weak_refits;
  int place_refits = RankingOptions().place_refits;
  int kind_refits = RankingOptions().kind_refits;
  int neighbour_refits = RankingOptions().neighbour_refits;
  int neighbour_rounds = RankingOptions().neighbour_rounds;
  double significance = ResidualTestOptions().significance;
  double resolution = RankingOptions().resolution;
  int max_iterations = DiagnosisOptions().calibration.max_iterations;
  int max_steps = DiagnosisOptions().max_steps;
  int first_step_alternatives = DiagnosisOptions().first_step_alternatives;
  bool alternatives_after_consistent_end = DiagnosisOptions().alternatives_after_consistent_end;
  int pair_exchanges = DiagnosisOptions().pair_exchanges;
  int calibration_starts = DiagnosisOptions().calibration_starts;
  double mesh_check = 1.5;
  double other_data_margin = DiagnosisOptions().other_data_margin;
  bool no_backward = false;
  bool no_exchange = false;
  bool walks_in_turn = false;  // the paths one after the other even with threads
  std::vector<std::string> add;
  double region_size = CandidateOptions().region_elements;
  int region_levels = CandidateOptions().region_levels;
  int jobs = 0;  // refits at a time in threads; 0: one per core
  std::string json, vtu, plot, map, write_problem;
  bool quiet = false;
};

/// The screen map's arrays for the VTU file (ScreenMap, effects.hpp).
void add_screen_map_fields(const ScreenMap& map, VtuFields* fields) {
  auto array = [](const char* name, const Vector& v) {
    return VtkArray{name, 1, std::vector<double>(v.data(), v.data() + v.size())};
  };
  fields->node_data.push_back(array("screen_score", map.node_score));
  fields->node_data.push_back(array("screen_added_mass", map.node_mass));
  const char* springs[3] = {"screen_spring_x", "screen_spring_y", "screen_spring_z"};
  for (int c = 0; c < 3; ++c) fields->node_data.push_back(array(springs[c], map.node_spring.col(c)));
  fields->element_data.push_back(array("screen_region_score", map.element_score));
  fields->element_data.push_back(array("screen_region_stiffness", map.element_stiffness));
  fields->element_data.push_back(array("screen_region_mass", map.element_mass));
}

/// The map as a picture: every node coloured by its score, or, where regions were screened and
/// the node is in no screened node candidate, by the best score of the elements around it.
void plot_screen_map(const std::string& path, const Problem& problem, const ScreenMap& map) {
  const Model& model = problem.model;
  Vector value = map.node_score;
  std::vector<bool> screened(model.num_nodes(), false);
  for (int v = 0; v < model.num_nodes(); ++v) screened[v] = !std::isnan(map.node_mass[v]) || !map.node_spring.row(v).array().isNaN().all();
  int element = 0;
  for (const ElementBlock& b : model.blocks) {
    const int npe = nodes_per_element(b.type);
    for (int e = 0; e < b.num_elements(); ++e, ++element)
      for (int k = 0; k < npe; ++k) {
        const int v = b.connectivity[e * npe + k];
        if (!screened[v]) value[v] = std::max(value[v], map.element_score[element]);
      }
  }
  PointCloud cloud;
  cloud.points.resize(model.num_nodes(), 3);
  for (int v = 0; v < model.num_nodes(); ++v) {
    cloud.points.row(v) = model.coordinates[v].transpose();
    cloud.values.push_back(value[v]);
  }
  cloud.value_title = "-log10 p of the best candidate (noise alone: mostly below 1)";
  cloud.max = std::max(3.0, value.maxCoeff());
  plot_point_cloud(path, "where the screen predicts a missing effect: " +
                             std::filesystem::path(problem.path).filename().string(), cloud);
}


nlohmann::json residual_json(const FitState& fit) {
  nlohmann::json json = {{"statistic", fit.statistic}};
  json["parameters"] = nlohmann::json::array();
  for (size_t j = 0; j < fit.parameter_names.size(); ++j)
    json["parameters"].push_back({{"name", fit.parameter_names[j]}, {"value", fit.parameters[j]}});
  json["modes"] = nlohmann::json::array();
  for (const PairedMode& pair : fit.pairs) {
    nlohmann::json mode = {{"measured", pair.measured + 1},
                           {"measured_hz", pair.measured_hz},
                           {"model_mode", pair.model + 1},
                           {"model_hz", pair.model_hz},
                           {"error_percent", 100 * (pair.model_hz / pair.measured_hz - 1)},
                           {"mac", pair.mac >= 0 ? json_number(pair.mac) : nlohmann::json()}};
    if (fit.test)
      for (const ModeResidual& m : fit.test->modes)
        if (m.measured == pair.measured) {
          mode["chi2"] = m.frequency_chi2 + m.shape_chi2;
          mode["dof"] = m.dof;
          mode["flagged"] = m.flagged;
        }
    json["modes"].push_back(mode);
  }
  if (fit.test) {
    json["dof"] = fit.test->dof;
    json["p_value"] = json_number(fit.test->p_value);
    json["reduced_chi2"] = fit.test->reduced_chi2;
    json["model_form_error"] = fit.test->model_form_error;
    json["verdict"] = fit.test->verdict;
  }
  return json;
}

const char* variable_name(EffectCandidate::Variable v) {
  switch (v) {
    case EffectCandidate::Variable::Log:
      return "log";
    case EffectCandidate::Variable::Linear:
      return "linear";
    case EffectCandidate::Variable::Compliance:
      return "compliance";
  }
  return "";
}

nlohmann::json location_json(const std::optional<Vec3>& location) {
  if (!location) return nullptr;
  return {(*location)[0], (*location)[1], (*location)[2]};
}

/// What would tell a step's effect from an alternative (null where nothing was found).
nlohmann::json tell_apart_json(const Problem& problem, const TellApart& t) {
  nlohmann::json reading, mode;
  if (t.node >= 0 && t.measured >= 0)
    reading = {{"node", problem.model.node_ids[static_cast<size_t>(t.node)]},
               {"location", {t.location[0], t.location[1], t.location[2]}},
               {"direction", std::string(1, "xyz"[t.component])},
               {"measured_mode", problem.measured[static_cast<size_t>(t.measured)].label},
               {"separation", json_number(t.shape_separation)}};
  if (t.model_mode >= 0)
    mode = {{"model_mode", t.model_mode + 1}, {"model_hz", json_number(t.model_hz)},
            {"separation", json_number(t.frequency_separation)}};
  return {{"reading", reading}, {"unmeasured_mode", mode}};
}

nlohmann::json alternatives_json(const Problem& problem, const DiagnosisStep& s) {
  nlohmann::json list = nlohmann::json::array();
  for (size_t k = 0; k < s.alternatives.size(); ++k) {
    const RankedEffect& a = s.alternatives[k];
    list.push_back({{"name", a.candidate.name},
                    {"value", json_number(a.value)},
                    {"chi2_after", json_number(a.chi2_after)},
                    {"score", json_number(a.score())},
                    {"data_favour", s.data_favour(a)},
                    {"prior_overruled", s.prior_overruled(a)},
                    {"tell_apart", k < s.tell_apart.size() ? tell_apart_json(problem, s.tell_apart[k]) : nlohmann::json()}});
  }
  return list;
}

nlohmann::json step_json(const Problem& problem, const DiagnosisStep& s) {
  const RankedEffect& e = s.effect;
  return {{"step", s.step},
          {"name", e.candidate.name},
          {"description", e.candidate.description},
          {"change", to_string(e.candidate.change)},
          {"location", location_json(s.location)},
          {"place_spread", json_number(s.place_spread)},
          {"places", s.places},
          {"value", json_number(e.value)},
          {"standard_error", json_number(e.standard_error)},
          {"chi2_before", s.chi2_before},
          {"chi2_after", json_number(e.chi2_after)},
          {"p_value_after", json_number(e.p_value_after)},
          {"delta_bic", json_number(e.delta_bic)},
          {"score", json_number(e.score())},
          {"critical_value", s.critical_value},
          {"screened", s.screened},
          {"alternatives", alternatives_json(problem, s)}};
}

/// The first step's ranking: every screened candidate, refitted or not.
nlohmann::json ranking_json(const Problem& problem, const EffectRanking& ranking) {
  nlohmann::json list = nlohmann::json::array();
  for (size_t k = 0; k < ranking.effects.size(); ++k) {
    const RankedEffect& r = ranking.effects[k];
    list.push_back({{"rank", k + 1},
                    {"name", r.candidate.name},
                    {"description", r.candidate.description},
                    {"change", to_string(r.candidate.change)},
                    {"location", location_json(effect_location(problem.model, r.candidate))},
                    {"variable", variable_name(r.candidate.variable)},
                    {"predicted_reduction", r.predicted_reduction},
                    {"predicted_value", json_number(r.predicted_value)},
                    {"refitted", r.refitted},
                    {"achieved_reduction", json_number(r.achieved_reduction)},
                    {"value", json_number(r.refitted ? r.value : r.predicted_value)},
                    {"chi2_after", json_number(r.chi2_after)},
                    {"delta_bic", json_number(r.delta_bic)},
                    {"kind_size", r.kind_size},
                    {"score", json_number(r.refitted ? r.score() : NAN)},
                    {"significant", r.significant},
                    {"at_bound", r.at_bound}});
  }
  return list;
}

/// The mesh's share of the residual, or null without the estimate.
nlohmann::json discretization_json(const Diagnosis& d) {
  if (!d.discretization) return nullptr;
  const DiscretizationEstimate& est = *d.discretization;
  nlohmann::json modes = nlohmann::json::array();
  for (const DiscretizationEstimate::Mode& m : est.per_mode)
    modes.push_back({{"label", m.label}, {"measured", m.measured + 1}, {"shift_percent", m.shift_percent}});
  return {{"refinement", est.refinement},         {"dofs", est.dofs},
          {"finer_dofs", est.finer_dofs},         {"per_mode", modes},
          {"sensors_moved", est.sensors_moved},   {"sensor_offset", est.sensor_offset},
          {"chi2_explained", est.chi2_explained}, {"critical_value", est.critical_value},
          {"significant", est.significant},       {"corrected", est.corrected},
          {"score_corrected", json_number(est.score_corrected)},
          {"score_as_measured", json_number(est.score_as_measured)},
          {"other_data_first_path_only", est.other_data_first_path_only},
          {"other_data_forward_steps_only", est.other_data_forward_steps_only}};
}

/// The stepwise loop: forward steps, exchanges, what was kept and dropped, the residual at the end.
void add_loop_json(const Problem& problem, const Diagnosis& d, nlohmann::json* out) {
  nlohmann::json& json = *out;
  json["steps"] = nlohmann::json::array();
  for (const DiagnosisStep& s : d.steps) json["steps"].push_back(step_json(problem, s));
  json["exchanges"] = nlohmann::json::array();
  for (const DiagnosisStep& x : d.exchanges) {
    nlohmann::json e = step_json(problem, x);
    e["replaces"] = x.replaces;
    e["replaced_score"] = json_number(x.replaced_score);
    e["replaced_on_bound"] = x.replaced_on_bound;
    e["after_step"] = x.after_step;
    e["pair_score_change"] = json_number(x.pair_score_change);
    json["exchanges"].push_back(e);
  }
  json["accepted"] = d.accepted();
  json["dropped"] = nlohmann::json::array();
  for (const DroppedEffect& x : d.dropped)
    json["dropped"].push_back({{"name", x.name},
                               {"chi2_increase", x.chi2_increase},
                               {"critical_value", x.critical_value},
                               {"on_bound", x.on_bound},
                               {"value", json_number(x.value)}});
  json["paths"] = nlohmann::json::array();
  for (const DiagnosisPath& x : d.paths)
    json["paths"].push_back({{"first", x.first},
                             {"accepted", x.accepted},
                             {"chi2_final", x.chi2_final},
                             {"score", x.score},
                             {"kept", x.kept},
                             {"joined", x.joined.empty() ? nlohmann::json() : nlohmann::json(x.joined)},
                             {"joined_after", x.joined_after},
                             {"joined_after_exchanges", x.joined_after_exchanges},
                             {"no_second_step", x.no_second_step}});
  json["screens"] = {{"run", d.screens}, {"taken_again", d.screens_reused}};
  json["started_with"] = nlohmann::json::array();
  for (const EffectCandidate& c : d.started_with) json["started_with"].push_back(c.name);
  json["residual_final"] = {{"statistic", d.final_fit.statistic},
                            {"dof", d.final_fit.test ? nlohmann::json(d.final_fit.test->dof) : nlohmann::json()},
                            {"p_value", d.final_fit.test ? json_number(d.final_fit.test->p_value) : nlohmann::json()},
                            {"model_form_error", d.final_fit.test ? nlohmann::json(d.final_fit.test->model_form_error)
                                                                  : nlohmann::json()},
                            {"at_resolution", d.final_fit.test ? nlohmann::json() : nlohmann::json(d.at_resolution)}};
}

nlohmann::json to_json(const Problem& problem, const Diagnosis& d) {
  nlohmann::json json;
  json["problem"] = problem.path;
  json["noise"] = nullptr;
  if (d.noise_known)
    json["noise"] = {{"frequency", problem.measurement_noise->frequency}, {"shape", problem.measurement_noise->shape}};
  json["model_form_error"] = d.model_form_error;
  json["first_calibration_local_minimum"] = json_number(d.first_calibration_local_minimum);
  json["calibration"] = {{"status", to_string(d.calibration.status)},
                         {"start", d.calibration_start},
                         {"iterations", d.calibration.iterations},
                         {"forward_solves", d.calibration.forward_solves},
                         {"time_s", d.calibration.seconds}};
  // The nominal calibration's values, as calibrate writes them (so that --params takes this file).
  json["parameters"] = nlohmann::json::array();
  for (size_t j = 0; j < problem.parameters.size(); ++j)
    json["parameters"].push_back({{"name", problem.parameters[j].name},
                                  {"initial", d.calibration.initial[j]},
                                  {"final", d.calibration.final[j]}});
  json["calibration_on_bounds"] = d.calibration_on_bounds;
  json["residual_before"] = residual_json(d.before);
  json["residual_after"] = d.after ? residual_json(*d.after) : nlohmann::json();
  json["recommended"] =
      d.recommended >= 0 ? nlohmann::json(d.ranking.effects[d.recommended].candidate.name) : nlohmann::json();
  json["recommendation"] = d.recommendation;
  json["localization"] = nlohmann::json::array();
  if (d.localization)
    for (size_t r = 0; r < d.localization->ranking.size() && r < 10; ++r)
      json["localization"].push_back({{"region", d.localization->ranking[r].name},
                                      {"kind", d.localization->ranking[r].kind},
                                      {"share", d.localization->ranking[r].share}});
  const EffectRanking& ranking = d.ranking;
  json["ranking"] = ranking_json(problem, ranking);
  json["chi2_before"] = ranking.chi2_before;
  json["num_data"] = ranking.num_data;
  json["candidates_screened"] = ranking.screened;
  json["critical_value"] = ranking.critical_value;
  json["screen_time_s"] = ranking.screen_seconds;
  json["refit_time_s"] = ranking.refit_seconds;
  json["set_aside"] = nlohmann::json::array();
  for (const auto& [name, why] : ranking.set_aside) json["set_aside"].push_back({{"name", name}, {"reason", why}});
  json["discretization"] = discretization_json(d);
  add_loop_json(problem, d, &json);
  json["map"] = {{"node_candidates", d.map.node_candidates},
                 {"region_candidates", d.map.region_candidates},
                 {"places", nlohmann::json::array()}};
  for (size_t k = 0; k < std::min<size_t>(20, d.map.places.size()); ++k) {
    const ScreenMap::Place& p = d.map.places[k];
    json["map"]["places"].push_back({{"what", p.what}, {"location", location_json(p.location)}, {"score", p.score}});
  }
  add_hidden_effect(problem, &json);
  if (problem.synthetic_truth) {
    json["hidden_effect_rank"] = nlohmann::json::array();
    for (const ModelEffect& e : problem.synthetic_truth->hidden_effects)
      json["hidden_effect_rank"].push_back({{"name", e.name}, {"rank", rank_of(ranking, e.name)}});
  }
  return json;
}

// The misfit after each step against the band noise alone gives (its dof, up to the critical
// value), and each measured mode's frequency error before and after the loop.
void plot_steps(const std::string& path, const Problem& problem, const Diagnosis& d, double significance) {
  PlotPanel misfit{d.noise_known ? "chi-square" : "2J", true, {}};
  PlotSeries chi2{"after each step", {0}, {d.before.statistic}};
  for (const DiagnosisStep& s : d.steps) {
    chi2.x.push_back(s.step);
    chi2.y.push_back(s.effect.chi2_after);
  }
  misfit.series.push_back(chi2);
  if (d.before.test) {
    const double last = std::max<double>(1, static_cast<double>(d.steps.size()));
    misfit.series.push_back({"noise alone: its dof", {0, last}, {double(d.before.test->dof), double(d.before.test->dof)}});
    const double critical = chi_square_critical_value(significance, d.before.test->dof);
    misfit.series.push_back({"noise alone: critical value", {0, last}, {critical, critical}});
  }
  PlotPanel errors{"frequency error [%]", false, {}};
  PlotSeries before{"before", {}, {}}, after{"after", {}, {}};
  const FitState& end = d.after ? *d.after : d.before;
  for (const PairedMode& b : d.before.pairs)
    for (const PairedMode& a : end.pairs)
      if (a.measured == b.measured) {
        before.x.push_back(b.measured + 1);
        before.y.push_back(100 * (b.model_hz / b.measured_hz - 1));
        after.x.push_back(a.measured + 1);
        after.y.push_back(100 * (a.model_hz / a.measured_hz - 1));
      }
  errors.series = {before, after};
  plot_panels(path, "diagnosis of " + std::filesystem::path(problem.path).filename().string(),
              "step (left) / measured mode (right)", {misfit, errors});
}

std::string yaml_quoted(const std::string& text) { return nlohmann::json(text).dump(); }

// The problem with the kept effects enabled and every parameter starting at the diagnosis's final
// value: a file that extends the problem and replaces its parameters and effects sections.
std::string problem_with_effects_yaml(const Problem& problem, const std::string& out_path, const Diagnosis& d) {
  const std::filesystem::path out_dir = std::filesystem::absolute(out_path).parent_path();
  std::string text = "# Written by fullspace_calib diagnose: " + problem.path +
                     " with the effects the diagnosis kept\n# enabled, every parameter starting at its "
                     "diagnosed value. `fullspace_calib calibrate` on this file\n# calibrates the effects "
                     "with the parameters.\n";
  text += "extends: " + yaml_quoted(std::filesystem::relative(std::filesystem::absolute(problem.path), out_dir).string()) + "\n";
  text += "parameters:\n";
  for (size_t j = 0; j < problem.parameters.size(); ++j) {
    const Parameter& q = problem.parameters[j];
    std::string targets;
    for (PropertyId id : q.targets) targets += (targets.empty() ? "" : ", ") + yaml_quoted(problem.model.properties[id].name);
    text += "  " + yaml_quoted(q.name) + ": {targets: [" + targets + "], initial: " +
            format_round_trip(std::clamp(d.final_parameters[j], q.lower, q.upper)) + ", lower: " + format_round_trip(q.lower) +
            ", upper: " + format_round_trip(q.upper) + ", scaling: " + to_string(q.scaling) +
            (q.scaling == Scaling::Linear ? ", reference: " + format_round_trip(q.reference) : "") +
            (q.truth ? ", truth: " + format_round_trip(*q.truth) : "") + "}\n";
  }
  std::string effects;
  const size_t np = problem.parameters.size();
  for (size_t k = 0; k < d.effects.size(); ++k) {
    const EffectCandidate& c = d.effects[k];
    std::string change = to_string(c.change);
    change = change.substr(0, change.rfind('='));  // an effect is a change without its value
    const double value = std::clamp(d.final_parameters[static_cast<Eigen::Index>(np + k)], c.lower, c.upper);
    effects += "  - {effect: " + yaml_quoted(change) + ", description: " + yaml_quoted(c.description) +
            ", initial: " + format_round_trip(value) + ", lower: " + format_round_trip(c.lower) +
            ", upper: " + format_round_trip(c.upper) + ", enable: true}\n";
  }
  for (const DeclaredEffect& e : problem.effects)
    if (!e.enable && std::none_of(d.effects.begin(), d.effects.end(), [&](const EffectCandidate& c) {
          return c.name == make_candidate(problem, e.effect).name;
        }))
      effects += "  - {effect: " + yaml_quoted(e.effect) + ", description: " + yaml_quoted(e.description) + "}\n";
  return text + (effects.empty() ? "effects: []\n" : "effects:\n" + effects);  // a bare "effects:" is no list
}

/// The diagnosis's options from the command line (the effects to add and the finer mesh apart).
DiagnosisOptions diagnosis_options(const DiagnoseArgs& args, WorkFarm& farm) {
  DiagnosisOptions options;
  options.calibration.max_iterations = args.max_iterations;
  options.ranking.refits = args.refits;
  options.ranking.weak_refits = args.weak_refits;
  options.ranking.place_refits = args.place_refits;
  options.ranking.kind_refits = args.kind_refits;
  options.ranking.neighbour_refits = args.neighbour_refits;
  options.ranking.neighbour_rounds = args.neighbour_rounds;
  options.ranking.significance = args.significance;
  options.test.significance = args.significance;
  options.ranking.resolution = args.resolution;
  options.max_steps = args.max_steps;
  options.first_step_alternatives = args.first_step_alternatives;
  options.alternatives_after_consistent_end = args.alternatives_after_consistent_end;
  options.other_data_margin = args.other_data_margin;
  options.pair_exchanges = args.pair_exchanges;
  options.calibration_starts = args.calibration_starts;
  options.candidates.region_elements = args.region_size;
  options.candidates.region_levels = args.region_levels;
  options.backward = !args.no_backward;
  options.exchange = !args.no_exchange;
  farm.set_threads(threads_for_jobs(args.jobs));
  options.ranking.task_map = farm.task_map();
  // An MPI job's maps go in one order.
  options.walk_side_by_side = farm.size() == 1 && farm.threads() > 1 && !args.walks_in_turn;
  if (!args.quiet && farm.is_root()) {
    options.calibration.progress = [](const IterationRecord& r) {
      std::fprintf(stderr, "  calibrate %3d  misfit %.6e  |pg| %.3e\n", r.iteration, r.objective, r.gradient_norm);
    };
    options.progress = [](const std::string& line) { std::fprintf(stderr, "%s\n", line.c_str()); };
    if (farm.threads() == 1)  // refits running side by side would mix their lines
      options.ranking.refit.progress = [](const IterationRecord& r) {
        std::fprintf(stderr, "  refit %3d  misfit %.6e  |pg| %.3e\n", r.iteration, r.objective, r.gradient_norm);
      };
  }
  std::string error;
  if (!options.IsValid(&error)) throw InputError(error);
  return options;
}

/// The same problem on a mesh `--mesh-check` times finer, for the discretization estimate; none
/// (with the reason printed) when the mesh comes from a file or the finer problem does not load.
std::optional<Problem> finer_mesh_problem(const DiagnoseArgs& args, const Problem& problem) {
  if (args.mesh_check > 0 && problem.mesh_refinement > 0) {
    try {
      LoadOptions load;
      load.refinement = problem.mesh_refinement * args.mesh_check;
      load.nearest_sensor_nodes = true;
      return load_problem_with_measurements(args.problem, load);
    } catch (const ProblemError& e) {  // e.g. sensors on a node set, which has more nodes there
      std::printf("no discretization estimate: on a mesh %g times finer the problem does not load: %s\n",
                  args.mesh_check, e.what());
    }
  } else if (args.mesh_check > 0) {
    std::printf("no discretization estimate: the mesh comes from a file, which cannot be refined here\n");
  }
  return std::nullopt;
}

/// The report, the hidden effects' ranks (synthetic data) and every file asked for.
void report_diagnosis(const DiagnoseArgs& args, const Problem& problem, const Diagnosis& d) {
  std::fputs(format_diagnosis(problem, d).c_str(), stdout);
  const std::string hidden = hidden_effect_text(problem);
  if (!hidden.empty()) {
    std::printf("\n%s", hidden.c_str());
    for (const ModelEffect& e : problem.synthetic_truth->hidden_effects) {
      const int rank = rank_of(d.ranking, e.name);
      std::printf("hidden effect %s: %s\n", e.name.c_str(),
                  rank ? ("ranked " + std::to_string(rank)).c_str() : "not among the ranked candidates");
    }
  }
  write_json(args.json, to_json(problem, d), problem);
  if (!args.plot.empty()) {
    plot_steps(args.plot, problem, d, args.significance);
    std::printf("wrote %s\n", args.plot.c_str());
  }
  if (!args.write_problem.empty()) {
    write_file_atomically(args.write_problem, problem_with_effects_yaml(problem, args.write_problem, d),
                          problem.source_files);
    std::printf("wrote %s: the problem with the effects the diagnosis kept, for calibrate\n", args.write_problem.c_str());
  }
  if (!args.map.empty()) {
    plot_screen_map(args.map, problem, d.map);
    std::printf("wrote %s\n", args.map.c_str());
  }
  if (!args.vtu.empty()) {
    const ParametricSystem system(problem.model, problem.parameter_targets());
    VtuFields fields = d.localization ? localization_fields(problem, *d.localization) : VtuFields();
    add_screen_map_fields(d.map, &fields);
    for (const std::string& path : write_vtu_set(args.vtu, "diagnose", problem, system, d.calibration.final, fields))
      std::cout << "wrote " << path << "\n";
  }
}

int run_diagnose(const DiagnoseArgs& args) {
  WorkFarm& farm = WorkFarm::join();  // in an MPI job every rank runs the diagnosis; the refits are shared
  Problem problem = load_problem_with_measurements(args.problem, LoadOptions{args.refine});
  if (!args.vtu.empty()) create_output_directory("--vtu", args.vtu);  // a file there: refused before the run
  require_parameters(problem);
  print_warnings(problem);
  // Refused before the diagnosis runs, not after: no output may replace a file the run reads.
  for (const std::string* out : {&args.json, &args.plot, &args.map, &args.write_problem})
    if (!out->empty()) check_output_path(*out, problem.source_files);
  const Vector start = choose_parameters(&problem, args.start) * args.start_factor;
  require_start_within_bounds(problem, start);
  DiagnosisOptions options = diagnosis_options(args, farm);
  std::printf("%s: %zu parameters, %zu measured modes%s\n", problem.path.c_str(), problem.parameters.size(),
              problem.measured.size(),
              problem.measurement_noise ? "" : "; no stated noise (measured: noise:), so no chi-square test");
  std::fflush(stdout);
  std::vector<EffectCandidate> effects = enabled_candidates(problem, options.candidates);  // --add repeats none
  const size_t enabled = effects.size();
  append_added_effects(problem, args.add, &effects);
  options.added.assign(effects.begin() + static_cast<std::ptrdiff_t>(enabled), effects.end());
  const std::optional<Problem> finer = finer_mesh_problem(args, problem);
  if (finer) options.finer_mesh = &*finer;
  if (farm.size() > 1)
    std::printf("the refits across %d MPI ranks, rank 0 handing them out\n", farm.size());
  else if (farm.threads() > 1)
    std::printf("the refits up to %d at a time, in threads\n", farm.threads());
  const Diagnosis d = [&] {
    const OneBlasThreadWhile side_by_side(options.walk_side_by_side);  // no map may change it meanwhile
    return diagnose(problem, start, options);
  }();
  if (farm.is_root()) report_diagnosis(args, problem, d);  // rank 0 reports
  return 0;
}

/// --significance and --resolution: when the data ask for an effect.
void add_test_flags(CLI::App* cmd, DiagnoseArgs* args) {
  cmd->add_option("--significance", args->significance,
                  "level of the residual and likelihood-ratio tests (default 0.01)")
      ->check(finite_number())
      ->check(FiniteRange(1e-12, 0.5));
  cmd->add_option("--resolution", args->resolution,
                  "without a stated noise: frequencies within this relative error and MACs within it of 1 count "
                  "as met (default 1e-4); no effect is looked for below it")
      ->check(finite_number())
      ->check(FiniteRange(1e-12, 0.01));
}

/// Adds the option `flag` into `*target`, whose value now is the default, with the help
/// `what (default VALUE; note)`.
template <typename T>
CLI::Option* add_with_default(CLI::App* cmd, const std::string& flag, T* target, const std::string& what,
                              const std::string& note) {
  return cmd->add_option(flag, *target, what + " (default " + detail::option_text(*target) + "; " + note + ")");
}

/// The flags that widen, leave out or reorder parts of the loop's walk.
void add_walk_flags(CLI::App* cmd, DiagnoseArgs* args) {
  cmd->add_flag("--walks-in-turn", args->walks_in_turn,
                "with --jobs above 1, walk the diagnosis's paths one after the other all the same, only the "
                "refits in threads: slower, and less peak memory (LFU 0.7: 0.7 GB against 1.0)");
  add_with_default(cmd, "--first-step-alternatives", &args->first_step_alternatives,
                   "when the loop ends above the noise, walk it again from this many of the first "
                   "step's next-best effects and keep the path that ends lowest",
                   "0: the greedy path only")
      ->check(non_negative_number());
  cmd->add_flag("--alternatives-after-consistent-end", args->alternatives_after_consistent_end,
                "walk those next-best effects also when the first path took two or more steps and ends "
                "consistent with the noise: now and then a better answer with several effects, in about twice "
                "the time");
  add_with_default(cmd, "--pair-exchanges", &args->pair_exchanges,
                   "when the loop ends above the noise, try two effects for each accepted one: this "
                   "many of the best in its place, each followed by the best step from there",
                   "0: none")
      ->check(FiniteRange(0, 100));
  add_with_default(cmd, "--other-data-margin", &args->other_data_margin,
                   "when the mesh check is significant, the data whose forward steps end higher finish their "
                   "first path (exchange, backward pass) only within this many critical values of the others'",
                   "1e9: always")
      ->check(FiniteRange(0.0, 1e9));
  cmd->add_flag("--no-exchange", args->no_exchange,
                "keep each forward step's effect (no exchange pass re-screening it with the others in the model)");
  cmd->add_flag("--no-backward", args->no_backward,
                "keep every accepted effect (no backward pass dropping those the others explain)");
}

}  // namespace

void register_diagnose_command(CLI::App& app, int* exit_code) {
  auto args = std::make_shared<DiagnoseArgs>();
  CLI::App* cmd = app.add_subcommand(
      "diagnose",
      "Model-form diagnosis: calibrate, test the residual, localize, rank candidate effects, refit the best");
  cmd->add_option("problem", args->problem, "problem file (YAML)")->required()->check(CLI::ExistingFile);
  cmd->add_option("--params", args->start.source, "start from: initial (default), truth, or a report JSON");
  cmd->add_option("--set", args->start.assignments, "start value NAME=VALUE (repeatable)");
  cmd->add_option("--start-factor", args->start_factor, "multiply the start values by this factor")
      ->check(positive_number());
  cmd->add_option("--refine", args->refine, "mesh refinement factor (overrides the problem file)")
      ->check(positive_number());
  cmd->add_option("--refits", args->refits, "refit this many of the best-predicted effects (default 3)")
      ->check(non_negative_number());
  add_with_default(cmd, "--weak-refits", &args->weak_refits,
                   "refit this many instead when the best prediction is under two critical values, where many "
                   "places predict alike",
                   "0: --refits always")
      ->check(non_negative_number());
  cmd->add_option("--place-refits", args->place_refits,
                  "then refit this many more, each the best-predicted effect apart from those chosen (default 2)")
      ->check(non_negative_number());
  cmd->add_option("--kind-refits", args->kind_refits,
                  "then refit this many more, each the best of a kind of effect not chosen yet (default 4)")
      ->check(non_negative_number());
  cmd->add_option("--neighbour-refits", args->neighbour_refits,
                  "then refit this many of the best refit's neighbours, the same effect a node or two away "
                  "(default 3), and as many of each kind's best that scores close to it")
      ->check(non_negative_number());
  cmd->add_option("--neighbour-rounds", args->neighbour_rounds,
                  "repeat the neighbour refits from a best that moved, at most this many rounds (default 3)")
      ->check(non_negative_number());
  add_test_flags(cmd, args.get());
  cmd->add_option("--max-iterations", args->max_iterations, "iteration limit of the calibration (default 60)")
      ->check(non_negative_number());
  cmd->add_option("--max-steps", args->max_steps,
                  "accept at most this many effects, one per step (default 4; 0: screen and refit only)")
      ->check(non_negative_number());
  cmd->add_option("--mesh-check", args->mesh_check,
                  "estimate the discretization error on a generated mesh this many times finer (default 1.5; 0: "
                  "no estimate)")
      ->check(FiniteRange(0.0, 4.0));
  add_with_default(cmd, "--calibration-starts", &args->calibration_starts,
                   "when the first calibration leaves more than the noise, calibrate again from this "
                   "many starts spread over the parameters' bounds and keep the lowest: a local minimum "
                   "looks like a model-form error",
                   "0: the given start only")
      ->check(FiniteRange(0, 1000));
  add_walk_flags(cmd, args.get());
  cmd->add_option("--add", args->add,
                  "start from the model with this effect, e.g. joint2.kry or point_mass@top:mass (repeatable)");
  cmd->add_option("--json", args->json, "write the diagnosis as JSON to this file")->check(OutputFile());
  cmd->add_option("--plot", args->plot,
                  "plot the chi-square per step against the noise band, and each mode's frequency error before "
                  "and after (.png or .svg)")->check(PlotFile());
  cmd->add_option("--write-problem", args->write_problem,
                  "write the problem with the kept effects enabled and the final values as starts (YAML), for "
                  "calibrate")->check(OutputFile());
  cmd->add_option("--vtu", args->vtu,
                  "write the screen map and the localization (diagnose.vtu, diagnose_sensors.vtu, .pvd) to this "
                  "directory");
  cmd->add_option("--map", args->map,
                  "draw the screen map (.png or .svg): where an added mass, spring or region scale would remove "
                  "the most chi-square")->check(PlotFile());
  cmd->add_option("--region-size", args->region_size,
                  "size of the block regions screened, in element sizes (default 3)")
      ->check(finite_number())
      ->check(FiniteRange(1.0, 1000.0));
  cmd->add_option("--region-levels", args->region_levels,
                  "grids of block regions screened, each twice as coarse as the one before (default 3)")
      ->check(CLI::Range(1, 6));
  cmd->add_option("--jobs", args->jobs,
                  "refits run at a time, each in a thread (default: one per core; 1: one after another); with more "
                  "than one, the diagnosis's paths that do not depend on one another also walk side by side "
                  "(--walks-in-turn: not). The results do not depend on it. In an MPI job the ranks share the "
                  "refits instead")
      ->check(CLI::Range(1, 1024));
  cmd->add_flag("--quiet", args->quiet, "no progress lines");
  cmd->callback([args, exit_code] { *exit_code = run_diagnose(*args); });
}

}  // namespace modalcal::cli
