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
#include "reduced/scaled_problem.hpp"
#ifdef MODALCAL_WITH_ROL
#include "rol_baseline.hpp"
#endif

using namespace modalcal;
using Clock = std::chrono::steady_clock;
using detail::ScaledProblem;
using Point = ScaledProblem::Point;

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
  int iterations = 0, forward_solves = 0;
  double seconds = 0, parameter_error = NAN, final_objective = NAN;
  bool converged = false;
  std::string termination;
};

// ---- L-BFGS on finite-difference gradients ------------------------------------------------------
// minimize_reduced's projected L-BFGS iteration, repeated here because its gradient comes from
// the Objective's adjoint and cannot be swapped without changing the public API. It shares
// ScaledProblem (projection, active set, projected Armijo search), so only the gradient differs.

Vector masked(const Vector& v, const std::vector<bool>& active) {
  Vector out = v;
  for (int j = 0; j < v.size(); ++j)
    if (active[j]) out[j] = 0;
  return out;
}

// Two-loop recursion on the free variables, with the same curvature safeguard as ours.
class LbfgsMemory {
 public:
  explicit LbfgsMemory(int size) : size_(size) {}
  void update(const Vector& s, const Vector& y) {
    if (s.dot(y) <= 1e-12 * s.norm() * y.norm()) return;
    pairs_.push_back({s, y});
    if (static_cast<int>(pairs_.size()) > size_) pairs_.pop_front();
  }
  void clear() { pairs_.clear(); }
  bool empty() const { return pairs_.empty(); }
  Vector apply_inverse(const Vector& g, const std::vector<bool>& active) const {
    Vector q = masked(g, active);
    std::vector<double> alpha(pairs_.size());
    for (int i = static_cast<int>(pairs_.size()) - 1; i >= 0; --i) {
      const Vector s = masked(pairs_[i].s, active), y = masked(pairs_[i].y, active);
      const double sy = s.dot(y);
      if (sy <= 0) continue;
      alpha[i] = s.dot(q) / sy;
      q -= alpha[i] * y;
    }
    if (!pairs_.empty()) {
      const Vector s = masked(pairs_.back().s, active), y = masked(pairs_.back().y, active);
      if (s.dot(y) > 0) q *= s.dot(y) / y.squaredNorm();
    }
    for (size_t i = 0; i < pairs_.size(); ++i) {
      const Vector s = masked(pairs_[i].s, active), y = masked(pairs_[i].y, active);
      const double sy = s.dot(y);
      if (sy <= 0) continue;
      q += s * (alpha[i] - y.dot(q) / sy);
    }
    return masked(q, active);
  }

 private:
  struct Pair {
    Vector s, y;
  };
  int size_;
  std::deque<Pair> pairs_;
};

// Central differences in the scaled variables, h_j = 1e-6 max(1, |x_j|): truncation O(h^2) and
// round-off O(eps J / h) balance near there. A stencil may reach h outside the bounds, which the
// physical model tolerates (h is a millionth of a decade for log scaling).
bool finite_difference_gradient(ScaledProblem& problem, Point* point) {
  const int n = static_cast<int>(point->x.size());
  point->gradient.resize(n);
  for (int j = 0; j < n; ++j) {
    Vector plus = point->x, minus = point->x;
    plus[j] += 1e-6 * std::max(1.0, std::abs(point->x[j]));
    minus[j] -= plus[j] - point->x[j];
    const Point a = problem.evaluate(plus, Need::Value), b = problem.evaluate(minus, Need::Value);
    if (!a.ok || !b.ok) {
      point->message = "forward solve failed in a finite-difference stencil: " + (a.ok ? b.message : a.message);
      return false;
    }
    point->gradient[j] = (a.value - b.value) / (plus[j] - minus[j]);
  }
  return true;
}

MethodResult finite_difference_lbfgs(Objective& objective, const Vector& p0, const ReducedOptions& options) {
  MethodResult r;
  r.method = "L-BFGS, central-FD gradient";
  ScaledProblem problem(objective, options);
  Point current = problem.evaluate(problem.project(problem.scaling().to_scaled(p0)), Need::Value);
  if (!current.ok || !finite_difference_gradient(problem, &current)) {
    r.termination = to_string(TerminationType::ForwardSolveFailed);
    return r;
  }
  const double tolerance = std::max(options.gradient_tolerance,
                                    options.relative_gradient_tolerance * problem.projected_gradient(current).norm());
  LbfgsMemory memory(options.memory);
  r.termination = to_string(TerminationType::MaxIterations);
  while (true) {
    if (problem.projected_gradient(current).norm() <= tolerance) {
      r.converged = true;
      r.termination = to_string(TerminationType::Converged);
      break;
    }
    if (r.iterations == options.max_iterations) break;
    const std::vector<bool> active = problem.active_set(current);
    Vector direction = -memory.apply_inverse(current.gradient, active);
    if (!(direction.dot(current.gradient) < 0)) {
      direction = -masked(current.gradient, active);
      memory.clear();
    }
    double step = memory.empty() ? std::min(1.0, 1.0 / direction.lpNorm<Eigen::Infinity>()) : 1.0;
    step = std::min(step, options.max_step / direction.lpNorm<Eigen::Infinity>());
    // Trial points need only the value: the 2n-solve gradient is paid at the accepted point.
    Point next = problem.line_search(current, direction, Need::Value, step);
    if (!next.ok && !memory.empty()) {
      memory.clear();
      direction = -masked(current.gradient, active);
      next = problem.line_search(current, direction, Need::Value,
                                 std::min(1.0, options.max_step) / direction.lpNorm<Eigen::Infinity>());
    }
    if (!next.ok) {
      r.termination = to_string(TerminationType::LineSearchFailed);
      break;
    }
    if (!finite_difference_gradient(problem, &next)) {
      r.termination = to_string(TerminationType::ForwardSolveFailed);
      break;
    }
    memory.update(next.x - current.x, next.gradient - current.gradient);
    current = next;
    ++r.iterations;
  }
  r.parameter_error = parameter_error(objective.problem(), current.p);
  r.final_objective = current.value;
  return r;
}

// ---- the runs ------------------------------------------------------------------------------------

// Each method gets a fresh Objective so that no solver state carries over from another method;
// its construction is outside the timing, as in minimize_reduced's own figures.
MethodResult run_method(const Problem& problem, const std::string& method, const ReducedOptions& options) {
  Objective objective(problem);
  const Vector p0 = problem.initial_values();
  const int solves_before = objective.forward_solves();
  const auto t0 = Clock::now();
  MethodResult r;
  if (method == "lbfgs" || method == "gauss-newton") {
    ReducedOptions o = options;
    if (method == "gauss-newton") o.method = ReducedOptions::Method::GaussNewton;
    const ReducedSummary s = minimize_reduced(objective, p0, o);
    r.method = method == "lbfgs" ? "L-BFGS (ours, adjoint)" : "Gauss-Newton (ours)";
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
  } else {
    r = finite_difference_lbfgs(objective, p0, options);
  }
  r.seconds = seconds_since(t0);
  r.forward_solves = objective.forward_solves() - solves_before;
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

struct GradientCost {
  double value_s = 0, gradient_s = 0;
  int linear_solves = 0;  // adjoint right-hand sides per gradient
  double fraction() const { return (gradient_s - value_s) / value_s; }
};

// Median of five timings each, interleaved so that both see the same solver state, after one
// warm-up evaluation (first-call setup such as the symbolic analysis is not a gradient cost).
GradientCost gradient_cost(const Problem& problem) {
  Objective objective(problem);
  const Vector p = problem.initial_values();
  if (!objective.evaluate(p, Need::Gradient).ok) throw std::runtime_error("cannot evaluate the start point");
  std::vector<double> value_s, gradient_s;
  GradientCost c;
  for (int k = 0; k < 5; ++k) {
    auto t0 = Clock::now();
    objective.evaluate(p, Need::Value);
    value_s.push_back(seconds_since(t0));
    t0 = Clock::now();
    c.linear_solves = objective.evaluate(p, Need::Gradient).linear_solves;
    gradient_s.push_back(seconds_since(t0));
  }
  c.value_s = median(value_s);
  c.gradient_s = median(gradient_s);
  return c;
}

nlohmann::json to_json(const GradientCost& c) {
  return {{"value_s", c.value_s}, {"gradient_s", c.gradient_s}, {"fraction_of_forward_solve", c.fraction()},
          {"linear_solves", c.linear_solves}};
}

}  // namespace

int main(int argc, char** argv) {
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
    std::printf("gradient cost at the start, as a fraction of one forward solve (median of 5):\n");
    std::printf("  %-22s %10s %12s %10s %8s %s\n", "objective", "value s", "gradient s", "fraction", "rhs", "target");
    std::printf("  %-22s %10.4f %12.4f %9.1f%% %8d %s\n", "eigenvalues only", eigenvalues.value_s,
                eigenvalues.gradient_s, 100 * eigenvalues.fraction(), eigenvalues.linear_solves, "<= 2 %");
    std::printf("  %-22s %10.4f %12.4f %9.1f%% %8d %s\n", "with mode shapes", shapes.value_s, shapes.gradient_s,
                100 * shapes.fraction(), shapes.linear_solves, "<= 100 %");
    std::fflush(stdout);

    std::printf("  %-30s %6s %8s %9s %11s %12s %5s  %s\n", "method", "iters", "solves", "time s", "param err",
                "objective", "conv", "termination");
    nlohmann::json results = nlohmann::json::array();
    for (const std::string& method : methods) {
      const MethodResult r = run_method(problem, method, options);
      if (r.built)
        std::printf("  %-30s %6d %8d %9.2f %11.3e %12.4e %5s  %s\n", r.method.c_str(), r.iterations, r.forward_solves,
                    r.seconds, r.parameter_error, r.final_objective, r.converged ? "yes" : "no",
                    r.termination.c_str());
      else
        std::printf("  %-30s %s\n", r.method.c_str(), r.termination.c_str());
      std::fflush(stdout);
      nlohmann::json m = {{"method", r.method}, {"built", r.built}, {"termination", r.termination}};
      if (r.built)
        m.update({{"iterations", r.iterations}, {"forward_solves", r.forward_solves}, {"seconds", r.seconds},
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
