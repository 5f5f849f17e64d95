// `fullspace_calib synth PROBLEM --truth TRUTH ... -o DATA`: measured modes with noise from a
// truth model that may hold physics the nominal model lacks, written as a data file that the
// nominal problem can point at (`measured: {file: DATA}`).

#include <CLI/CLI.hpp>

#include <cstdint>
#include <cstdio>
#include <filesystem>
#include <optional>

#include "cli/cli_common.hpp"
#include "cli/cli_validators.hpp"
#include "cli/commands.hpp"
#include "modalcal/measured_data.hpp"
#include "modalcal/model_change.hpp"
#include "modalcal/synthesis.hpp"
#include "modalcal/problem_file.hpp"

namespace modalcal::cli {

namespace {

struct SynthArgs {
  std::string problem;
  std::vector<std::string> truths;
  double noise_frequency = 0, noise_shape = 0;
  std::string sensors;
  std::vector<int> modes;
  std::uint64_t seed = 1;
  double refine = 0;
  std::string output;
};

/// The truth-model modes to measure: those the nominal problem measures, when it says which.
std::vector<int> modes_of(const Problem& nominal) {
  if (nominal.synthetic) return nominal.synthetic->modes;
  if (nominal.measured.empty())
    throw InputError(nominal.path + " has no measured modes to take the mode numbers from; give --modes 1,2,3");
  std::vector<int> modes;
  for (size_t i = 0; i < nominal.measured.size(); ++i) {
    const MeasuredMode& m = nominal.measured[i];
    if (m.pairing.kind != PairingRule::Kind::ModelIndex)
      throw InputError(nominal.path + ": measured mode " + std::to_string(i + 1) + " ('" + m.label +
                       "') is paired by " + (m.pairing.kind == PairingRule::Kind::Mac ? "MAC" : "family") +
                       ", so which truth-model mode it is is not known; give --modes 1,2,3");
    modes.push_back(m.pairing.model_index);
  }
  return modes;
}

/// Triaxial sensors at every node of a node set.
std::vector<Sensor> sensors_on(const Model& model, const std::string& set_name) {
  const NodeSet* set = model.find_node_set(set_name);
  if (!set) {
    std::string known;
    for (const NodeSet& s : model.node_sets) known += (known.empty() ? "" : ", ") + s.name;
    throw InputError("--sensors " + set_name + ": unknown node set; " +
                     (known.empty() ? std::string("the problem defines none") : "known node sets: " + known));
  }
  std::vector<Sensor> sensors;
  for (int v : set->nodes)
    for (int c = 0; c < 3; ++c)
      sensors.push_back({v, c, "node " + std::to_string(model.node_ids[v]) + " +" + component_name(c)});
  return sensors;
}

int run_synth(const SynthArgs& args) {
  const LoadOptions load{args.refine};
  const Problem nominal = load_problem_with_measurements(args.problem, load);
  // Each --truth is a problem file, a changes file or a change string.
  std::optional<Problem> truth_file;
  std::vector<ModelChange> changes;
  std::vector<std::string> inputs = nominal.source_files;
  for (const std::string& t : args.truths) {
    if (!std::filesystem::is_regular_file(t)) {
      if (t.find('=') == std::string::npos)
        throw InputError("--truth " + t + ": neither a file nor a change (ENTITY.PROPERTY=VALUE or KIND@PLACE:PROPERTY=VALUE)");
      changes.push_back(parse_model_change(t));
      continue;
    }
    inputs.push_back(t);
    if (std::optional<std::vector<ModelChange>> listed = load_model_changes(t)) {
      changes.insert(changes.end(), listed->begin(), listed->end());
    } else {
      if (truth_file) throw InputError("--truth " + t + ": a second truth problem file (" + truth_file->path + " is the first)");
      truth_file = load_problem_with_measurements(t, load);
      inputs.insert(inputs.end(), truth_file->source_files.begin(), truth_file->source_files.end());
    }
  }
  TruthModel truth = make_truth(nominal, truth_file ? &*truth_file : nullptr, changes);
  if (args.refine > 0) {
    // The data are made on the refined mesh, the problems they serve use their own: the truth
    // differs from the nominal model in its discretization too.
    char mesh[200];
    std::snprintf(mesh, sizeof mesh,
                  "mesh: made on the generated mesh with refinement %g (synth --refine), not the nominal problem's "
                  "own mesh",
                  args.refine);
    std::string& other = truth.record.other_differences;
    other += (other.empty() ? "" : "; ") + std::string(mesh);
  }

  SynthesisOptions options;
  options.modes = args.modes.empty() ? modes_of(nominal) : args.modes;
  options.noise.frequency = args.noise_frequency;
  options.noise.shape = args.noise_shape;
  options.noise.seed = args.seed;
  const std::vector<Sensor> sensors = args.sensors.empty() ? nominal.sensors : sensors_on(nominal.model, args.sensors);
  options.shapes = !sensors.empty() && (!args.sensors.empty() || !nominal.synthetic || nominal.synthetic->shapes);
  std::string error;
  if (!options.IsValid(&error)) throw InputError("synth: " + error);
  const MeasuredData data = synthesize_measured_data(nominal, truth, sensors, options);
  write_measured_data(args.output, data, inputs);

  std::printf("%s: %zu modes of the truth model%s, noise: frequency %g, shape %g, seed %llu\n", args.problem.c_str(),
              data.modes.size(),
              options.shapes ? (" at " + std::to_string(sensors.size()) + " sensor DOFs").c_str() : " (frequencies only)",
              options.noise.frequency, options.noise.shape, static_cast<unsigned long long>(options.noise.seed));
  std::fputs(hidden_effect_text(truth.record, "").c_str(), stdout);
  std::printf("\n%-12s %10s %14s %14s %9s\n", "label", "truth mode", "truth [Hz]", "measured [Hz]", "noise %");
  for (size_t i = 0; i < data.modes.size(); ++i)
    std::printf("%-12s %10d %14.4f %14.4f %9.4f\n", data.modes[i].label.c_str(), data.truth_modes[i].mode,
                data.truth_modes[i].frequency_hz, data.modes[i].frequency_hz,
                100 * (data.modes[i].frequency_hz / data.truth_modes[i].frequency_hz - 1));
  std::printf("wrote %s\n", args.output.c_str());
  return 0;
}

}  // namespace

void register_synth_command(CLI::App& app, int* exit_code) {
  auto args = std::make_shared<SynthArgs>();
  CLI::App* cmd = app.add_subcommand(
      "synth", "Synthetic measured modes (with noise) from a truth model that may hold physics the nominal model lacks");
  cmd->add_option("problem", args->problem, "nominal problem file (YAML)")->required()->check(CLI::ExistingFile);
  cmd->add_option("--truth", args->truths,
                  "truth: a problem file, a changes file, or a change such as joint2.krx=3e5 or "
                  "point_mass@top:mass=0.05 (repeatable; default: the nominal model at the parameters' truth values)");
  cmd->add_option("--noise-freq", args->noise_frequency, "relative standard deviation of the frequencies (default 0)")
      ->check(finite_number())
      ->check(FiniteRange(0.0, 0.2));
  cmd->add_option("--noise-shape", args->noise_shape,
                  "standard deviation of each shape value relative to the shape's largest (default 0)")
      ->check(finite_number())
      ->check(FiniteRange(0.0, 1.0));
  cmd->add_option("--sensors", args->sensors, "node set measured in x, y and z (default: the problem's sensors)");
  cmd->add_option("--modes", args->modes, "truth-model modes to measure, e.g. 1,2,3 (default: the problem's)")
      ->delimiter(',')
      ->check(positive_number());
  cmd->add_option("--seed", args->seed, "random seed (default 1); the same seed gives the same data everywhere")
      ->check(SeedText());
  cmd->add_option("--refine", args->refine, "mesh refinement factor for the nominal and a truth problem file")
      ->check(positive_number());
  cmd->add_option("-o,--output", args->output, "data file to write (YAML)")->required()->check(OutputFile());
  cmd->callback([args, exit_code] { *exit_code = run_synth(*args); });
}

}  // namespace modalcal::cli
