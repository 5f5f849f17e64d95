// `fullspace_calib modes PROBLEM`: the forward modal solve at chosen parameter values, as a
// table, as JSON and as VTU files for ParaView.

#include <CLI/CLI.hpp>

#include <cstdio>
#include <iostream>

#include "cli/cli_common.hpp"
#include "cli/cli_validators.hpp"
#include "cli/commands.hpp"
#include "modalcal/assembly.hpp"
#include "modalcal/eigen.hpp"
#include "modalcal/mode_description.hpp"
#include "modalcal/vtu.hpp"
#include "modalcal/problem_file.hpp"

namespace modalcal::cli {

namespace {

struct ModesArgs {
  std::string problem;
  ParameterChoice params;
  std::string json, vtu;
  double refine = 0;
  int num_modes = 0;
};

const char* const kDirections[3] = {"x", "y", "z"};

/// The modes as a table: frequency, kinetic energy by direction, part translation, effective mass.
void print_modes(const ModesArgs& args, const Problem& problem, const ParametricSystem& system, const ModalResult& result,
                 const std::vector<ModeDescription>& modes, double seconds_analyze) {
  std::printf("%s: %d DOFs, %d elements, parameters = %s\n", problem.path.c_str(), system.num_dofs(),
              problem.model.num_elements(), args.params.source.c_str());
  if (result.rigid_eigenvalues.size() > 0)
    std::printf("rigid-body modes: %d (|f| < %.2e Hz)\n", static_cast<int>(result.rigid_eigenvalues.size()),
                std::abs(frequency_hz(result.rigid_eigenvalues.cwiseAbs().maxCoeff())) + 1e-300);
  std::printf("%4s %12s  %6s %6s %6s %6s  %6s %6s %6s  %6s %6s %6s  %3s  %-10s %9s\n", "mode", "freq [Hz]",
              "KE x", "KE y", "KE z", "KE rot", "tr x", "tr y", "tr z", "meff x", "meff y", "meff z", "dir", "label",
              "residual");
  for (const ModeDescription& d : modes)
    std::printf("%4d %12.3f  %6.3f %6.3f %6.3f %6.3f  %6.3f %6.3f %6.3f  %6.3f %6.3f %6.3f  %3s  %-10s %9.1e\n",
                d.index, d.frequency_hz, d.energy_fraction[0], d.energy_fraction[1], d.energy_fraction[2],
                d.rotational_fraction, d.part_translation_fraction[0], d.part_translation_fraction[1],
                d.part_translation_fraction[2], d.effective_mass_fraction[0], d.effective_mass_fraction[1],
                d.effective_mass_fraction[2], kDirections[d.dominant_direction], d.label.c_str(),
                result.residuals[d.index - 1]);
  std::printf("solve: %.3f s (analysis %.3f s, factorization %.3f s, %d solves, shift %.4g)\n",
              result.seconds_total + seconds_analyze, seconds_analyze, result.seconds_factorize,
              result.operator_solves, result.shift);

}

nlohmann::json modes_json(const ModesArgs& args, const Problem& problem, const ParametricSystem& system, const Vector& p,
                          const ModalResult& result, const std::vector<ModeDescription>& modes, double seconds_analyze) {
  nlohmann::json json;
  json["problem"] = problem.path;
  json["dofs"] = system.num_dofs();
  json["elements"] = problem.model.num_elements();
  json["parameter_source"] = args.params.source;
  json["parameters"] = nlohmann::json::array();
  for (size_t j = 0; j < problem.parameters.size(); ++j)
    json["parameters"].push_back({{"name", problem.parameters[j].name}, {"value", p[j]}});
  json["rigid_body_modes"] = nlohmann::json::array();
  for (int k = 0; k < result.rigid_eigenvalues.size(); ++k)
    json["rigid_body_modes"].push_back({{"frequency_hz", frequency_hz(result.rigid_eigenvalues[k])}});
  json["modes"] = nlohmann::json::array();
  for (const ModeDescription& d : modes)
    json["modes"].push_back({{"index", d.index},
                             {"frequency_hz", d.frequency_hz},
                             {"dominant_direction", kDirections[d.dominant_direction]},
                             {"label", d.label},
                             {"energy_fraction", d.energy_fraction},
                             {"rotational_fraction", d.rotational_fraction},
                             {"effective_mass_fraction", d.effective_mass_fraction},
                             {"part_translation_fraction", d.part_translation_fraction},
                             {"residual", result.residuals[d.index - 1]}});
  json["solve"] = {{"seconds", result.seconds_total + seconds_analyze},
                   {"seconds_analyze", seconds_analyze},
                   {"factorizations", result.factorizations},
                   {"operator_solves", result.operator_solves},
                   {"shift", result.shift}};
  return json;
}

int run_modes(const ModesArgs& args) {
  Problem problem = load_problem_with_measurements(args.problem, LoadOptions{args.refine});
  if (!args.vtu.empty()) create_output_directory("--vtu", args.vtu);  // a file there: refused before the run
  print_warnings(problem);
  const Vector p = choose_parameters(&problem, args.params);
  ParametricSystem system(problem.model, problem.parameter_targets());
  SparseMatrix K, M;
  system.assemble(p, &K, &M);
  ModalOptions options;
  options.num_modes = args.num_modes > 0 ? args.num_modes : problem.options.num_modes;
  options.max_rigid_modes = problem.expected_rigid_modes();
  options.tolerance = problem.options.tolerance;
  ModalSolver solver(system.pattern(), options);
  if (options.num_modes + options.max_rigid_modes > solver.most_modes())
    throw InputError("--num-modes " + std::to_string(options.num_modes) + ": the model of " + problem.path + " has " +
                     std::to_string(system.num_dofs()) + " free DOFs, of which at most " +
                     std::to_string(solver.most_modes()) + " modes can be found" +
                     (options.max_rigid_modes ? " (up to " + std::to_string(options.max_rigid_modes) +
                                                    " of them rigid-body modes)"
                                              : ""));
  const ModalResult result = solver.solve(K, M);
  if (result.status != EigenStatus::Successful) {
    std::cerr << "error: modal solve failed (" << to_string(result.status)
              << "): " << system.failure_message(p, result.message) << "\n";
    return 1;
  }
  const std::vector<ModeDescription> modes = describe_modes(system, p, M, result);

  print_modes(args, problem, system, result, modes, solver.seconds_analyze());
  write_json(args.json, modes_json(args, problem, system, p, result, modes, solver.seconds_analyze()), problem);
  if (!args.vtu.empty()) {
    VtuFields fields;
    add_mode_fields(result, -1, &fields);
    for (const std::string& path : write_vtu_set(args.vtu, "modes", problem, system, p, fields))
      std::printf("wrote %s\n", path.c_str());
  }
  return 0;
}

}  // namespace

void register_modes_command(CLI::App& app, int* exit_code) {
  auto args = std::make_shared<ModesArgs>();
  CLI::App* cmd = app.add_subcommand("modes", "Forward modal solve: frequencies, directions and labels of the lowest modes");
  cmd->add_option("problem", args->problem, "problem file (YAML)")->required()->check(CLI::ExistingFile);
  cmd->add_option("--params", args->params.source, "parameter values: initial, truth, or a calibration report JSON");
  cmd->add_option("--set", args->params.assignments, "NAME=VALUE for a parameter or a model property (repeatable)");
  cmd->add_option("--json", args->json, "write the results as JSON to this file")->check(OutputFile());
  cmd->add_option("--vtu", args->vtu, "write modes.vtu (mesh, blocks, properties, mode shapes), modes_sensors.vtu and modes.pvd to this directory");
  cmd->add_option("--refine", args->refine, "mesh refinement factor (overrides the problem file)")
      ->check(positive_number());
  cmd->add_option("--num-modes", args->num_modes, "number of elastic modes (overrides the problem file)")->check(positive_number());
  cmd->callback([args, exit_code] { *exit_code = run_modes(*args); });
}

}  // namespace modalcal::cli
