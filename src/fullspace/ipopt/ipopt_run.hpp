#pragma once
// Internal: one Ipopt solve of a FullSpaceProblem. This header is free of Ipopt types so that
// only ipopt_adapter.cpp sees Ipopt (the modalcal_ipopt target, linked privately).

#include <functional>
#include <string>

#include "fullspace/fullspace_problem.hpp"

namespace modalcal::detail {

struct IpoptRunOptions {
  int max_iterations = 200;
  double tolerance = 1e-10;
  double mu_init = 1e-9;
  bool exact_hessian = true;
  bool derivative_test = false;
  int print_level = 0;
};

/// What Ipopt reports at the end of an iteration.
struct IpoptIteration {
  int iteration = 0;
  double objective = 0, primal_infeasibility = 0, dual_infeasibility = 0, complementarity = 0, mu = 0;
};

/// Called after every iteration with the current unknowns; returning false stops Ipopt.
using IpoptCallback = std::function<bool(const IpoptIteration&, const double* x)>;

struct IpoptRunResult {
  int status_code = 0;      ///< Ipopt::ApplicationReturnStatus
  std::string status;       ///< its name, e.g. "Solve_Succeeded"
  bool solved = false;      ///< Solve_Succeeded or Solved_To_Acceptable_Level
  bool stopped_by_callback = false;
  bool max_iterations = false;
  Vector x, y;              ///< final unknowns and constraint multipliers
  double objective = 0;
  int iterations = 0;
  int hessian_evaluations = 0;
  std::string message;      ///< for failures: what Ipopt said and what it likely means
};

/// Solves from the primal-dual point (x0, y0) (warm start; bound multipliers mu/(x - bound)).
IpoptRunResult run_ipopt(FullSpaceProblem& problem, const Vector& x0, const Vector& y0, const IpoptRunOptions& options,
                         const IpoptCallback& callback);

}  // namespace modalcal::detail
