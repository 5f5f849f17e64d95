#include "cli/calibration_report.hpp"

#include <cmath>
#include <cstdio>
#include <stdexcept>
#include <utility>

#include "cli/cli_common.hpp"
#include "modalcal/output.hpp"
#include "cli/plot.hpp"

namespace modalcal::cli {

nlohmann::json CalibrationReport::json() const {
  nlohmann::json out = summary;
  out["parameters"] = parameters;
  out["modes"] = modes;
  out["settings"] = settings;
  return out;
}

CalibrationReport make_report(Objective& objective, const Vector& initial, const Vector& final) {
  const Problem& problem = objective.problem();
  CalibrationReport report;
  char line[320];
  std::snprintf(line, sizeof line, "%-14s %13s %13s %13s %10s %11s %11s\n", "parameter", "initial", "computed", "true",
                "error %", "lower", "upper");
  report.text = line;
  report.parameters = nlohmann::json::array();
  const bool have_final = final.size() == static_cast<int>(problem.parameters.size());
  for (size_t j = 0; j < problem.parameters.size(); ++j) {
    const Parameter& q = problem.parameters[j];
    const double final_value = have_final ? final[j] : NAN;
    nlohmann::json entry = {{"name", q.name}, {"initial", initial[j]}, {"final", final_value},
                            {"lower", q.lower}, {"upper", q.upper}};
    std::string truth = "-", error = "-";
    if (q.truth) {
      const double error_percent = 100 * (final_value / *q.truth - 1);
      entry["truth"] = *q.truth;
      entry["error_percent"] = json_number(error_percent);
      char buffer[32];
      std::snprintf(buffer, sizeof buffer, "%.4e", *q.truth);
      truth = buffer;
      std::snprintf(buffer, sizeof buffer, "%.4f", error_percent);
      error = buffer;
    }
    report.parameters.push_back(entry);
    std::snprintf(line, sizeof line, "%-14s %13.4e %13.4e %13s %10s %11.3e %11.3e\n", q.name.c_str(),
                  initial[j], final_value, truth.c_str(), error.c_str(), q.lower, q.upper);
    report.text += line;
  }
  report.modes = nlohmann::json::array();
  if (have_final) {
    const Evaluation e = objective.evaluate(final);
    report.text += "\n";
    std::snprintf(line, sizeof line, "%-12s %10s %14s %14s %9s %7s\n", "measured", "model mode", "measured [Hz]",
                  "predicted [Hz]", "error %", "MAC");
    report.text += line;
    for (const PairedMode& pair : e.pairs) {
      const MeasuredMode& m = problem.measured[pair.measured];
      const std::string label = m.label.empty() ? "mode " + std::to_string(pair.measured + 1) : m.label;
      const double error = 100 * (pair.model_hz / pair.measured_hz - 1);
      nlohmann::json entry = {{"label", label}, {"measured_hz", pair.measured_hz}, {"predicted_hz", pair.model_hz},
                              {"error_percent", error}, {"model_mode", pair.model + 1}};
      if (pair.mac >= 0) entry["mac"] = pair.mac;
      report.modes.push_back(entry);
      std::snprintf(line, sizeof line, "%-12s %10d %14.3f %14.3f %9.4f %7s\n", label.c_str(), pair.model + 1,
                    pair.measured_hz, pair.model_hz, error,
                    pair.mac >= 0 ? std::to_string(pair.mac).substr(0, 6).c_str() : "-");
      report.text += line;
    }
    for (const std::string& w : e.warnings) report.text += "warning: " + w + "\n";
  }
  const std::string hidden = hidden_effect_text(problem);
  if (!hidden.empty()) report.text += "\n" + hidden;
  return report;
}

void add_uncertainty(const Uncertainty& u, CalibrationReport* report) {
  report->text += "\n" + u.FullReport();
  for (size_t j = 0; j < u.parameters.size() && j < report->parameters.size(); ++j) {
    const ParameterUncertainty& pu = u.parameters[j];
    nlohmann::json& entry = report->parameters[j];
    entry["standard_error"] = json_number(pu.standard_error);
    entry["interval"] = {json_number(pu.lower), json_number(pu.upper)};
    entry["profile_interval"] = nullptr;
    if (pu.profile)
      entry["profile_interval"] = {pu.profile_open_below ? nlohmann::json() : json_number(pu.profile->first),
                                   pu.profile_open_above ? nlohmann::json() : json_number(pu.profile->second)};
    entry["correlation"] = nlohmann::json::array();
    for (Eigen::Index k = 0; k < u.correlation.cols(); ++k)
      entry["correlation"].push_back(json_number(u.correlation(static_cast<Eigen::Index>(j), k)));
  }
  report->summary["uncertainty"] = {{"confidence", u.confidence},
                                    {"noise", u.noise_stated ? "stated" : "estimated from the residual"},
                                    {"statistic", u.statistic},
                                    {"num_data", u.num_data},
                                    {"note", u.note}};
}

namespace {

nlohmann::json history_json(const std::vector<IterationRecord>& records) {
  nlohmann::json history = nlohmann::json::array();
  for (const IterationRecord& r : records) {
    nlohmann::json h = {{"iteration", r.iteration}, {"objective", r.objective}, {"gradient_norm", r.gradient_norm},
                        {"forward_solves", r.forward_solves}};
    if (!std::isnan(r.parameter_error)) h["parameter_error"] = r.parameter_error;
    history.push_back(h);
  }
  return history;
}

/// One CSV cell: numbers to ten significant digits, strings quoted when they need it, empty if absent.
std::string csv_cell(const nlohmann::json& entry, const char* key) {
  if (!entry.contains(key) || entry[key].is_null()) return "";
  const nlohmann::json& v = entry[key];
  if (v.is_number()) {
    char buffer[32];
    std::snprintf(buffer, sizeof buffer, "%.10g", v.get<double>());
    return buffer;
  }
  const std::string text =
      v.is_string() ? v.get<std::string>() : v.dump(-1, ' ', false, nlohmann::json::error_handler_t::replace);
  if (text.find_first_of(",\"\n") == std::string::npos) return text;
  std::string quoted = "\"";
  for (char c : text) quoted += c == '"' ? std::string("\"\"") : std::string(1, c);
  return quoted + "\"";
}

std::string csv_table(const nlohmann::json& rows, const std::vector<const char*>& columns) {
  std::string out;
  for (size_t c = 0; c < columns.size(); ++c) out += std::string(c ? "," : "") + columns[c];
  out += "\n";
  for (const nlohmann::json& row : rows) {
    for (size_t c = 0; c < columns.size(); ++c) out += (c ? "," : "") + csv_cell(row, columns[c]);
    out += "\n";
  }
  return out;
}

}  // namespace

std::vector<std::string> write_csv_report(const std::string& prefix, const nlohmann::json& report,
                                          const Problem& problem) {
  const std::vector<std::pair<std::string, std::string>> files = {
      {prefix + "_parameters.csv", csv_table(report.value("parameters", nlohmann::json::array()),
                                             {"name", "initial", "final", "truth", "error_percent", "lower", "upper"})},
      {prefix + "_modes.csv", csv_table(report.value("modes", nlohmann::json::array()),
                                        {"label", "model_mode", "measured_hz", "predicted_hz", "error_percent", "mac"})},
      {prefix + "_history.csv", csv_table(report.value("history", nlohmann::json::array()),
                                          {"iteration", "phase", "objective", "gradient_norm"})}};
  for (const auto& file : files) check_not_input(file.first, problem.source_files);
  std::vector<std::string> paths;
  for (const auto& file : files) {
    write_file_atomically(file.first, file.second, problem.source_files);
    paths.push_back(file.first);
  }
  return paths;
}

void plot_history(const std::string& path, const nlohmann::json& report, const Problem& problem) {
  check_not_input(path, problem.source_files);
  PlotSeries objective{"objective", {}, {}}, gradient{"gradient norm", {}, {}};
  for (const nlohmann::json& h : report.value("history", nlohmann::json::array())) {
    const double iteration = h["iteration"].get<double>();
    // Log axes: a zero (an exact fit) cannot be drawn and is left out.
    if (h["objective"].is_number() && h["objective"].get<double>() > 0) {
      objective.x.push_back(iteration);
      objective.y.push_back(h["objective"].get<double>());
    }
    if (h["gradient_norm"].is_number() && h["gradient_norm"].get<double>() > 0) {
      gradient.x.push_back(iteration);
      gradient.y.push_back(h["gradient_norm"].get<double>());
    }
  }
  if (objective.x.empty()) throw std::runtime_error("--history-plot " + path + ": the run recorded no iterations");
  const std::string method = report.value("method", std::string("calibration"));
  plot_panels(path, method + ": " + problem.name, "iteration",
              {PlotPanel{"objective J", true, {objective}}, PlotPanel{"gradient norm", true, {gradient}}});
}

nlohmann::json summary_json(const Problem& problem, const ReducedSummary& summary) {
  nlohmann::json json = {{"problem", problem.path},
          {"method", summary.method},
          {"converged", summary.converged()},
          {"status", to_string(summary.status)},
          {"message", summary.message},
          {"iterations", summary.iterations},
          {"initial_objective", summary.initial_objective},
          {"final_objective", summary.final_objective},
          {"forward_solves", summary.forward_solves},
          {"linear_solves", summary.linear_solves},
          {"failed_evaluations", summary.failed_evaluations},
          {"time_s", summary.seconds},
          {"convergence_order", json_number(summary.convergence_order)},
          {"history", history_json(summary.history)}};
  add_hidden_effect(problem, &json);
  return json;
}

nlohmann::json summary_json(const Problem& problem, const FullSpaceSummary& summary) {
  nlohmann::json kkt = nlohmann::json::array(), history = nlohmann::json::array();
  for (const KktRecord& r : summary.kkt_history) {
    nlohmann::json k = {{"iteration", r.iteration},
                        {"objective", r.objective},
                        {"primal_infeasibility", r.primal_infeasibility},
                        {"dual_infeasibility", r.dual_infeasibility},
                        {"complementarity", r.complementarity},
                        {"kkt_error", r.kkt_error()},
                        {"mu", r.mu},
                        {"step_length", r.step_length},
                        {"hessian_shift", r.hessian_shift},
                        {"parameter_error", json_number(r.parameter_error)},
                        {"guard_min_mac", json_number(r.min_mac)}};
    kkt.push_back(k);
    // The common history: the full-space "gradient norm" is the dual infeasibility (the
    // gradient of the Lagrangian), iterations numbered after the globalization.
    history.push_back({{"iteration", summary.globalization_iterations + r.iteration},
                       {"objective", r.objective},
                       {"gradient_norm", r.dual_infeasibility},
                       {"phase", "newton"}});
  }
  nlohmann::json global = history_json(summary.globalization_history);
  for (auto& h : global) h["phase"] = "globalization";
  global.insert(global.end(), history.begin(), history.end());
  nlohmann::json check = {{"passed", summary.mode_check.passed},
                          {"reason", summary.mode_check.reason},
                          {"mac", summary.mode_check.mac},
                          {"eigenvalue_error", summary.mode_check.eigenvalue_error}};
  nlohmann::json escapes = nlohmann::json::array();
  for (const CrossingEscape& e : summary.crossing_escapes)
    escapes.push_back({{"crossing", e.crossing},
                       {"objective_at_minimum", json_number(e.objective_at_minimum)},
                       {"objective_after", json_number(e.objective_after)},
                       {"converged", e.converged},
                       {"kept", e.kept}});
  nlohmann::json json = {{"problem", problem.path},
          {"method", "fullspace"},
          {"converged", summary.converged()},
          {"status", to_string(summary.status)},
          {"message", summary.message},
          {"newton_solver", summary.newton_solver},
          {"ipopt_status", summary.newton_solver == "ipopt" ? summary.newton_status : ""},
          {"newton_status", summary.newton_status},
          {"kkt_solver", summary.kkt_solver},
          {"kkt_factorizations", {{"structured", summary.structured_factorizations}, {"mumps", summary.mumps_factorizations}}},
          {"bordered_solves", {{"method", summary.bordered_solves},
                               {"shared_eliminations", summary.shared_eliminations},
                               {"shared_failures", summary.shared_failures}}},
          {"iterations", summary.iterations},
          {"globalization_iterations", summary.globalization_iterations},
          {"restarts", summary.restarts},
          {"crossing_escapes", escapes},
          {"initial_objective", summary.initial_objective},
          {"final_objective", json_number(summary.final_objective)},
          {"forward_solves", summary.forward_solves},
          {"kkt_solves", summary.kkt_solves},
          {"unknowns", summary.num_unknowns},
          {"constraints", summary.num_constraints},
          {"time_s", summary.seconds},
          {"newton_time_s", summary.newton_seconds},
          {"guard_time_s", summary.guard_seconds},
          {"convergence_order", json_number(summary.convergence_order)},
          {"mode_check", check},
          {"kkt_history", kkt},
          {"history", global}};
  add_hidden_effect(problem, &json);
  return json;
}

}  // namespace modalcal::cli
