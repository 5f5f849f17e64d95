// `fullspace_calib diagnose PROBLEM`: the model-form diagnosis loop. Calibrates, tests the
// residual against the stated noise, localizes it, ranks candidate effects, refits the best and
// says what to add (diagnosis.hpp).

#include <CLI/CLI.hpp>
#include <cmath>
#include <cstdio>
#include <iostream>

#include "cli/cli_common.hpp"
#include "cli/commands.hpp"
#include "modalcal/diagnosis.hpp"

namespace modalcal::cli {

namespace {

struct DiagnoseArgs {
  std::string problem;
  ParameterChoice start;
  double start_factor = 1;
  double refine = 0;
  int refits = RankingOptions().refits;
  double significance = ResidualTestOptions().significance;
  int max_iterations = DiagnosisOptions().calibration.max_iterations;
  std::string json, vtu;
  bool quiet = false;
};


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
                           {"mac", json_number(pair.mac)}};
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
    json["p_value"] = fit.test->p_value;
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

nlohmann::json to_json(const Problem& problem, const Diagnosis& d) {
  nlohmann::json json;
  json["problem"] = problem.path;
  json["noise"] = nullptr;
  if (d.noise_known)
    json["noise"] = {{"frequency", problem.measurement_noise->frequency}, {"shape", problem.measurement_noise->shape}};
  json["model_form_error"] = d.before.test ? d.before.test->model_form_error : true;
  json["calibration"] = {{"status", to_string(d.calibration.termination)},
                         {"iterations", d.calibration.iterations},
                         {"forward_solves", d.calibration.forward_solves},
                         {"time_s", d.calibration.seconds}};
  // The nominal calibration's values, as calibrate writes them (so that --params takes this file).
  json["parameters"] = nlohmann::json::array();
  for (size_t j = 0; j < problem.parameters.size(); ++j)
    json["parameters"].push_back({{"name", problem.parameters[j].name},
                                  {"initial", d.calibration.initial[j]},
                                  {"final", d.calibration.final[j]}});
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
  json["chi2_before"] = ranking.chi2_before;
  json["num_data"] = ranking.num_data;
  json["candidates_screened"] = ranking.screened;
  json["critical_value"] = ranking.critical_value;
  json["screen_time_s"] = ranking.screen_seconds;
  json["refit_time_s"] = ranking.refit_seconds;
  json["ranking"] = nlohmann::json::array();
  for (size_t k = 0; k < ranking.effects.size(); ++k) {
    const RankedEffect& r = ranking.effects[k];
    json["ranking"].push_back({{"rank", k + 1},
                               {"name", r.candidate.name},
                               {"description", r.candidate.description},
                               {"change", to_string(r.candidate.change)},
                               {"variable", variable_name(r.candidate.variable)},
                               {"predicted_reduction", r.predicted_reduction},
                               {"predicted_value", json_number(r.predicted_value)},
                               {"refitted", r.refitted},
                               {"achieved_reduction", json_number(r.achieved_reduction)},
                               {"value", json_number(r.refitted ? r.value : r.predicted_value)},
                               {"chi2_after", json_number(r.chi2_after)},
                               {"delta_bic", json_number(r.delta_bic)},
                               {"significant", r.significant}});
  }
  json["set_aside"] = nlohmann::json::array();
  for (const auto& [name, why] : ranking.set_aside) json["set_aside"].push_back({{"name", name}, {"reason", why}});
  add_hidden_effect(problem, &json);
  if (problem.synthetic_truth) {
    json["hidden_effect_rank"] = nlohmann::json::array();
    for (const ModelEffect& e : problem.synthetic_truth->hidden_effects)
      json["hidden_effect_rank"].push_back({{"name", e.name}, {"rank", rank_of(ranking, e.name)}});
  }
  return json;
}

int run_diagnose(const DiagnoseArgs& args) {
  Problem problem = load_problem(args.problem, LoadOptions{args.refine});
  require_parameters(problem);
  print_warnings(problem);
  const Vector start = choose_parameters(&problem, args.start) * args.start_factor;
  require_start_within_bounds(problem, start);
  DiagnosisOptions options;
  options.calibration.max_iterations = args.max_iterations;
  options.ranking.refits = args.refits;
  options.ranking.significance = args.significance;
  options.test.significance = args.significance;
  if (!args.quiet) {
    options.calibration.progress = [](const IterationRecord& r) {
      std::fprintf(stderr, "  calibrate %3d  misfit %.6e  |pg| %.3e\n", r.iteration, r.objective, r.gradient_norm);
    };
    options.ranking.refit.progress = [](const IterationRecord& r) {
      std::fprintf(stderr, "  refit %3d  misfit %.6e  |pg| %.3e\n", r.iteration, r.objective, r.gradient_norm);
    };
  }
  std::string error;
  if (!options.IsValid(&error)) throw InputError(error);
  std::printf("%s: %zu parameters, %zu measured modes%s\n", problem.path.c_str(), problem.parameters.size(),
              problem.measured.size(),
              problem.measurement_noise ? "" : "; no stated noise (measured: noise:), so no chi-square test");
  std::fflush(stdout);
  const Diagnosis d = diagnose(problem, start, options);
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
  if (!args.vtu.empty() && d.localization) {
    const ParametricSystem system(problem.model, problem.parameter_targets());
    for (const std::string& path : write_vtu_set(args.vtu, "diagnose", problem, system, d.calibration.final,
                                                 localization_fields(problem, *d.localization)))
      std::cout << "wrote " << path << "\n";
  }
  return 0;
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
  cmd->add_option("--significance", args->significance,
                  "level of the residual and likelihood-ratio tests (default 0.01)")
      ->check(finite_number())
      ->check(CLI::Range(1e-12, 0.5));
  cmd->add_option("--max-iterations", args->max_iterations, "iteration limit of the calibration (default 60)")
      ->check(non_negative_number());
  cmd->add_option("--json", args->json, "write the diagnosis as JSON to this file");
  cmd->add_option("--vtu", args->vtu,
                  "write the localization (diagnose.vtu, diagnose_sensors.vtu, .pvd) to this directory");
  cmd->add_flag("--quiet", args->quiet, "no progress lines");
  cmd->callback([args, exit_code] { *exit_code = run_diagnose(*args); });
}

}  // namespace modalcal::cli
