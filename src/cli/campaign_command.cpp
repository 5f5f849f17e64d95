// `fullspace_calib campaign PROBLEM DATA...`: one calibration per measured data set (the same
// model and start), each with its uncertainty, then the distribution of every parameter and
// whether it varies from test to test beyond each calibration's own uncertainty.

#include <CLI/CLI.hpp>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>

#include <unistd.h>

#include "cli/cli_common.hpp"
#include "cli/commands.hpp"
#include "modalcal/output.hpp"
#include "modalcal/reduced.hpp"
#include "modalcal/residual_test.hpp"
#include "modalcal/uncertainty.hpp"

namespace modalcal::cli {

namespace {

namespace fs = std::filesystem;

struct CampaignArgs {
  std::string problem;
  std::vector<std::string> data;  // data files, or folders of them (*.yaml, in name order)
  std::string json;
  double significance = 0.01;
};

/// One data set's calibration.
struct Run {
  std::string data;
  bool ok = false;
  bool input_error = false;
  std::string reason;  // why it failed
  Uncertainty uncertainty;
  int iterations = 0;
  std::string status;
};

/// The data files named: files as given, folders expanded to their .yaml files in name order.
std::vector<std::string> data_files(const std::vector<std::string>& given) {
  std::vector<std::string> files;
  for (const std::string& item : given) {
    std::error_code error;
    if (fs::is_directory(item, error)) {
      std::vector<std::string> in_folder;
      for (const fs::directory_entry& e : fs::directory_iterator(item))
        if (e.is_regular_file() && (e.path().extension() == ".yaml" || e.path().extension() == ".yml"))
          in_folder.push_back(e.path().string());
      std::sort(in_folder.begin(), in_folder.end());
      if (in_folder.empty()) throw InputError("campaign: folder " + item + " holds no .yaml data file");
      files.insert(files.end(), in_folder.begin(), in_folder.end());
    } else {
      files.push_back(item);
    }
  }
  return files;
}

/// The problem with its measured modes from `data`: a problem file that extends it, written
/// to `folder`, so that the data are read exactly as `measured: {file: ...}` reads them.
Problem problem_with_data(const std::string& problem, const std::string& data, const fs::path& folder, int k) {
  const fs::path file = folder / ("data-" + std::to_string(k) + ".yaml");
  std::ofstream(file) << "extends: " << fs::absolute(problem).string() << "\nmeasured: {file: "
                      << fs::absolute(data).string() << "}\n";
  return load_problem(file.string());
}

Run calibrate_one(const CampaignArgs& args, const std::string& data, const fs::path& folder, int k) {
  Run run;
  run.data = data;
  try {
    const Problem problem = problem_with_data(args.problem, data, folder, k);
    Objective objective(problem);
    const ReducedSummary fit = minimize_reduced(objective, problem.initial_values(), ReducedOptions());
    run.iterations = fit.iterations;
    run.status = to_string(fit.termination);
    if (fit.final.size() != static_cast<Eigen::Index>(problem.parameters.size()))
      throw std::runtime_error("the calibration could not start: " + fit.message);
    UncertaintyOptions options;
    options.profiles = false;  // a campaign's many runs: the Laplace intervals
    run.uncertainty = estimate_uncertainty(problem, fit.final, options);
    run.ok = true;
  } catch (const std::invalid_argument& e) {
    run.input_error = true;
    run.reason = e.what();
  } catch (const std::exception& e) {
    run.reason = e.what();
  }
  return run;
}

double quantile(std::vector<double> v, double q) {
  std::sort(v.begin(), v.end());
  const double at = q * static_cast<double>(v.size() - 1);
  const size_t i = static_cast<size_t>(std::floor(at));
  return i + 1 < v.size() ? v[i] + (at - static_cast<double>(i)) * (v[i + 1] - v[i]) : v[i];
}

/// One parameter over the runs: its distribution, and the homogeneity test of the values
/// against their own standard errors (in the optimizer's variable, where the Laplace intervals
/// are symmetric): Q = sum (x_i - x_w)^2 / s_i^2, chi-square with n - 1 degrees of freedom when
/// every test measured the same structure.
nlohmann::json parameter_summary(const Problem& problem, size_t j, const std::vector<Run>& runs, double significance,
                                 std::string* text) {
  const ParameterScaling scaling({problem.parameters[j]});
  std::vector<double> values, errors, x, sx;
  for (const Run& r : runs) {
    if (!r.ok) continue;
    const ParameterUncertainty& pu = r.uncertainty.parameters[j];
    values.push_back(pu.value);
    errors.push_back(pu.standard_error);
    x.push_back(scaling.to_scaled(Vector::Constant(1, pu.value))[0]);
    sx.push_back(pu.scaled_standard_error);
  }
  const size_t n = values.size();
  double mean = 0, sd = 0, rms_error = 0;
  for (size_t i = 0; i < n; ++i) mean += values[i] / static_cast<double>(n);
  for (size_t i = 0; i < n; ++i) sd += (values[i] - mean) * (values[i] - mean);
  sd = n > 1 ? std::sqrt(sd / static_cast<double>(n - 1)) : NAN;
  for (double e : errors) rms_error += e * e / static_cast<double>(n);
  rms_error = std::sqrt(rms_error);
  double weight = 0, weighted = 0;
  for (size_t i = 0; i < n; ++i)
    if (sx[i] > 0 && std::isfinite(sx[i])) {
      weight += 1 / (sx[i] * sx[i]);
      weighted += x[i] / (sx[i] * sx[i]);
    }
  double Q = 0;
  int terms = 0;
  for (size_t i = 0; i < n; ++i)
    if (weight > 0 && sx[i] > 0 && std::isfinite(sx[i])) {
      Q += std::pow((x[i] - weighted / weight) / sx[i], 2);
      ++terms;
    }
  const double p = terms > 1 ? chi_square_upper_tail(Q, terms - 1) : NAN;
  const bool varies = p < significance;
  char line[320];
  std::snprintf(line, sizeof line, "%-16s %4zu %12.4g %10.3g %12.4g %12.4g %12.4g %10.3g %7.2f %9.3g  %s\n",
                problem.parameters[j].name.c_str(), n, mean, sd, n ? quantile(values, 0.05) : NAN,
                n ? quantile(values, 0.5) : NAN, n ? quantile(values, 0.95) : NAN, rms_error, sd / rms_error, p,
                std::isnan(p) ? "-" : varies ? "varies between tests" : "spread of the noise");
  *text += line;
  return {{"name", problem.parameters[j].name},
          {"runs", n},
          {"mean", json_number(mean)},
          {"standard_deviation", json_number(sd)},
          {"quantiles", {{"q05", json_number(n ? quantile(values, 0.05) : NAN)},
                         {"median", json_number(n ? quantile(values, 0.5) : NAN)},
                         {"q95", json_number(n ? quantile(values, 0.95) : NAN)}}},
          {"rms_standard_error", json_number(rms_error)},
          {"spread_ratio", json_number(sd / rms_error)},
          {"homogeneity", {{"statistic", json_number(Q)}, {"dof", std::max(0, terms - 1)}, {"p_value", json_number(p)}}},
          {"varies_between_tests", varies}};
}

nlohmann::json run_json(const Run& r) {
  nlohmann::json j = {{"data", r.data}, {"ok", r.ok}};
  if (!r.ok) {
    j["reason"] = r.reason;
    return j;
  }
  j["status"] = r.status;
  j["iterations"] = r.iterations;
  j["statistic"] = r.uncertainty.statistic;
  j["parameters"] = nlohmann::json::array();
  for (const ParameterUncertainty& pu : r.uncertainty.parameters)
    j["parameters"].push_back({{"name", pu.name},
                               {"value", pu.value},
                               {"standard_error", json_number(pu.standard_error)},
                               {"interval", {json_number(pu.lower), json_number(pu.upper)}}});
  return j;
}

int run_campaign(const CampaignArgs& args) {
  const Problem problem = load_problem(args.problem);
  require_parameters(problem);
  const std::vector<std::string> files = data_files(args.data);
  std::vector<std::string> inputs = problem.source_files;
  for (const std::string& f : files) inputs.push_back(fs::absolute(f).string());
  if (!args.json.empty()) check_output_path(args.json, inputs);
  const fs::path folder = fs::temp_directory_path() / ("modalcal-campaign-" + std::to_string(::getpid()));
  fs::create_directories(folder);
  std::vector<Run> runs;
  for (size_t k = 0; k < files.size(); ++k) {
    runs.push_back(calibrate_one(args, files[k], folder, static_cast<int>(k)));
    const Run& r = runs.back();
    if (r.ok)
      std::printf("%-40s %s after %d iterations, chi-square %.4g\n", r.data.c_str(), r.status.c_str(), r.iterations,
                  r.uncertainty.statistic);
    else
      std::printf("%-40s FAILED, skipped: %s\n", r.data.c_str(), r.reason.c_str());
  }
  fs::remove_all(folder);
  const long usable = std::count_if(runs.begin(), runs.end(), [](const Run& r) { return r.ok; });
  std::string text;
  char line[320];
  std::snprintf(line, sizeof line, "\n%ld of %zu data sets calibrated; every parameter over them:\n", usable, runs.size());
  text += line;
  std::snprintf(line, sizeof line, "%-16s %4s %12s %10s %12s %12s %12s %10s %7s %9s\n", "parameter", "n", "mean", "std. dev.",
                "5 %", "median", "95 %", "rms s.e.", "ratio", "p");
  text += line;
  nlohmann::json summary = nlohmann::json::array();
  if (usable > 0)
    for (size_t j = 0; j < problem.parameters.size(); ++j)
      summary.push_back(parameter_summary(problem, j, runs, args.significance, &text));
  std::snprintf(line, sizeof line,
                "(ratio: the spread between tests over each calibration's own standard error; p: of the test that "
                "every data set measured the same structure, each with its own uncertainty; below %g, the parameter "
                "varies between tests beyond the noise)\n",
                args.significance);
  text += line;
  std::fputs(text.c_str(), stdout);
  if (!args.json.empty()) {
    nlohmann::json json = {{"problem", args.problem}, {"runs", nlohmann::json::array()}, {"summary", summary}};
    for (const Run& r : runs) json["runs"].push_back(run_json(r));
    write_json(args.json, json, problem);
  }
  if (usable > 0) return 0;
  const bool all_input = std::all_of(runs.begin(), runs.end(), [](const Run& r) { return r.input_error; });
  std::fprintf(stderr, "campaign: no data set could be calibrated\n");
  return all_input ? 2 : 1;
}

}  // namespace

void register_campaign_command(CLI::App& app, int* exit_code) {
  auto args = std::make_shared<CampaignArgs>();
  CLI::App* cmd = app.add_subcommand(
      "campaign", "Calibrate each measured data set on its own; the distribution of every parameter over them");
  cmd->add_option("problem", args->problem, "problem file (YAML): the model, its parameters and their start")
      ->required()
      ->check(CLI::ExistingFile);
  cmd->add_option("data", args->data,
                  "measured data files (as synth writes them, or as measured: file: reads), or folders of .yaml data "
                  "files")
      ->required()
      ->check(CLI::ExistingPath);
  cmd->add_option("--json", args->json, "write every run and the summary as JSON to this file");
  cmd->add_option("--significance", args->significance,
                  "level of the test that a parameter varies between tests (default 0.01)")
      ->check(CLI::Range(1e-6, 0.5));
  cmd->callback([args, exit_code] { *exit_code = run_campaign(*args); });
}

}  // namespace modalcal::cli
