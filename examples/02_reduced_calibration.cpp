// Example 2: calibrating joint and foam stiffness against measured modes (reduced space).
//
// Shows: the objective (eigenvalue and MAC-based shape misfit), checking its adjoint gradient
// against finite differences, projected L-BFGS with bounds and log scaling from a start 10x
// below the truth (the report's synthetic study), and reading the summary.
//
// Run:   build/bin/example_02_reduced_calibration [problem.yaml]
//        (default: problems/lfu/synthetic.yaml; takes about a minute)

#include <cstdio>
#include <iostream>
#include <string>

#include "modalcal/gradient_check.hpp"
#include "modalcal/objective.hpp"
#include "modalcal/reduced.hpp"
#include "modalcal/problem_file.hpp"
#include "modalcal/synthesis.hpp"

int main(int argc, char** argv) {
  using namespace modalcal;
  const std::string path = argc > 1 ? argv[1] : std::string(MODALCAL_SOURCE_DIR) + "/problems/lfu/synthetic.yaml";

  // 1. The problem carries parameters (start, bounds, scaling, truth) and measured modes; those of
  //    a `measured: synthetic:` section are computed from the model at the truth values.
  Problem problem = load_problem(path);
  synthesize_measured(&problem);

  // 2. The objective pairs measured and model modes at every evaluation and gives exact
  //    gradients by the adjoint method.
  Objective objective(problem);

  // 3. Trust, but verify: the adjoint gradient against central differences.
  const GradientCheck check = check_gradient(objective, problem.initial_values());
  std::cout << check.report;
  if (!check.ok) return 1;

  // 4. Calibrate: projected L-BFGS in log10 variables within the bounds.
  ReducedOptions options;
  options.max_iterations = 40;
  options.progress = [](const IterationRecord& r) {
    std::printf("  iteration %2d  J = %.3e  |projected gradient| = %.2e\n", r.iteration, r.objective, r.gradient_norm);
  };
  const ReducedSummary summary = minimize_reduced(objective, problem.initial_values(), options);
  std::cout << summary.BriefReport() << "\n";

  // 5. Compare with the truth the synthetic data were made from.
  for (size_t j = 0; j < problem.parameters.size(); ++j) {
    const Parameter& q = problem.parameters[j];
    std::printf("%-10s start %.4e  calibrated %.4e", q.name.c_str(), summary.initial[j], summary.final[j]);
    if (q.truth) std::printf("  truth %.4e", *q.truth);
    std::printf("\n");
  }
  return summary.converged() ? 0 : 1;
}
