// `fullspace_calib localize PROBLEM`: where the model fails. Expands the measured shapes, ranks
// the model's regions by the energy of the residual forces, and writes VTU files for ParaView.

#include <CLI/CLI.hpp>

#include <iostream>

#include "cli/cli_common.hpp"
#include "cli/cli_validators.hpp"
#include "cli/commands.hpp"
#include "modalcal/localization.hpp"
#include "modalcal/vtu.hpp"
#include "modalcal/problem_file.hpp"

namespace modalcal::cli {

namespace {

struct LocalizeArgs {
  std::string problem;
  ParameterChoice params;
  std::string json, vtu;
  double refine = 0;
  LocalizationOptions options;
  int rows = 15;
};

nlohmann::json to_json(const Problem& problem, const Vector& p, const Localization& result,
                       const std::string& source) {
  nlohmann::json json;
  json["problem"] = problem.path;
  json["parameter_source"] = source;
  json["parameters"] = nlohmann::json::array();
  for (size_t j = 0; j < problem.parameters.size(); ++j)
    json["parameters"].push_back({{"name", problem.parameters[j].name}, {"value", p[j]}});
  json["basis_size"] = result.basis_size;
  json["basis_condition"] = result.basis_condition;
  json["total_energy"] = result.total_energy;
  json["modes"] = nlohmann::json::array();
  for (const ExpandedMode& m : result.modes)
    json["modes"].push_back({{"measured", m.measured + 1},
                             {"label", problem.measured[m.measured].label},
                             {"measured_hz", m.measured_hz},
                             {"model_mode", m.model_mode + 1},
                             {"model_hz", m.model_hz},
                             {"mac", m.mac},
                             {"scale_factor", m.scale_factor},
                             {"sensor_misfit", m.sensor_misfit},
                             {"energy", m.energy}});
  json["ranking"] = nlohmann::json::array();
  for (size_t r = 0; r < result.ranking.size(); ++r)
    json["ranking"].push_back({{"rank", r + 1},
                               {"region", result.ranking[r].name},
                               {"kind", result.ranking[r].kind},
                               {"share", result.ranking[r].share},
                               {"energy", result.ranking[r].energy}});
  json["warnings"] = result.warnings;
  return json;
}

int run_localize(const LocalizeArgs& args) {
  Problem problem = load_problem_with_measurements(args.problem, LoadOptions{args.refine});
  if (!args.vtu.empty()) create_output_directory("--vtu", args.vtu);  // a file there: refused before the run
  const Vector p = choose_parameters(&problem, args.params);
  std::string error;
  if (!args.options.IsValid(&error)) throw InputError(error);
  const Localization result = localize_model_error(problem, p, args.options);
  for (const std::string& warning : result.warnings) std::cerr << "warning: " << warning << "\n";
  if (!result.ok) {
    std::cerr << "error: localization failed: " << result.message << "\n";
    return 1;
  }
  std::cout << problem.path << ": parameters = " << args.params.source << "\n" << format_ranking(result, args.rows);
  write_json(args.json, to_json(problem, p, result, args.params.source), problem);
  if (!args.vtu.empty()) {
    const ParametricSystem system(problem.model, problem.parameter_targets());
    for (const std::string& path : write_vtu_set(args.vtu, "localize", problem, system, p, localization_fields(problem, result)))
      std::cout << "wrote " << path << "\n";
  }
  return 0;
}

}  // namespace

void register_localize_command(CLI::App& app, int* exit_code) {
  auto args = std::make_shared<LocalizeArgs>();
  CLI::App* cmd = app.add_subcommand(
      "localize", "Where the model fails: rank regions by the residual forces of the expanded measured shapes");
  cmd->add_option("problem", args->problem, "problem file (YAML) with measured shapes")->required()->check(CLI::ExistingFile);
  cmd->add_option("--params", args->params.source, "parameter values: initial, truth, or a calibration report JSON");
  cmd->add_option("--set", args->params.assignments, "NAME=VALUE for a parameter or a model property (repeatable)");
  cmd->add_option("--refine", args->refine, "mesh refinement factor (overrides the problem file)")
      ->check(positive_number());
  cmd->add_option("--basis-modes", args->options.basis_modes,
                  "elastic model modes in the expansion basis (0: as many as the sensors allow, at most 40)");
  cmd->add_option("--regularization", args->options.regularization,
                  "Tikhonov weight of the expansion, relative to the largest singular value (0: SEREP)")
      ->check(finite_number());
  cmd->add_option("--rows", args->rows, "regions to print")->check(positive_number());
  cmd->add_option("--json", args->json, "write the expansion and the ranking as JSON to this file")
      ->check(OutputFile());
  cmd->add_option("--vtu", args->vtu, "write localize.vtu, localize_sensors.vtu and localize.pvd to this directory");
  cmd->callback([args, exit_code] { *exit_code = run_localize(*args); });
}

}  // namespace modalcal::cli
