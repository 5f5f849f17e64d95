#include "fullspace/block_newton.hpp"

#include <Eigen/Cholesky>
#include <Eigen/Eigenvalues>

#include <algorithm>
#include <cmath>

#include "fullspace/block_kkt.hpp"
#include "fullspace/box_qp.hpp"

namespace modalcal::detail {

namespace {

struct Bounds {
  Vector lower, upper;  // of q
};

// The gradient of the Lagrangian with the components that push q against an active bound
// removed (their bound multipliers take them), and the largest entry of the rest.
double dual_infeasibility(const Vector& gradient, const Vector& q, const Bounds& b, int q0) {
  double worst = 0;
  for (int k = 0; k < gradient.size(); ++k) {
    double g = gradient[k];
    if (k >= q0) {
      const int j = k - q0;
      const double tolerance = 1e-12 * std::max(1.0, std::abs(q[j]));
      if (q[j] <= b.lower[j] + tolerance && g > 0) g = 0;
      if (q[j] >= b.upper[j] - tolerance && g < 0) g = 0;
    }
    worst = std::max(worst, std::abs(g));
  }
  return worst;
}

/// The bounds of the parameters q, the last block of the full-space variables.
Bounds parameter_bounds(FullSpaceProblem& problem) {
  const int nv = problem.num_variables(), np = problem.num_parameters();
  Vector lower(nv), upper(nv);
  problem.bounds(lower.data(), upper.data());
  return {lower.tail(np), upper.tail(np)};
}

std::string outside_newton_region_message(bool accepted, double kkt_error) {
  return "block Newton: " +
         std::string(accepted ? "three steps in a row were cut by the line search or the trust region"
                              : "the filter line search found no acceptable step") +
         " (KKT error " + std::to_string(kkt_error) + "): the start is outside Newton's region, or the derivatives are wrong";
}

/// Ipopt's filter line search (Waechter & Biegler 2006, sec. 2.3) on theta = |c|_1 and f:
/// iterates may leave the constraints far behind while f falls, which is what lets the full
/// space cut across the curved valleys a feasible method must follow.
class FilterLineSearch {
 public:
  struct Outcome {
    bool accepted = false;
    double alpha = 0;
  };

  /// Backtracks from a full step along dx from x (objective f0, infeasibility theta, slope the
  /// objective's directional derivative); the first call sets the filter's envelope.
  Outcome search(FullSpaceProblem& problem, const Vector& x, const Vector& dx, double f0, double theta, double slope) {
    if (filter_.empty() && theta_max_ == 0) {
      theta_max_ = 1e4 * std::max(1.0, theta);
      theta_min_ = 1e-4 * std::max(1.0, theta);
    }
    Outcome out;
    bool f_type = false;
    for (double alpha = 1; alpha >= 1e-10; alpha *= 0.5) {
      const Vector trial = x + alpha * dx;
      const double f = problem.objective(trial.data());
      Vector ct(problem.num_constraints());
      problem.constraints(trial.data(), ct.data());
      const double theta_trial = ct.lpNorm<1>();
      if (!std::isfinite(f) || !std::isfinite(theta_trial) || theta_trial > theta_max_ || dominated(theta_trial, f))
        continue;
      // Switching condition: a descent direction for f that dominates the infeasibility.
      f_type = slope < 0 && alpha * std::pow(-slope, 2.3) > std::pow(theta, 1.1) && theta <= theta_min_;
      if (f_type ? f <= f0 + 1e-4 * alpha * slope : (theta_trial <= (1 - 1e-5) * theta || f <= f0 - 1e-5 * theta)) {
        out = {true, alpha};
        break;
      }
    }
    if (out.accepted && !f_type) filter_.push_back({(1 - 1e-5) * theta, f0 - 1e-5 * theta});
    return out;
  }

 private:
  struct Entry {
    double theta, f;
  };
  bool dominated(double theta, double f) const {
    return std::any_of(filter_.begin(), filter_.end(), [&](const Entry& e) { return theta >= e.theta && f >= e.f; });
  }
  std::vector<Entry> filter_;  // (theta, f) pairs no trial point may be worse in both
  double theta_max_ = 0, theta_min_ = 0;
};

/// The Newton step on q from the reduced system: the reduced Hessian with an inertia correction
/// (a shift that makes its smallest eigenvalue 1e-4 of its largest where it was below that, on the
/// null space of the constraints only), in a trust box of `radius` inside the bounds. Returns
/// the box QP's solution and the shift (*shift).
BoxQpResult reduced_newton_step(const BlockKktSystem& kkt, const Vector& q, const Bounds& bounds, double radius,
                                double* shift) {
  Matrix H = kkt.reduced_hessian();
  const Eigen::SelfAdjointEigenSolver<Matrix> spectrum(H, Eigen::EigenvaluesOnly);
  const double largest = std::max(spectrum.eigenvalues().cwiseAbs().maxCoeff(), 1e-300);
  const double smallest = spectrum.eigenvalues().minCoeff();
  *shift = smallest < 1e-8 * largest ? 1e-4 * largest - smallest : 0.0;
  H.diagonal().array() += *shift;
  // A box, so the QP stays a box QP: far from the solution the reduced Hessian can be nearly
  // singular along a parameter the data barely see, and the Newton step along it leaves the
  // region where the linearized eigen-constraints mean anything.
  const Vector lower = (bounds.lower - q).cwiseMax(-radius), upper = (bounds.upper - q).cwiseMin(radius);
  return solve_box_qp(H, kkt.reduced_rhs(), lower, upper);
}

}  // namespace

NewtonPhaseResult run_block_newton(FullSpaceProblem& problem, const Vector& x0, const Vector& y0,
                                   const NewtonPhaseOptions& options, const NewtonCallback& callback) {
  NewtonPhaseResult result;
  const int np = problem.num_parameters(), q0 = problem.parameter_offset();
  const Bounds bounds = parameter_bounds(problem);
  BlockKktSystem kkt(problem, options.shared_factorization);
  Vector x = x0, y = y0;
  FilterLineSearch line_search;
  double radius = 1;
  int cut_steps = 0;   // consecutive steps the line search or the trust box shortened
  auto finish = [&](const std::string& status, bool solved, const std::string& message) {
    result.status = status;
    result.solved = solved;
    result.message = message;
    result.x = x;
    result.y = y;
    result.shared_modes = kkt.shared_eliminations();
    result.shared_failures = kkt.shared_failures();
    result.objective = problem.objective(x.data());
    return result;
  };
  double last_step_length = 0, last_shift = 0;  // of the step that led to the current iterate
  for (int k = 0;; ++k) {
    std::string error;
    if (!kkt.build(x, y, &error)) return finish("Singular_Mode_Block", false, "block Newton: " + error);
    ++result.hessian_evaluations;
    ++result.structured_factorizations;
    const double primal = kkt.constraints().lpNorm<Eigen::Infinity>();
    const double dual = dual_infeasibility(kkt.lagrangian_gradient(), x.tail(np), bounds, q0);
    const double f0 = problem.objective(x.data());
    result.iterations = k;
    if (callback && !callback(NewtonIteration::at(k, f0, primal, dual, last_step_length, last_shift), x.data())) {
      result.stopped_by_callback = true;
      return finish("User_Requested_Stop", false, "");
    }
    if (std::max(primal, dual) <= options.tolerance) return finish("Converged", true, "");
    if (k >= options.max_iterations) {
      result.max_iterations = true;
      return finish("Maximum_Iterations_Exceeded", false,
                    "block Newton: KKT error " + std::to_string(std::max(primal, dual)) + " after " +
                        std::to_string(k) + " iterations");
    }

    const Vector q = x.tail(np);
    const BoxQpResult qp = reduced_newton_step(kkt, q, bounds, radius, &last_shift);
    Vector dx, dy;
    kkt.step(qp.d, &dx, &dy);
    const double kkt0 = std::max(primal, dual);
    const FilterLineSearch::Outcome found = line_search.search(problem, x, dx, f0, kkt.constraints().lpNorm<1>(),
                                                               kkt.objective_gradient().dot(dx));
    const bool accepted = found.accepted;
    const double alpha = found.alpha;
    // Cut steps (by the line search or the trust box) mean the iterate is outside the region
    // where Newton's model holds: the driver hands it back to the reduced globalization.
    const bool newton_step = accepted && alpha == 1 && qp.d.lpNorm<Eigen::Infinity>() < 0.999 * radius;
    cut_steps = newton_step ? 0 : cut_steps + 1;
    if (!accepted || cut_steps >= 3) {
      result.outside_newton_region = true;
      return finish("Outside_Newton_Region", false, outside_newton_region_message(accepted, kkt0));
    }
    // The radius follows what the line search accepted.
    const double length = qp.d.lpNorm<Eigen::Infinity>();
    radius = alpha == 1 ? std::max(radius, 2 * length) : std::max(alpha * length, 1e-8);
    x += alpha * dx;
    y += alpha * dy;
    last_step_length = alpha;
  }
}

}  // namespace modalcal::detail
