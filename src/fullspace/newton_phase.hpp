#pragma once
// Internal: what the driver (minimize_fullspace.cpp) exchanges with a Newton-phase solver of a
// FullSpaceProblem - Ipopt (fullspace/ipopt/ipopt_run.hpp) or the block-elimination SQP
// (fullspace/block_newton.hpp). Free of solver types.

#include <functional>
#include <string>

#include "modalcal/types.hpp"

namespace modalcal::detail {

struct NewtonPhaseOptions {
  int max_iterations = 200;
  double tolerance = 1e-10;
  double mu_init = 1e-9;        ///< Ipopt only
  bool exact_hessian = true;    ///< Ipopt only (the block solver always uses the exact Hessian)
  bool derivative_test = false; ///< Ipopt only
  /// Ipopt only: its KKT systems by the structured solver (fullspace/structured_kkt.hpp) rather
  /// than MUMPS on the whole matrix.
  bool structured_kkt = true;
  /// Structured solves (Ipopt's and the block solver's): every mode's bordered block through one
  /// factorization of K - sigma M (fullspace/shared_shift_solve.hpp) instead of one per mode.
  bool shared_factorization = false;
  /// Ipopt only, for tests: begin in Ipopt's feasibility restoration phase.
  bool start_with_restoration = false;
  int print_level = 0;
};

/// What the solver reports at the end of an iteration.
struct NewtonIteration {
  int iteration = 0;
  double objective = 0, primal_infeasibility = 0, dual_infeasibility = 0, complementarity = 0, mu = 0;
  double step_length = 0;    ///< of the step that led here (0 at the start)
  double hessian_shift = 0;  ///< added to the Hessian for that step (inertia correction)

  /// Iteration k at `objective` with these infeasibilities, after a step of `step_length` on a
  /// Hessian shifted by `shift` (complementarity and mu stay 0 where the solver has none).
  static NewtonIteration at(int k, double objective, double primal, double dual, double step_length, double shift) {
    NewtonIteration info;
    info.iteration = k;
    info.objective = objective;
    info.primal_infeasibility = primal;
    info.dual_infeasibility = dual;
    info.step_length = step_length;
    info.hessian_shift = shift;
    return info;
  }
};

/// Called after every iteration with the current unknowns; returning false stops the solver.
using NewtonCallback = std::function<bool(const NewtonIteration&, const double* x)>;

struct NewtonPhaseResult {
  std::string status;       ///< e.g. Ipopt's "Solve_Succeeded", the block solver's "Converged"
  bool solved = false;      ///< converged (Ipopt: also Solved_To_Acceptable_Level)
  bool stopped_by_callback = false;
  bool max_iterations = false;
  /// Block solver: its line search kept cutting the Newton step (no filter to go on with); the
  /// driver globalizes again from the returned point.
  bool outside_newton_region = false;
  Vector x, y;              ///< final unknowns and constraint multipliers
  double objective = 0;
  int iterations = 0;
  int hessian_evaluations = 0;  ///< = Newton (KKT) systems
  /// KKT factorizations by block elimination and by MUMPS on the whole matrix (Ipopt: every
  /// inertia correction is one more; the block solver counts one structured per system).
  int structured_factorizations = 0, mumps_factorizations = 0;
  /// With shared_factorization: mode eliminations through it, and modes it failed (factored).
  int shared_modes = 0, shared_failures = 0;
  std::string message;      ///< for failures: what went wrong and what it likely means
};

}  // namespace modalcal::detail
