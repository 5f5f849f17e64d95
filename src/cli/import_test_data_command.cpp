// `fullspace_calib import-test-data FILE`: what a universal file or test CSV holds (datasets,
// header, units, coordinate systems, nodes, modes, warnings), and with --problem how its nodes
// map onto the model; --csv writes the modes in the plain CSV form.

#include <CLI/CLI.hpp>
#include <cmath>
#include <cstdio>

#include "cli/cli_common.hpp"
#include "cli/cli_validators.hpp"
#include "cli/commands.hpp"
#include "modalcal/output.hpp"
#include "modalcal/test_data.hpp"
#include "modalcal/problem_file.hpp"

namespace modalcal::cli {

namespace {

struct ImportArgs {
  std::string file;
  std::string problem;
  std::string map = "id";
  double tolerance = 0;
  LengthConversion lengths;
  std::string csv;
};

/// Values are sorted by node, so nodes are the runs of equal node ids.
int num_nodes(const TestMode& m) {
  int n = 0;
  for (size_t k = 0; k < m.values.size(); ++k) n += k == 0 || m.values[k].node != m.values[k - 1].node;
  return n;
}

void print_datasets(const TestData& data) {
  std::printf("datasets:\n");
  for (const UffDatasetEntry& d : data.datasets)
    std::printf("  line %6d  %5d  %s\n", d.line, d.number, d.read ? "read" : ("skipped: " + d.note).c_str());
}

void print_contents(const TestData& data) {
  if (data.header)
    std::printf("header (151): model '%s', '%s'; written by '%s', %s\n", data.header->model_name.c_str(),
                data.header->description.c_str(), data.header->file_program.c_str(), data.header->file_written.c_str());
  if (data.units)
    std::printf("units (164): code %d '%s'; per SI unit: %g length, %g force, %g temperature units (offset %g)\n",
                data.units->code, data.units->description.c_str(), data.units->length_factor, data.units->force_factor,
                data.units->temperature_factor, data.units->temperature_offset);
  else if (data.format == TestData::Format::Uff)
    std::printf("units: no dataset 164 (unknown; taken as SI only when converted to a named unit)\n");
  if (!data.coordinate_systems.empty()) {
    int cartesian = 0;
    for (const CoordinateSystem& s : data.coordinate_systems) cartesian += s.type == 0;
    std::printf("coordinate systems: %zu (%d Cartesian)\n", data.coordinate_systems.size(), cartesian);
  }
  if (!data.nodes.empty()) {
    Vec3 lo = data.nodes.front().coordinates, hi = lo;
    for (const TestNode& n : data.nodes) {
      lo = lo.cwiseMin(n.coordinates);
      hi = hi.cwiseMax(n.coordinates);
    }
    std::printf("nodes: %zu, global frame, from [%g, %g, %g] to [%g, %g, %g]\n", data.nodes.size(), lo[0], lo[1], lo[2],
                hi[0], hi[1], hi[2]);
  } else {
    std::printf("nodes: no geometry\n");
  }
  std::printf("modes: %zu\n", data.modes.size());
  if (!data.modes.empty())
    std::printf("  %6s %12s %9s %6s %11s  %s\n", "mode", "freq [Hz]", "damping", "nodes", "values/node", "source");
  for (const TestMode& m : data.modes) {
    char damping[32] = "-";
    if (m.damping_ratio) std::snprintf(damping, sizeof(damping), "%.4g", *m.damping_ratio);
    const std::string source = m.dataset ? "dataset " + std::to_string(m.dataset) + ", line " + std::to_string(m.line)
                                         : "line " + std::to_string(m.line);
    std::printf("  %6d %12.4f %9s %6d %11d  %s%s\n", m.number, m.frequency_hz, damping, num_nodes(m), m.values_per_node,
                source.c_str(), m.from_complex ? " (complex, made real)" : "");
  }
}

int run_import(const ImportArgs& args) {
  TestData data = read_test_data(args.file);
  std::printf("%s: %s\n", args.file.c_str(), data.format == TestData::Format::Uff ? "universal file" : "CSV");
  if (data.format == TestData::Format::Uff) print_datasets(data);

  std::vector<std::string> inputs{args.file};
  std::string conversion;
  if (!args.problem.empty()) {
    const Problem problem = load_problem_with_measurements(args.problem);
    inputs.insert(inputs.end(), problem.source_files.begin(), problem.source_files.end());
    print_warnings(problem);
    conversion = convert_lengths(&data, args.lengths, problem.units);
    NodeMapOptions options;
    options.by = args.map == "coordinates" ? NodeMatchBy::Coordinates : NodeMatchBy::Id;
    if (args.tolerance > 0) options.tolerance = args.tolerance;
    print_contents(data);
    std::printf("mapping onto %s (%d model nodes): %s", args.problem.c_str(), problem.model.num_nodes(),
                map_test_nodes(data, problem.model, options).report().c_str());
  } else {
    conversion = convert_lengths(&data, args.lengths, "");
    print_contents(data);
  }
  if (!conversion.empty()) data.warnings.insert(data.warnings.begin(), conversion);
  for (const std::string& w : data.warnings) std::printf("warning: %s\n", w.c_str());
  if (!args.csv.empty()) {
    write_test_csv(data, args.csv, inputs);
    std::printf("wrote %s\n", args.csv.c_str());
  }
  return 0;
}

}  // namespace

void register_import_test_data_command(CLI::App& app, int* exit_code) {
  auto args = std::make_shared<ImportArgs>();
  CLI::App* cmd = app.add_subcommand(
      "import-test-data", "Read a universal file (UFF/UNV) or test CSV: datasets, units, nodes, modes, warnings");
  cmd->add_option("file", args->file, "universal file, or CSV (mode,frequency_hz,node,direction,value)")
      ->required()
      ->check(CLI::ExistingFile);
  cmd->add_option("--problem", args->problem, "problem file whose model the test nodes are mapped onto")
      ->check(CLI::ExistingFile);
  cmd->add_option("--map", args->map, "match test nodes to model nodes by id or coordinates (default id)")
      ->check(CLI::IsMember({"id", "coordinates"}));
  cmd->add_option("--tolerance", args->tolerance, "largest distance for --map coordinates, in model units")
      ->check(positive_number());
  auto* unit = cmd->add_option("--length-unit", args->lengths.unit, "convert lengths to this unit (m, cm, mm, in, ft)")
                   ->check(CLI::IsMember({"m", "cm", "mm", "in", "ft"}));
  cmd->add_option("--scale-length", args->lengths.scale, "multiply the file's lengths by this factor")
      ->check(positive_number())
      ->excludes(unit);
  cmd->add_option("--csv", args->csv, "write the modes as CSV (mode,frequency_hz,node,direction,value) to this file")
      ->check(OutputFile());
  cmd->callback([args, exit_code] { *exit_code = run_import(*args); });
}

}  // namespace modalcal::cli
