#include <Eigen/Cholesky>
#include <Eigen/Eigenvalues>

#include <chrono>
#include <cmath>
#include <cstdio>
#include <deque>
#include <optional>

#include "modalcal/reduced.hpp"
#include "reduced/scaled_problem.hpp"
#include "support/text_util.hpp"

namespace modalcal {

std::string to_string(ReducedStatus status) {
  switch (status) {
    case ReducedStatus::Converged: return "Converged";
    case ReducedStatus::MaxIterations: return "MaxIterations";
    case ReducedStatus::LineSearchFailed: return "LineSearchFailed";
    case ReducedStatus::ForwardSolveFailed: return "ForwardSolveFailed";
  }
  return "?";
}

bool ReducedOptions::IsValid(std::string* error) const {
  auto bad = [&](const std::string& message) {
    if (error) *error = message;
    return false;
  };
  if (max_iterations < 0) return bad("max_iterations = " + detail::option_text(max_iterations) + ": must be >= 0");
  if (!(gradient_tolerance >= 0)) return bad("gradient_tolerance = " + detail::option_text(gradient_tolerance) + ": must be >= 0");
  if (!(relative_gradient_tolerance >= 0 && relative_gradient_tolerance < 1))
    return bad("relative_gradient_tolerance = " + detail::option_text(relative_gradient_tolerance) + ": must be in [0, 1)");
  if (!(function_scale > 0 && std::isfinite(function_scale)))
    return bad("function_scale = " + detail::option_text(function_scale) + ": must be > 0");
  if (!(function_tolerance >= 0 && function_tolerance < 1))
    return bad("function_tolerance = " + detail::option_text(function_tolerance) + ": must be in [0, 1)");
  if (memory < 1) return bad("memory = " + detail::option_text(memory) + ": must be >= 1");
  if (!(armijo > 0 && armijo < 0.5)) return bad("armijo = " + detail::option_text(armijo) + ": must be in (0, 0.5)");
  if (max_line_search_steps < 1)
    return bad("max_line_search_steps = " + detail::option_text(max_line_search_steps) + ": must be >= 1");
  if (!(max_step > 0)) return bad("max_step = " + detail::option_text(max_step) + ": must be > 0");
  if (!(initial_damping > 0 && initial_damping <= 1))
    return bad("initial_damping = " + detail::option_text(initial_damping) + ": must be in (0, 1]");
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
  if (free.empty()) return Vector::Zero(current.x.size());  // every variable held on a bound
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

namespace {

/// One run of minimize_reduced(): the state its iterations share.
class ReducedRun {
 public:
  ReducedRun(Objective& objective, const ReducedOptions& options)
      : objective_(objective),
        options_(options),
        second_order_(options.method != ReducedOptions::Method::Lbfgs),
        newton_(options.method == ReducedOptions::Method::Newton),
        need_(second_order_ ? Need::Jacobian : Need::Gradient),
        problem_(objective, options),
        memory_(options.memory),
        damping_(options.initial_damping) {}

  ReducedSummary run(const Vector& p0) {
    summary_.method = newton_ ? "reduced Newton" : second_order_ ? "reduced Gauss-Newton" : "reduced L-BFGS";
    summary_.initial = p0;
    const Vector x0 = problem_.project(problem_.scaling().to_scaled(p0));
    // Steps are capped per variable in units of O(1): scaled variables are O(1) already; an
    // unscaled one is measured against its starting magnitude, so that the cap limits relative
    // changes and does not itself cripple the unscaled case.
    unit_ = Vector::Ones(x0.size());
    for (int j = 0; j < x0.size(); ++j)
      if (problem_.scaling().scaling(j) == Scaling::None && x0[j] != 0) unit_[j] = std::abs(x0[j]);
    current_ = problem_.evaluate(x0, need_);
    if (!current_.ok)
      return finish(ReducedStatus::ForwardSolveFailed, "cannot evaluate the start: " + current_.message);
    summary_.initial_objective = current_.value;
    record(0, 0);
    tolerance_ = std::max(options_.gradient_tolerance,
                          options_.relative_gradient_tolerance * summary_.history.front().gradient_norm);
    for (int k = 1; k <= options_.max_iterations; ++k)
      if (std::optional<ReducedSummary> done = iterate(k)) return *done;
    if (summary_.history.back().gradient_norm <= tolerance_)
      return finish(ReducedStatus::Converged, "projected gradient norm below tolerance");
    return finish(ReducedStatus::MaxIterations, "reached max_iterations = " + std::to_string(options_.max_iterations));
  }

 private:
  using Point = ScaledProblem::Point;

  /// Iteration k from current_: the summary when the run ends in it.
  std::optional<ReducedSummary> iterate(int k) {
    summary_.iterations = k - 1;
    const double gradient_norm = summary_.history.back().gradient_norm;
    if (gradient_norm <= tolerance_) {
      char message[160];
      std::snprintf(message, sizeof message, "projected gradient norm %.3e <= tolerance %.3e", gradient_norm, tolerance_);
      return finish(ReducedStatus::Converged, message);
    }
    Vector direction;
    Point next = step(&direction);
    if (!next.ok) return finish(ReducedStatus::LineSearchFailed, next.message);
    const Vector s = next.x - current_.x;
    const double decrease = current_.value - next.value;
    const bool last = options_.function_tolerance > 0 &&
                      decrease <= options_.function_tolerance * std::max(std::abs(next.value), options_.function_scale);
    if (second_order_) {
      use_exact_hessian_ = newton_ && next.value > 0.8 * current_.value;
      // The last iterate needs only its gradient (for the record): its Jacobian or Hessian, one
      // solve per parameter and measured shape, would serve a step that is not taken.
      const Need need = last ? Need::Gradient : use_exact_hessian_ ? Need::Hessian : Need::Jacobian;
      next = problem_.evaluate(next.x, need);
      if (!next.ok)
        return finish(ReducedStatus::ForwardSolveFailed, "derivatives at the accepted point: " + next.message);
      // Full steps mean the Gauss-Newton model is good: trust it more; backtracking: less.
      damping_ = (s - direction).norm() <= 1e-12 * direction.norm() ? damping_ / 10 : std::min(damping_ * 10, 1.0);
      damping_ = std::max(damping_, 1e-12);
    } else {
      memory_.update(s, next.gradient - current_.gradient);
    }
    current_ = next;
    record(k, s.norm());
    summary_.iterations = k;
    if (last) {
      char message[160];
      std::snprintf(message, sizeof message,
                    "the last iteration lowered the objective by only %.3e (function tolerance %.1e of its value)",
                    decrease, options_.function_tolerance);
      return finish(ReducedStatus::Converged, message);
    }
    return std::nullopt;
  }

  /// The line search from current_ along the method's direction (set in *direction): the
  /// damped second-order step or L-BFGS's, steepest descent when that is no descent direction
  /// or a stale quasi-Newton model fails the search.
  Point step(Vector* direction) {
    const std::vector<bool> active = problem_.active_set(current_);
    *direction = second_order_ ? damped_newton_direction(problem_, current_, active, newton_ && use_exact_hessian_, damping_)
                               : Vector(-memory_.apply_inverse(current_.gradient, active));
    if (!(direction->dot(current_.gradient) < 0)) {
      *direction = -masked(current_.gradient, active);  // not a descent direction: steepest descent
      memory_.clear();
    }
    double length = 1.0;
    if (!second_order_ && memory_.empty()) length = std::min(1.0, 1.0 / longest(*direction));
    length = std::min(length, options_.max_step / longest(*direction));
    Point next = problem_.line_search(current_, *direction, need_, length);
    if (!next.ok && !second_order_ && !memory_.empty()) {
      memory_.clear();  // a stale quasi-Newton model: retry along the steepest descent
      *direction = -masked(current_.gradient, active);
      next = problem_.line_search(current_, *direction, need_, std::min(1.0, options_.max_step) / longest(*direction));
    }
    return next;
  }

  double longest(const Vector& d) const { return d.cwiseQuotient(unit_).lpNorm<Eigen::Infinity>(); }

  void record(int iteration, double step) {
    IterationRecord r;
    r.iteration = iteration;
    r.objective = current_.value;
    r.gradient_norm = problem_.projected_gradient(current_).norm();
    r.step_norm = step;
    r.parameter_error = parameter_error(objective_.problem(), current_.p);
    r.forward_solves = objective_.forward_solves() - forward_before_;
    r.p = current_.p;
    summary_.history.push_back(r);
    if (options_.progress) options_.progress(r);
  }

  ReducedSummary finish(ReducedStatus type, const std::string& message) {
    summary_.status = type;
    summary_.message = message;
    if (current_.ok) {
      summary_.final = current_.p;
      summary_.final_objective = current_.value;
    }
    summary_.forward_solves = objective_.forward_solves() - forward_before_;
    summary_.linear_solves = objective_.linear_solves() - linear_before_;
    summary_.failed_evaluations = problem_.failed_evaluations();
    summary_.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start_).count();
    std::vector<double> gradients;
    for (const IterationRecord& r : summary_.history) gradients.push_back(r.gradient_norm);
    summary_.convergence_order = estimate_convergence_order(gradients);
    return summary_;
  }

  Objective& objective_;
  const ReducedOptions& options_;
  const std::chrono::steady_clock::time_point start_ = std::chrono::steady_clock::now();
  const int forward_before_ = objective_.forward_solves(), linear_before_ = objective_.linear_solves();
  // Gauss-Newton and Newton share the damped second-order step; they differ in the model matrix.
  const bool second_order_, newton_;
  const Need need_;
  ScaledProblem problem_;
  ReducedSummary summary_;
  Vector unit_;
  Point current_;
  double tolerance_ = 0;
  LbfgsMemory memory_;
  // Fletcher-Xu hybrid for Newton: Gauss-Newton while it reduces J by 20 % per step (it is
  // globally better behaved and needs no second derivatives), the exact Hessian once it slows
  // down, where only the exact Hessian converges quadratically.
  bool use_exact_hessian_ = false;
  // Levenberg parameter, relative to the Gauss-Newton diagonal: by default strong at first, so
  // that steps from a far start stay gradient-like and do not leap into another basin; relaxed by
  // 10 after every full step.
  double damping_;
};

}  // namespace

ReducedSummary minimize_reduced(Objective& objective, const Vector& p0, const ReducedOptions& options) {
  std::string error;
  if (!options.IsValid(&error)) throw std::invalid_argument("ReducedOptions: " + error);
  objective.require_parameters(p0, "minimize_reduced");
  return ReducedRun(objective, options).run(p0);
}

std::string ReducedSummary::BriefReport() const {
  char line[320];
  std::snprintf(line, sizeof line,
                "%s: %s after %d iterations, objective %.6e -> %.6e, %d forward solves (%d failed), %d linear "
                "solves, order %.2f, %.2f s",
                method.c_str(), to_string(status).c_str(), iterations, initial_objective, final_objective,
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
