// Full-space calibration (minimize_fullspace: Newton on modes, eigenvalues and parameters at
// once: Ipopt on the structured KKT solver, Ipopt with MUMPS on the whole KKT matrix, or the
// block-elimination SQP) against reduced-space projected L-BFGS
// (minimize_reduced), side by side in one run, on the LFU synthetic problem at several mesh sizes.
//
// Problem: problems/lfu/synthetic.yaml (five parameters, log scaling, bounds, noise-free modes
// with shapes synthesized from the truth on the same mesh) with only the first --modes measured
// modes kept. Both methods start from truth x --start-factor (clamped to the bounds). The default
// 0.7 is a start near enough that both converge to the truth on the paired modes; the report's
// 10x-low start is a globalization study, not a cost study.
//
// Each (size, method) runs in a forked child so that its peak memory (max RSS) is its own and a
// case that runs too long or too big can be stopped without stopping the run: the child is
// killed by alarm() after --max-seconds (reported as "timeout"), and by the parent once its
// resident memory exceeds --max-memory-mb (reported as "memory limit"; the parent polls it every
// 0.1 s). The parent prints what it got and goes on: the child fills its result in memory
// shared with the parent as it goes, so a killed case still shows what it reached (iterations so
// far, for full space as "k+?" with s/it measured between its first and last Ipopt iteration,
// and the last iterate's parameter error in "final err"). (An address-space limit, RLIMIT_AS, does
// not work as a memory limit here: MUMPS as called by Ipopt asks for ~10x its estimated
// workspace up front, and at 31k DOFs that 2.5 GB request failed under a 14 GB RLIMIT_AS while
// the resident peak was 1.6 GB.)
//
// Same final accuracy. Full space runs with FullSpaceOptions defaults (scaled KKT tolerance
// 1e-10); reduced L-BFGS with ReducedOptions defaults (projected gradient 1e-10 in the scaled
// variables, relative 1e-12) but a higher iteration cap (--reduced-max-iterations), so that both
// stop on a converged optimum. Their final max relative parameter errors |p/p_true - 1| are
// printed, and because a gradient tolerance and a KKT tolerance are not the same accuracy, also
// the time each method took to first reach a common parameter error (--target-error, 1e-8): the
// second ratio compares time to the same accuracy.
//
// Columns: iterations are L-BFGS iterations, or for full space Ipopt iterations + reduced L-BFGS
// globalization iterations; "fwd" forward modal solves (full space: globalization, start, one per
// Ipopt iteration for the mode guard, final check); "KKT" Newton systems Ipopt assembled (Hessian
// evaluations); "s/it" = ipopt_seconds / Ipopt iterations, including the guard's forward solve
// (guard s is its total); "out s" the full-space time outside Ipopt (globalization, start,
// final check); "peak MB" the child's max RSS, "setup MB" its max RSS before the method started
// (problem load with the synthesis of the measured modes, identical for both methods); "cpu s"
// the method's user + system CPU time over all threads, which, unlike the wall time, other
// processes on a shared machine barely change (the load average is printed at start and end).
//
// Where the time goes inside Ipopt: --ipopt-print-level 5 prints Ipopt's iteration table (the
// lg(rg) column shows inertia corrections: a Hessian regularization and refactorization) and at
// the end "Total CPU secs in IPOPT (w/o function evaluations)" (mostly the MUMPS factorizations)
// against "Total CPU secs in NLP function evaluations" (Jacobian/Hessian assembly). Ipopt reads
// ./ipopt.opt when it starts, so running in a directory with an ipopt.opt containing
// "print_timing_statistics yes" adds the per-component breakdown (LinearSystemFactorization,
// symbolic factorization, back solves, function evaluations).
//
// Measured results, each with its date, commit and command line: docs/benchmarks.md.
//
// Usage: fullspace_benchmark --help

#include <sys/mman.h>
#include <sys/resource.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <csignal>
#include <cstdio>
#include <cstring>
#include <fstream>
#include <iostream>
#include <map>
#include <new>
#include <nlohmann/json.hpp>
#include <string>
#include <vector>

#include "bench_util.hpp"
#include "modalcal/assembly.hpp"
#include "modalcal/fullspace.hpp"
#include "modalcal/objective.hpp"
#include "modalcal/output.hpp"
#include "modalcal/problem.hpp"
#include "modalcal/reduced.hpp"
#include "modalcal/problem_file.hpp"
#include "modalcal/synthesis.hpp"

using namespace modalcal;
using modalcal::bench::parse_list;
using modalcal::bench::split_list;
using modalcal::bench::load_average;
using modalcal::bench::seconds_since;
using Clock = modalcal::bench::Clock;

namespace {


// VmRSS of a process from /proc, in kB (0 if it cannot be read).
long resident_kb(pid_t pid) {
  std::ifstream in("/proc/" + std::to_string(pid) + "/status");
  std::string line;
  while (std::getline(in, line))
    if (line.rfind("VmRSS:", 0) == 0) return std::atol(line.c_str() + 6);
  return 0;
}

// User + system CPU seconds of this process, all threads.
double cpu_seconds() {
  struct rusage usage;
  getrusage(RUSAGE_SELF, &usage);
  auto seconds = [](const timeval& t) { return t.tv_sec + 1e-6 * t.tv_usec; };
  return seconds(usage.ru_utime) + seconds(usage.ru_stime);
}

long max_rss_kb() {
  struct rusage usage;
  getrusage(RUSAGE_SELF, &usage);
  return usage.ru_maxrss;
}

// FullSpace: Ipopt on the structured KKT solver (the default); FullSpaceMumps: Ipopt with MUMPS
// on the whole KKT matrix; FullSpaceBlock: the block SQP.
// FullSpace and FullSpaceBlock use the default bordered solves (FullSpaceOptions::BorderedSolves::
// Automatic: shared from its DOF threshold on); *PerMode and *Shared force one factorization per
// mode or one shared by all modes.
enum class Method {
  Reduced, FullSpace, FullSpaceMumps, FullSpaceBlock,
  FullSpacePerMode, FullSpaceBlockPerMode, FullSpaceShared, FullSpaceBlockShared
};
struct MethodInfo {
  Method method;
  const char* token;  // in --methods
  const char* name;   // in the table and the JSON
};
constexpr MethodInfo kMethods[] = {
    {Method::Reduced, "reduced", "reduced L-BFGS"},
    {Method::FullSpace, "fullspace", "full (Ipopt, structured)"},
    {Method::FullSpaceMumps, "mumps", "full (Ipopt, MUMPS)"},
    {Method::FullSpaceBlock, "block", "full (block SQP)"},
    {Method::FullSpacePerMode, "fullspace-per-mode", "full (Ipopt, per-mode)"},
    {Method::FullSpaceBlockPerMode, "block-per-mode", "full (block, per-mode)"},
    {Method::FullSpaceShared, "fullspace-shared", "full (Ipopt, shared)"},
    {Method::FullSpaceBlockShared, "block-shared", "full (block, shared)"},
};
const char* method_name(Method m) {
  for (const MethodInfo& info : kMethods)
    if (info.method == m) return info.name;
  return "?";
}
bool is_block_sqp(Method m) {
  return m == Method::FullSpaceBlock || m == Method::FullSpaceBlockPerMode || m == Method::FullSpaceBlockShared;
}
FullSpaceOptions::BorderedSolves bordered_solves(Method m) {
  if (m == Method::FullSpacePerMode || m == Method::FullSpaceBlockPerMode) return FullSpaceOptions::BorderedSolves::PerMode;
  if (m == Method::FullSpaceShared || m == Method::FullSpaceBlockShared) return FullSpaceOptions::BorderedSolves::Shared;
  return FullSpaceOptions::BorderedSolves::Automatic;
}

struct Settings {
  std::string problem_path, mesh_problem_path;
  int modes = 4;
  double start_factor = 0.7;
  double target_error = 1e-8;
  int reduced_max_iterations = 1000;
  double globalization_reduction = FullSpaceOptions().globalization_reduction;
  double mu_init = FullSpaceOptions().mu_init;
  int ipopt_print_level = 0;
  double max_seconds = 900;
  double max_memory_mb = 0;
};

// Plain data in memory shared with the child, which fills it in as it goes: a child that is
// killed leaves what it had reached (setup, iterations so far, last parameter error).
struct CaseResult {
  bool ran = false;                // the child finished (converged or not)
  bool ok = false;                 // the method converged (full space: mode check passed too)
  char status[96] = "";
  char bordered[16] = "";          // FullSpaceSummary::bordered_solves
  int shared_eliminations = 0, shared_failures = 0;
  int dofs = 0, modes = 0;
  int iterations = 0, globalization_iterations = 0, restarts = 0;
  int forward_solves = 0, kkt_solves = 0;
  int unknowns = 0, constraints = 0;
  double setup_s = 0, seconds = 0, cpu_s = 0, ipopt_s = 0, guard_s = 0;
  double time_to_target = NAN;     // first iterate with parameter error <= target
  double start_error = NAN, final_error = NAN, final_objective = NAN;
  double convergence_order = NAN;
  long setup_kb = 0;
  int kkt_records = 0;             // Ipopt iteration callbacks so far (iteration 0 included)
  double first_kkt_s = NAN;        // time of the first one
  // Set by the parent.
  long peak_kb = 0;
  bool timed_out = false;
  int signal = 0;
};

void set_status(CaseResult* r, const std::string& s) {
  std::snprintf(r->status, sizeof r->status, "%s", s.c_str());
}

double parameter_error(const Problem& problem, const Vector& p) {
  return (p.array() / problem.truth_values().array() - 1).abs().maxCoeff();
}

// Runs in the child, filling in r (shared with the parent) as it goes.
void run_case(const Settings& s, double refinement, Method method, CaseResult& r) {
  const auto setup_start = Clock::now();
  Problem problem = load_problem(s.problem_path, LoadOptions{refinement});
  synthesize_measured(&problem);
  if (!problem.has_truth()) throw std::invalid_argument(s.problem_path + ": the benchmark needs truth values");
  if (static_cast<int>(problem.measured.size()) < s.modes)
    throw std::invalid_argument(s.problem_path + " has only " + std::to_string(problem.measured.size()) +
                                " measured modes");
  // Fewer measured modes; the forward solve still computes problem.options.num_modes (+ extra)
  // model modes, which MAC pairing needs.
  problem.measured.resize(s.modes);
  r.modes = s.modes;
  Vector p0 = s.start_factor * problem.truth_values();
  p0 = p0.cwiseMax(problem.lower_bounds()).cwiseMin(problem.upper_bounds());
  r.start_error = parameter_error(problem, p0);
  Objective objective(problem);
  r.dofs = ParametricSystem(problem.model, problem.parameter_targets()).num_dofs();
  r.setup_s = seconds_since(setup_start);
  r.setup_kb = max_rss_kb();

  Clock::time_point t0;
  double cpu0 = 0;
  auto note = [&](double error) {
    if (std::isnan(r.time_to_target) && error <= s.target_error) r.time_to_target = seconds_since(t0);
  };
  if (method == Method::Reduced) {
    ReducedOptions o;
    o.max_iterations = s.reduced_max_iterations;
    o.progress = [&](const IterationRecord& record) {
      note(record.parameter_error);
      r.iterations = record.iteration;
      r.forward_solves = record.forward_solves;
      r.final_error = record.parameter_error;
    };
    t0 = Clock::now();
    cpu0 = cpu_seconds();
    const ReducedSummary summary = minimize_reduced(objective, p0, o);
    r.seconds = seconds_since(t0);
    r.cpu_s = cpu_seconds() - cpu0;
    r.ok = summary.converged();
    set_status(&r, to_string(summary.status));
    r.iterations = summary.iterations;
    r.forward_solves = summary.forward_solves;
    if (summary.final.size()) r.final_error = parameter_error(problem, summary.final);
    r.final_objective = summary.final_objective;
  } else {
    FullSpaceOptions o;
    o.globalization_reduction = s.globalization_reduction;
    o.mu_init = s.mu_init;
    o.print_level = s.ipopt_print_level;
    if (is_block_sqp(method)) o.newton_solver = FullSpaceOptions::NewtonSolver::BlockElimination;
    o.bordered_solves = bordered_solves(method);
    if (method == Method::FullSpaceMumps) o.kkt_solver = FullSpaceOptions::KktSolver::Mumps;
    o.progress = [&](const KktRecord& record) {
      note(record.parameter_error);
      // For a killed run: Ipopt iterations and their time so far (guard included).
      const double t = seconds_since(t0);
      if (r.kkt_records++ == 0) r.first_kkt_s = t;
      r.iterations = record.iteration;
      r.ipopt_s = t - r.first_kkt_s;
      r.final_error = record.parameter_error;
    };
    t0 = Clock::now();
    cpu0 = cpu_seconds();
    const FullSpaceSummary summary = minimize_fullspace(objective, p0, o);
    r.seconds = seconds_since(t0);
    r.cpu_s = cpu_seconds() - cpu0;
    r.ok = summary.converged();
    set_status(&r, to_string(summary.status));
    r.iterations = summary.iterations;
    r.globalization_iterations = summary.globalization_iterations;
    r.restarts = summary.restarts;
    r.forward_solves = summary.forward_solves;
    r.kkt_solves = summary.kkt_solves;
    std::snprintf(r.bordered, sizeof r.bordered, "%s", summary.bordered_solves.c_str());
    r.shared_eliminations = summary.shared_eliminations;
    r.shared_failures = summary.shared_failures;
    r.unknowns = summary.num_unknowns;
    r.constraints = summary.num_constraints;
    r.ipopt_s = summary.newton_seconds;
    r.guard_s = summary.guard_seconds;
    r.convergence_order = summary.convergence_order;
    if (summary.final.size()) r.final_error = parameter_error(problem, summary.final);
    r.final_objective = summary.final_objective;
    if (!r.ok && !summary.message.empty()) std::fprintf(stderr, "full space: %s\n", summary.message.c_str());
  }
}

CaseResult run_in_child(const Settings& s, double refinement, Method method) {
  void* shared = mmap(nullptr, sizeof(CaseResult), PROT_READ | PROT_WRITE, MAP_SHARED | MAP_ANONYMOUS, -1, 0);
  if (shared == MAP_FAILED) throw std::runtime_error("mmap failed");
  CaseResult* result = new (shared) CaseResult();
  std::fflush(stdout);
  std::fflush(stderr);
  const pid_t pid = fork();
  if (pid < 0) throw std::runtime_error("fork failed");
  if (pid == 0) {
    // The default action of SIGALRM ends the process; the parent sees the signal.
    signal(SIGALRM, SIG_DFL);
    alarm(static_cast<unsigned>(std::ceil(s.max_seconds)));
    try {
      run_case(s, refinement, method, *result);
    } catch (const std::exception& e) {
      std::fprintf(stderr, "%s case failed: %s\n", method_name(method), e.what());
      set_status(result, std::string("failed: ") + e.what());
    }
    result->ran = true;
    std::cout.flush();
    std::fflush(stdout);
    std::fflush(stderr);
    _exit(0);
  }
  // Wait, watching the child's resident memory.
  int status = 0;
  struct rusage usage;
  bool over_memory = false;
  for (;;) {
    const pid_t done = wait4(pid, &status, WNOHANG, &usage);
    if (done == pid) break;
    if (done < 0) throw std::runtime_error("wait4 failed");
    if (s.max_memory_mb > 0 && !over_memory && resident_kb(pid) > s.max_memory_mb * 1024) {
      over_memory = true;
      kill(pid, SIGKILL);
    }
    usleep(100000);
  }
  CaseResult r = *result;
  munmap(shared, sizeof(CaseResult));
  if (!r.ran) {
    // What it reached stays (see CaseResult); the totals are unknown.
    r.seconds = r.cpu_s = NAN;
    if (method != Method::Reduced) r.globalization_iterations = -1;
    if (over_memory) {
      set_status(&r, "memory limit");
    } else if (WIFSIGNALED(status)) {
      r.signal = WTERMSIG(status);
      r.timed_out = r.signal == SIGALRM;
      set_status(&r, r.timed_out ? "timeout" : std::string("killed by signal ") + std::to_string(r.signal) +
                                                   (r.signal == SIGKILL ? " (out of memory?)" : ""));
    } else {
      set_status(&r, "child exited without a result");
    }
  }
  r.peak_kb = usage.ru_maxrss;
  return r;
}

std::string format(const char* fmt, double v) {
  if (std::isnan(v)) return "-";
  char text[64];
  std::snprintf(text, sizeof text, fmt, v);
  return text;
}

void print_header() {
  std::printf("%7s %5s %-14s %-15s %9s %5s %4s %8s %7s %7s %7s %7s %10s %9s %9s %8s %8s %8s %9s %8s\n", "DOFs",
              "modes", "method", "status", "iters", "fwd", "KKT", "total s", "cpu s", "s/it", "guard s", "out s",
              "t(target)",
              "start err", "final err", "setup MB", "peak MB", "t ratio", "cpu ratio", "tt ratio");
}

void print_row(const CaseResult& r, Method method, int dofs_hint, int modes, const CaseResult* reduced) {
  const bool full = method != Method::Reduced;
  const bool have = r.dofs > 0;  // set up, finished or not
  std::string iterations = "-";
  if (have)
    iterations = full ? std::to_string(r.iterations) + "+" +
                            (r.globalization_iterations < 0 ? "?" : std::to_string(r.globalization_iterations))
                      : std::to_string(r.iterations);
  if (have && full && r.restarts) iterations += "r" + std::to_string(r.restarts);
  // A killed run: the time between its first and last Ipopt iteration callbacks.
  const double per_iteration = !full ? NAN
                               : r.ran ? (r.iterations > 0 ? r.ipopt_s / r.iterations : NAN)
                                       : (r.kkt_records > 1 ? r.ipopt_s / (r.kkt_records - 1) : NAN);
  const double outside = full && r.ran ? r.seconds - r.ipopt_s : NAN;
  double ratio = NAN, cpu_ratio = NAN, target_ratio = NAN;
  if (full && reduced && r.ran && reduced->ran && reduced->seconds > 0) {
    ratio = r.seconds / reduced->seconds;
    cpu_ratio = r.cpu_s / reduced->cpu_s;
    target_ratio = r.time_to_target / reduced->time_to_target;
  }
  std::printf("%7d %5d %-14s %-15.15s %9s %5s %4s %8s %7s %7s %7s %7s %10s %9s %9s %8s %8.0f %8s %9s %8s\n",
              have ? r.dofs : dofs_hint, modes, method_name(method), r.status, iterations.c_str(),
              have && (r.ran || !full) ? std::to_string(r.forward_solves).c_str() : "-",
              r.ran && full ? std::to_string(r.kkt_solves).c_str() : "-", format("%.1f", r.ran ? r.seconds : NAN).c_str(),
              format("%.1f", r.ran ? r.cpu_s : NAN).c_str(),
              format("%.2f", per_iteration).c_str(), format("%.1f", full && r.ran ? r.guard_s : NAN).c_str(),
              format("%.1f", outside).c_str(), format("%.1f", r.time_to_target).c_str(),
              format("%.1e", r.start_error).c_str(), format("%.1e", r.final_error).c_str(),
              format("%.0f", have ? r.setup_kb / 1024.0 : NAN).c_str(), r.peak_kb / 1024.0,
              format("%.2f", ratio).c_str(), format("%.2f", cpu_ratio).c_str(),
              format("%.2f", target_ratio).c_str());
  std::fflush(stdout);
}

nlohmann::json to_json(const CaseResult& r, Method method, double refinement) {
  auto number = [](double v) { return std::isnan(v) ? nlohmann::json(nullptr) : nlohmann::json(v); };
  return {{"method", method_name(method)},
          {"refinement", refinement},
          {"dofs", r.dofs},
          {"modes", r.modes},
          {"status", r.status},
          {"converged", r.ok},
          {"timed_out", r.timed_out},
          {"iterations", r.iterations},
          {"globalization_iterations", r.globalization_iterations},
          {"restarts", r.restarts},
          {"forward_solves", r.forward_solves},
          {"kkt_solves", r.kkt_solves},
          {"bordered_solves", r.bordered},
          {"shared_eliminations", r.shared_eliminations},
          {"shared_failures", r.shared_failures},
          {"unknowns", r.unknowns},
          {"constraints", r.constraints},
          {"setup_seconds", r.setup_s},
          {"finished", r.ran},
          {"seconds", number(r.seconds)},
          {"cpu_seconds", number(r.cpu_s)},
          {"ipopt_seconds", r.ipopt_s},
          {"guard_seconds", r.guard_s},
          {"seconds_to_target", number(r.time_to_target)},
          {"start_parameter_error", number(r.start_error)},
          {"final_parameter_error", number(r.final_error)},
          {"final_objective", number(r.final_objective)},
          {"convergence_order", number(r.convergence_order)},
          {"setup_memory_mb", r.setup_kb / 1024.0},
          {"peak_memory_mb", r.peak_kb / 1024.0}};
}

const char* kUsage =
    "usage: fullspace_benchmark [options]\n"
    "  --problem FILE              problem with truth values (default problems/lfu/synthetic.yaml)\n"
    "  --mesh-problem FILE         file whose mesh gives the DOF count during the search for the\n"
    "                              refinement (default problems/lfu/lfu.yaml with the default problem,\n"
    "                              else --problem; lfu.yaml has the same mesh and no synthesis)\n"
    "  --dofs LIST                 DOF targets (default 1e4,3e4,1e5)\n"
    "  --modes LIST                measured modes kept, the first K (default 4)\n"
    "  --methods LIST              reduced,fullspace,mumps,block: reduced L-BFGS, full space with Ipopt\n"
    "                              on the structured KKT solver (the default), Ipopt with MUMPS on the\n"
    "                              whole KKT matrix, the block-elimination SQP (default all); with\n"
    "                              -per-mode / -shared: one factorization per mode's bordered block, or\n"
    "                              one shared by all modes, where the default shares from\n"
    "                              FullSpaceOptions::shared_factorization_min_dofs DOFs on\n"
    "  --start-factor F            start at truth x F, clamped to the bounds (default 0.7)\n"
    "  --target-error E            parameter error for the time-to-accuracy column (default 1e-8)\n"
    "  --reduced-max-iterations N  L-BFGS iteration cap (default 1000)\n"
    "  --ipopt-print-level N       FullSpaceOptions::print_level (default 0, silent)\n"
    "  --globalization-reduction R FullSpaceOptions::globalization_reduction (default: its default)\n"
    "  --mu-init MU                FullSpaceOptions::mu_init, Ipopt's first barrier parameter (default: its default)\n"
    "  --max-seconds S             per case; the child is killed after it (default 900)\n"
    "  --max-memory-mb M           per case resident-memory limit (default 60 % of RAM; 0 none)\n"
    "  --json OUT                  also write the results as JSON\n";

int run(int argc, char** argv) {
  Settings s;
  s.problem_path = std::string(MODALCAL_SOURCE_DIR) + "/problems/lfu/synthetic.yaml";
  const std::string default_mesh = std::string(MODALCAL_SOURCE_DIR) + "/problems/lfu/lfu.yaml";
  bool problem_given = false;
  std::vector<double> targets = {1e4, 3e4, 1e5};
  std::vector<double> mode_counts = {4};
  std::vector<Method> methods = {Method::Reduced, Method::FullSpace, Method::FullSpaceMumps, Method::FullSpaceBlock};
  std::string json_path;
  const long pages = sysconf(_SC_PHYS_PAGES), page_size = sysconf(_SC_PAGE_SIZE);
  s.max_memory_mb = pages > 0 && page_size > 0 ? 0.6 * static_cast<double>(pages) * page_size / (1024.0 * 1024.0) : 0;
  for (int i = 1; i < argc; ++i) {
    const std::string a = argv[i];
    auto next = [&]() -> std::string {
      if (i + 1 >= argc) throw std::invalid_argument(a + " needs a value");
      return argv[++i];
    };
    auto number = [&]() {
      const std::vector<double> v = parse_list(next());
      if (v.size() != 1) throw std::invalid_argument(a + " takes one number");
      return v[0];
    };
    if (a == "--problem") s.problem_path = next(), problem_given = true;
    else if (a == "--mesh-problem") s.mesh_problem_path = next();
    else if (a == "--dofs") targets = parse_list(next());
    else if (a == "--modes") mode_counts = parse_list(next());
    else if (a == "--methods") {
      methods.clear();
      for (const std::string& m : split_list(next())) {
        const auto info = std::find_if(std::begin(kMethods), std::end(kMethods),
                                       [&](const MethodInfo& known) { return m == known.token; });
        if (info == std::end(kMethods))
          throw std::invalid_argument("unknown method '" + m +
                                      "' (reduced, fullspace, mumps, block, fullspace-per-mode, block-per-mode, "
                                      "fullspace-shared, block-shared)");
        methods.push_back(info->method);
      }
    } else if (a == "--start-factor") s.start_factor = number();
    else if (a == "--target-error") s.target_error = number();
    else if (a == "--reduced-max-iterations") s.reduced_max_iterations = static_cast<int>(number());
    else if (a == "--globalization-reduction") s.globalization_reduction = number();
    else if (a == "--mu-init") s.mu_init = number();
    else if (a == "--ipopt-print-level") s.ipopt_print_level = static_cast<int>(number());
    else if (a == "--max-seconds") s.max_seconds = number();
    else if (a == "--max-memory-mb") s.max_memory_mb = number();
    else if (a == "--json") json_path = next();
    else if (a == "--help" || a == "-h") {
      std::printf("%s", kUsage);
      return 0;
    } else {
      std::fprintf(stderr, "unknown option '%s'\n%s", a.c_str(), kUsage);
      return 2;
    }
  }
  if (s.mesh_problem_path.empty()) s.mesh_problem_path = problem_given ? s.problem_path : default_mesh;
  for (double k : mode_counts)
    if (k < 1 || k != std::floor(k)) throw std::invalid_argument("--modes: positive integers");
  if (!(s.start_factor > 0)) throw std::invalid_argument("--start-factor must be > 0");
  if (!(s.max_seconds >= 1)) throw std::invalid_argument("--max-seconds must be >= 1");
  if (s.ipopt_print_level < 0 || s.ipopt_print_level > 12) throw std::invalid_argument("--ipopt-print-level: 0..12");

  // DOFs grow roughly as r^3 (grid intervals are divided into ceil(r L / h) parts). Refinement 1
  // is the coarsest valid one (below it the foam elements degenerate), so a target below its
  // DOF count means r = 1; above, bracket the target by doubling and bisect on log r (counting
  // DOFs needs only the mesh and the DOF map).
  std::map<double, int> dof_cache;
  auto dofs_at = [&](double refinement) {
    auto it = dof_cache.find(refinement);
    if (it != dof_cache.end()) return it->second;
    Problem problem = load_problem(s.mesh_problem_path, LoadOptions{refinement});
    return dof_cache[refinement] = DofMap(problem.model).num_free();
  };
  auto refinement_for = [&](double target) {
    double lo = 1.0;
    if (dofs_at(lo) >= target) return lo;
    double hi = 2.0;
    while (dofs_at(hi) < target) lo = hi, hi *= 2;
    for (int k = 0; k < 12; ++k) {
      const double mid = std::sqrt(lo * hi);
      (dofs_at(mid) < target ? lo : hi) = mid;
    }
    // Nearest on a log scale: the DOF count jumps (on the LFU mesh from 66,393 at r = 1.97 to
    // 133,794 at r = 2.03, nothing in between), and a target is an order of magnitude.
    return std::abs(std::log(dofs_at(lo) / target)) < std::abs(std::log(dofs_at(hi) / target)) ? lo : hi;
  };

  std::printf("Full space (Ipopt on the structured KKT solver or on MUMPS, block SQP) vs reduced L-BFGS, %s\n", s.problem_path.c_str());
  std::printf("start: truth x %g (clamped to bounds); target parameter error %.0e; per case: max %.0f s, %s\n",
              s.start_factor, s.target_error, s.max_seconds,
              s.max_memory_mb > 0 ? (format("%.0f", s.max_memory_mb) + " MB resident").c_str()
                                  : "no memory limit");
  std::printf("load average at start: %s\n", load_average().c_str());
  std::printf("iters: L-BFGS, or Newton + globalization (rN: N restarts); s/it = Newton-phase s / Newton iteration "
              "(guard included); out s = full-space s outside the Newton phase;\n"
              "t(target): s to parameter error <= target; t ratio = full space / reduced total s; cpu ratio = the "
              "same for cpu s, tt ratio for t(target)\n\n");
  bool header_printed = false;  // before the first row (after any note on the mesh)

  struct Row {
    CaseResult result;
    Method method;
    int dofs_hint, modes;
    double refinement;
  };
  std::vector<Row> rows;
  nlohmann::json json = nlohmann::json::array();
  for (double target : targets) {
    const double refinement = refinement_for(target);
    const int dofs_hint = dofs_at(refinement);
    if (std::abs(dofs_hint / target - 1) > 0.2)
      std::printf("note: no mesh near %.0f DOFs; the nearest (log scale) has %d (refinement %.4f)\n", target,
                  dofs_hint, refinement);
    for (double modes : mode_counts) {
      s.modes = static_cast<int>(modes);
      const CaseResult* reduced = nullptr;
      CaseResult reduced_result;
      for (Method method : methods) {
        if (s.ipopt_print_level > 0)
          std::printf("--- %d DOFs (refinement %.4f), %d modes, %s ---\n", dofs_hint, refinement, s.modes,
                      method_name(method));
        std::fflush(stdout);
        CaseResult r = run_in_child(s, refinement, method);
        if (s.ipopt_print_level == 0) {
          if (!header_printed) print_header(), header_printed = true;
          print_row(r, method, dofs_hint, s.modes, reduced);
        }
        if (method == Method::Reduced) reduced_result = r, reduced = &reduced_result;
        rows.push_back({r, method, dofs_hint, s.modes, refinement});
        nlohmann::json j = to_json(r, method, refinement);
        if (method != Method::Reduced && reduced && reduced->seconds > 0 && r.seconds > 0)
          j["time_ratio_to_reduced"] = r.seconds / reduced->seconds;
        json.push_back(j);
      }
    }
  }
  // With Ipopt's output in between, the table once more at the end, in one piece.
  if (s.ipopt_print_level > 0) {
    std::printf("\n");
    print_header();
    const CaseResult* reduced = nullptr;
    for (const Row& row : rows) {
      if (row.method == Method::Reduced) reduced = &row.result;
      print_row(row.result, row.method, row.dofs_hint, row.modes, reduced);
    }
  }
  std::printf("\nload average at end: %s\n", load_average().c_str());
  if (!json_path.empty()) write_file_atomically(json_path, json.dump(2) + "\n");
  return 0;
}

}  // namespace

int main(int argc, char** argv) { return modalcal::bench::run_guarded("fullspace_benchmark", run, argc, argv); }
