#pragma once
// The seed's optimizer as a baseline: ROL's projected line-search L-BFGS (Trilinos 13.2, the
// OptimizationProblem/OptimizationSolver API), driven by our Objective in the same scaled
// variables and bounds as minimize_reduced (detail::ScaledProblem). Kept behind this plain
// interface so that only rol_baseline.cpp sees the ROL headers, which take about a minute to compile.

#include <string>

#include "modalcal/reduced.hpp"

namespace modalcal::bench {

struct RolRun {
  bool converged = false;  // ROL's status test met its gradient tolerance
  std::string status;      // ROL's exit status, or why it stopped (e.g. the start cannot be evaluated)
  int iterations = 0;
  Vector final;            // physical parameters of the last iterate
  double final_objective = 0;
};

// Runs ROL with `options`' method-independent settings: iteration limit, absolute gradient
// tolerance, L-BFGS memory, Armijo constant, backtracking steps, bounds and scaling.
// relative_gradient_tolerance and max_step have no ROL counterpart and are ignored.
RolRun rol_projected_lbfgs(Objective& objective, const Vector& p0, const ReducedOptions& options);

}  // namespace modalcal::bench
