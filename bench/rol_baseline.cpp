#include "rol_baseline.hpp"

#include <ROL_Bounds.hpp>
#include <ROL_OptimizationSolver.hpp>
#include <ROL_StdVector.hpp>

#include <limits>
#include <stdexcept>

#include "reduced/scaled_problem.hpp"

namespace modalcal::bench {

namespace {

using detail::ScaledProblem;

Vector to_eigen(const ROL::Vector<double>& v) {
  const std::vector<double>& data = *static_cast<const ROL::StdVector<double>&>(v).getVector();
  return Eigen::Map<const Vector>(data.data(), static_cast<Eigen::Index>(data.size()));
}

ROL::Ptr<ROL::StdVector<double>> to_rol(const Vector& v) {
  return ROL::makePtr<ROL::StdVector<double>>(ROL::makePtr<std::vector<double>>(v.data(), v.data() + v.size()));
}

// Our objective in scaled variables. Value and gradient come from one evaluation, as in our
// line search: ROL asks for the value at each trial point and then for the gradient at the
// accepted one, so a one-point cache makes every ROL point cost one forward solve, as ours do.
class ScaledObjective : public ROL::Objective<double> {
 public:
  explicit ScaledObjective(ScaledProblem& problem) : problem_(problem) {}

  double value(const ROL::Vector<double>& x, double&) override {
    const ScaledProblem::Point& point = at(to_eigen(x));
    // A failed forward solve counts as +infinity: the Armijo test rejects it and ROL backtracks.
    return point.ok ? point.value : std::numeric_limits<double>::infinity();
  }

  void gradient(ROL::Vector<double>& g, const ROL::Vector<double>& x, double&) override {
    const ScaledProblem::Point& point = at(to_eigen(x));
    if (!point.ok) throw std::runtime_error("gradient requested where the forward solve failed: " + point.message);
    std::vector<double>& out = *static_cast<ROL::StdVector<double>&>(g).getVector();
    Eigen::Map<Vector>(out.data(), static_cast<Eigen::Index>(out.size())) = point.gradient;
  }

 private:
  const ScaledProblem::Point& at(const Vector& x) {
    // ROL forms the accepted iterate as x + (P(x + a s) - x), which can differ from the trial
    // point P(x + a s) it evaluated in the last bits: treat that as the same point.
    const bool same = cached_.x.size() == x.size() &&
                      (cached_.x - x).lpNorm<Eigen::Infinity>() <= 1e-14 * std::max(1.0, x.lpNorm<Eigen::Infinity>());
    if (!same) cached_ = problem_.evaluate(x, Need::Gradient);
    return cached_;
  }

  ScaledProblem& problem_;
  ScaledProblem::Point cached_;
};

}  // namespace

RolRun rol_projected_lbfgs(Objective& objective, const Vector& p0, const ReducedOptions& options) {
  std::string error;
  if (!options.IsValid(&error)) throw std::invalid_argument("ReducedOptions: " + error);
  ScaledProblem problem(objective, options);
  RolRun run;
  const Vector x0 = problem.project(problem.scaling().to_scaled(p0));

  // The seed's algorithm: projected L-BFGS with a backtracking (Armijo only) line search.
  ROL::ParameterList parameters;
  parameters.sublist("General").sublist("Secant").set("Type", "Limited-Memory BFGS");
  parameters.sublist("General").sublist("Secant").set("Maximum Storage", options.memory);
  parameters.sublist("Step").set("Type", "Line Search");
  ROL::ParameterList& line_search = parameters.sublist("Step").sublist("Line Search");
  line_search.sublist("Descent Method").set("Type", "Quasi-Newton Method");
  line_search.sublist("Line-Search Method").set("Type", "Backtracking");
  line_search.sublist("Line-Search Method").set("Backtracking Rate", 0.5);
  line_search.sublist("Curvature Condition").set("Type", "Null Curvature Condition");
  line_search.set("Sufficient Decrease Tolerance", options.armijo);
  line_search.set("Function Evaluation Limit", options.max_line_search_steps);
  ROL::ParameterList& status = parameters.sublist("Status Test");
  status.set("Gradient Tolerance", options.gradient_tolerance);
  // Stop on a step only when the line search failed (a zero step), as minimize_reduced does.
  status.set("Step Tolerance", 0.0);
  status.set("Iteration Limit", options.max_iterations);

  auto rol_objective = ROL::makePtr<ScaledObjective>(problem);
  auto x = to_rol(x0);
  ROL::Ptr<ROL::BoundConstraint<double>> bounds = ROL::nullPtr;
  if (options.use_bounds) bounds = ROL::makePtr<ROL::Bounds<double>>(to_rol(problem.lower()), to_rol(problem.upper()));
  ROL::OptimizationProblem<double> rol_problem(rol_objective, x, bounds);
  ROL::OptimizationSolver<double> solver(rol_problem, parameters);
  try {
    solver.solve();
  } catch (const std::exception& e) {
    run.status = std::string("ROL stopped: ") + e.what();
  }
  const ROL::Ptr<const ROL::AlgorithmState<double>> state = solver.getAlgorithmState();
  run.converged = state->statusFlag == ROL::EXITSTATUS_CONVERGED;
  if (run.status.empty()) run.status = ROL::EExitStatusToString(state->statusFlag);
  run.iterations = state->iter;
  run.final = problem.scaling().to_physical(to_eigen(*x));
  run.final_objective = state->value;
  return run;
}

}  // namespace modalcal::bench
