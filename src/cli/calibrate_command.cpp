// `fullspace_calib calibrate PROBLEM`: calibration with a report in the style of the report's
// Tables 1-4 (parameters: initial, computed, true, bounds) and Table 7 (measured vs predicted).

#include <CLI/CLI.hpp>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <optional>
#include <iostream>

#include "cli/calibration_report.hpp"
#include "cli/cli_common.hpp"
#include "cli/cli_validators.hpp"
#include "cli/commands.hpp"
#include "modalcal/diagnosis.hpp"
#include "modalcal/effects.hpp"
#include "modalcal/fullspace.hpp"
#include "modalcal/output.hpp"
#include "cli/plot.hpp"
#include "modalcal/reduced.hpp"
#include "modalcal/residual_test.hpp"
#include "modalcal/vtu.hpp"
#include "modalcal/problem_file.hpp"

namespace modalcal::cli {

namespace {

struct CalibrateArgs {
  std::string problem;
  std::string method = "fullspace";
  std::string scaling;
  bool no_bounds = false;
  std::string json;
  std::string vtu;
  std::string csv;           // prefix of the CSV tables
  std::string history_plot;  // .png or .svg
  double refine = 0;
  int max_iterations = 100;
  double start_factor = 1;
  int starts = 0;  // further starts spread over the bounds (--starts)
  ParameterChoice start;  // --params / --set: where to start
  double regularization = 0;
  bool quiet = false;
  // Full-space tuning, for studies of what each safeguard buys.
  int globalization = FullSpaceOptions().globalization_iterations;
  bool no_guard = false;
  std::string globalization_misfit =
      FullSpaceOptions().globalization_misfit == ObjectiveOptions::EigenvalueMisfit::Relative ? "relative" : "log";
  bool no_eigenvalues_first = false;
  bool no_crossing_escape = false;
  std::string newton_solver = to_string(FullSpaceOptions().newton_solver);
  std::string kkt_solver = to_string(FullSpaceOptions().kkt_solver);
  std::string bordered_solves = "auto";
  double mu_init = FullSpaceOptions().mu_init;
  bool limited_memory = false;
  int print_level = 0;
  std::vector<std::string> add;  // effects to add (change texts or candidate names)
  std::string uncertainty = "profile";  // profile, laplace or none
  std::string uncertainty_plot;         // .png or .svg: the correlation matrix (and the profiles beside)
};

/// `path` with `suffix` before its extension: out/u.png -> out/u_profiles.png.
std::string with_suffix(const std::string& path, const std::string& suffix) {
  const std::filesystem::path p(path);
  return (p.parent_path() / (p.stem().string() + suffix + p.extension().string())).string();
}

/// The correlation matrix as a heat map at `path`, and the profiles (the chi-square's rise against
/// the value relative to the fit, with the interval's threshold) beside it as PATH_profiles.EXT.
void plot_uncertainty(const std::string& path, const Uncertainty& u) {
  HeatMap map;
  for (const ParameterUncertainty& pu : u.parameters) {
    map.row_labels.push_back(pu.name);
    map.column_labels.push_back(pu.name);
  }
  map.values = u.correlation;
  map.min = -1;
  map.max = 1;
  map.value_title = "correlation";
  plot_heat_map(path, "correlation of the calibrated parameters", map);
  std::printf("wrote %s\n", path.c_str());
  std::vector<PlotPanel> panels;
  const double threshold = chi_square_critical_value(1 - u.confidence, 1);
  for (const ParameterUncertainty& pu : u.parameters) {
    if (pu.profile_points.size() < 2) continue;
    PlotPanel panel;
    panel.ylabel = "rise of the chi-square";
    panel.log_y = false;
    PlotSeries curve{pu.name, {}, {}}, level{"interval threshold", {}, {}};
    for (const auto& [value, rise] : pu.profile_points) {
      curve.x.push_back(value / pu.value);
      curve.y.push_back(rise);
    }
    level.x = {curve.x.front(), curve.x.back()};
    level.y = {threshold, threshold};
    panel.series = {curve, level};
    panels.push_back(panel);
  }
  if (panels.empty()) return;
  const std::string profiles = with_suffix(path, "_profiles");
  plot_panels(profiles, "profiles of the parameters the data hardly see", "value / calibrated value", panels);
  std::printf("wrote %s\n", profiles.c_str());
}

Scaling parse_scaling(const std::string& name) {
  if (name == "none") return Scaling::None;
  if (name == "linear") return Scaling::Linear;
  if (name == "log") return Scaling::Log;
  throw InputError("--scaling " + name + ": expected none, linear or log");
}

void print_iteration(const IterationRecord& r) {
  std::fprintf(stderr, "  iter %3d  J = %.6e  |pg| = %.3e  solves %d%s\n", r.iteration, r.objective, r.gradient_norm,
               r.forward_solves,
               std::isnan(r.parameter_error) ? "" : ("  param err " + std::to_string(r.parameter_error)).c_str());
}

void print_kkt(const KktRecord& r) {
  char guard[32] = "guard skipped";  // FullSpaceOptions::guard_step
  if (!std::isnan(r.min_mac)) std::snprintf(guard, sizeof guard, "guard MAC %.4f", r.min_mac);
  std::fprintf(stderr, "  newton %3d  J = %.6e  inf_pr %.2e  inf_du %.2e  compl %.2e  alpha %.2g  shift %.1e  %s%s\n",
               r.iteration, r.objective, r.primal_infeasibility, r.dual_infeasibility, r.complementarity, r.step_length,
               r.hessian_shift, guard,
               std::isnan(r.parameter_error) ? "" : ("  param err " + std::to_string(r.parameter_error)).c_str());
}

/// One calibration of `objective` from p0 by the chosen method: its report and whether it has a
/// usable result.
struct Calibrated {
  CalibrationReport report;
  Vector final;
  bool usable = false;
};

/// `chi_square`: the objective is noise-weighted, so the diagnosis' tolerances apply (its values
/// are of the order of the number of data, and 1e-10 on the gradient would mean rounding).
Calibrated calibrate(Objective& objective, const Vector& p0, const CalibrateArgs& args, bool chi_square = false) {
  const Problem& problem = objective.problem();
  const std::optional<Scaling> scaling =
      args.scaling.empty() ? std::nullopt : std::optional<Scaling>(parse_scaling(args.scaling));
  std::printf("%s: %d parameters, %zu measured modes, %d DOFs, method %s\n", problem.path.c_str(),
              objective.num_parameters(), problem.measured.size(), objective.system().num_dofs(), args.method.c_str());
  CalibrationReport report;
  Vector final;
  bool usable = false;
  if (args.method == "fullspace") {
    if (args.no_bounds) throw InputError("--no-bounds: the full-space method always uses the parameters' bounds");
    FullSpaceOptions options;
    options.max_iterations = args.max_iterations;
    options.scaling = scaling;
    options.globalization_iterations = args.globalization;
    options.mode_guard = !args.no_guard;
    options.globalization_misfit = args.globalization_misfit == "relative"
                                       ? ObjectiveOptions::EigenvalueMisfit::Relative
                                       : ObjectiveOptions::EigenvalueMisfit::Logarithmic;
    if (args.no_eigenvalues_first) options.eigenvalues_first = false;
    if (args.no_crossing_escape) options.max_crossing_escapes = 0;
    options.newton_solver = args.newton_solver == "block" ? FullSpaceOptions::NewtonSolver::BlockElimination
                                                          : FullSpaceOptions::NewtonSolver::Ipopt;
    options.kkt_solver = args.kkt_solver == "mumps" ? FullSpaceOptions::KktSolver::Mumps
                                                     : FullSpaceOptions::KktSolver::Structured;
    options.bordered_solves = args.bordered_solves == "shared"     ? FullSpaceOptions::BorderedSolves::Shared
                              : args.bordered_solves == "per-mode" ? FullSpaceOptions::BorderedSolves::PerMode
                                                                   : FullSpaceOptions::BorderedSolves::Automatic;
    options.mu_init = args.mu_init;
    options.print_level = args.print_level;
    if (args.limited_memory) options.hessian = FullSpaceOptions::Hessian::LimitedMemory;
    std::string invalid;  // combinations of flags the options refuse (e.g. --limited-memory with block)
    if (!options.IsValid(&invalid)) throw InputError("the full-space flags give invalid options: " + invalid);
    if (!args.quiet) options.progress = print_kkt;
    std::fflush(stdout);
    const FullSpaceSummary summary = minimize_fullspace(objective, p0, options);
    std::printf("%s\n%s\n", summary.BriefReport().c_str(), summary.message.c_str());
    for (const CrossingEscape& escape : summary.crossing_escapes)
      std::printf("crossing escape: %s\n", escape.ToString().c_str());
    std::printf("\n");
    report = make_report(objective, summary.initial, summary.final);
    report.summary = summary_json(problem, summary);
    usable = summary.converged();
    final = summary.final;
  } else {
    ReducedOptions options = chi_square ? DiagnosisOptions::default_calibration_options() : ReducedOptions();
    options.method = parse_method(args.method);
    options.max_iterations = args.max_iterations;
    options.use_bounds = !args.no_bounds;
    options.scaling = scaling;
    if (!args.quiet) options.progress = print_iteration;
    const ReducedSummary summary = minimize_reduced(objective, p0, options);
    std::printf("%s\n%s\n\n", summary.BriefReport().c_str(), summary.message.c_str());
    report = make_report(objective, summary.initial, summary.final);
    report.summary = summary_json(problem, summary);
    // L-BFGS often ends on its line search at the rounding floor with a perfect fit: any end
    // with a final iterate is a result; the status in the report says how it ended.
    usable = summary.status != ReducedStatus::ForwardSolveFailed && summary.final.size() > 0;
    final = summary.final;
  }
  report.settings = {{"scaling", args.scaling.empty() ? "problem file" : args.scaling},
                     {"bounds", !args.no_bounds},
                     {"start_factor", args.start_factor},
                     {"regularization", args.regularization}};
  return {report, final, usable};
}

/// The calibration from p0 (calibrate()), and with --starts N from N further starts spread over
/// the parameters' bounds (spread_start()), quietly: the run with the lowest misfit is kept. A
/// line per start says where it began and ended; the JSON summary gets `start` (the kept run's:
/// 0 for p0) and `starts` [{start, misfit, usable}].
Calibrated calibrate_from_starts(Objective& objective, const Vector& p0, const CalibrateArgs& args,
                                 bool chi_square = false) {
  Calibrated best = calibrate(objective, p0, args, chi_square);
  if (args.starts == 0) return best;
  auto misfit = [&](const Calibrated& c) {
    const Evaluation e = c.usable ? objective.evaluate(c.final, Need::Value) : Evaluation();
    return e.ok ? e.value : INFINITY;
  };
  double lowest = misfit(best);
  int kept = 0;
  nlohmann::json starts = nlohmann::json::array();
  starts.push_back({{"start", 0}, {"misfit", json_number(lowest)}, {"usable", best.usable}});
  CalibrateArgs quiet = args;
  quiet.quiet = true;
  for (int k = 1; k <= args.starts; ++k) {
    std::printf("--- further start %d of %d, spread over the parameters' bounds\n", k, args.starts);
    Calibrated from_k = calibrate(objective, spread_start(objective.problem().parameters, k), quiet, chi_square);
    const double value = misfit(from_k);
    starts.push_back({{"start", k}, {"misfit", json_number(value)}, {"usable", from_k.usable}});
    if (!(value < lowest * (1 - 1e-9))) continue;
    best = std::move(from_k);
    lowest = value;
    kept = k;
  }
  std::printf("--- kept the calibration from %s (misfit %.6g; %d further starts)\n\n",
              kept == 0 ? std::string("the given start").c_str() : ("further start " + std::to_string(kept)).c_str(),
              lowest, args.starts);
  best.report.summary["start"] = kept;
  best.report.summary["starts"] = starts;
  return best;
}

/// The report's files other than the VTU set: JSON, CSV tables, convergence plot.
void write_outputs(const CalibrateArgs& args, const nlohmann::json& report, const Problem& problem) {
  write_json(args.json, report, problem);
  if (!args.csv.empty())
    for (const std::string& path : write_csv_report(args.csv, report, problem)) std::printf("wrote %s\n", path.c_str());
  if (!args.history_plot.empty()) {
    plot_history(args.history_plot, report, problem);
    std::printf("wrote %s\n", args.history_plot.c_str());
  }
}

/// Calibrates without the effects, then with them (started from the first calibration and the
/// effects' first-order values), and reports both side by side. With a stated noise both fits
/// minimize the chi-square (noise_weighted), as diagnose does.
int calibrate_with_effects(const Problem& problem, const Vector& p0, const std::vector<EffectCandidate>& effects,
                           const CalibrateArgs& args, const ObjectiveOptions& objective_options) {
  const bool noise = problem.measurement_noise && problem.measurement_noise->frequency > 0;
  const Problem fitted = noise ? noise_weighted(problem, *problem.measurement_noise) : problem;
  if (noise) std::printf("fits weighted by the stated noise (chi-square)\n");
  std::printf("--- without the added effects\n");
  Objective objective(fitted, objective_options);
  const Calibrated before = calibrate_from_starts(objective, p0, args, noise);
  std::fputs(before.report.text.c_str(), stdout);
  if (!before.usable) {
    std::fprintf(stderr, "error: the calibration without the effects has no usable result\n");
    return 1;
  }
  // Start values: declared, else the first-order estimate at the first calibration.
  RankingOptions screen;
  screen.refits = 0;
  screen.objective = objective_options;
  const EffectRanking first_order = rank_effects(fitted, before.final, effects, screen);
  std::vector<double> starts;
  for (const EffectCandidate& c : effects) {
    double start = c.variable == EffectCandidate::Variable::Compliance ? c.upper : c.screen_value;
    for (const RankedEffect& r : first_order.effects)
      if (r.candidate.name == c.name && r.predicted_reduction > 0) start = r.predicted_value;
    starts.push_back(std::clamp(c.initial.value_or(start), c.lower, c.upper));
  }
  const Problem with = problem_with_effects(fitted, effects, starts);
  Vector p1(with.parameters.size());
  p1 << before.final, Eigen::Map<const Vector>(starts.data(), static_cast<Eigen::Index>(starts.size()));
  std::printf("\n--- with");
  for (size_t k = 0; k < effects.size(); ++k)
    std::printf(" %s (%s, from %.4g)", effects[k].name.c_str(), effects[k].description.c_str(), starts[k]);
  std::printf("\n");
  Objective with_objective(with, objective_options);
  Calibrated after = calibrate(with_objective, p1, args, noise);
  std::fputs(after.report.text.c_str(), stdout);
  if (!after.usable) {
    std::fprintf(stderr, "error: the calibration with the effects has no usable result\n");
    return 1;
  }
  const FitState fit_before = evaluate_fit(fitted, before.final), fit_after = evaluate_fit(with, after.final);
  std::printf("\n--- before and after adding the effects\n%s",
              format_before_after(with, fit_before, fit_after, "without", "with").c_str());
  nlohmann::json json = after.report.json();
  for (auto& entry : json["parameters"])
    for (const EffectCandidate& c : effects)
      if (entry["name"] == c.name) entry["effect"] = true;
  json["effects"] = nlohmann::json::array();
  for (size_t k = 0; k < effects.size(); ++k)
    json["effects"].push_back({{"name", effects[k].name},
                               {"description", effects[k].description},
                               {"start", starts[k]},
                               {"value", after.final[p0.size() + k]}});
  json["before"] = before.report.json();
  auto residual = [](const FitState& fit) {
    nlohmann::json r = {{"statistic", fit.statistic}};
    if (fit.test)
      r.update({{"dof", fit.test->dof}, {"p_value", json_number(fit.test->p_value)}, {"model_form_error", fit.test->model_form_error},
                {"verdict", fit.test->verdict}});
    return r;
  };
  json["residual_before"] = residual(fit_before);
  json["residual_after"] = residual(fit_after);
  write_outputs(args, json, problem);
  return 0;
}

int run_calibrate(const CalibrateArgs& args) {
  Problem problem = load_problem_with_measurements(args.problem, LoadOptions{args.refine});
  if (!args.vtu.empty()) create_output_directory("--vtu", args.vtu);  // a file there: refused before the run
  if (!args.uncertainty_plot.empty()) {  // refused before the run, like --vtu
    if (const std::string problem_with_name = plot_name_problem(args.uncertainty_plot); !problem_with_name.empty())
      throw InputError("--uncertainty-plot " + args.uncertainty_plot + ": " + problem_with_name);
    check_output_path(args.uncertainty_plot, problem.source_files);
    check_output_path(with_suffix(args.uncertainty_plot, "_profiles"), problem.source_files);
  }
  // Refused before the run, not after: a bad output name costs no computation.
  for (const std::string* out : {&args.json, &args.history_plot})
    if (!out->empty()) check_output_path(*out, problem.source_files);
  if (!args.csv.empty()) check_output_path(args.csv + "_parameters.csv", problem.source_files);
  // The files an option's name only begins (--csv PREFIX, the profiles beside --uncertainty-plot) too.
  std::vector<std::pair<std::string, std::string>> outputs = {
      {"--json", args.json}, {"--history-plot", args.history_plot}, {"--uncertainty-plot", args.uncertainty_plot}};
  if (!args.uncertainty_plot.empty())
    outputs.emplace_back("--uncertainty-plot", with_suffix(args.uncertainty_plot, "_profiles"));
  if (!args.csv.empty())
    for (const char* table : {"_parameters.csv", "_modes.csv", "_history.csv"}) outputs.emplace_back("--csv", args.csv + table);
  check_outputs_apart(outputs);
  require_parameters(problem);
  print_warnings(problem);
  ObjectiveOptions objective_options;
  objective_options.regularization = args.regularization;
  const Vector p0 = choose_parameters(&problem, args.start) * args.start_factor;
  if (!args.no_bounds) require_start_within_bounds(problem, p0);
  std::vector<EffectCandidate> effects = enabled_candidates(problem);
  append_added_effects(problem, args.add, &effects);
  if (!effects.empty()) return calibrate_with_effects(problem, p0, effects, args, objective_options);
  Objective objective(problem, objective_options);
  Calibrated result = calibrate_from_starts(objective, p0, args);
  if (result.usable && args.uncertainty != "none") {
    UncertaintyOptions options;
    options.profiles = args.uncertainty == "profile";
    std::optional<Uncertainty> u;
    try {
      u = estimate_uncertainty(problem, result.final, options);
      add_uncertainty(*u, &result.report);
    } catch (const std::runtime_error& e) {
      result.report.text += std::string("\nno parameter uncertainty: ") + e.what() + "\n";
    }
    if (u && !args.uncertainty_plot.empty()) plot_uncertainty(args.uncertainty_plot, *u);
  }
  std::fputs(result.report.text.c_str(), stdout);
  write_outputs(args, result.report.json(), problem);
  if (!args.vtu.empty() && result.usable) {
    // The calibrated model for ParaView: blocks with their calibrated properties, the computed
    // modes at the final parameters, and the measured shapes at the sensors.
    const Evaluation at_final = objective.evaluate(result.final, Need::Value);
    if (!at_final.ok) throw std::runtime_error("--vtu: forward solve at the final parameters failed: " + at_final.message);
    VtuFields fields;
    add_mode_fields(at_final.modal, -1, &fields);
    for (const std::string& path :
         write_vtu_set(args.vtu, "calibrated", problem, objective.system(), result.final, fields))
      std::printf("wrote %s\n", path.c_str());
  }
  return result.usable ? 0 : 1;
}

}  // namespace

/// The full space's tuning flags, for studies of what each safeguard buys.
void add_fullspace_flags(CLI::App* cmd, CalibrateArgs* args) {
  cmd->add_option("--globalization", args->globalization,
                  "fullspace: reduced L-BFGS iterations before the Newton phase, at most (default 50; 0: none)")
      ->check(non_negative_number());
  cmd->add_option("--globalization-misfit", args->globalization_misfit,
                  "fullspace: eigenvalue misfit of the globalization, log (default: ln(lambda/lambda_m), no "
                  "stationary points where the model is far too soft) or relative (the objective's own)")
      ->check(CLI::IsMember({"log", "relative"}));
  cmd->add_flag("--no-eigenvalues-first", args->no_eigenvalues_first,
                "fullspace: globalize on the whole objective from the start (default: on the eigenvalue terms "
                "alone first, the shapes still pairing the modes)");
  cmd->add_option("--newton-solver", args->newton_solver,
                  "fullspace: the Newton method: ipopt (interior point, Ipopt's filter line search) or block (SQP "
                  "with an active set on the bounds)")
      ->check(CLI::IsMember({"ipopt", "block"}))
      ->default_str(args->newton_solver);
  cmd->add_option("--kkt-solver", args->kkt_solver,
                  "fullspace, ipopt: who factors Ipopt's KKT matrices: structured (one factorization per mode and a "
                  "Schur complement on the parameters) or mumps (MUMPS on the whole matrix; slow beyond a few "
                  "thousand DOFs)")
      ->check(CLI::IsMember({"structured", "mumps"}))
      ->default_str(args->kkt_solver);
  cmd->add_option("--bordered-solves", args->bordered_solves,
                  "fullspace, structured: each mode's bordered block by its own factorization (per-mode) or by "
                  "deflated CG on one shared factorization of K - sigma M (shared; less memory and time on large "
                  "models); auto: shared from " +
                      std::to_string(FullSpaceOptions().shared_factorization_min_dofs) + " DOFs on")
      ->check(CLI::IsMember({"auto", "per-mode", "shared"}))
      ->default_str(args->bordered_solves);
  cmd->add_flag("--no-guard", args->no_guard, "fullspace: no forward-solve mode check at every iteration");
  cmd->add_flag("--no-crossing-escape", args->no_crossing_escape,
                "fullspace: accept a minimum where two measured modes pair with model modes in crossed order (default: "
                "globalize again from there on the eigenvalues in frequency order and keep the lower minimum)");
  cmd->add_option("--mu-init", args->mu_init, "fullspace: Ipopt's initial barrier parameter")->check(positive_number());
  cmd->add_flag("--limited-memory", args->limited_memory, "fullspace: Ipopt's L-BFGS Hessian instead of the exact one");
  cmd->add_option("--ipopt-print-level", args->print_level, "fullspace: Ipopt's own output (0-12, default 0)")
      ->check(CLI::Range(0, 12));
}

void register_calibrate_command(CLI::App& app, int* exit_code) {
  auto args = std::make_shared<CalibrateArgs>();
  CLI::App* cmd = app.add_subcommand("calibrate", "Calibrate the parameters against the measured modes");
  cmd->add_option("problem", args->problem, "problem file (YAML)")->required()->check(CLI::ExistingFile);
  cmd->add_option("--method", args->method, "fullspace (default), reduced-lbfgs, reduced-gauss-newton or reduced-newton")
      ->check(CLI::IsMember(calibration_method_names()));
  cmd->add_option("--scaling", args->scaling, "none, linear or log for every parameter (default: the problem file's)")
      ->check(CLI::IsMember({"none", "linear", "log"}));
  cmd->add_flag("--no-bounds", args->no_bounds, "ignore the parameters' bounds");
  cmd->add_option("--json", args->json, "write the report as JSON to this file")->check(OutputFile());
  cmd->add_option("--csv", args->csv,
                  "write the tables as CSV: PREFIX_parameters.csv, PREFIX_modes.csv and PREFIX_history.csv");
  cmd->add_option("--history-plot", args->history_plot,
                  "plot objective and gradient norm against iteration to this .png or .svg file")
      ->check(PlotFile());
  cmd->add_option("--vtu", args->vtu,
                  "write the calibrated model for ParaView to this directory: calibrated.vtu (blocks, calibrated "
                  "properties, mode shapes), calibrated_sensors.vtu (measured shapes) and calibrated.pvd");
  cmd->add_option("--refine", args->refine, "mesh refinement factor")->check(positive_number());
  cmd->add_option("--max-iterations", args->max_iterations, "iteration limit (default 100)")->check(non_negative_number());
  cmd->add_option("--params", args->start.source, "start from: initial (default), truth, or a report JSON");
  cmd->add_option("--set", args->start.assignments, "start value NAME=VALUE (repeatable)");
  cmd->add_option("--starts", args->starts,
                  "calibrate again from this many further starts spread over the parameters' bounds and keep the "
                  "lowest misfit: the misfit has local minima (default 0)")
      ->check(FiniteRange(0, 1000));
  cmd->add_option("--start-factor", args->start_factor, "multiply the initial values by this factor")
      ->check(positive_number());
  cmd->add_option("--regularization", args->regularization, "Tikhonov weight toward the initial values (scaled variables)")
      ->check(non_negative_number());
  cmd->add_option("--add", args->add,
                  "calibrate again with this effect added and show before and after: a change without its value "
                  "(joint2.kry, point_mass@top:mass, support@post_bottom:kx), with a start value (joint2.kry=1e5), "
                  "or a candidate's name from diagnose (repeatable)");
  cmd->add_option("--uncertainty", args->uncertainty,
                  "parameter uncertainty at the result: profile (default: standard errors, 95 % intervals and "
                  "correlations, and profile intervals where the data hardly see a parameter), laplace (without "
                  "the profiles) or none")
      ->check(CLI::IsMember({"profile", "laplace", "none"}))
      ->default_str(args->uncertainty);
  cmd->add_option("--uncertainty-plot", args->uncertainty_plot,
                  "plot the parameters' correlation matrix to this .png or .svg file, and their profiles (where "
                  "profiled) beside it as FILE_profiles.png")->check(OutputFile());
  cmd->add_flag("--quiet", args->quiet, "no progress lines");
  add_fullspace_flags(cmd, args.get());
  cmd->callback([args, exit_code] { *exit_code = run_calibrate(*args); });
}

}  // namespace modalcal::cli
