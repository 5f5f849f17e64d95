// Example 3: full-space calibration with Ipopt, its cross-check against the reduced space, and
// the block-elimination Newton solver.
//
// Shows: checking the full-space derivatives, FullSpaceOptions and what the safeguards do,
// reading the per-iteration KKT history (primal and dual infeasibility, the quadratic tail of
// Newton's method) and the final mode check, comparing the result with reduced-space L-BFGS, and
// choosing the Newton solver (FullSpaceOptions::newton_solver).
//
// Run:   build/bin/example_03_fullspace_calibration [problem.yaml]
//        (default: problems/portal-frame/synthetic.yaml; a few seconds)

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <string>

#include "modalcal/fullspace.hpp"
#include "modalcal/reduced.hpp"
#include "modalcal/problem_file.hpp"
#include "modalcal/synthesis.hpp"

int main(int argc, char** argv) {
  using namespace modalcal;
  const std::string path =
      argc > 1 ? argv[1] : std::string(MODALCAL_SOURCE_DIR) + "/problems/portal-frame/synthetic.yaml";
  Problem problem = load_problem(path);
  synthesize_measured(&problem);  // the measured modes of its `measured: synthetic:` section
  Objective objective(problem);

  // 1. The full-space unknowns are every mode, every eigenvalue and the parameters; check the
  //    exact Jacobian and Lagrangian Hessian along random directions before trusting Newton.
  const FullSpaceDerivativeCheck check = check_fullspace_derivatives(objective, problem.initial_values());
  std::printf("full-space derivative check (relative errors vs central differences):\n");
  for (const std::string& line : check.lines) std::printf("  %s\n", line.c_str());

  // 2. Options: the defaults globalize with reduced L-BFGS, guard every Newton iteration with a
  //    forward solve and verify the modes at the end. Print the Newton iterations as they come.
  FullSpaceOptions options;
  options.progress = [](const KktRecord& r) {
    std::printf("  Newton %2d  J %.3e  constraint violation %.2e  dual infeasibility %.2e  guard MAC %.4f\n",
                r.iteration, r.objective, r.primal_infeasibility, r.dual_infeasibility, r.min_mac);
  };
  const FullSpaceSummary full = minimize_fullspace(objective, problem.initial_values(), options);
  std::printf("%s\n", full.BriefReport().c_str());

  // 3. A run that converged on other eigenpairs than the measured modes says so.
  std::printf("mode check: %s%s\n", full.mode_check.passed ? "passed" : "FAILED: ", full.mode_check.reason.c_str());
  if (!full.converged()) return 1;

  // 4. Cross-check: reduced-space L-BFGS from the same start reaches the same parameters.
  Objective reduced_objective(problem);
  ReducedOptions reduced_options;
  reduced_options.gradient_tolerance = 1e-9;
  const ReducedSummary reduced = minimize_reduced(reduced_objective, problem.initial_values(), reduced_options);
  std::printf("\n%-14s %14s %14s %14s\n", "parameter", "full space", "reduced", "truth");
  double largest = 0;
  for (size_t j = 0; j < problem.parameters.size(); ++j) {
    std::printf("%-14s %14.8e %14.8e %14.8e\n", problem.parameters[j].name.c_str(), full.final[j], reduced.final[j],
                problem.parameters[j].truth.value_or(NAN));
    largest = std::max(largest, std::abs(full.final[j] / reduced.final[j] - 1));
  }
  std::printf("largest relative difference full space vs reduced space: %.2e\n", largest);

  // 5. The same full-space problem with the other Newton solver: one factorization per mode and a
  //    Schur complement on the parameters instead of Ipopt's factorization of the whole KKT matrix
  //    (the faster choice on large meshes). Same globalization, guard and mode check.
  FullSpaceOptions block_options;
  block_options.newton_solver = FullSpaceOptions::NewtonSolver::BlockElimination;
  Objective block_objective(problem);
  const FullSpaceSummary block = minimize_fullspace(block_objective, problem.initial_values(), block_options);
  std::printf("\n%s\n", block.BriefReport().c_str());
  double solvers_differ = 0;
  for (size_t j = 0; j < problem.parameters.size(); ++j)
    solvers_differ = std::max(solvers_differ, std::abs(block.final[j] / full.final[j] - 1));
  std::printf("largest relative difference block vs Ipopt: %.2e (Newton phase %.2f s vs %.2f s)\n", solvers_differ,
              block.newton_seconds, full.newton_seconds);
  return largest < 1e-6 && block.converged() && solvers_differ < 1e-8 ? 0 : 1;
}
