// Reduced-space calibration against its baselines, side by side in one run, on the LFU synthetic
// study (five parameters from 10x-low starts, log scaling, bounds) at several mesh sizes:
//
// - our projected L-BFGS and Gauss-Newton (minimize_reduced, default options);
// - ROL's projected line-search L-BFGS, the seed's optimizer, on the same scaled variables and
//   bounds (built with -DMODALCAL_WITH_ROL=ON);
// - the same projected L-BFGS driven by central finite-difference gradients, which is what a
//   black-box calibration tool does: 2n extra forward solves per gradient.
//
// It also measures what the adjoint gradient costs as a fraction of one forward solve, at the
// start point: for the eigenvalue-only objective (no linear solve at all; target <= 2 %) and with
// mode shapes (deflated adjoint solves; target <= 1 forward solve).
//
// Usage: reduced_baselines_benchmark [--problem FILE] [--refine 1,1.5]
//                                    [--methods lbfgs,gauss-newton,rol,fd-lbfgs] [--max-iterations 100]
//                                    [--json OUT]

#include <sys/resource.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <deque>
#include <fstream>
#include <nlohmann/json.hpp>
#include <sstream>
#include <string>
#include <vector>

#include "modalcal/assembly.hpp"
#include "modalcal/objective.hpp"
#include "modalcal/output.hpp"
#include "modalcal/problem.hpp"
#include "modalcal/reduced.hpp"
#ifdef MODALCAL_WITH_ROL
#include "rol_baseline.hpp"
#endif

using namespace modalcal;
using Clock = std::chrono::steady_clock;

namespace {

double seconds_since(Clock::time_point t0) { return std::chrono::duration<double>(Clock::now() - t0).count(); }

std::vector<std::string> split(const std::string& text) {
  std::vector<std::string> out;
  std::stringstream s(text);
  std::string item;
  while (std::getline(s, item, ',')) out.push_back(item);
  return out;
}

// Wall times are only comparable on an otherwise idle machine: print the load next to them.
std::string load_average() {
  std::ifstream in("/proc/loadavg");
  double one = NAN, five = NAN;
  in >> one >> five;
  char text[64];
  std::snprintf(text, sizeof text, "%.1f (1 min), %.1f (5 min)", one, five);
  return text;
}

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
MethodResult run_method(const Problem& problem, const std::string& method, const ReducedOptions& options) {
  // The black-box baseline is our own L-BFGS with the gradient taken by central differences.
  ObjectiveOptions objective_options;
  if (method == "fd-lbfgs") objective_options.gradient = ObjectiveOptions::Gradient::CentralDifferences;
  Objective objective(problem, objective_options);
  const Vector p0 = problem.initial_values();
  const int solves_before = objective.forward_solves(), linear_before = objective.linear_solves();
  const auto t0 = Clock::now();
  MethodResult r;
  if (method == "lbfgs" || method == "gauss-newton" || method == "fd-lbfgs") {
    ReducedOptions o = options;
    if (method == "gauss-newton") o.method = ReducedOptions::Method::GaussNewton;
    const ReducedSummary s = minimize_reduced(objective, p0, o);
    r.method = method == "lbfgs"          ? "L-BFGS (ours, adjoint)"
               : method == "gauss-newton" ? "Gauss-Newton (ours)"
                                          : "L-BFGS, central-difference gradient";
    r.iterations = s.iterations;
    r.converged = s.converged();
    r.termination = to_string(s.termination);
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
// other processes, which swamps a gradient that costs a few percent of a solve; CPU time (all
// threads of this process) is not charged while it waits.
struct Timing {
  double wall = 0, cpu = 0;
  int linear_solves = 0;  // adjoint right-hand sides
};

double cpu_seconds() {
  struct rusage usage;
  getrusage(RUSAGE_SELF, &usage);
  auto seconds = [](const timeval& t) { return t.tv_sec + 1e-6 * t.tv_usec; };
  return seconds(usage.ru_utime) + seconds(usage.ru_stime);
}

Timing time_evaluation(Objective& objective, const Vector& p, Need need) {
  const auto wall0 = Clock::now();
  const double cpu0 = cpu_seconds();
  const Evaluation e = objective.evaluate(p, need);
  if (!e.ok) throw std::runtime_error("cannot evaluate the start point: " + e.message);
  return {seconds_since(wall0), cpu_seconds() - cpu0, e.linear_solves};
}

struct GradientCost {
  Timing value, gradient;  // medians
  int linear_solves = 0;   // adjoint right-hand sides per gradient
  double wall_fraction() const { return (gradient.wall - value.wall) / value.wall; }
  double cpu_fraction() const { return (gradient.cpu - value.cpu) / value.cpu; }
};

// Medians of five timings each, interleaved so that both see the same solver state, after one
// warm-up evaluation (first-call setup such as the symbolic analysis is not a gradient cost).
GradientCost gradient_cost(const Problem& problem) {
  Objective objective(problem);
  const Vector p = problem.initial_values();
  GradientCost c;
  time_evaluation(objective, p, Need::Gradient);
  std::vector<double> value_wall, value_cpu, gradient_wall, gradient_cpu;
  for (int k = 0; k < 5; ++k) {
    const Timing v = time_evaluation(objective, p, Need::Value);
    const Timing g = time_evaluation(objective, p, Need::Gradient);
    c.linear_solves = g.linear_solves;
    value_wall.push_back(v.wall);
    value_cpu.push_back(v.cpu);
    gradient_wall.push_back(g.wall);
    gradient_cpu.push_back(g.cpu);
  }
  c.value = {median(value_wall), median(value_cpu)};
  c.gradient = {median(gradient_wall), median(gradient_cpu)};
  return c;
}

void print(const char* name, const GradientCost& c, const char* target) {
  std::printf("  %-18s %8.3f %8.3f %8.1f%% %8.3f %8.3f %8.1f%% %6d  %s\n", name, c.value.wall, c.gradient.wall,
              100 * c.wall_fraction(), c.value.cpu, c.gradient.cpu, 100 * c.cpu_fraction(), c.linear_solves, target);
}

nlohmann::json to_json(const GradientCost& c) {
  return {{"value_wall_s", c.value.wall}, {"gradient_wall_s", c.gradient.wall},
          {"value_cpu_s", c.value.cpu}, {"gradient_cpu_s", c.gradient.cpu},
          {"fraction_of_forward_solve_wall", c.wall_fraction()}, {"fraction_of_forward_solve_cpu", c.cpu_fraction()},
          {"linear_solves", c.linear_solves}};
}

int run(int argc, char** argv) {
  std::string problem_path = std::string(MODALCAL_SOURCE_DIR) + "/problems/lfu/synthetic.yaml";
  std::vector<double> refinements = {1.0, 1.5};
  const std::vector<std::string> all_methods = {"lbfgs", "gauss-newton", "rol", "fd-lbfgs"};
  std::vector<std::string> methods = all_methods;
  ReducedOptions options;  // the defaults, for every method
  std::string json_path;
  for (int i = 1; i < argc; ++i) {
    const std::string a = argv[i];
    auto next = [&]() -> std::string {
      if (i + 1 >= argc) throw std::invalid_argument(a + " needs a value");
      return argv[++i];
    };
    if (a == "--problem") problem_path = next();
    else if (a == "--refine") {
      refinements.clear();
      for (const std::string& item : split(next())) refinements.push_back(std::stod(item));
    } else if (a == "--methods") methods = split(next());
    else if (a == "--max-iterations") options.max_iterations = std::stoi(next());
    else if (a == "--json") json_path = next();
    else {
      std::fprintf(stderr, "usage: %s [--problem FILE] [--refine 1,1.5] [--methods lbfgs,gauss-newton,rol,fd-lbfgs]"
                   " [--max-iterations 100] [--json OUT]\n", argv[0]);
      return 2;
    }
  }
  std::string error;
  if (!options.IsValid(&error)) {
    std::fprintf(stderr, "%s\n", error.c_str());
    return 2;
  }
  for (const std::string& m : methods)
    if (std::find(all_methods.begin(), all_methods.end(), m) == all_methods.end()) {
      std::fprintf(stderr, "unknown method '%s'\n", m.c_str());
      return 2;
    }
  std::printf("Reduced-space calibration vs baselines, %s\n", problem_path.c_str());
  std::printf("start: the problem's initial values; stop: projected gradient (scaled) <= %.0e, or %d iterations\n",
              options.gradient_tolerance, options.max_iterations);
  nlohmann::json json = {{"problem", problem_path}, {"gradient_tolerance", options.gradient_tolerance},
                         {"max_iterations", options.max_iterations}, {"cases", nlohmann::json::array()}};
  for (double refinement : refinements) {
    const Problem problem = load_problem(problem_path, LoadOptions{refinement});
    if (!problem.has_truth()) throw std::invalid_argument(problem_path + ": needs truth values for every parameter");
    const int dofs = ParametricSystem(problem.model, problem.parameter_targets()).num_dofs();
    std::printf("\nrefinement %.2f: %d DOFs, %zu parameters, %zu measured modes; load average %s\n", refinement,
                dofs, problem.parameters.size(), problem.measured.size(), load_average().c_str());

    const GradientCost eigenvalues = gradient_cost(eigenvalue_only(problem));
    const GradientCost shapes = gradient_cost(problem);
    std::printf("gradient cost at the start: (gradient - value) / value, medians of 5, wall and CPU seconds\n");
    std::printf("  %-18s %8s %8s %9s %8s %8s %9s %6s  %s\n", "objective", "value", "gradient", "fraction",
                "cpu val", "cpu grad", "fraction", "rhs", "target");
    print("eigenvalues only", eigenvalues, "<= 2 %");
    print("with mode shapes", shapes, "<= 100 %");
    std::fflush(stdout);

    std::printf("  %-30s %6s %8s %8s %9s %11s %12s %5s  %s\n", "method", "iters", "solves", "rhs", "time s",
                "param err", "objective", "conv", "termination");
    nlohmann::json results = nlohmann::json::array();
    for (const std::string& method : methods) {
      const MethodResult r = run_method(problem, method, options);
      if (r.built)
        std::printf("  %-30s %6d %8d %8d %9.2f %11.3e %12.4e %5s  %s\n", r.method.c_str(), r.iterations,
                    r.forward_solves, r.linear_solves, r.seconds, r.parameter_error, r.final_objective,
                    r.converged ? "yes" : "no", r.termination.c_str());
      else
        std::printf("  %-30s %s\n", r.method.c_str(), r.termination.c_str());
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
                             {"gradient_cost", {{"eigenvalues_only", to_json(eigenvalues)}, {"with_shapes", to_json(shapes)}}},
                             {"methods", results}});
  }
  if (!json_path.empty()) write_file_atomically(json_path, json.dump(2) + "\n");
  return 0;
}

}  // namespace

int main(int argc, char** argv) {
  try {
    return run(argc, argv);
  } catch (const std::exception& e) {
    std::fprintf(stderr, "reduced_baselines_benchmark: %s\n", e.what());
    return 1;
  }
}
