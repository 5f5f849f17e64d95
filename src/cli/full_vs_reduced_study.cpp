// `fullspace_calib study full-vs-reduced PROBLEM`: full space, reduced L-BFGS and reduced Newton
// from the problem's start and from N random starts p0 = p_true 10^U(-1.5, 0.5) (within bounds).
// Every calibration runs in a child process (this program's `calibrate`), so that its peak memory
// is its own and a crash or an exhausted memory in one run does not end the study.

#include <CLI/CLI.hpp>
#include <sys/resource.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <map>
#include <string>
#include <vector>

#include "cli/cli_common.hpp"
#include "cli/cli_validators.hpp"
#include "cli/commands.hpp"
#include "cli/work_farm.hpp"
#include "modalcal/fullspace.hpp"
#include "modalcal/output.hpp"
#include "cli/plot.hpp"
#include "modalcal/reduced.hpp"
#include "modalcal/problem_file.hpp"
#include "support/random_draws.hpp"

namespace modalcal::cli {

namespace {

struct FullVsReducedArgs {
  std::string problem;
  std::string out = "out";
  std::string json;
  double refine = 0;
  int starts = 10;
  int jobs = 1;  // runs at a time
  unsigned seed = 1;
  double success_tolerance = 1e-4;
  std::vector<std::string> methods{"fullspace", "reduced-lbfgs", "reduced-newton"};
};

struct Run {
  bool ok = false;        // the child reported back
  bool success = false;   // right modes and parameters within the tolerance
  std::string status;
  int iterations = 0, extra_iterations = 0, forward_solves = 0, kkt_solves = 0;
  double seconds = 0, peak_mb = 0, order = NAN, error = NAN;
  std::vector<double> objective, gradient;  // history, for the plot
};

double median(std::vector<double> v) {
  v.erase(std::remove_if(v.begin(), v.end(), [](double x) { return !std::isfinite(x); }), v.end());
  if (v.empty()) return NAN;
  std::sort(v.begin(), v.end());
  return v.size() % 2 ? v[v.size() / 2] : 0.5 * (v[v.size() / 2 - 1] + v[v.size() / 2]);
}

bool is_fullspace(const std::string& method) { return method.rfind("fullspace", 0) == 0; }

// One calibration in a child process: this program's own `calibrate` (a fork alone is not
// safe once BLAS or OpenMP threads exist), started here and read back by read_report.
pid_t start_isolated(const FullVsReducedArgs& args, const Problem& problem, const std::string& method,
                     const Vector& start, const std::string& report_path) {
  // Variants of the full-space method without its safeguards, to measure what each one buys, and
  // with the other Newton solver.
  std::vector<std::string> argv_strings = {"/proc/self/exe", "calibrate", args.problem, "--method",
                                           is_fullspace(method) ? "fullspace" : method, "--quiet", "--json", report_path,
                                           "--max-iterations", "300"};
  if (method == "fullspace-unguarded" || method == "fullspace-naive") argv_strings.push_back("--no-guard");
  if (method == "fullspace-no-globalization" || method == "fullspace-naive") {
    argv_strings.push_back("--globalization");
    argv_strings.push_back("0");
  }
  if (method == "fullspace-relative-globalization" || method == "fullspace-plain-globalization") {
    argv_strings.push_back("--globalization-misfit");
    argv_strings.push_back("relative");
  }
  if (method == "fullspace-no-eigenvalues-first" || method == "fullspace-plain-globalization")
    argv_strings.push_back("--no-eigenvalues-first");
  if (method == "fullspace-block") {
    argv_strings.push_back("--newton-solver");
    argv_strings.push_back("block");
  }
  if (args.refine > 0) {
    argv_strings.push_back("--refine");
    argv_strings.push_back(std::to_string(args.refine));
  }
  for (size_t j = 0; j < problem.parameters.size(); ++j) {
    char value[64];
    std::snprintf(value, sizeof value, "%.17g", start[j]);
    argv_strings.push_back("--set");
    argv_strings.push_back(problem.parameters[j].name + "=" + value);
  }
  std::vector<char*> argv;
  for (std::string& a : argv_strings) argv.push_back(a.data());
  argv.push_back(nullptr);
  std::filesystem::remove(report_path);
  std::fflush(stdout);
  const pid_t pid = fork();
  if (pid < 0) throw std::runtime_error("fork() failed");
  if (pid == 0) {
    if (!freopen("/dev/null", "w", stdout)) _exit(127);
    // Parallel runs share the cores: one BLAS thread each, unless the user chose otherwise.
    if (args.jobs > 1) setenv("OPENBLAS_NUM_THREADS", "1", 0);
    execv(argv[0], argv.data());
    _exit(127);
  }
  return pid;
}

// The finished child's report, judged against the truth.
Run read_report(const FullVsReducedArgs& args, const Problem& problem, const std::string& method,
                const std::string& report_path, int status, const struct rusage& usage) {
  Run run;
  run.peak_mb = usage.ru_maxrss / 1024.0;
  if (!std::filesystem::exists(report_path)) {
    run.status = WIFSIGNALED(status) ? "killed by signal " + std::to_string(WTERMSIG(status))
                                     : "no report (exit " + std::to_string(WEXITSTATUS(status)) + ")";
    return run;
  }
  std::ifstream in(report_path);
  const nlohmann::json j = nlohmann::json::parse(in);
  in.close();
  std::filesystem::remove(report_path);
  const Vector truth = problem.truth_values();
  double error = 0;
  for (size_t k = 0; k < problem.parameters.size(); ++k) {
    const nlohmann::json& value = j["parameters"][k]["final"];
    error = std::max(error, value.is_null() ? INFINITY : std::abs(value.get<double>() / truth[k] - 1));
  }
  run.ok = true;
  run.status = j.value("status", "?");
  run.error = error;
  run.iterations = j.value("iterations", 0);
  run.extra_iterations = j.value("globalization_iterations", 0);
  run.forward_solves = j.value("forward_solves", 0);
  run.kkt_solves = j.value("kkt_solves", 0);
  run.seconds = j.value("time_s", 0.0);
  for (const nlohmann::json& h : j["history"]) {
    run.objective.push_back(h["objective"]);
    run.gradient.push_back(h["gradient_norm"]);
  }
  run.order = j["convergence_order"].is_null() ? NAN : j["convergence_order"].get<double>();
  if (is_fullspace(method)) {
    // Reduced evaluations pair a forward solve each, so their modes are right by construction;
    // the full space must pass its final mode check.
    run.success = j["mode_check"]["passed"].get<bool>() && error <= args.success_tolerance;
  } else {
    run.success = error <= args.success_tolerance;
  }
  return run;
}

// The problem's start and `args.starts` random ones, p_true 10^U(-1.5, 0.5) within the bounds.
std::vector<Vector> study_starts(const FullVsReducedArgs& args, const Problem& problem) {
  const Vector truth = problem.truth_values(), lower = problem.lower_bounds(), upper = problem.upper_bounds();
  std::vector<Vector> starts{problem.initial_values()};
  detail::Uniform exponent(args.seed);  // the same starts for a seed on every platform
  for (int s = 0; s < args.starts; ++s) {
    Vector p(truth.size());
    for (int j = 0; j < p.size(); ++j) p[j] = truth[j] * std::pow(10.0, exponent(-1.5, 0.5));
    starts.push_back(p.cwiseMax(lower).cwiseMin(upper));
  }
  return starts;
}

struct Task {
  size_t start, method;
  std::string report;
};

void print_run(const FullVsReducedArgs& args, const Task& t, const Run& r) {
  std::printf("start %2zu %-15s %-9s %-20s its %3d+%-3d error %.2e  %.2f s  %.0f MB\n", t.start,
              args.methods[t.method].c_str(), r.success ? "success" : "failure", r.status.c_str(), r.extra_iterations,
              r.iterations, r.error, r.seconds, r.peak_mb);
  std::fflush(stdout);
}

// A run as it travels between the ranks of an MPI job (WorkFarm), and back.
std::string run_text(const Run& r) {
  nlohmann::json j = {{"ok", r.ok},
                      {"success", r.success},
                      {"status", r.status},
                      {"numbers", {r.iterations, r.extra_iterations, r.forward_solves, r.kkt_solves}},
                      {"seconds", r.seconds},
                      {"peak_mb", r.peak_mb},
                      {"order", json_number(r.order)},
                      {"error", json_number(r.error)},
                      {"objective", r.objective},
                      {"gradient", r.gradient}};
  return j.dump();
}
Run run_of(const std::string& text) {
  const nlohmann::json j = nlohmann::json::parse(text);
  Run r;
  r.ok = j["ok"];
  r.success = j["success"];
  r.status = j["status"];
  r.iterations = j["numbers"][0];
  r.extra_iterations = j["numbers"][1];
  r.forward_solves = j["numbers"][2];
  r.kkt_solves = j["numbers"][3];
  r.seconds = j["seconds"];
  r.peak_mb = j["peak_mb"];
  r.order = j["order"].is_number() ? j["order"].get<double>() : NAN;
  r.error = j["error"].is_number() ? j["error"].get<double>() : INFINITY;
  r.objective = j["objective"].get<std::vector<double>>();
  r.gradient = j["gradient"].get<std::vector<double>>();
  return r;
}

// Every (start, method) run of an MPI job's share: one child at a time on each rank.
std::vector<std::vector<Run>> run_across_ranks(const FullVsReducedArgs& args, const Problem& problem,
                                               const std::vector<Vector>& starts, const std::vector<Task>& tasks) {
  const std::vector<std::string> results = WorkFarm::join().map(
      tasks.size(),
      [&](size_t k) {
        const Task& t = tasks[k];
        const pid_t pid = start_isolated(args, problem, args.methods[t.method], starts[t.start], t.report);
        int status = 0;
        struct rusage usage {};
        if (wait4(pid, &status, 0, &usage) < 0) throw std::runtime_error("wait4() failed while a study run was going");
        return run_text(read_report(args, problem, args.methods[t.method], t.report, status, usage));
      },
      [&](size_t k, const std::string& text) { print_run(args, tasks[k], run_of(text)); });
  std::vector<std::vector<Run>> runs(args.methods.size(), std::vector<Run>(starts.size()));
  for (size_t k = 0; k < tasks.size(); ++k) runs[tasks[k].method][tasks[k].start] = run_of(results[k]);
  return runs;
}

// Every (start, method) run, up to `jobs` at a time (or across the ranks of an MPI job), each
// child with its own report file; runs[method][start], printed as they finish.
std::vector<std::vector<Run>> run_all(const FullVsReducedArgs& args, const Problem& problem,
                                      const std::vector<Vector>& starts) {
  std::vector<Task> tasks;
  for (size_t s = 0; s < starts.size(); ++s)
    for (size_t m = 0; m < args.methods.size(); ++m) {
      tasks.push_back({s, m,
                       (std::filesystem::path(args.out) /
                        ("full_vs_reduced_run_" + std::to_string(s) + "_" + std::to_string(m) + ".json"))
                           .string()});
      check_not_input(tasks.back().report, problem.source_files);  // each is removed before its run
    }
  if (WorkFarm::join().size() > 1) return run_across_ranks(args, problem, starts, tasks);
  std::vector<std::vector<Run>> runs(args.methods.size(), std::vector<Run>(starts.size()));
  std::map<pid_t, size_t> running;  // child -> task
  size_t next = 0;
  while (next < tasks.size() || !running.empty()) {
    while (next < tasks.size() && static_cast<int>(running.size()) < args.jobs) {
      const Task& t = tasks[next];
      const pid_t pid = start_isolated(args, problem, args.methods[t.method], starts[t.start], t.report);
      running[pid] = next++;
    }
    int status = 0;
    struct rusage usage {};
    const pid_t pid = wait4(-1, &status, 0, &usage);
    if (pid < 0) throw std::runtime_error("wait4() failed while the study's runs were going");
    const auto child = running.find(pid);
    if (child == running.end()) continue;
    const Task& t = tasks[child->second];
    running.erase(child);
    const Run r = read_report(args, problem, args.methods[t.method], t.report, status, usage);
    runs[t.method][t.start] = r;
    print_run(args, t, r);
  }
  return runs;
}

nlohmann::json runs_json(const FullVsReducedArgs& args, const std::vector<Vector>& starts,
                         const std::vector<std::vector<Run>>& runs) {
  nlohmann::json json_runs = nlohmann::json::array();
  for (size_t s = 0; s < starts.size(); ++s)
    for (size_t m = 0; m < args.methods.size(); ++m) {
      const Run& r = runs[m][s];
      const Vector& p = starts[s];
      nlohmann::json j = {{"start", s},           {"method", args.methods[m]}, {"success", r.success},
                          {"status", r.status},   {"iterations", r.iterations},
                          {"globalization_iterations", r.extra_iterations},
                          {"forward_solves", r.forward_solves}, {"kkt_solves", r.kkt_solves},
                          {"seconds", r.seconds}, {"peak_mb", r.peak_mb},
                          {"start_parameters", std::vector<double>(p.data(), p.data() + p.size())}};
      j["order"] = json_number(r.order);
      j["parameter_error"] = json_number(r.error);
      json_runs.push_back(j);
    }
  return json_runs;
}

// A history's positive values against their index, for a log-scale plot.
PlotSeries positive_series(const std::string& title, const std::vector<double>& values) {
  PlotSeries series{title, {}, {}};
  for (size_t k = 0; k < values.size(); ++k)
    if (values[k] > 0) {
      series.x.push_back(static_cast<double>(k));
      series.y.push_back(values[k]);
    }
  return series;
}

// Prints the per-method table, plots the histories from the problem's start together and
// returns the per-method summary for the JSON.
nlohmann::json summarize(const FullVsReducedArgs& args, const Problem& problem,
                         const std::vector<std::vector<Run>>& runs) {
  std::printf("\n%-15s %9s %12s %12s %8s %8s %10s %10s %9s %7s\n", "method", "successes", "iterations",
              "(+global.)", "solves", "KKT", "median s", "total s", "peak MB", "order");
  nlohmann::json summary = nlohmann::json::object();
  PlotPanel objective_panel{"objective J", true, {}}, gradient_panel{"|projected gradient| or dual infeasibility", true, {}};
  for (size_t m = 0; m < args.methods.size(); ++m) {
    int successes = 0;
    std::vector<double> iterations, extra, solves, kkt, seconds, orders;
    double peak = 0, total = 0;
    for (const Run& r : runs[m]) {
      successes += r.success;
      peak = std::max(peak, r.peak_mb);
      total += r.seconds;
      if (!r.ok) continue;
      iterations.push_back(r.iterations);
      extra.push_back(r.extra_iterations);
      solves.push_back(r.forward_solves);
      kkt.push_back(r.kkt_solves);
      seconds.push_back(r.seconds);
      if (r.success) orders.push_back(r.order);
    }
    std::printf("%-15s %4d/%-4zu %12.1f %12.1f %8.1f %8.1f %10.2f %10.1f %9.0f %7.2f\n", args.methods[m].c_str(),
                successes, runs[m].size(), median(iterations), median(extra), median(solves), median(kkt),
                median(seconds), total, peak, median(orders));
    summary[args.methods[m]] = {{"successes", successes},           {"runs", runs[m].size()},
                                {"median_iterations", json_number(median(iterations))},
                                {"median_globalization_iterations", json_number(median(extra))},
                                {"median_forward_solves", json_number(median(solves))},
                                {"median_kkt_solves", json_number(median(kkt))},
                                {"median_seconds", json_number(median(seconds))}, {"total_seconds", total},
                                {"peak_mb", peak},                  {"median_order", json_number(median(orders))}};
    objective_panel.series.push_back(positive_series(args.methods[m], runs[m].front().objective));
    gradient_panel.series.push_back(positive_series(args.methods[m], runs[m].front().gradient));
  }
  std::printf("success: right modes and every parameter within %.0e of the truth; iterations: Ipopt's for "
              "fullspace (+ its reduced globalization), medians over the runs\n",
              args.success_tolerance);
  if (WorkFarm::join().size() > 1)
    std::printf("%d MPI ranks, rank 0 handing out the runs: the times include waiting for shared cores\n",
                WorkFarm::join().size());
  else if (args.jobs > 1)
    std::printf("%d runs at a time: the times include waiting for the shared cores\n", args.jobs);
  const std::string plot_path = (std::filesystem::path(args.out) / "full_vs_reduced.png").string();
  try {
    plot_panels(plot_path, "Convergence from the problem's start: " + problem.name, "iteration",
                {objective_panel, gradient_panel});
    std::printf("plot: %s\n", plot_path.c_str());
  } catch (const std::exception& e) {
    std::fprintf(stderr, "warning: no plot: %s\n", e.what());
  }
  return summary;
}

int run_full_vs_reduced(const FullVsReducedArgs& args) {
  const WorkFarm& farm = WorkFarm::join();  // in an MPI job, the runs are shared among the ranks
  const Problem problem = load_problem_with_measurements(args.problem, LoadOptions{args.refine});
  require_parameters(problem);
  if (!problem.has_truth())
    throw InputError(problem.path + ": full-vs-reduced needs a truth value for every parameter (a synthetic problem)");
  create_output_directory("--out", args.out);
  const std::vector<Vector> starts = study_starts(args, problem);
  std::printf("%s: %zu starts (the problem's and %d random, seed %u), methods:", problem.path.c_str(), starts.size(),
              args.starts, args.seed);
  for (const std::string& m : args.methods) std::printf(" %s", m.c_str());
  std::printf("\n");
  const std::vector<std::vector<Run>> runs = run_all(args, problem, starts);
  if (!farm.is_root()) return 0;  // rank 0 reports
  const nlohmann::json summary = summarize(args, problem, runs);
  write_json(args.json,
             {{"problem", problem.path}, {"seed", args.seed}, {"methods", summary}, {"runs", runs_json(args, starts, runs)}},
             problem);
  return 0;
}

}  // namespace

void register_full_vs_reduced_study(CLI::App* study, int* exit_code) {
  auto args = std::make_shared<FullVsReducedArgs>();
  CLI::App* cmd = study->add_subcommand(
      "full-vs-reduced", "Full space, reduced L-BFGS and reduced Newton from the start and from random starts");
  cmd->add_option("problem", args->problem, "problem file (YAML) with the truth of every parameter")
      ->required()
      ->check(CLI::ExistingFile);
  // Every start is drawn (and each run's report named) before the first run: a cap keeps a typo
  // such as 1000000000 from allocating them all.
  cmd->add_option("--starts", args->starts, "random starts p_true 10^U(-1.5, 0.5) (default 10, at most 10000)")
      ->check(CLI::Range(0, 10000));
  cmd->add_option("--seed", args->seed, "random seed (default 1)");
  std::vector<std::string> names = calibration_method_names();
  for (const char* variant :
       {"fullspace-unguarded", "fullspace-no-globalization", "fullspace-naive", "fullspace-relative-globalization",
        "fullspace-no-eigenvalues-first", "fullspace-plain-globalization", "fullspace-block"})
    names.push_back(variant);
  cmd->add_option("--methods", args->methods,
                  "any of: fullspace reduced-lbfgs reduced-newton reduced-gauss-newton, and the full-space "
                  "variants without a safeguard: fullspace-unguarded, fullspace-no-globalization, fullspace-naive "
                  "(neither), fullspace-relative-globalization (globalization on the relative eigenvalue misfit), "
                  "fullspace-no-eigenvalues-first (globalization on the whole objective from the start) and "
                  "fullspace-plain-globalization (both); and fullspace-block, every safeguard with the block-"
                  "elimination Newton solver (--newton-solver block); default: the first three")
      ->check(CLI::IsMember(names));
  cmd->add_option("--success-tolerance", args->success_tolerance, "largest parameter error of a success (default 1e-4)")
      ->check(positive_number());
  cmd->add_option("--out", args->out, "directory for the plot (default: out)");
  cmd->add_option("--json", args->json, "write the study as JSON to this file")->check(OutputFile());
  cmd->add_option("--refine", args->refine, "mesh refinement factor")->check(positive_number());
  cmd->add_option("--jobs", args->jobs,
                  "runs at a time, each with one BLAS thread (default 1); successes and counts are unchanged, "
                  "times then include waiting for the cores")
      ->check(positive_number());
  cmd->callback([args, exit_code] { *exit_code = run_full_vs_reduced(*args); });
}

}  // namespace modalcal::cli
