// Reduced-space calibration against its baselines, side by side in one run, on the LFU synthetic
// study (five parameters from 10x-low starts, log scaling, bounds) at several mesh sizes:
//
// - our projected L-BFGS, Newton (Fletcher-Xu hybrid: Gauss-Newton steps while they cut J by
//   20 %, then the exact reduced Hessian) and Gauss-Newton (minimize_reduced, default options;
//   Gauss-Newton alone stalls near a spurious minimum from this start, so it has its own, lower
//   iteration cap, --gauss-newton-max-iterations);
// - ROL's projected line-search L-BFGS, the seed's optimizer, on the same scaled variables and
//   bounds (built with -DMODALCAL_WITH_ROL=ON);
// - the same projected L-BFGS driven by central finite-difference gradients, which is what a
//   black-box calibration tool does: 2n extra forward solves per gradient.
//
// It also measures what the adjoint gradient costs as a fraction of one forward solve, at the
// start point: for the eigenvalue-only objective (no linear solve at all; target <= 2 %) and with
// mode shapes (deflated adjoint solves; target <= 1 forward solve). The fraction is
// (gradient evaluation - value evaluation) / value evaluation, from the fastest of --repeats
// interleaved timings of each (the minimum is what survives other processes on a shared machine;
// the medians are printed next to it).
//
// Usage: reduced_baselines_benchmark --help

#include <sys/resource.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <ctime>
#include <fstream>
#include <nlohmann/json.hpp>
#include <string>
#include <vector>

#include "bench_util.hpp"
#include "modalcal/assembly.hpp"
#include "modalcal/objective.hpp"
#include "modalcal/output.hpp"
#include "modalcal/problem.hpp"
#include "modalcal/reduced.hpp"
#include "modalcal/problem_file.hpp"
#include "modalcal/synthesis.hpp"
#ifdef MODALCAL_WITH_ROL
#include "rol_baseline.hpp"
#endif

using namespace modalcal;
using modalcal::bench::parse_list;
using modalcal::bench::split_list;
using modalcal::bench::load_average;
using modalcal::bench::seconds_since;
using Clock = modalcal::bench::Clock;

namespace {


double median(std::vector<double> v) {
  std::sort(v.begin(), v.end());
  const size_t n = v.size();
  return n % 2 ? v[n / 2] : 0.5 * (v[n / 2 - 1] + v[n / 2]);
}

double parameter_error(const Problem& problem, const Vector& p) {
  return (p.array() / problem.truth_values().array() - 1).abs().maxCoeff();
}

struct MethodResult {
  std::string method;
  bool built = true;
  int iterations = 0, forward_solves = 0, linear_solves = 0;
  double seconds = 0, parameter_error = NAN, final_objective = NAN;
  bool converged = false;
  std::string termination;
};

// Each method gets a fresh Objective so that no solver state carries over from another method;
// its construction is outside the timing, as in minimize_reduced's own figures.
MethodResult run_method(const Problem& problem, const std::string& method, const ReducedOptions& options,
                        int gauss_newton_max_iterations) {
  // The black-box baseline is our own L-BFGS with the gradient taken by central differences.
  ObjectiveOptions objective_options;
  if (method == "fd-lbfgs") objective_options.gradient = ObjectiveOptions::Gradient::CentralDifferences;
  Objective objective(problem, objective_options);
  const Vector p0 = problem.initial_values();
  const int solves_before = objective.forward_solves(), linear_before = objective.linear_solves();
  const auto t0 = Clock::now();
  MethodResult r;
  if (method == "lbfgs" || method == "newton" || method == "gauss-newton" || method == "fd-lbfgs") {
    ReducedOptions o = options;
    if (method == "newton") o.method = ReducedOptions::Method::Newton;
    if (method == "gauss-newton") {
      o.method = ReducedOptions::Method::GaussNewton;
      o.max_iterations = std::min(options.max_iterations, gauss_newton_max_iterations);
    }
    const ReducedSummary s = minimize_reduced(objective, p0, o);
    r.method = method == "lbfgs"          ? "L-BFGS (ours, adjoint)"
               : method == "newton"       ? "Newton (ours, Fletcher-Xu)"
               : method == "gauss-newton" ? "Gauss-Newton (ours)"
                                          : "L-BFGS, central-difference gradient";
    r.iterations = s.iterations;
    r.converged = s.converged();
    r.termination = to_string(s.status);
    if (s.final.size()) {
      r.parameter_error = parameter_error(problem, s.final);
      r.final_objective = s.final_objective;
    }
  } else if (method == "rol") {
    r.method = "ROL L-BFGS (adjoint)";
#ifdef MODALCAL_WITH_ROL
    const bench::RolRun run = bench::rol_projected_lbfgs(objective, p0, options);
    r.iterations = run.iterations;
    r.converged = run.converged;
    r.termination = run.status;
    r.parameter_error = parameter_error(problem, run.final);
    r.final_objective = run.final_objective;
#else
    r.built = false;
    r.termination = "not built (configure with -DMODALCAL_WITH_ROL=ON)";
    return r;
#endif
  }
  r.seconds = seconds_since(t0);
  r.forward_solves = objective.forward_solves() - solves_before;
  r.linear_solves = objective.linear_solves() - linear_before;
  return r;
}

// The same measured modes without shapes, paired by model index (MAC pairing needs shapes).
Problem eigenvalue_only(const Problem& problem) {
  Problem copy = problem;
  copy.sensors.clear();
  for (MeasuredMode& m : copy.measured) {
    m.shape.resize(0);
    m.pairing.kind = PairingRule::Kind::ModelIndex;
  }
  return copy;
}

// Wall and CPU seconds of one evaluation. On a shared machine the wall time includes waiting for
// other processes, which swamps a gradient that costs well under 1 % of a solve; CPU time is not
// charged while the process waits. `cpu` counts all threads of this process (OpenBLAS helpers
// included, spin-waiting too); `thread` only the calling thread, which does all the gradient
// work and takes part in every BLAS call of the solve, so it is close to the wall time on an idle
// machine and the least disturbed measure on a loaded one.
struct Timing {
  double wall = 0, cpu = 0, thread = 0;
  int linear_solves = 0;  // adjoint right-hand sides
};

double thread_cpu_seconds() {
  timespec t;
  clock_gettime(CLOCK_THREAD_CPUTIME_ID, &t);
  return t.tv_sec + 1e-9 * t.tv_nsec;
}

double cpu_seconds() {
  struct rusage usage;
  getrusage(RUSAGE_SELF, &usage);
  auto seconds = [](const timeval& t) { return t.tv_sec + 1e-6 * t.tv_usec; };
  return seconds(usage.ru_utime) + seconds(usage.ru_stime);
}

Timing time_evaluation(Objective& objective, const Vector& p, Need need) {
  const auto wall0 = Clock::now();
  const double cpu0 = cpu_seconds(), thread0 = thread_cpu_seconds();
  const Evaluation e = objective.evaluate(p, need);
  const double thread = thread_cpu_seconds() - thread0;
  if (!e.ok) throw std::runtime_error("cannot evaluate the start point: " + e.message);
  return {seconds_since(wall0), cpu_seconds() - cpu0, thread, e.linear_solves};
}

struct GradientCost {
  Timing value, gradient;                 // fastest of the repeats
  Timing value_median, gradient_median;
  int repeats = 0;
  int linear_solves = 0;  // adjoint right-hand sides per gradient
  double wall_fraction() const { return (gradient.wall - value.wall) / value.wall; }
  double cpu_fraction() const { return (gradient.cpu - value.cpu) / value.cpu; }
  double thread_fraction() const { return (gradient.thread - value.thread) / value.thread; }
  double median_wall_fraction() const { return (gradient_median.wall - value_median.wall) / value_median.wall; }
};

// `repeats` timings each, interleaved so that both see the same solver state, after one warm-up
// evaluation (first-call setup such as the symbolic analysis is not a gradient cost). The
// eigenvalue-only gradient costs well under 1 % of a solve, less than the jitter of one timing
// on a loaded machine: the difference of the fastest timings is the robust estimate (load only
// ever adds time), the difference of medians shows the spread.
GradientCost gradient_cost(const Problem& problem, int repeats) {
  Objective objective(problem);
  const Vector p = problem.initial_values();
  GradientCost c;
  c.repeats = repeats;
  time_evaluation(objective, p, Need::Gradient);
  std::vector<double> value_wall, value_cpu, value_thread, gradient_wall, gradient_cpu, gradient_thread;
  for (int k = 0; k < repeats; ++k) {
    const Timing v = time_evaluation(objective, p, Need::Value);
    const Timing g = time_evaluation(objective, p, Need::Gradient);
    c.linear_solves = g.linear_solves;
    value_wall.push_back(v.wall);
    value_cpu.push_back(v.cpu);
    value_thread.push_back(v.thread);
    gradient_wall.push_back(g.wall);
    gradient_cpu.push_back(g.cpu);
    gradient_thread.push_back(g.thread);
  }
  auto smallest = [](const std::vector<double>& v) { return *std::min_element(v.begin(), v.end()); };
  c.value = {smallest(value_wall), smallest(value_cpu), smallest(value_thread)};
  c.gradient = {smallest(gradient_wall), smallest(gradient_cpu), smallest(gradient_thread)};
  c.value_median = {median(value_wall), median(value_cpu), median(value_thread)};
  c.gradient_median = {median(gradient_wall), median(gradient_cpu), median(gradient_thread)};
  return c;
}

void print(const char* name, const GradientCost& c, const char* target) {
  std::printf("  %-18s %8.3f %8.3f %8.2f%% %8.2f%% %8.3f %8.3f %8.2f%% %8.2f%% %6d  %s\n", name, c.value.wall,
              c.gradient.wall, 100 * c.wall_fraction(), 100 * c.median_wall_fraction(), c.value.thread,
              c.gradient.thread, 100 * c.thread_fraction(), 100 * c.cpu_fraction(), c.linear_solves, target);
}

nlohmann::json to_json(const GradientCost& c) {
  return {{"repeats", c.repeats},
          {"value_wall_s", c.value.wall}, {"gradient_wall_s", c.gradient.wall},
          {"value_cpu_s", c.value.cpu}, {"gradient_cpu_s", c.gradient.cpu},
          {"value_thread_cpu_s", c.value.thread}, {"gradient_thread_cpu_s", c.gradient.thread},
          {"fraction_of_forward_solve_thread_cpu", c.thread_fraction()},
          {"value_wall_median_s", c.value_median.wall}, {"gradient_wall_median_s", c.gradient_median.wall},
          {"fraction_of_forward_solve_wall", c.wall_fraction()}, {"fraction_of_forward_solve_cpu", c.cpu_fraction()},
          {"fraction_of_forward_solve_wall_medians", c.median_wall_fraction()},
          {"linear_solves", c.linear_solves}};
}

// The work the eigenvalue-only gradient adds to a value evaluation is, apart from O(n m) vector
// copies, the eigenvalue sensitivities u^T K_j u, u^T M_j u of the paired modes: timed alone (fastest
// of `repeats` x 20 calls, this thread's CPU) it is a load-insensitive check of the fraction above,
// blocked (what the objective does) and one call per mode (what it did before).
struct FormsCost {
  double blocked = 0, per_mode = 0;  // seconds per gradient
};

FormsCost forms_cost(const Problem& problem, int repeats) {
  Objective objective(problem);
  const Vector p = problem.initial_values();
  const Evaluation e = objective.evaluate(p, Need::Value);
  if (!e.ok) throw std::runtime_error("cannot evaluate the start point: " + e.message);
  Matrix U(e.modal.modes.rows(), static_cast<Eigen::Index>(e.pairs.size()));
  for (size_t i = 0; i < e.pairs.size(); ++i) U.col(i) = e.modal.modes.col(e.pairs[i].model);
  const ParametricSystem& system = objective.system();
  constexpr int kCalls = 20;
  FormsCost c{INFINITY, INFINITY};
  Matrix A, B;
  Vector a, b;
  for (int r = 0; r < repeats; ++r) {
    double t0 = thread_cpu_seconds();
    for (int k = 0; k < kCalls; ++k) system.derivative_forms(p, U, U, &A, &B);
    c.blocked = std::min(c.blocked, (thread_cpu_seconds() - t0) / kCalls);
    t0 = thread_cpu_seconds();
    for (int k = 0; k < kCalls; ++k)
      for (Eigen::Index i = 0; i < U.cols(); ++i) system.derivative_forms(p, Vector(U.col(i)), Vector(U.col(i)), &a, &b);
    c.per_mode = std::min(c.per_mode, (thread_cpu_seconds() - t0) / kCalls);
  }
  return c;
}

const char* kUsage =
    "usage: %s [--problem FILE] [--refine 1,1.5] [--methods lbfgs,newton,gauss-newton,rol,fd-lbfgs]\n"
    "          [--max-iterations 100] [--gauss-newton-max-iterations 30] [--repeats 7] [--json OUT]\n"
    "\n"
    "  --problem FILE    problem with truth values (default problems/lfu/synthetic.yaml)\n"
    "  --refine LIST     mesh refinements, one case each (1 = 13,764 DOFs on the LFU problem)\n"
    "  --methods LIST    methods to run, in order; \"\" measures only the gradient cost\n"
    "                    (rol needs a build with -DMODALCAL_WITH_ROL=ON)\n"
    "  --max-iterations N                 iteration limit of every method (default 100)\n"
    "  --gauss-newton-max-iterations N    lower limit for plain Gauss-Newton, which stalls near a\n"
    "                                     spurious minimum from the LFU start (default 30)\n"
    "  --repeats N       timings of value and gradient each for the gradient cost (default 7)\n"
    "  --json OUT        also write the figures as JSON\n";

int run(int argc, char** argv) {
  std::string problem_path = std::string(MODALCAL_SOURCE_DIR) + "/problems/lfu/synthetic.yaml";
  std::vector<double> refinements = {1.0, 1.5};
  const std::vector<std::string> all_methods = {"lbfgs", "newton", "gauss-newton", "rol", "fd-lbfgs"};
  std::vector<std::string> methods = all_methods;
  ReducedOptions options;  // the defaults, for every method
  int gauss_newton_max_iterations = 30;
  int repeats = 7;
  std::string json_path;
  for (int i = 1; i < argc; ++i) {
    const std::string a = argv[i];
    auto next = [&]() -> std::string {
      if (i + 1 >= argc) throw std::invalid_argument(a + " needs a value");
      return argv[++i];
    };
    auto next_int = [&]() {
      const std::vector<double> v = parse_list(next());
      if (v.size() != 1 || v[0] != std::floor(v[0]) || std::abs(v[0]) > 1e9)
        throw std::invalid_argument(a + " needs one integer");
      return static_cast<int>(v[0]);
    };
    if (a == "--help" || a == "-h") {
      std::printf(kUsage, argv[0]);
      return 0;
    } else if (a == "--problem") problem_path = next();
    else if (a == "--refine") refinements = parse_list(next());
    else if (a == "--methods") methods = split_list(next());
    else if (a == "--max-iterations") options.max_iterations = next_int();
    else if (a == "--gauss-newton-max-iterations") gauss_newton_max_iterations = next_int();
    else if (a == "--repeats") repeats = next_int();
    else if (a == "--json") json_path = next();
    else {
      std::fprintf(stderr, "unknown option '%s'\n", a.c_str());
      std::fprintf(stderr, kUsage, argv[0]);
      return 2;
    }
  }
  std::string error;
  if (!options.IsValid(&error)) {
    std::fprintf(stderr, "%s\n", error.c_str());
    return 2;
  }
  if (gauss_newton_max_iterations < 0 || repeats < 1) {
    std::fprintf(stderr, "--gauss-newton-max-iterations must be >= 0 and --repeats >= 1\n");
    return 2;
  }
  for (double r : refinements)
    if (!(r > 0)) {
      std::fprintf(stderr, "--refine: refinements must be > 0\n");
      return 2;
    }
  for (const std::string& m : methods)
    if (std::find(all_methods.begin(), all_methods.end(), m) == all_methods.end()) {
      std::fprintf(stderr, "unknown method '%s'\n", m.c_str());
      return 2;
    }
  std::printf("Reduced-space calibration vs baselines, %s\n", problem_path.c_str());
  std::printf("start: the problem's initial values; stop: projected gradient (scaled) <= %.0e, or %d iterations"
              " (Gauss-Newton: %d)\n",
              options.gradient_tolerance, options.max_iterations, gauss_newton_max_iterations);
  nlohmann::json json = {{"problem", problem_path}, {"gradient_tolerance", options.gradient_tolerance},
                         {"max_iterations", options.max_iterations},
                         {"gauss_newton_max_iterations", gauss_newton_max_iterations},
                         {"cases", nlohmann::json::array()}};
  for (double refinement : refinements) {
    Problem problem = load_problem(problem_path, LoadOptions{refinement});
    synthesize_measured(&problem);
    if (!problem.has_truth()) throw std::invalid_argument(problem_path + ": needs truth values for every parameter");
    const int dofs = ParametricSystem(problem.model, problem.parameter_targets()).num_dofs();
    std::printf("\nrefinement %.2f: %d DOFs, %zu parameters, %zu measured modes; load average %s\n", refinement,
                dofs, problem.parameters.size(), problem.measured.size(), load_average().c_str());

    const GradientCost eigenvalues = gradient_cost(eigenvalue_only(problem), repeats);
    const GradientCost shapes = gradient_cost(problem, repeats);
    std::printf("gradient cost at the start: (gradient - value) / value, fastest of %d evaluations each (wall\n"
                "medians in parentheses); seconds of wall time and of this thread's CPU, fraction of all threads' CPU\n",
                repeats);
    std::printf("  %-18s %8s %8s %9s %9s %8s %8s %9s %9s %6s  %s\n", "objective", "value", "gradient", "fraction",
                "(median)", "thr val", "thr grad", "fraction", "all cpu", "rhs", "target");
    print("eigenvalues only", eigenvalues, "<= 2 %");
    print("with mode shapes", shapes, "<= 100 %");
    const FormsCost forms = forms_cost(problem, repeats);
    std::printf("  eigenvalue sensitivities alone: %.3f ms blocked = %.2f%% of the value evaluation (this thread's"
                " CPU);\n  one call per mode: %.3f ms = %.2f%%\n",
                1e3 * forms.blocked, 100 * forms.blocked / eigenvalues.value.thread, 1e3 * forms.per_mode,
                100 * forms.per_mode / eigenvalues.value.thread);
    std::fflush(stdout);

    std::printf("  %-36s %6s %8s %8s %9s %11s %12s %5s  %s\n", "method", "iters", "solves", "rhs", "time s",
                "param err", "objective", "conv", "termination");
    nlohmann::json results = nlohmann::json::array();
    for (const std::string& method : methods) {
      const MethodResult r = run_method(problem, method, options, gauss_newton_max_iterations);
      if (r.built)
        std::printf("  %-36s %6d %8d %8d %9.2f %11.3e %12.4e %5s  %s\n", r.method.c_str(), r.iterations,
                    r.forward_solves, r.linear_solves, r.seconds, r.parameter_error, r.final_objective,
                    r.converged ? "yes" : "no", r.termination.c_str());
      else
        std::printf("  %-36s %s\n", r.method.c_str(), r.termination.c_str());
      std::fflush(stdout);
      nlohmann::json m = {{"method", r.method}, {"built", r.built}, {"termination", r.termination}};
      if (r.built)
        m.update({{"iterations", r.iterations}, {"forward_solves", r.forward_solves},
                  {"linear_solves", r.linear_solves}, {"seconds", r.seconds},
                  {"max_relative_parameter_error", r.parameter_error}, {"final_objective", r.final_objective},
                  {"converged", r.converged}});
      results.push_back(m);
    }
    json["cases"].push_back({{"refinement", refinement}, {"dofs", dofs}, {"load_average_after", load_average()},
                             {"gradient_cost", {{"eigenvalues_only", to_json(eigenvalues)}, {"with_shapes", to_json(shapes)},
                                                {"eigenvalue_forms_blocked_s", forms.blocked},
                                                {"eigenvalue_forms_per_mode_s", forms.per_mode}}},
                             {"methods", results}});
  }
  if (!json_path.empty()) write_file_atomically(json_path, json.dump(2) + "\n");
  return 0;
}

}  // namespace

int main(int argc, char** argv) { return modalcal::bench::run_guarded("reduced_baselines_benchmark", run, argc, argv); }
