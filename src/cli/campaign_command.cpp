// `fullspace_calib campaign PROBLEM DATA...`: one calibration per measured data set (the same
// model and start), each with its uncertainty, then the distribution of every parameter and
// whether it varies from test to test beyond each calibration's own uncertainty. The runs are
// independent: across the ranks of an MPI job (WorkFarm), or in parts (--json each) merged later
// (--merge). Either way the summary is made from the runs' JSON, so all three agree.

#include <CLI/CLI.hpp>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>

#include <unistd.h>

#include "cli/cli_common.hpp"
#include "cli/cli_validators.hpp"
#include "cli/commands.hpp"
#include "cli/work_farm.hpp"
#include "modalcal/output.hpp"
#include "cli/plot.hpp"
#include "modalcal/reduced.hpp"
#include "modalcal/residual_test.hpp"
#include "modalcal/uncertainty.hpp"
#include "modalcal/problem_file.hpp"

namespace modalcal::cli {

namespace {

namespace fs = std::filesystem;

struct CampaignArgs {
  std::string problem;
  std::vector<std::string> data;  // data files, or folders of them (*.yaml, in name order)
  std::vector<std::string> merge;  // campaign JSON files whose runs to summarize
  std::string json;
  std::string plot;
  double significance = 0.01;
  int jobs = 0;  // data sets calibrated at a time in threads; 0: one per core
};

/// The data files named: files as given, folders expanded to their .yaml files in name order
/// (but `problem`, which may sit beside its data).
std::vector<std::string> data_files(const std::vector<std::string>& given, const std::string& problem) {
  std::vector<std::string> files;
  for (const std::string& item : given) {
    std::error_code error;
    if (fs::is_directory(item, error)) {
      std::vector<std::string> in_folder;
      for (const fs::directory_entry& e : fs::directory_iterator(item))
        if (e.is_regular_file() && (e.path().extension() == ".yaml" || e.path().extension() == ".yml") &&
            !fs::equivalent(e.path(), problem, error))  // the problem itself, kept beside its data
          in_folder.push_back(e.path().string());
      std::sort(in_folder.begin(), in_folder.end());
      if (in_folder.empty()) throw InputError("campaign: folder " + item + " holds no .yaml data file");
      files.insert(files.end(), in_folder.begin(), in_folder.end());
    } else {
      files.push_back(item);
    }
  }
  // A test counted twice would weigh double and make the tests look more alike than they are.
  if (const auto twice = same_file_twice(files))
    throw InputError("campaign: data file " + files[twice->second] + " is given twice (also as " +
                     files[twice->first] + "); each test counts once");
  return files;
}

/// The problem with its measured modes from `data`: a problem file that extends it, written
/// to `folder`, so that the data are read exactly as `measured: {file: ...}` reads them.
Problem problem_with_data(const std::string& problem, const std::string& data, const fs::path& folder, int k) {
  const fs::path file = folder / ("data-" + std::to_string(k) + ".yaml");
  std::ofstream(file) << "extends: " << fs::absolute(problem).string() << "\nmeasured: {file: "
                      << fs::absolute(data).string() << "}\n";
  return load_problem_with_measurements(file.string());
}

/// One data set's calibration, as its entry in the JSON's `runs`: ok with the parameters' values
/// and Laplace uncertainty, or not ok with the reason (`input_error`: the data set is bad input).
nlohmann::json calibrate_one(const CampaignArgs& args, const std::string& data, const fs::path& folder, int k) {
  nlohmann::json run = {{"data", data}, {"ok", false}};
  try {
    const Problem problem = problem_with_data(args.problem, data, folder, k);
    Objective objective(problem);
    const ReducedSummary fit = minimize_reduced(objective, problem.initial_values(), ReducedOptions());
    if (fit.final.size() != static_cast<Eigen::Index>(problem.parameters.size()))
      throw std::runtime_error("the calibration could not start: " + fit.message);
    UncertaintyOptions options;
    options.profiles = false;  // a campaign's many runs: the Laplace intervals
    const Uncertainty uncertainty = estimate_uncertainty(problem, fit.final, options);
    run["ok"] = true;
    run["status"] = to_string(fit.status);
    run["iterations"] = fit.iterations;
    run["statistic"] = json_number(uncertainty.statistic);
    run["parameters"] = nlohmann::json::array();
    for (const ParameterUncertainty& pu : uncertainty.parameters)
      run["parameters"].push_back({{"name", pu.name},
                                   {"value", pu.value},
                                   {"standard_error", json_number(pu.standard_error)},
                                   {"scaled_standard_error", json_number(pu.scaled_standard_error)},
                                   {"interval", {json_number(pu.lower), json_number(pu.upper)}}});
  } catch (const std::invalid_argument& e) {
    run["input_error"] = true;
    run["reason"] = e.what();
  } catch (const std::exception& e) {
    run["reason"] = e.what();
  }
  return run;
}

/// A number of a run's JSON: null (written for NaN and infinities) reads as +infinity, which is
/// what a standard error without information is.
double number_of(const nlohmann::json& value) {
  return value.is_number() ? value.get<double>() : INFINITY;
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
nlohmann::json parameter_summary(const Problem& problem, size_t j, const std::vector<nlohmann::json>& runs,
                                 double significance, std::string* text) {
  const ParameterScaling scaling({problem.parameters[j]});
  std::vector<double> values, errors, x, sx;
  for (const nlohmann::json& r : runs) {
    if (!r.value("ok", false)) continue;
    const nlohmann::json& pu = r.at("parameters").at(j);
    values.push_back(pu.at("value").get<double>());
    errors.push_back(number_of(pu.at("standard_error")));
    x.push_back(scaling.to_scaled(Vector::Constant(1, values.back()))[0]);
    sx.push_back(number_of(pu.at("scaled_standard_error")));
  }
  const size_t n = values.size();
  double mean = 0, sd = 0, rms_error = 0;
  for (size_t i = 0; i < n; ++i) mean += values[i] / static_cast<double>(n);
  for (size_t i = 0; i < n; ++i) sd += (values[i] - mean) * (values[i] - mean);
  sd = n > 1 ? std::sqrt(sd / static_cast<double>(n - 1)) : NAN;
  // Over the calibrations that have a standard error: NaN (null) when none has, and then no
  // spread ratio and no test either.
  int finite_errors = 0;
  for (double e : errors)
    if (std::isfinite(e)) {
      rms_error += e * e;
      ++finite_errors;
    }
  rms_error = finite_errors ? std::sqrt(rms_error / finite_errors) : NAN;
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
          {"varies_between_tests", std::isnan(p) ? nlohmann::json() : nlohmann::json(varies)}};
}

/// The runs of the campaign JSON files `merge` (in the order given), checked against the
/// problem's parameters.
std::vector<nlohmann::json> merged_runs(const Problem& problem, const std::vector<std::string>& merge) {
  std::vector<nlohmann::json> runs;
  for (const std::string& file : merge) {
    if (const std::string why = unreadable_input(file, "campaign JSON"); !why.empty())
      throw InputError("campaign --merge: " + why);
    nlohmann::json json;
    try {
      json = nlohmann::json::parse(std::ifstream(file));
    } catch (const nlohmann::json::exception&) {
      throw InputError("campaign --merge " + file + ": not a JSON file (the --json of a campaign)");
    }
    if (!json.is_object() || !json.contains("runs") || !json["runs"].is_array())
      throw InputError("campaign --merge " + file + ": no `runs` list (is it the --json of a campaign?)");
    for (const nlohmann::json& r : json["runs"]) {
      if (!r.is_object() || !r.contains("ok") || !r.contains("data"))
        throw InputError("campaign --merge " + file + ": a run without `data` and `ok`");
      if (r["ok"] == true) {
        const nlohmann::json& ps = r.at("parameters");
        bool same = ps.is_array() && ps.size() == problem.parameters.size();
        for (size_t j = 0; same && j < ps.size(); ++j)
          same = ps[j].value("name", "") == problem.parameters[j].name && ps[j].contains("value") &&
                 ps[j]["value"].is_number() && ps[j].contains("scaled_standard_error");
        if (!same)
          throw InputError("campaign --merge " + file + ": run '" + r["data"].dump().substr(0, 80) +
                           "' calibrated other parameters than the problem's (another problem file?)");
      }
      runs.push_back(r);
    }
  }
  return runs;
}

void print_run(const nlohmann::json& r) {
  if (r["ok"] == true)
    std::printf("%-40s %s after %d iterations, chi-square %.4g\n", r["data"].get<std::string>().c_str(),
                r["status"].get<std::string>().c_str(), r["iterations"].get<int>(), r["statistic"].is_number() ? r["statistic"].get<double>() : NAN);
  else
    std::printf("%-40s FAILED, skipped: %s\n", r["data"].get<std::string>().c_str(),
                r["reason"].get<std::string>().c_str());
  std::fflush(stdout);
}

/// A folder of its own for the runs' files, removed however the campaign ends.
struct TemporaryFolder {
  explicit TemporaryFolder(fs::path p) : path(std::move(p)) { fs::create_directories(path); }
  ~TemporaryFolder() {
    std::error_code ec;
    fs::remove_all(path, ec);
  }
  TemporaryFolder(const TemporaryFolder&) = delete;
  TemporaryFolder& operator=(const TemporaryFolder&) = delete;
  fs::path path;
};

/// Every data set calibrated, across the farm's ranks, in input order.
std::vector<nlohmann::json> calibrate_all(const CampaignArgs& args, const std::vector<std::string>& files,
                                          WorkFarm& farm) {
  if (farm.size() > 1)
    std::printf("%zu data sets across %d MPI ranks, rank 0 handing them out\n", files.size(), farm.size());
  const TemporaryFolder folder(fs::temp_directory_path() / ("modalcal-campaign-" + std::to_string(::getpid())));
  farm.set_threads(threads_for_jobs(args.jobs));
  if (farm.threads() > 1 && files.size() > 1)
    std::printf("%zu data sets, up to %d at a time in threads\n", files.size(), farm.threads());
  // A reason quoting a file's bytes need not be UTF-8: such bytes are written as U+FFFD.
  const auto run_text = [&](size_t k) {
    return calibrate_one(args, files[k], folder.path, static_cast<int>(k))
        .dump(-1, ' ', false, nlohmann::json::error_handler_t::replace);
  };
  const std::vector<std::string> results =
      farm.map(files.size(), run_text, [](size_t, const std::string& r) { print_run(nlohmann::json::parse(r)); });
  std::vector<nlohmann::json> runs;
  for (const std::string& r : results) runs.push_back(nlohmann::json::parse(r));
  return runs;
}

/// The calibrated values of the usable runs as a scatter-plot matrix.
void plot_runs(const std::string& path, const Problem& problem, const std::vector<nlohmann::json>& runs) {
  SampleMatrix m;
  for (const Parameter& p : problem.parameters) {
    m.names.push_back(p.name);
    m.log_scale.push_back(p.scaling == Scaling::Log);
  }
  std::vector<const nlohmann::json*> usable;
  for (const nlohmann::json& r : runs)
    if (r["ok"] == true) usable.push_back(&r);
  m.samples.resize(static_cast<Eigen::Index>(usable.size()), static_cast<Eigen::Index>(m.names.size()));
  for (size_t i = 0; i < usable.size(); ++i)
    for (size_t j = 0; j < m.names.size(); ++j)
      m.samples(static_cast<Eigen::Index>(i), static_cast<Eigen::Index>(j)) =
          (*usable[i])["parameters"][j]["value"].get<double>();
  plot_sample_matrix(path, "campaign: " + std::to_string(usable.size()) + " calibrations", m);
}

int run_campaign(const CampaignArgs& args) {
  WorkFarm& farm = WorkFarm::join();  // first: in an MPI job only rank 0 writes to the standard output
  const Problem problem = load_problem_with_measurements(args.problem);
  require_parameters(problem);
  if (args.data.empty() && args.merge.empty())
    throw InputError("campaign: no measured data sets to calibrate (or --merge the JSON of earlier parts)");
  if (!args.data.empty() && !args.merge.empty())
    throw InputError("campaign: measured data sets and --merge together; calibrate the data sets, then merge");
  const std::vector<std::string> files = data_files(args.data, args.problem);
  std::vector<std::string> inputs = problem.source_files;
  for (const std::string& f : files) inputs.push_back(fs::absolute(f).string());
  for (const std::string& f : args.merge) inputs.push_back(fs::absolute(f).string());
  if (!args.json.empty()) check_output_path(args.json, inputs);
  if (!args.plot.empty()) check_output_path(args.plot, inputs);
  std::vector<nlohmann::json> runs;
  if (args.merge.empty()) {
    runs = calibrate_all(args, files, farm);
  } else {
    runs = merged_runs(problem, args.merge);
    for (const nlohmann::json& r : runs) print_run(r);
  }
  if (!farm.is_root()) return 0;  // rank 0 reports
  const long usable = std::count_if(runs.begin(), runs.end(), [](const nlohmann::json& r) { return r["ok"] == true; });
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
  if (!args.json.empty())
    write_json(args.json, {{"problem", args.problem}, {"runs", runs}, {"summary", summary}}, problem);
  if (!args.plot.empty() && usable > 0) plot_runs(args.plot, problem, runs);
  if (usable > 0) return 0;
  const bool all_input = std::all_of(runs.begin(), runs.end(), [](const nlohmann::json& r) {
    return r.value("input_error", false);
  });
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
      ->check(CLI::ExistingPath);
  cmd->add_option("--merge", args->merge,
                  "instead of data: the --json files of campaigns run in parts (e.g. one per data set, as a batch "
                  "array job); their runs are summarized in the order given")
      ->check(CLI::ExistingFile);
  cmd->add_option("--json", args->json, "write every run and the summary as JSON to this file")->check(OutputFile());
  cmd->add_option("--plot", args->plot,
                  "draw the calibrated values (.png or .svg): each parameter's histogram and every pair's scatter")
      ->check(PlotFile());
  cmd->add_option("--significance", args->significance,
                  "level of the test that a parameter varies between tests (default 0.01)")
      ->check(FiniteRange(1e-6, 0.5));
  cmd->add_option("--jobs", args->jobs,
                  "data sets calibrated at a time, each in a thread (default: one per core; 1: one after another). "
                  "The results do not depend on it. In an MPI job the ranks share the data sets instead")
      ->check(CLI::Range(1, 1024));
  cmd->callback([args, exit_code] { *exit_code = run_campaign(*args); });
}

}  // namespace modalcal::cli
