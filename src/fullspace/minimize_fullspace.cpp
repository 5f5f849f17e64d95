// The full-space driver: globalization, start, guarded Newton phase (Ipopt or block SQP) with restarts, and
// the final check against a forward solve (see include/modalcal/fullspace.hpp).

#include <algorithm>
#include <chrono>
#include <cmath>
#include <memory>
#include <stdexcept>

#include "fullspace/block_newton.hpp"
#include "fullspace/fullspace_driver.hpp"
#include "fullspace/fullspace_problem.hpp"
#include "fullspace/ipopt/ipopt_run.hpp"
#include "modalcal/fullspace.hpp"

namespace modalcal {

namespace {

using Clock = std::chrono::steady_clock;
double seconds_since(Clock::time_point start) {
  return std::chrono::duration<double>(Clock::now() - start).count();
}

// (a^T M b)^2 / ((a^T M a)(b^T M b)): the MAC in the energy inner product, which unlike the
// plain MAC separates modes that look alike at a few DOFs.
double mass_mac(const SparseMatrix& M, const Vector& a, const Vector& b) {
  const Vector Mb = M * b;
  const double ab = a.dot(Mb), aa = a.dot(M * a), bb = b.dot(Mb);
  return (aa > 0 && bb > 0) ? ab * ab / (aa * bb) : 0.0;
}

std::optional<Vector> truth_of(const Problem& problem) {
  Vector truth(problem.parameters.size());
  for (size_t j = 0; j < problem.parameters.size(); ++j) {
    if (!problem.parameters[j].truth) return std::nullopt;
    truth[j] = *problem.parameters[j].truth;
  }
  return truth;
}

double parameter_error(const std::optional<Vector>& truth, const Vector& p) {
  if (!truth) return NAN;
  return (p.array() / truth->array() - 1).abs().maxCoeff();
}

// The first two MAC-paired measured modes whose model modes come in the opposite order of their
// frequencies, described ("measured modes 3 ('mode 3') and 4 ('mode 4') pair with model modes 4
// and 3"), or empty when no pairs cross.
std::string crossed_pairs(const Problem& problem, const std::vector<PairedMode>& pairs) {
  for (const PairedMode& a : pairs)
    for (const PairedMode& b : pairs) {
      const MeasuredMode &ma = problem.measured[a.measured], &mb = problem.measured[b.measured];
      if (ma.pairing.kind != PairingRule::Kind::Mac || mb.pairing.kind != PairingRule::Kind::Mac) continue;
      if (!(ma.frequency_hz < mb.frequency_hz && a.model > b.model)) continue;
      auto name = [](const MeasuredMode& m, int index) {
        return std::to_string(index + 1) + (m.label.empty() ? "" : " ('" + m.label + "')");
      };
      return "measured modes " + name(ma, a.measured) + " and " + name(mb, b.measured) + " pair with model modes " +
             std::to_string(a.model + 1) + " and " + std::to_string(b.model + 1);
    }
  return "";
}

// Puts back the end point of an earlier attempt (its result fields), keeping the counters and
// histories of every attempt.
void keep_result(const FullSpaceSummary& from, FullSpaceSummary* to) {
  to->newton_status = from.newton_status;
  to->final = from.final;
  to->final_objective = from.final_objective;
  to->convergence_order = from.convergence_order;
  to->mode_check = from.mode_check;
  to->multipliers = from.multipliers;
  to->normalization_multipliers = from.normalization_multipliers;
  to->eigenvalues = from.eigenvalues;
  to->modes = from.modes;
  to->measured_of_mode = from.measured_of_mode;
}

// Compares the full-space eigenpairs with a forward solve at their p, paired as the reduced
// objective pairs.
ModeCheck check_modes(Objective& objective, detail::FullSpaceProblem& fp, const Vector& x, const Evaluation& forward,
                      const FullSpaceOptions& options) {
  ModeCheck check;
  if (!forward.ok) {
    check.reason = "forward solve at the final parameters failed: " + forward.message;
    return check;
  }
  Matrix U;
  Vector lambda, p;
  fp.unpack(x.data(), &U, &lambda, &p);
  const SparseMatrix& M = fp.mass_matrix(x.data());
  check.passed = true;
  for (int i = 0; i < fp.num_modes(); ++i) {
    const int m = fp.measured_of(i);
    const int k = forward.pairs[m].model;
    const double mac = mass_mac(M, U.col(i), forward.modal.modes.col(k));
    const double error = std::abs(lambda[i] / forward.modal.eigenvalues[k] - 1);
    check.mac.push_back(mac);
    check.eigenvalue_error.push_back(error);
    if (check.passed && (mac < options.verify_mac || error > options.verify_eigenvalue_tolerance)) {
      check.passed = false;
      const MeasuredMode& mm = objective.problem().measured[m];
      check.reason = "measured mode " + std::to_string(m + 1) + (mm.label.empty() ? "" : " ('" + mm.label + "')") +
                     ": the full-space eigenpair (" + std::to_string(frequency_hz(lambda[i])) +
                     " Hz) is not model mode " + std::to_string(k + 1) + " of the forward solve (" +
                     std::to_string(frequency_hz(forward.modal.eigenvalues[k])) + " Hz): MAC " + std::to_string(mac) +
                     ", eigenvalue difference " + std::to_string(error);
    }
  }
  return check;
}


}  // namespace

namespace detail {

FullSpaceDriver::FullSpaceDriver(Objective& objective, const Vector& p0, const FullSpaceOptions& options)
    : objective_(objective),
      options_(options),
      problem_(objective.problem()),
      start_(Clock::now()),
      forward_solves_before_(objective.forward_solves()),
      truth_(truth_of(problem_)),
      weighted_shapes_(std::any_of(problem_.measured.begin(), problem_.measured.end(),
                                   [](const MeasuredMode& m) { return m.has_shape_term(); })),
      weighted_eigenvalues_(std::any_of(problem_.measured.begin(), problem_.measured.end(),
                                        [](const MeasuredMode& m) { return m.weight > 0; })) {
  // The Newton phase keeps the parameters within their bounds: so does the start.
  summary_.initial = summary_.final = p0.cwiseMax(problem_.lower_bounds()).cwiseMin(problem_.upper_bounds());
  // The globalization's objective: the same data and options with its own eigenvalue misfit.
  if (options.globalization_misfit != objective.options().eigenvalue_misfit) {
    ObjectiveOptions global_options = objective.options();
    global_options.eigenvalue_misfit = options.globalization_misfit;
    misfit_objective_.reset(new Objective(problem_, global_options, objective_));  // shares its forward solves
  }
  if (options.eigenvalues_first && options.globalization_iterations > 0 && weighted_shapes_ && weighted_eigenvalues_)
    eigenvalue_objective_.reset(new Objective(eigenvalue_terms(), global_objective().options(), objective_));
  const bool structured = options.newton_solver == FullSpaceOptions::NewtonSolver::BlockElimination ||
                          options.kkt_solver == FullSpaceOptions::KktSolver::Structured;
  summary_.kkt_solver =
      to_string(structured ? FullSpaceOptions::KktSolver::Structured : FullSpaceOptions::KktSolver::Mumps);
}

// The eigenvalues-first stage and the crossing escape minimize the eigenvalue terms alone: the
// same problem with every shape weight 0 (the shapes still pair the modes), made once when needed.
const Problem& FullSpaceDriver::eigenvalue_terms() {
  if (!eigenvalue_problem_) {
    eigenvalue_problem_ = std::make_unique<Problem>(problem_);
    for (MeasuredMode& m : eigenvalue_problem_->measured) m.shape_weight = 0;
  }
  return *eigenvalue_problem_;
}

FullSpaceSummary FullSpaceDriver::finish(FullSpaceStatus status, const std::string& message) {
  summary_.status = status;
  if (summary_.message.empty()) summary_.message = message;
  summary_.forward_solves = objective_.forward_solves() - forward_solves_before_;
  for (const std::unique_ptr<Objective>* other : {&misfit_objective_, &eigenvalue_objective_, &escape_objective_})
    if (*other) summary_.forward_solves += (*other)->forward_solves();
  summary_.seconds = seconds_since(start_);
  return summary_;
}

FullSpaceSummary FullSpaceDriver::run() {
  const Vector start_point = summary_.initial;
  const Evaluation initial = objective_.evaluate(start_point, Need::Value);
  if (!initial.ok) return finish(FullSpaceStatus::ForwardSolveFailed, "at the start: " + initial.message);
  summary_.initial_objective = summary_.final_objective = initial.value;
  if (options_.max_iterations == 0) {
    summary_.newton_solver = to_string(options_.newton_solver);
    summary_.newton_status = "not run";
    summary_.mode_check.reason = "not checked: no iteration";
    return finish(FullSpaceStatus::MaxIterations, "max_iterations = 0: the start evaluated, no iteration made");
  }
  const Vector globalized = globalize_from_start(start_point);
  set_up_newton(globalized);
  // 2-4. Newton to convergence (guarded, restarted), checked; 5. the crossing escape.
  const Outcome outcome = escape_crossings(solve_from(globalized));
  return finish(outcome.status, outcome.message);
}

// 1. Globalization: reduced L-BFGS always tracks the paired modes; the eigenvalue terms first.
Vector FullSpaceDriver::globalize_from_start(const Vector& start) {
  Vector globalized = start;
  if (eigenvalue_objective_)
    globalized = globalize_on(*eigenvalue_objective_, globalized, options_.globalization_iterations);
  if (options_.globalization_iterations > 0) globalized = globalize(globalized, options_.globalization_iterations);
  return globalized;
}

// The Newton phase's variables and scaling, at the parameters it will start from.
void FullSpaceDriver::set_up_newton(const Vector& p) {
  scaling_.emplace(options_.scaling ? ParameterScaling(problem_.parameters, *options_.scaling)
                                    : ParameterScaling(problem_.parameters));
  fp_ = std::make_unique<detail::FullSpaceProblem>(objective_, *scaling_, p);
  summary_.num_unknowns = fp_->num_variables();
  summary_.num_constraints = fp_->num_constraints();
  summary_.newton_solver = to_string(options_.newton_solver);
  using Solves = FullSpaceOptions::BorderedSolves;
  shared_factorization_ = summary_.kkt_solver == "structured" &&
                          (options_.bordered_solves == Solves::Shared ||
                           (options_.bordered_solves == Solves::Automatic &&
                            fp_->num_dofs() >= options_.shared_factorization_min_dofs));
  if (summary_.kkt_solver == "structured") summary_.bordered_solves = shared_factorization_ ? "shared" : "per-mode";
}

Vector FullSpaceDriver::globalize_on(Objective& on, const Vector& from, int iterations) {
  ReducedOptions reduced;
  reduced.max_iterations = iterations;
  reduced.relative_gradient_tolerance = options_.globalization_reduction;
  reduced.scaling = options_.scaling;
  const ReducedSummary run = minimize_reduced(on, from, reduced);
  for (IterationRecord record : run.history) {
    if (!summary_.globalization_history.empty() && record.iteration == 0) continue;
    record.iteration += summary_.globalization_iterations;
    summary_.globalization_history.push_back(record);
  }
  summary_.globalization_iterations += run.iterations;
  return run.final;
}

// Restart point after the guard fired at `to`: the first of q(from) + a (q(to) - q(from)),
// a = 1, 1/2, ..., that decreases the reduced objective, else reduced L-BFGS from `from`.
Vector FullSpaceDriver::backtrack(const Vector& from, const Vector& to) {
  const Evaluation at_from = objective_.evaluate(from, Need::Value);
  const Vector q0 = scaling_->to_scaled(from), dq = scaling_->to_scaled(to) - q0;
  for (double a = 1; at_from.ok && a > 1e-3; a *= 0.5) {
    const Vector trial = scaling_->to_physical(q0 + a * dq);
    const Evaluation e = objective_.evaluate(trial, Need::Value);
    if (e.ok && e.value < at_from.value) return trial;
  }
  return globalize(from, std::max(options_.globalization_iterations, 10));
}

// 2. The Newton start at p: the forward solution, signs aligned with the measured shapes,
// multipliers from the adjoint. The reason when the forward solve fails.
std::optional<std::string> FullSpaceDriver::newton_start(const Vector& p, Vector* x0, Vector* y0) {
  const detail::FullSpaceProblem& fp = *fp_;
  const Evaluation e = objective_.evaluate(p, Need::Gradient);
  if (!e.ok) return "start of the Newton phase: " + e.message;
  Matrix U(fp.num_dofs(), fp.num_modes()), W(fp.num_dofs(), fp.num_modes());
  Vector lambda(fp.num_modes()), eta(fp.num_modes());
  for (int i = 0; i < fp.num_modes(); ++i) {
    const int m = fp.measured_of(i);
    const int k = e.pairs[m].model;
    const double sign = fp.shape_sign(i, e.modal.modes.col(k));
    U.col(i) = sign * e.modal.modes.col(k);
    W.col(i) = sign * e.adjoint.col(m);
    lambda[i] = e.modal.eigenvalues[k];
    eta[i] = e.adjoint_eta[m];
  }
  *x0 = fp.pack(U, lambda, p);
  *y0 = fp.pack_multipliers(W, eta);
  if (shared_factorization_) fp_->set_deflation_basis(e.modal.modes);
  return std::nullopt;
}

// 3. Each Newton iteration recorded and guarded: a forward solve at its p whose paired modes must
// have M-weighted MAC >= guard_mac with the iterate's; the phase stops when they do not.
NewtonCallback FullSpaceDriver::guarded(Guard* guard) {
  return [this, guard](const detail::NewtonIteration& info, const double* x) {
    detail::FullSpaceProblem& fp = *fp_;  // mass_matrix caches M at x
    KktRecord record;
    record.iteration = guard->offset + info.iteration;
    record.objective = info.objective;
    record.primal_infeasibility = info.primal_infeasibility;
    record.dual_infeasibility = info.dual_infeasibility;
    record.complementarity = info.complementarity;
    record.mu = info.mu;
    record.step_length = info.step_length;
    record.hessian_shift = info.hessian_shift;
    record.p = fp.parameters(x);
    record.parameter_error = parameter_error(truth_, record.p);
    if (options_.mode_guard && guard_needed(*guard, record)) {
      const Clock::time_point guard_start = Clock::now();
      const Evaluation forward = objective_.evaluate(record.p, Need::Value);
      double min_mac = 0;
      if (forward.ok) {
        if (shared_factorization_) fp.set_deflation_basis(forward.modal.modes);  // nearer the iterate's p
        const SparseMatrix& M = fp.mass_matrix(x);
        min_mac = 1;
        for (int i = 0; i < fp.num_modes(); ++i) {
          const Eigen::Map<const Vector> u(x + i * fp.num_dofs(), fp.num_dofs());
          min_mac = std::min(min_mac, mass_mac(M, u, forward.modal.modes.col(forward.pairs[fp.measured_of(i)].model)));
        }
      }
      record.min_mac = min_mac;
      summary_.guard_seconds += seconds_since(guard_start);
      if (min_mac < options_.guard_mac) {
        guard->fired = true;
        guard->fired_at = record.p;
      } else {
        guard->last_good = record.p;
      }
    }
    summary_.kkt_history.push_back(record);
    if (options_.progress) options_.progress(record);
    if (!guard->fired && at_rounding_floor(*guard, record)) guard->at_floor = true;
    if (guard->start_primal < 0) guard->start_primal = record.primal_infeasibility;
    guard->previous_primal = record.primal_infeasibility;
    return !guard->fired && !guard->at_floor;
  };
}

// FullSpaceOptions::guard_step: a guard is needed unless the iterate is within guard_step of the
// last guarded point in q and meets its constraints to guard_step.
bool FullSpaceDriver::guard_needed(const Guard& guard, const KktRecord& record) const {
  const double step = (scaling_->to_scaled(record.p) - scaling_->to_scaled(guard.last_good)).lpNorm<Eigen::Infinity>();
  return !(step <= options_.guard_step && record.primal_infeasibility <= options_.guard_step);
}

bool FullSpaceDriver::at_rounding_floor(const Guard& guard, const KktRecord& record) const {
  const double tol = options_.tolerance, primal = record.primal_infeasibility;
  const bool no_longer_squared = primal * kFloorReduction > guard.previous_primal;
  const bool as_the_forward_solve = guard.start_primal > tol && guard.start_primal <= kFloorFactor * tol &&
                                    primal <= kFloorReduction * guard.start_primal;
  return guard.previous_primal > 0 && record.step_length == 1 && record.dual_infeasibility <= tol &&
         record.complementarity <= tol && primal > tol && primal <= kFloorFactor * tol &&
         (no_longer_squared || as_the_forward_solve);
}

NewtonPhaseOptions FullSpaceDriver::newton_options() const {
  detail::NewtonPhaseOptions newton;
  newton.max_iterations = std::max(1, options_.max_iterations - summary_.iterations);
  newton.tolerance = options_.tolerance;
  newton.mu_init = options_.mu_init;
  newton.exact_hessian = options_.hessian == FullSpaceOptions::Hessian::Exact;
  newton.derivative_test = options_.ipopt_derivative_test;
  newton.print_level = options_.print_level;
  newton.structured_kkt = options_.kkt_solver == FullSpaceOptions::KktSolver::Structured;
  newton.shared_factorization = shared_factorization_;
  return newton;
}

// 2-4. Newton from p to convergence: restarted from the globalization where it stalls outside its
// region, from a backtracked point where the guard fires; then checked against a forward solve.
FullSpaceDriver::Outcome FullSpaceDriver::solve_from(Vector p) {
  detail::NewtonPhaseResult run;
  size_t attempt_start = 0;  // first KKT record of the last attempt
  for (;;) {
    Vector x0, y0;
    if (std::optional<std::string> failed = newton_start(p, &x0, &y0))
      return {FullSpaceStatus::ForwardSolveFailed, *failed, {}};
    Guard guard{p, p, false, summary_.iterations};
    attempt_start = summary_.kkt_history.size();
    const Clock::time_point newton_began = Clock::now();
    run = options_.newton_solver == FullSpaceOptions::NewtonSolver::Ipopt
              ? detail::run_ipopt(*fp_, x0, y0, newton_options(), guarded(&guard))
              : detail::run_block_newton(*fp_, x0, y0, newton_options(), guarded(&guard));
    summary_.newton_seconds += seconds_since(newton_began);
    summary_.iterations += run.iterations;
    summary_.kkt_solves += run.hessian_evaluations;
    summary_.structured_factorizations += run.structured_factorizations;
    summary_.mumps_factorizations += run.mumps_factorizations;
    summary_.shared_eliminations += run.shared_modes;
    summary_.shared_failures += run.shared_failures;
    summary_.newton_status = run.status;
    if (run.outside_newton_region && summary_.restarts < options_.max_restarts &&
        summary_.iterations < options_.max_iterations) {
      ++summary_.restarts;  // more reduced iterations from where Newton stalled, then Newton again
      p = globalize(fp_->parameters(run.x.data()), std::max(options_.globalization_iterations, 10));
      continue;
    }
    if (guard.at_floor && run.stopped_by_callback) {
      run.status = "Stopped_At_Rounding_Floor";
      summary_.newton_status = run.status;
      return verify(run, true, attempt_start);
    }
    if (!(guard.fired && run.stopped_by_callback)) return verify(run, run.solved, attempt_start);
    // The iterate left its modes: keep the Newton direction in q, drop the modes (see header).
    if (summary_.restarts >= options_.max_restarts || summary_.iterations >= options_.max_iterations) {
      summary_.final = guard.last_good;
      summary_.final_objective = objective_.evaluate(guard.last_good, Need::Value).value;
      return {FullSpaceStatus::WrongModes,
              "the mode guard fired " + std::to_string(summary_.restarts + 1) +
                  " times (an eigenpair left its measured mode); restarts exhausted",
              {}};
    }
    ++summary_.restarts;
    p = backtrack(guard.last_good, guard.fired_at);
  }
}

// 4. The end point against a forward solve at its parameters, and the result fields.
FullSpaceDriver::Outcome FullSpaceDriver::verify(const detail::NewtonPhaseResult& run, bool converged,
                                                 size_t attempt_start) {
  const detail::FullSpaceProblem& fp = *fp_;
  Matrix U;
  Vector lambda;
  fp.unpack(run.x.data(), &U, &lambda, &summary_.final);
  Outcome outcome;
  outcome.forward = objective_.evaluate(summary_.final, Need::Value);
  const Evaluation& final_forward = outcome.forward;
  summary_.mode_check = check_modes(objective_, *fp_, run.x, final_forward, options_);
  summary_.final_objective = final_forward.ok ? final_forward.value : NAN;
  summary_.eigenvalues = lambda;
  summary_.modes = U;
  summary_.measured_of_mode = fp.measured_modes();
  fp.unpack_multipliers(run.y.data(), &summary_.multipliers, &summary_.normalization_multipliers);
  std::vector<double> errors;
  for (size_t k = attempt_start; k < summary_.kkt_history.size(); ++k)  // the rate of the attempt that finished
    errors.push_back(std::max(summary_.kkt_history[k].primal_infeasibility, summary_.kkt_history[k].dual_infeasibility));
  summary_.convergence_order = estimate_convergence_order(errors);
  const std::string solver_name = to_string(options_.newton_solver);
  if (converged && summary_.mode_check.passed) {
    outcome.status = FullSpaceStatus::Converged;
    outcome.message = solver_name + ": " + run.status;
  } else if (converged) {
    outcome.status = FullSpaceStatus::WrongModes;
    outcome.message = summary_.mode_check.reason;
  } else {
    outcome.status = run.max_iterations ? FullSpaceStatus::MaxIterations : FullSpaceStatus::Failed;
    outcome.message = run.max_iterations ? solver_name + ": " + run.status : run.message;
  }
  return outcome;
}

// 5. Escape from a minimum where paired modes cross (FullSpaceOptions::max_crossing_escapes):
// globalize again on the eigenvalues in frequency order, solve again, keep the lower minimum.
FullSpaceDriver::Outcome FullSpaceDriver::escape_crossings(Outcome outcome) {
  for (int escape = 0; escape < options_.max_crossing_escapes && weighted_eigenvalues_ &&
                       options_.globalization_iterations > 0 && outcome.status == FullSpaceStatus::Converged;
       ++escape) {
    const std::string crossing = crossed_pairs(problem_, outcome.forward.pairs);
    if (crossing.empty()) break;
    if (!escape_objective_) {
      ObjectiveOptions in_order = global_objective().options();
      in_order.eigenvalues_in_frequency_order = true;
      escape_objective_.reset(new Objective(eigenvalue_terms(), in_order, objective_));
    }
    const FullSpaceSummary minimum = summary_;
    const Outcome minimum_outcome = outcome;
    Vector from = globalize_on(*escape_objective_, summary_.final, options_.globalization_iterations);
    from = globalize(from, options_.globalization_iterations);
    outcome = solve_from(from);
    CrossingEscape record;
    record.crossing = crossing;
    record.objective_at_minimum = minimum.final_objective;
    record.objective_after = summary_.final_objective;
    record.converged = outcome.status == FullSpaceStatus::Converged;
    record.kept = record.converged && summary_.final_objective < minimum.final_objective;
    if (!record.kept) {
      keep_result(minimum, &summary_);
      outcome = minimum_outcome;
    }
    summary_.crossing_escapes.push_back(record);
    if (!record.kept) break;
  }
  return outcome;
}

}  // namespace detail

FullSpaceSummary minimize_fullspace(Objective& objective, const Vector& p0, const FullSpaceOptions& options) {
  std::string error;
  if (!options.IsValid(&error)) throw std::invalid_argument("FullSpaceOptions: " + error);
  objective.require_parameters(p0, "minimize_fullspace");
  if (objective.options().eigenvalue_misfit != ObjectiveOptions::EigenvalueMisfit::Relative)
    throw std::invalid_argument(
        "minimize_fullspace: the objective's eigenvalue_misfit must be Relative (the full-space constraints carry "
        "the relative misfit); FullSpaceOptions::globalization_misfit chooses the globalization's");
  return detail::FullSpaceDriver(objective, p0, options).run();
}

}  // namespace modalcal
