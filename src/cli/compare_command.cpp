// `fullspace_calib compare PROBLEM`: test-analysis correlation at chosen parameter values: the
// pairing table, unpaired modes, the MAC matrix, COMAC per sensor DOF and the SEREP
// cross-orthogonality, as text, JSON and plots.

#include <CLI/CLI.hpp>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <set>

#include "cli/cli_common.hpp"
#include "cli/cli_validators.hpp"
#include "cli/commands.hpp"
#include "modalcal/comparison.hpp"
#include "modalcal/output.hpp"
#include "cli/plot.hpp"
#include "modalcal/problem_file.hpp"

namespace modalcal::cli {

namespace {

struct CompareArgs {
  std::string problem;
  ParameterChoice params;
  std::string json;
  double refine = 0;
  double unpaired_mac = ComparisonOptions().unpaired_mac;
  std::string mac_plot, error_plot;
};


nlohmann::json matrix_json(const Matrix& m) {
  nlohmann::json rows = nlohmann::json::array();
  for (Eigen::Index i = 0; i < m.rows(); ++i) {
    nlohmann::json row = nlohmann::json::array();
    for (Eigen::Index k = 0; k < m.cols(); ++k) row.push_back(json_number(m(i, k)));
    rows.push_back(row);
  }
  return rows;
}

/// Measured-mode labels for tables and plots, numbered when they do not tell the modes apart.
std::vector<std::string> measured_labels(const Problem& problem) {
  std::vector<std::string> labels;
  std::set<std::string> seen;
  bool unique = true;
  for (const MeasuredMode& m : problem.measured) {
    labels.push_back(m.label);
    unique = unique && seen.insert(m.label).second;
  }
  if (!unique)
    for (size_t i = 0; i < labels.size(); ++i) labels[i] = std::to_string(i + 1) + ": " + labels[i];
  return labels;
}

std::string cell(double v, const char* format) {
  if (!std::isfinite(v)) return "-";
  char buffer[32];
  std::snprintf(buffer, sizeof buffer, format, v);
  return buffer;
}

/// The MAC matrix, COMAC per sensor DOF and the SEREP cross-orthogonality as text.
void print_correlation_matrices(const Problem& problem, const ModalComparison& c, const std::vector<std::string>& labels,
                                int width) {
  std::printf("\nMAC matrix (rows: measured modes, columns: model modes)\n%-*s", width, "");
  for (Eigen::Index k = 0; k < c.mac.cols(); ++k) std::printf(" %5d", static_cast<int>(k + 1));
  std::printf("\n");
  for (Eigen::Index i = 0; i < c.mac.rows(); ++i) {
    std::printf("%-*s", width, labels[i].c_str());
    for (Eigen::Index k = 0; k < c.mac.cols(); ++k) std::printf(" %5s", cell(c.mac(i, k), "%.2f").c_str());
    std::printf("\n");
  }
  if (c.comac.size() > 0) {
    Eigen::Index lowest = 0;
    for (Eigen::Index s = 0; s < c.comac.size(); ++s)
      if (std::isfinite(c.comac[s]) && !(c.comac[s] >= c.comac[lowest])) lowest = s;
    std::printf("\nCOMAC per sensor DOF (lowest: %s, %s)\n", problem.sensors[lowest].label.c_str(),
                cell(c.comac[lowest], "%.4f").c_str());
    for (Eigen::Index s = 0; s < c.comac.size(); ++s)
      std::printf("  %-16s %8s\n", problem.sensors[s].label.c_str(), cell(c.comac[s], "%.4f").c_str());
  }
  if (c.cross_orthogonality.size() > 0) {
    std::printf("\ncross-orthogonality with the SEREP test mass (rows: measured, columns: model modes of its basis)\n%-*s",
                width, "");
    for (int k : c.serep_modes) std::printf(" %6d", k + 1);
    std::printf("\n");
    for (size_t i = 0; i < c.shape_pairs.size(); ++i) {
      std::printf("%-*s", width, labels[c.pairs[c.shape_pairs[i]].measured].c_str());
      for (Eigen::Index k = 0; k < c.cross_orthogonality.cols(); ++k)
        std::printf(" %6s", cell(c.cross_orthogonality(static_cast<Eigen::Index>(i), k), "%.3f").c_str());
      std::printf("\n");
    }
  } else {
    std::printf("\nno cross-orthogonality: %s\n", c.cross_orthogonality_note.c_str());
  }
}

/// The pairing table, the unpaired modes, the MAC matrix, COMAC and cross-orthogonality as text.
void print_comparison(const Problem& problem, const Vector& p, const ModalComparison& c, const CompareArgs& args,
                      const std::vector<std::string>& labels) {
  int width = 14;  // of the label column
  for (const std::string& l : labels) width = std::max(width, static_cast<int>(l.size()));
  std::printf("%s: %zu measured modes, %d model modes computed, parameters (%s%s):", problem.path.c_str(),
              problem.measured.size(), static_cast<int>(c.model_hz.size()), args.params.source.c_str(),
              args.params.assignments.empty() ? "" : ", --set");
  for (size_t j = 0; j < problem.parameters.size(); ++j)
    std::printf(" %s = %.6g", problem.parameters[j].name.c_str(), p[static_cast<Eigen::Index>(j)]);
  std::printf("\n");
  std::fputs(hidden_effect_text(problem).c_str(), stdout);
  std::printf("\n%-*s %10s %14s %14s %9s %7s %7s\n", width, "measured", "model mode", "measured [Hz]", "model [Hz]", "error %",
              "MAC", "XOR");
  for (const ComparedPair& pair : c.pairs)
    std::printf("%-*s %10d %14.4f %14.4f %9.4f %7s %7s\n", width, labels[pair.measured].c_str(), pair.model + 1,
                pair.measured_hz, pair.model_hz, pair.error_percent, cell(pair.mac >= 0 ? pair.mac : NAN, "%.4f").c_str(),
                cell(pair.cross_orthogonality, "%.4f").c_str());
  std::printf("unpaired measured modes (MAC < %g):", args.unpaired_mac);
  for (int index : c.unpaired_measured)
    std::printf(" %s (MAC %.3f with model mode %d)", labels[c.pairs[index].measured].c_str(), c.pairs[index].mac,
                c.pairs[index].model + 1);
  std::printf("%s\nunpaired model modes:", c.unpaired_measured.empty() ? " none" : "");
  for (int k : c.unpaired_model) std::printf(" %d (%.4f Hz)", k + 1, c.model_hz[k]);
  std::printf("%s\n", c.unpaired_model.empty() ? " none" : "");
  print_correlation_matrices(problem, c, labels, width);
  for (const std::string& w : c.warnings) std::printf("warning: %s\n", w.c_str());
}

/// The comparison as JSON (docs/output-format.md, "compare").
nlohmann::json comparison_json(const Problem& problem, const Vector& p, const ModalComparison& c,
                               const CompareArgs& args) {
  nlohmann::json json;
  json["problem"] = problem.path;
  json["parameter_source"] = args.params.source;
  json["parameters"] = nlohmann::json::array();
  for (size_t j = 0; j < problem.parameters.size(); ++j)
    json["parameters"].push_back({{"name", problem.parameters[j].name}, {"value", p[static_cast<Eigen::Index>(j)]}});
  add_hidden_effect(problem, &json);
  json["pairs"] = nlohmann::json::array();
  for (const ComparedPair& pair : c.pairs)
    json["pairs"].push_back({{"measured", pair.measured + 1},
                             {"label", problem.measured[pair.measured].label},
                             {"model_mode", pair.model + 1},
                             {"measured_hz", pair.measured_hz},
                             {"model_hz", pair.model_hz},
                             {"error_percent", pair.error_percent},
                             {"mac", pair.mac >= 0 ? nlohmann::json(pair.mac) : nlohmann::json()},
                             {"cross_orthogonality", json_number(pair.cross_orthogonality)}});
  json["unpaired_mac"] = args.unpaired_mac;
  json["unpaired_measured"] = nlohmann::json::array();
  for (int index : c.unpaired_measured)
    json["unpaired_measured"].push_back({{"measured", c.pairs[index].measured + 1},
                                         {"label", problem.measured[c.pairs[index].measured].label},
                                         {"model_mode", c.pairs[index].model + 1},
                                         {"mac", c.pairs[index].mac}});
  json["unpaired_model"] = nlohmann::json::array();
  for (int k : c.unpaired_model) json["unpaired_model"].push_back({{"model_mode", k + 1}, {"frequency_hz", c.model_hz[k]}});
  json["model_modes_hz"] = std::vector<double>(c.model_hz.data(), c.model_hz.data() + c.model_hz.size());
  json["mac_matrix"] = matrix_json(c.mac);
  json["comac"] = nlohmann::json::array();
  for (Eigen::Index s = 0; s < c.comac.size(); ++s) {
    const Sensor& sensor = problem.sensors[s];
    json["comac"].push_back({{"sensor", sensor.label},
                             {"node", problem.model.node_ids[sensor.node]},
                             {"direction", component_name(sensor.component)},
                             {"comac", json_number(c.comac[s])}});
  }
  if (c.cross_orthogonality.size() > 0) {
    nlohmann::json rows = nlohmann::json::array(), columns = nlohmann::json::array();
    for (int index : c.shape_pairs) rows.push_back(c.pairs[index].measured + 1);
    for (int k : c.serep_modes) columns.push_back(k + 1);
    json["cross_orthogonality"] = {{"measured", rows}, {"model_modes", columns}, {"values", matrix_json(c.cross_orthogonality)}};
  } else {
    json["cross_orthogonality"] = nullptr;
    json["cross_orthogonality_note"] = c.cross_orthogonality_note;
  }
  json["warnings"] = c.warnings;
  return json;
}

/// The MAC matrix as a heat map and the frequency errors as bars, where asked for.
void plot_comparison(const Problem& problem, const ModalComparison& c, const CompareArgs& args,
                     const std::vector<std::string>& labels) {
  const std::string name = problem.name.empty() ? problem.path : problem.name;
  if (!args.mac_plot.empty()) {
    HeatMap map;
    map.row_labels = labels;
    for (Eigen::Index k = 0; k < c.mac.cols(); ++k) map.column_labels.push_back(std::to_string(k + 1));
    map.row_title = "measured mode";
    map.column_title = "model mode";
    map.value_title = "MAC";
    map.values = c.mac;
    plot_heat_map(args.mac_plot, "MAC matrix, " + name, map);
  }
  if (!args.error_plot.empty()) {
    BarChart chart;
    for (const ComparedPair& pair : c.pairs) {
      chart.labels.push_back(labels[pair.measured] + " / " + std::to_string(pair.model + 1));
      chart.values.push_back(pair.error_percent);
    }
    chart.ylabel = "frequency error (model / measured - 1) [%]";
    plot_bars(args.error_plot, "frequency errors (measured / model mode), " + name, chart);
  }
}

int run_compare(const CompareArgs& args) {
  Problem problem = load_problem_with_measurements(args.problem, LoadOptions{args.refine});
  const Vector p = choose_parameters(&problem, args.params);
  ComparisonOptions options;
  options.unpaired_mac = args.unpaired_mac;
  const ModalComparison c = compare_modes(problem, p, options);
  const std::vector<std::string> labels = measured_labels(problem);
  print_comparison(problem, p, c, args, labels);
  const nlohmann::json json = comparison_json(problem, p, c, args);
  for (const std::string& plot : {args.mac_plot, args.error_plot})
    if (!plot.empty()) check_output_path(plot, problem.source_files);
  write_json(args.json, json, problem);
  plot_comparison(problem, c, args, labels);
  return 0;
}

}  // namespace

void register_compare_command(CLI::App& app, int* exit_code) {
  auto args = std::make_shared<CompareArgs>();
  CLI::App* cmd = app.add_subcommand(
      "compare", "Correlate measured and model modes: pairing, frequency errors, MAC matrix, COMAC, cross-orthogonality");
  cmd->add_option("problem", args->problem, "problem file (YAML)")->required()->check(CLI::ExistingFile);
  cmd->add_option("--params", args->params.source,
                  "parameter values: initial (default), truth, or a calibration report JSON (its final values)");
  cmd->add_option("--set", args->params.assignments, "NAME=VALUE for a parameter or a model property (repeatable)");
  cmd->add_option("--json", args->json, "write the comparison as JSON to this file")->check(OutputFile());
  cmd->add_option("--refine", args->refine, "mesh refinement factor (overrides the problem file)")
      ->check(positive_number());
  cmd->add_option("--unpaired-mac", args->unpaired_mac, "pairs with a lower MAC are listed as unpaired (default 0.5)")
      ->check(finite_number())
      ->check(FiniteRange(0.0, 1.0));
  cmd->add_option("--mac-plot", args->mac_plot, "plot the MAC matrix to this .png or .svg file")
      ->check(PlotFile());
  cmd->add_option("--error-plot", args->error_plot, "plot the frequency errors to this .png or .svg file")
      ->check(PlotFile());
  cmd->callback([args, exit_code] { *exit_code = run_compare(*args); });
}

}  // namespace modalcal::cli
