// Options validation, outcome names, convergence-order estimate and reports of the full-space
// method.

#include <algorithm>
#include <cmath>
#include <cstdio>

#include "modalcal/fullspace.hpp"
#include "support/text_util.hpp"

namespace modalcal {

std::string to_string(FullSpaceStatus status) {
  switch (status) {
    case FullSpaceStatus::Converged: return "Converged";
    case FullSpaceStatus::WrongModes: return "WrongModes";
    case FullSpaceStatus::MaxIterations: return "MaxIterations";
    case FullSpaceStatus::Failed: return "Failed";
    case FullSpaceStatus::ForwardSolveFailed: return "ForwardSolveFailed";
  }
  return "?";
}

std::string to_string(FullSpaceOptions::NewtonSolver solver) {
  return solver == FullSpaceOptions::NewtonSolver::Ipopt ? "ipopt" : "block";
}

std::string to_string(FullSpaceOptions::KktSolver solver) {
  return solver == FullSpaceOptions::KktSolver::Structured ? "structured" : "mumps";
}

double KktRecord::kkt_error() const { return std::max({primal_infeasibility, dual_infeasibility, complementarity}); }

bool FullSpaceOptions::IsValid(std::string* error) const {
  auto bad = [&](const std::string& message) {
    if (error) *error = message;
    return false;
  };
  if (max_iterations < 0) return bad("max_iterations = " + detail::option_text(max_iterations) + ": must be >= 0");
  if (!(tolerance > 0 && tolerance < 1)) return bad("tolerance = " + detail::option_text(tolerance) + ": must be in (0, 1)");
  if (!(mu_init > 0)) return bad("mu_init = " + detail::option_text(mu_init) + ": must be > 0");
  if (globalization_iterations < 0)
    return bad("globalization_iterations = " + detail::option_text(globalization_iterations) + ": must be >= 0");
  if (!(globalization_reduction > 0 && globalization_reduction <= 1))
    return bad("globalization_reduction = " + detail::option_text(globalization_reduction) + ": must be in (0, 1]");
  if (!(guard_mac > 0 && guard_mac < 1)) return bad("guard_mac = " + detail::option_text(guard_mac) + ": must be in (0, 1)");
  if (shared_factorization_min_dofs < 0)
    return bad("shared_factorization_min_dofs = " + detail::option_text(shared_factorization_min_dofs) + ": must be >= 0");
  if (!(guard_step >= 0 && guard_step <= 0.1))
    return bad("guard_step = " + detail::option_text(guard_step) + ": must be in [0, 0.1]");
  if (max_restarts < 0) return bad("max_restarts = " + detail::option_text(max_restarts) + ": must be >= 0");
  if (max_crossing_escapes < 0)
    return bad("max_crossing_escapes = " + detail::option_text(max_crossing_escapes) + ": must be >= 0");
  if (!(verify_mac > 0 && verify_mac < 1)) return bad("verify_mac = " + detail::option_text(verify_mac) + ": must be in (0, 1)");
  if (!(verify_eigenvalue_tolerance > 0 && verify_eigenvalue_tolerance < 1))
    return bad("verify_eigenvalue_tolerance = " + detail::option_text(verify_eigenvalue_tolerance) + ": must be in (0, 1)");
  if (hessian == Hessian::LimitedMemory && newton_solver != NewtonSolver::Ipopt)
    return bad("hessian = LimitedMemory with newton_solver = BlockElimination: the L-BFGS Hessian is Ipopt's; the "
               "block solver needs the exact one");
  if (print_level < 0 || print_level > 12)
    return bad("print_level = " + detail::option_text(print_level) + ": must be in [0, 12]");
  return true;
}

std::string CrossingEscape::ToString() const {
  char values[160];
  std::snprintf(values, sizeof values, " at J = %.6e; the escape %s at J = %.6e: ", objective_at_minimum,
                converged ? "converged" : "ended unconverged", objective_after);
  return crossing + values + (kept ? "its end point kept" : "the first minimum kept");
}

std::string FullSpaceSummary::BriefReport() const {
  char line[400];
  std::snprintf(line, sizeof line,
                "fullspace: %s (%s %s, KKT %s, mode check %s) after %d Newton iterations (%d restarts) and %d globalization "
                "iterations, objective %.6e -> %.6e, %d forward solves, %d KKT solves, order %.2f, %.2f s",
                to_string(status).c_str(), newton_solver.c_str(), newton_status.c_str(), kkt_solver.c_str(), mode_check.passed ? "passed" : "failed", iterations,
                restarts, globalization_iterations, initial_objective, final_objective, forward_solves, kkt_solves,
                convergence_order, seconds);
  return line;
}

std::string FullSpaceSummary::FullReport() const {
  std::string out = BriefReport() + "\n" + message + "\n";
  if (!mode_check.passed && !mode_check.reason.empty()) out += "mode check: " + mode_check.reason + "\n";
  for (const CrossingEscape& escape : crossing_escapes) out += "crossing escape: " + escape.ToString() + "\n";
  char line[240];
  std::snprintf(line, sizeof line, "KKT factorizations: %d by block elimination, %d by MUMPS on the whole matrix\n",
                structured_factorizations, mumps_factorizations);
  out += line;
  if (bordered_solves == "shared") {
    std::snprintf(line, sizeof line,
                  "bordered blocks: %d mode eliminations through one shared factorization, %d factored instead\n",
                  shared_eliminations, shared_failures);
    out += line;
  }
  std::snprintf(line, sizeof line, "unknowns %d, constraints %d; time: Newton phase %.2f s, mode guard %.2f s, total %.2f s\n",
                num_unknowns, num_constraints, newton_seconds, guard_seconds, seconds);
  out += line;
  std::snprintf(line, sizeof line, "%5s %14s %11s %11s %11s %10s %6s %9s %12s %8s\n", "iter", "objective", "inf_pr",
                "inf_du", "compl", "mu", "alpha", "shift", "param error", "min MAC");
  out += line;
  for (const KktRecord& r : kkt_history) {
    std::snprintf(line, sizeof line, "%5d %14.6e %11.3e %11.3e %11.3e %10.2e %6.3f %9.2e %12.4e %8.5f\n", r.iteration,
                  r.objective, r.primal_infeasibility, r.dual_infeasibility, r.complementarity, r.mu, r.step_length,
                  r.hessian_shift, r.parameter_error, r.min_mac);
    out += line;
  }
  return out;
}

}  // namespace modalcal
