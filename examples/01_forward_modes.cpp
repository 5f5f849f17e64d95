// Example 1: the lowest modes of a model, and what they look like.
//
// Shows: loading a problem file, assembling K(p) and M(p) for chosen parameter values, the
// shift-invert modal solve, and describing modes the way test engineers do (direction shares,
// effective mass, family labels such as "axial").
//
// Run:   build/bin/example_01_forward_modes [problem.yaml]   (default: problems/lfu/lfu.yaml)

#include <cstdio>
#include <string>

#include "modalcal/assembly.hpp"
#include "modalcal/eigen.hpp"
#include "modalcal/mode_description.hpp"
#include "modalcal/problem.hpp"
#include "modalcal/problem_file.hpp"

int main(int argc, char** argv) {
  using namespace modalcal;
  const std::string path = argc > 1 ? argv[1] : std::string(MODALCAL_SOURCE_DIR) + "/problems/lfu/lfu.yaml";

  // 1. Read the problem: mesh, materials, joints, supports, parameters. Errors name file and line.
  const Problem problem = load_problem(path);

  // 2. Bind the parameters to model properties; K and M are assembled once per term and then
  //    rescaled for any parameter values, with exact derivatives available.
  ParametricSystem system(problem.model, problem.parameter_targets());
  SparseMatrix K, M;
  const Vector p = problem.initial_values();
  system.assemble(p, &K, &M);

  // 3. Solve: CHOLMOD analyses the pattern once; each solve is one factorization of K - sigma M
  //    plus block Lanczos iterations. Free-free models report rigid-body modes separately.
  ModalOptions options;
  options.num_modes = 10;
  options.max_rigid_modes = problem.expected_rigid_modes();
  ModalSolver solver(system.pattern(), options);
  const ModalResult result = solver.solve(K, M);
  if (result.status != EigenStatus::Successful) {
    std::fprintf(stderr, "modal solve failed: %s\n", result.message.c_str());
    return 1;
  }

  // 4. Describe the modes: where the kinetic energy goes and which family each belongs to.
  std::printf("%d DOFs; %d rigid-body modes\n", system.num_dofs(), static_cast<int>(result.rigid_eigenvalues.size()));
  for (const ModeDescription& d : describe_modes(system, p, M, result))
    std::printf("mode %2d  %9.2f Hz  KE x/y/z %.2f %.2f %.2f  %s\n", d.index, d.frequency_hz, d.energy_fraction[0],
                d.energy_fraction[1], d.energy_fraction[2], d.label.c_str());
  return 0;
}
