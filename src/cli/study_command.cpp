// `fullspace_calib study ...`: the report's studies as users run them.
//  - bounds-scaling: L-BFGS with and without bounds and design-variable scaling (report
//    Figures 2-4), histories as CSV and a plot;
//  - starts: calibrations from several starts (report: "an order of magnitude above and below"),
//    the spread of each parameter, and the identifiability analysis that names the parameter the
//    data do not determine.

#include <CLI/CLI.hpp>

#include <cmath>
#include <cstdio>
#include <filesystem>
#include <sstream>

#include "cli/calibration_report.hpp"
#include "cli/cli_common.hpp"
#include "cli/cli_validators.hpp"
#include "cli/commands.hpp"
#include "cli/work_farm.hpp"
#include "modalcal/identifiability.hpp"
#include "modalcal/output.hpp"
#include "cli/plot.hpp"
#include "modalcal/reduced.hpp"
#include "modalcal/problem_file.hpp"

namespace modalcal::cli {

namespace {

struct StudyArgs {
  std::string problem;
  std::string out = "out";
  std::string json;
  double refine = 0;
  int iterations = 25;
  std::vector<double> factors{0.1, 10.0};
  std::string method = "reduced-lbfgs";
};

std::string output_path(const StudyArgs& args, const std::string& name) {
  return (std::filesystem::path(args.out) / name).string();
}

int run_bounds_scaling(const StudyArgs& args) {
  Problem problem = load_problem_with_measurements(args.problem, LoadOptions{args.refine});
  require_parameters(problem);
  create_output_directory("--out", args.out);
  struct Case {
    std::string name;
    bool bounds;
    std::optional<Scaling> scaling;  // unset: the problem file's (log for the LFU)
  };
  const std::vector<Case> cases = {{"no bounds, no scaling", false, Scaling::None},
                                   {"bounds, no scaling", true, Scaling::None},
                                   {"scaling, no bounds", false, std::nullopt},
                                   {"bounds and scaling", true, std::nullopt}};
  std::printf("%s: L-BFGS for %d iterations from the problem's start, four ways\n", problem.path.c_str(),
              args.iterations);
  std::printf("%-24s %6s %8s %12s %14s %14s %12s\n", "case", "iters", "solves", "J/J0", "|pg|/|pg0|",
              "grad. orders", "param error");
  std::ostringstream csv;
  csv << "case,iteration,objective,gradient_norm,relative_objective,relative_gradient,parameter_error\n";
  PlotPanel objective_panel{"objective J / J_0", true, {}}, gradient_panel{"projected gradient |pg| / |pg_0|", true, {}};
  nlohmann::json json = nlohmann::json::array();
  for (const Case& c : cases) {
    Objective objective(problem);
    ReducedOptions options;
    options.max_iterations = args.iterations;
    options.use_bounds = c.bounds;
    options.scaling = c.scaling;
    options.gradient_tolerance = 0;
    options.relative_gradient_tolerance = 0;
    const ReducedSummary s = minimize_reduced(objective, problem.initial_values(), options);
    if (s.history.empty()) {
      std::printf("%-24s failed: %s\n", c.name.c_str(), s.message.c_str());
      continue;
    }
    const double j0 = s.history.front().objective, g0 = s.history.front().gradient_norm;
    double smallest_gradient = g0;
    PlotSeries objective_series{c.name, {}, {}}, gradient_series{c.name, {}, {}};
    for (const IterationRecord& r : s.history) {
      smallest_gradient = std::min(smallest_gradient, r.gradient_norm);
      csv << '"' << c.name << "\"," << r.iteration << ',' << r.objective << ',' << r.gradient_norm << ','
          << r.objective / j0 << ',' << r.gradient_norm / g0 << ',' << r.parameter_error << '\n';
      objective_series.x.push_back(r.iteration);
      objective_series.y.push_back(r.objective / j0);
      gradient_series.x.push_back(r.iteration);
      gradient_series.y.push_back(r.gradient_norm / g0);
    }
    objective_panel.series.push_back(objective_series);
    gradient_panel.series.push_back(gradient_series);
    const IterationRecord& last = s.history.back();
    const double orders = std::log10(g0 / last.gradient_norm);
    std::printf("%-24s %6d %8d %12.3e %14.3e %14.1f %12.3e  %s\n", c.name.c_str(), s.iterations, s.forward_solves,
                last.objective / j0, last.gradient_norm / g0, orders, last.parameter_error,
                to_string(s.status).c_str());
    json.push_back({{"case", c.name}, {"iterations", s.iterations}, {"forward_solves", s.forward_solves},
                    {"relative_objective", last.objective / j0}, {"relative_gradient", last.gradient_norm / g0},
                    {"gradient_orders", orders}, {"parameter_error", last.parameter_error},
                    {"status", to_string(s.status)}});
  }
  const std::string csv_path = output_path(args, "bounds_scaling.csv");
  write_file_atomically(csv_path, csv.str(), problem.source_files);
  const std::string plot_path = output_path(args, "bounds_scaling.png");
  check_output_path(plot_path, problem.source_files);
  plot_panels(plot_path, "L-BFGS with and without bounds and scaling: " + problem.name, "iteration",
              {objective_panel, gradient_panel});
  std::printf("histories: %s\nplot: %s\n", csv_path.c_str(), plot_path.c_str());
  write_json(args.json, {{"problem", problem.path}, {"cases", json}}, problem);
  return 0;
}

/// One start's calibration as it travels between the ranks of an MPI job: its brief report and,
/// when it ended with a result, the report's text and JSON, the calibrated values and objective.
nlohmann::json calibrate_from(const StudyArgs& args, const Problem& problem, double factor) {
  Objective objective(problem);
  ReducedOptions options;
  options.method = parse_method(args.method);
  options.max_iterations = 200;
  const Vector start = (problem.initial_values() * factor).cwiseMax(problem.lower_bounds()).cwiseMin(problem.upper_bounds());
  const ReducedSummary s = minimize_reduced(objective, start, options);
  nlohmann::json result = {{"brief", s.BriefReport()}, {"ok", false}};
  if (s.final.size() != static_cast<Eigen::Index>(problem.parameters.size())) return result;
  CalibrationReport report = make_report(objective, s.initial, s.final);
  report.summary = summary_json(problem, s);
  nlohmann::json run = report.json();
  run["start_factor"] = factor;
  result["ok"] = true;
  result["text"] = report.text;
  result["run"] = run;
  result["final"] = std::vector<double>(s.final.data(), s.final.data() + s.final.size());
  result["objective"] = s.final_objective;
  return result;
}

int run_starts(const StudyArgs& args) {
  WorkFarm& farm = WorkFarm::join();  // in an MPI job, the starts are shared among the ranks
  Problem problem = load_problem_with_measurements(args.problem, LoadOptions{args.refine});
  require_parameters(problem);
  const int n = static_cast<int>(problem.parameters.size());
  std::printf("%s: calibrations from the problem's start times", problem.path.c_str());
  for (double f : args.factors) std::printf(" %g", f);
  std::printf("\n");
  const std::vector<std::string> results = farm.map(
      args.factors.size(), [&](size_t k) { return calibrate_from(args, problem, args.factors[k]).dump(); },
      [&](size_t k, const std::string& text) {
        const nlohmann::json r = nlohmann::json::parse(text);
        std::printf("\nstart x %g: %s\n", args.factors[k], r["brief"].get<std::string>().c_str());
        if (r["ok"] == true) std::fputs(r["text"].get<std::string>().c_str(), stdout);
      });
  if (!farm.is_root()) return 0;  // rank 0 reports
  std::vector<Vector> finals;
  std::vector<double> objectives;
  nlohmann::json runs = nlohmann::json::array();
  int best = -1;
  for (const std::string& text : results) {
    const nlohmann::json r = nlohmann::json::parse(text);
    if (r["ok"] != true) continue;
    const std::vector<double> final = r["final"].get<std::vector<double>>();
    finals.push_back(Eigen::Map<const Vector>(final.data(), static_cast<Eigen::Index>(final.size())));
    objectives.push_back(r["objective"].get<double>());
    if (best < 0 || objectives.back() < objectives[best]) best = static_cast<int>(finals.size()) - 1;
    runs.push_back(r["run"]);
  }
  if (finals.empty()) {
    std::fprintf(stderr, "error: no calibration succeeded\n");
    return 1;
  }
  std::printf("\n%-16s %13s %13s %12s\n", "parameter", "min", "max", "max/min");
  nlohmann::json spread = nlohmann::json::array();
  for (int j = 0; j < n; ++j) {
    double lo = INFINITY, hi = -INFINITY;
    for (const Vector& p : finals) {
      lo = std::min(lo, p[j]);
      hi = std::max(hi, p[j]);
    }
    std::printf("%-16s %13.4e %13.4e %12.4f\n", problem.parameters[j].name.c_str(), lo, hi, hi / lo);
    spread.push_back({{"name", problem.parameters[j].name}, {"min", lo}, {"max", hi}, {"ratio", hi / lo}});
  }
  Objective objective(problem);
  const Identifiability id = analyze_identifiability(objective, finals[best], ParameterScaling(problem.parameters));
  std::printf("\nidentifiability at the best fit (J = %.3e):\n%s", objectives[best], id.report.c_str());
  nlohmann::json flagged = nlohmann::json::array();
  for (int j = 0; j < n; ++j)
    if (id.poorly_identified[j]) flagged.push_back(problem.parameters[j].name);
  write_json(args.json,
             {{"problem", problem.path}, {"runs", runs}, {"spread", spread}, {"poorly_identified", flagged},
              {"singular_values", std::vector<double>(id.singular_values.data(), id.singular_values.data() + n)}},
             problem);
  return 0;
}

}  // namespace

void register_study_command(CLI::App& app, int* exit_code) {
  CLI::App* study = app.add_subcommand("study", "Run a calibration study (several calibrations side by side)");
  study->require_subcommand(1);
  auto common = [](CLI::App* cmd, StudyArgs* args) {
    cmd->add_option("problem", args->problem, "problem file (YAML)")->required()->check(CLI::ExistingFile);
    cmd->add_option("--json", args->json, "write the study's figures as JSON to this file")->check(OutputFile());
    cmd->add_option("--refine", args->refine, "mesh refinement factor")->check(positive_number());
  };
  auto bounds = std::make_shared<StudyArgs>();
  CLI::App* bs = study->add_subcommand("bounds-scaling", "L-BFGS with/without bounds and scaling (report Figures 2-4)");
  common(bs, bounds.get());
  // Only this study writes files besides --json; `starts` has no --out, so that a folder given
  // there is not silently left empty.
  bs->add_option("--out", bounds->out, "directory for CSV and plots (default: out)");
  bs->add_option("--iterations", bounds->iterations, "iterations per run (default 25)")->check(positive_number());
  bs->callback([bounds, exit_code] { *exit_code = run_bounds_scaling(*bounds); });
  auto starts = std::make_shared<StudyArgs>();
  CLI::App* st = study->add_subcommand("starts", "Calibrate from several starts; parameter spread and identifiability");
  common(st, starts.get());
  st->add_option("--factors", starts->factors, "start = initial x factor, for each factor (default 0.1 10)")
      ->check(positive_number());
  st->add_option("--method", starts->method, "reduced-lbfgs (default), reduced-gauss-newton or reduced-newton")
      ->check(CLI::IsMember(method_names()));
  st->callback([starts, exit_code] { *exit_code = run_starts(*starts); });
  register_full_vs_reduced_study(study, exit_code);
}

}  // namespace modalcal::cli
