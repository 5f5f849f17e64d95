#include <Eigen/Cholesky>
#include <Eigen/Eigenvalues>

#include <chrono>
#include <cmath>
#include <cstdio>
#include <deque>

#include "modalcal/reduced.hpp"
#include "reduced/scaled_problem.hpp"

namespace modalcal {

std::string to_string(TerminationType type) {
  switch (type) {
    case TerminationType::Converged: return "Converged";
    case TerminationType::MaxIterations: return "MaxIterations";
    case TerminationType::LineSearchFailed: return "LineSearchFailed";
    case TerminationType::ForwardSolveFailed: return "ForwardSolveFailed";
  }
  return "?";
}

bool ReducedOptions::IsValid(std::string* error) const {
  auto bad = [&](const std::string& message) {
    if (error) *error = message;
    return false;
  };
  if (max_iterations < 0) return bad("max_iterations = " + std::to_string(max_iterations) + ": must be >= 0");
  if (!(gradient_tolerance >= 0)) return bad("gradient_tolerance = " + std::to_string(gradient_tolerance) + ": must be >= 0");
  if (!(relative_gradient_tolerance >= 0 && relative_gradient_tolerance < 1))
    return bad("relative_gradient_tolerance = " + std::to_string(relative_gradient_tolerance) + ": must be in [0, 1)");
  if (!(function_tolerance >= 0 && function_tolerance < 1))
    return bad("function_tolerance = " + std::to_string(function_tolerance) + ": must be in [0, 1)");
  if (memory < 1) return bad("memory = " + std::to_string(memory) + ": must be >= 1");
  if (!(armijo > 0 && armijo < 0.5)) return bad("armijo = " + std::to_string(armijo) + ": must be in (0, 0.5)");
  if (max_line_search_steps < 1)
    return bad("max_line_search_steps = " + std::to_string(max_line_search_steps) + ": must be >= 1");
  if (!(max_step > 0)) return bad("max_step = " + std::to_string(max_step) + ": must be > 0");
  return true;
}

namespace {

using detail::ScaledProblem;
using Point = ScaledProblem::Point;

Vector masked(const Vector& v, const std::vector<bool>& active) {
  Vector out = v;
  for (int j = 0; j < v.size(); ++j)
    if (active[j]) out[j] = 0;
  return out;
}

// L-BFGS two-loop recursion (Nocedal & Wright, Algorithm 7.4) applied to the free variables.
class LbfgsMemory {
 public:
  explicit LbfgsMemory(int size) : size_(size) {}
  void update(const Vector& s, const Vector& y) {
    if (s.dot(y) <= 1e-12 * s.norm() * y.norm()) return;  // keeps H positive definite
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

double parameter_error(const Problem& problem, const Vector& p) {
  if (!problem.has_truth()) return NAN;
  return (p.array() / problem.truth_values().array() - 1).abs().maxCoeff();
}

// The damped second-order step on the free variables: (H_f + damping diag(H_f)) d_f = -g_f, H
// the Gauss-Newton matrix J^T J (with the regularization's Hessian) or, with `exact`, the exact
// Hessian with its eigenvalues made positive (their absolute values, floored at 1e-8 of the
// largest); zero on the active bounds.
Vector damped_newton_direction(const ScaledProblem& problem, const Point& current, const std::vector<bool>& active,
                               bool exact, double damping) {
  Matrix H;
  if (exact) {
    Eigen::SelfAdjointEigenSolver<Matrix> eig(0.5 * (current.hessian + current.hessian.transpose()));
    const Vector mu = eig.eigenvalues().cwiseAbs();
    const double floor = 1e-8 * std::max(mu.maxCoeff(), 1e-300);
    H = eig.eigenvectors() * mu.cwiseMax(floor).asDiagonal() * eig.eigenvectors().transpose();
  } else {
    H = current.jacobian.transpose() * current.jacobian;
    H.diagonal() += problem.regularization_hessian(current.x);
  }
  std::vector<int> free;
  for (int j = 0; j < current.x.size(); ++j)
    if (!active[j]) free.push_back(j);
  Matrix Hf(free.size(), free.size());
  Vector gf(free.size());
  for (size_t a = 0; a < free.size(); ++a) {
    gf[a] = current.gradient[free[a]];
    for (size_t b = 0; b < free.size(); ++b) Hf(a, b) = H(free[a], free[b]);
  }
  const double scale = std::max(Hf.diagonal().maxCoeff(), 1e-300);
  Hf.diagonal() += damping * (Hf.diagonal() + Vector::Constant(free.size(), 1e-12 * scale));
  const Vector df = Hf.ldlt().solve(-gf);
  Vector direction = Vector::Zero(current.x.size());
  for (size_t a = 0; a < free.size(); ++a) direction[free[a]] = df[a];
  return direction;
}

}  // namespace

ReducedSummary minimize_reduced(Objective& objective, const Vector& p0, const ReducedOptions& options) {
  std::string error;
  if (!options.IsValid(&error)) throw std::invalid_argument("ReducedOptions: " + error);
  objective.require_parameters(p0, "minimize_reduced");
  const auto start = std::chrono::steady_clock::now();
  const int forward_before = objective.forward_solves(), linear_before = objective.linear_solves();
  // Gauss-Newton and Newton share the damped second-order step; they differ in the model matrix.
  const bool second_order = options.method != ReducedOptions::Method::Lbfgs;
  const bool newton = options.method == ReducedOptions::Method::Newton;
  const Need need = second_order ? Need::Jacobian : Need::Gradient;
  ScaledProblem problem(objective, options);

  ReducedSummary summary;
  summary.method = newton ? "reduced Newton" : second_order ? "reduced Gauss-Newton" : "reduced L-BFGS";
  summary.initial = p0;
  auto finish = [&](TerminationType type, const std::string& message, const Point& best) {
    summary.termination = type;
    summary.message = message;
    if (best.ok) {
      summary.final = best.p;
      summary.final_objective = best.value;
    }
    summary.forward_solves = objective.forward_solves() - forward_before;
    summary.linear_solves = objective.linear_solves() - linear_before;
    summary.failed_evaluations = problem.failed_evaluations();
    summary.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
    std::vector<double> gradients;
    for (const IterationRecord& r : summary.history) gradients.push_back(r.gradient_norm);
    summary.convergence_order = estimate_convergence_order(gradients);
    return summary;
  };
  auto record = [&](int iteration, const Point& point, double step) {
    IterationRecord r;
    r.iteration = iteration;
    r.objective = point.value;
    r.gradient_norm = problem.projected_gradient(point).norm();
    r.step_norm = step;
    r.parameter_error = parameter_error(objective.problem(), point.p);
    r.forward_solves = objective.forward_solves() - forward_before;
    r.p = point.p;
    summary.history.push_back(r);
    if (options.progress) options.progress(r);
  };

  const Vector x0 = problem.project(problem.scaling().to_scaled(p0));
  // Steps are capped per variable in units of O(1): scaled variables are O(1) already; an
  // unscaled one is measured against its starting magnitude, so that the cap limits relative
  // changes and does not itself cripple the unscaled case.
  Vector unit = Vector::Ones(x0.size());
  for (int j = 0; j < x0.size(); ++j)
    if (problem.scaling().scaling(j) == Scaling::None && x0[j] != 0) unit[j] = std::abs(x0[j]);
  auto longest = [&](const Vector& d) { return d.cwiseQuotient(unit).lpNorm<Eigen::Infinity>(); };
  Point current = problem.evaluate(x0, need);
  if (!current.ok) return finish(TerminationType::ForwardSolveFailed, "cannot evaluate the start: " + current.message, current);
  summary.initial_objective = current.value;
  record(0, current, 0);
  const double initial_gradient = summary.history.front().gradient_norm;
  const double tolerance = std::max(options.gradient_tolerance, options.relative_gradient_tolerance * initial_gradient);

  LbfgsMemory memory(options.memory);
  // Fletcher-Xu hybrid for Newton: Gauss-Newton while it reduces J by 20 % per step (it is
  // globally better behaved and needs no second derivatives), the exact Hessian once it slows
  // down, where only the exact Hessian converges quadratically.
  bool use_exact_hessian = false;
  // Levenberg parameter, relative to the Gauss-Newton diagonal: strong at first, so that steps
  // from a far start stay gradient-like and do not leap into another basin; relaxed by 10 after
  // every full step.
  double damping = 1.0;
  for (int k = 1; k <= options.max_iterations; ++k) {
    const double gradient_norm = summary.history.back().gradient_norm;
    if (gradient_norm <= tolerance) {
      summary.iterations = k - 1;
      char message[160];
      std::snprintf(message, sizeof message, "projected gradient norm %.3e <= tolerance %.3e", gradient_norm, tolerance);
      return finish(TerminationType::Converged, message, current);
    }
    const std::vector<bool> active = problem.active_set(current);
    Vector direction = second_order ? damped_newton_direction(problem, current, active, newton && use_exact_hessian, damping)
                                    : Vector(-memory.apply_inverse(current.gradient, active));
    if (!(direction.dot(current.gradient) < 0)) {
      direction = -masked(current.gradient, active);  // not a descent direction: steepest descent
      memory.clear();
    }
    double step = 1.0;
    if (!second_order && memory.empty()) step = std::min(1.0, 1.0 / longest(direction));
    step = std::min(step, options.max_step / longest(direction));
    Point next = problem.line_search(current, direction, need, step);
    if (!next.ok && !second_order && !memory.empty()) {
      memory.clear();  // a stale quasi-Newton model: retry along the steepest descent
      direction = -masked(current.gradient, active);
      next = problem.line_search(current, direction, need, std::min(1.0, options.max_step) / longest(direction));
    }
    if (!next.ok) {
      summary.iterations = k - 1;
      return finish(TerminationType::LineSearchFailed, next.message, current);
    }
    const Vector s = next.x - current.x;
    if (second_order) {
      use_exact_hessian = newton && next.value > 0.8 * current.value;
      next = problem.evaluate(next.x, use_exact_hessian ? Need::Hessian : Need::Jacobian);
      if (!next.ok) {
        summary.iterations = k - 1;
        return finish(TerminationType::ForwardSolveFailed, "derivatives at the accepted point: " + next.message, current);
      }
    }
    if (second_order) {
      // Full steps mean the Gauss-Newton model is good: trust it more; backtracking: less.
      damping = (s - direction).norm() <= 1e-12 * direction.norm() ? damping / 10 : std::min(damping * 10, 1.0);
      damping = std::max(damping, 1e-12);
    } else {
      memory.update(s, next.gradient - current.gradient);
    }
    const double decrease = current.value - next.value;
    current = next;
    record(k, current, s.norm());
    summary.iterations = k;
    if (options.function_tolerance > 0 && decrease <= options.function_tolerance * std::max(std::abs(current.value), 1.0)) {
      char message[160];
      std::snprintf(message, sizeof message,
                    "the last iteration lowered the objective by only %.3e (function tolerance %.1e of its value)",
                    decrease, options.function_tolerance);
      return finish(TerminationType::Converged, message, current);
    }
  }
  if (summary.history.back().gradient_norm <= tolerance)
    return finish(TerminationType::Converged, "projected gradient norm below tolerance", current);
  return finish(TerminationType::MaxIterations,
                "reached max_iterations = " + std::to_string(options.max_iterations), current);
}

std::string ReducedSummary::BriefReport() const {
  char line[320];
  std::snprintf(line, sizeof line,
                "%s: %s after %d iterations, objective %.6e -> %.6e, %d forward solves (%d failed), %d linear "
                "solves, order %.2f, %.2f s",
                method.c_str(), to_string(termination).c_str(), iterations, initial_objective, final_objective,
                forward_solves, failed_evaluations, linear_solves, convergence_order, seconds);
  return line;
}

std::string ReducedSummary::FullReport() const {
  std::string out = BriefReport() + "\n" + message + "\n";
  char line[200];
  std::snprintf(line, sizeof line, "%5s %14s %12s %10s %12s %8s\n", "iter", "objective", "|proj grad|", "|step|",
                "param error", "solves");
  out += line;
  for (const IterationRecord& r : history) {
    std::snprintf(line, sizeof line, "%5d %14.6e %12.4e %10.3e %12.4e %8d\n", r.iteration, r.objective,
                  r.gradient_norm, r.step_norm, r.parameter_error, r.forward_solves);
    out += line;
  }
  return out;
}

}  // namespace modalcal
