// The full-space driver: globalization, start, guarded Newton phase (Ipopt or block SQP) with restarts, and
// the final check against a forward solve (see include/modalcal/fullspace.hpp).

#include <algorithm>
#include <chrono>
#include <cmath>
#include <memory>
#include <stdexcept>

#include "fullspace/block_newton.hpp"
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

FullSpaceSummary minimize_fullspace(Objective& objective, const Vector& p0, const FullSpaceOptions& options) {
  std::string error;
  if (!options.IsValid(&error)) throw std::invalid_argument("FullSpaceOptions: " + error);
  objective.require_parameters(p0, "minimize_fullspace");
  if (objective.options().eigenvalue_misfit != ObjectiveOptions::EigenvalueMisfit::Relative)
    throw std::invalid_argument(
        "minimize_fullspace: the objective's eigenvalue_misfit must be Relative (the full-space constraints carry "
        "the relative misfit); FullSpaceOptions::globalization_misfit chooses the globalization's");
  const Clock::time_point start = Clock::now();
  const Problem& problem = objective.problem();
  const int forward_solves_before = objective.forward_solves();
  const std::optional<Vector> truth = truth_of(problem);
  FullSpaceSummary summary;
  // The Newton phase keeps the parameters within their bounds: so does the start.
  const Vector start_point = p0.cwiseMax(problem.lower_bounds()).cwiseMin(problem.upper_bounds());
  summary.initial = summary.final = start_point;
  // The globalization's objective: the same data and options with its own eigenvalue misfit.
  std::unique_ptr<Objective> misfit_objective;
  if (options.globalization_misfit != objective.options().eigenvalue_misfit) {
    ObjectiveOptions global_options = objective.options();
    global_options.eigenvalue_misfit = options.globalization_misfit;
    misfit_objective = std::make_unique<Objective>(problem, global_options);
  }
  Objective& global_objective = misfit_objective ? *misfit_objective : objective;
  // The eigenvalues-first stage and the crossing escape minimize the eigenvalue terms alone: the
  // same problem with every shape weight 0 (the shapes still pair the modes), made once when needed.
  const bool weighted_shapes = std::any_of(problem.measured.begin(), problem.measured.end(),
                                           [](const MeasuredMode& m) { return m.has_shape_term(); });
  const bool weighted_eigenvalues = std::any_of(problem.measured.begin(), problem.measured.end(),
                                                [](const MeasuredMode& m) { return m.weight > 0; });
  std::unique_ptr<Problem> eigenvalue_problem;
  auto eigenvalue_terms = [&]() -> const Problem& {
    if (!eigenvalue_problem) {
      eigenvalue_problem = std::make_unique<Problem>(problem);
      for (MeasuredMode& m : eigenvalue_problem->measured) m.shape_weight = 0;
    }
    return *eigenvalue_problem;
  };
  std::unique_ptr<Objective> eigenvalue_objective;
  if (options.eigenvalues_first && options.globalization_iterations > 0 && weighted_shapes && weighted_eigenvalues)
    eigenvalue_objective = std::make_unique<Objective>(eigenvalue_terms(), global_objective.options());
  // The crossing escape's: compared in frequency order (made when needed).
  std::unique_ptr<Objective> escape_objective;
  auto finish = [&](FullSpaceStatus status, const std::string& message) {
    summary.status = status;
    if (summary.message.empty()) summary.message = message;
    summary.forward_solves = objective.forward_solves() - forward_solves_before +
                             (misfit_objective ? misfit_objective->forward_solves() : 0) +
                             (eigenvalue_objective ? eigenvalue_objective->forward_solves() : 0) +
                             (escape_objective ? escape_objective->forward_solves() : 0);
    summary.seconds = seconds_since(start);
    return summary;
  };

  const bool structured = options.newton_solver == FullSpaceOptions::NewtonSolver::BlockElimination ||
                          options.kkt_solver == FullSpaceOptions::KktSolver::Structured;
  summary.kkt_solver = to_string(structured ? FullSpaceOptions::KktSolver::Structured : FullSpaceOptions::KktSolver::Mumps);
  const Evaluation initial = objective.evaluate(start_point, Need::Value);
  if (!initial.ok) return finish(FullSpaceStatus::ForwardSolveFailed, "at the start: " + initial.message);
  summary.initial_objective = summary.final_objective = initial.value;
  if (options.max_iterations == 0) {
    summary.newton_solver = to_string(options.newton_solver);
    summary.newton_status = "not run";
    summary.mode_check.reason = "not checked: no iteration";
    return finish(FullSpaceStatus::MaxIterations, "max_iterations = 0: the start evaluated, no iteration made");
  }

  // 1. Globalization: reduced L-BFGS always tracks the paired modes.
  auto globalize_on = [&](Objective& on, const Vector& from, int iterations) {
    ReducedOptions reduced;
    reduced.max_iterations = iterations;
    reduced.relative_gradient_tolerance = options.globalization_reduction;
    reduced.scaling = options.scaling;
    const ReducedSummary run = minimize_reduced(on, from, reduced);
    for (IterationRecord record : run.history) {
      if (!summary.globalization_history.empty() && record.iteration == 0) continue;
      record.iteration += summary.globalization_iterations;
      summary.globalization_history.push_back(record);
    }
    summary.globalization_iterations += run.iterations;
    return run.final;
  };
  auto globalize = [&](const Vector& from, int iterations) { return globalize_on(global_objective, from, iterations); };
  Vector globalized = start_point;
  if (eigenvalue_objective) globalized = globalize_on(*eigenvalue_objective, globalized, options.globalization_iterations);
  if (options.globalization_iterations > 0) globalized = globalize(globalized, options.globalization_iterations);

  const ParameterScaling scaling = options.scaling ? ParameterScaling(problem.parameters, *options.scaling)
                                                   : ParameterScaling(problem.parameters);
  // Restart point after the guard fired at `to`: the first of q(from) + a (q(to) - q(from)),
  // a = 1, 1/2, ..., that decreases the reduced objective, else reduced L-BFGS from `from`.
  auto backtrack = [&](const Vector& from, const Vector& to) {
    const Evaluation at_from = objective.evaluate(from, Need::Value);
    const Vector q0 = scaling.to_scaled(from), dq = scaling.to_scaled(to) - q0;
    for (double a = 1; at_from.ok && a > 1e-3; a *= 0.5) {
      const Vector trial = scaling.to_physical(q0 + a * dq);
      const Evaluation e = objective.evaluate(trial, Need::Value);
      if (e.ok && e.value < at_from.value) return trial;
    }
    return globalize(from, std::max(options.globalization_iterations, 10));
  };
  detail::FullSpaceProblem fp(objective, scaling, globalized);
  summary.num_unknowns = fp.num_variables();
  summary.num_constraints = fp.num_constraints();

  const std::string solver_name = to_string(options.newton_solver);
  summary.newton_solver = solver_name;
  // 2-4. Newton from p to convergence (guarded, restarted), then the check against a forward solve.
  struct Outcome {
    FullSpaceStatus status = FullSpaceStatus::Failed;
    std::string message;
    Evaluation forward;  // at the final parameters (when the Newton phase ended normally)
  };
  auto solve_from = [&](Vector p) -> Outcome {
    detail::NewtonPhaseResult run;
    bool converged_run = false;
    size_t attempt_start = 0;  // first KKT record of the last attempt
    for (;;) {
      // 2. Start from the forward solution at p, signs aligned, multipliers from the adjoint.
      const Evaluation e = objective.evaluate(p, Need::Gradient);
      if (!e.ok) return {FullSpaceStatus::ForwardSolveFailed, "start of the Newton phase: " + e.message, {}};
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
      const Vector x0 = fp.pack(U, lambda, p), y0 = fp.pack_multipliers(W, eta);

      // 3. Newton phase, guarded.
      Vector last_good = p, fired_at = p;
      bool guard_fired = false;
      const int offset = summary.iterations;
      attempt_start = summary.kkt_history.size();
      detail::NewtonCallback callback = [&](const detail::NewtonIteration& info, const double* x) {
        KktRecord record;
        record.iteration = offset + info.iteration;
        record.objective = info.objective;
        record.primal_infeasibility = info.primal_infeasibility;
        record.dual_infeasibility = info.dual_infeasibility;
        record.complementarity = info.complementarity;
        record.mu = info.mu;
        record.step_length = info.step_length;
        record.hessian_shift = info.hessian_shift;
        record.p = fp.parameters(x);
        record.parameter_error = parameter_error(truth, record.p);
        if (options.mode_guard) {
          const Clock::time_point guard_start = Clock::now();
          const Evaluation forward = objective.evaluate(record.p, Need::Value);
          double min_mac = 0;
          if (forward.ok) {
            const SparseMatrix& M = fp.mass_matrix(x);
            min_mac = 1;
            for (int i = 0; i < fp.num_modes(); ++i) {
              const Eigen::Map<const Vector> u(x + i * fp.num_dofs(), fp.num_dofs());
              min_mac = std::min(min_mac, mass_mac(M, u, forward.modal.modes.col(forward.pairs[fp.measured_of(i)].model)));
            }
          }
          record.min_mac = min_mac;
          summary.guard_seconds += seconds_since(guard_start);
          if (min_mac < options.guard_mac) {
            guard_fired = true;
            fired_at = record.p;
          } else {
            last_good = record.p;
          }
        }
        summary.kkt_history.push_back(record);
        if (options.progress) options.progress(record);
        return !guard_fired;
      };
      detail::NewtonPhaseOptions newton;
      newton.max_iterations = std::max(1, options.max_iterations - summary.iterations);
      newton.tolerance = options.tolerance;
      newton.mu_init = options.mu_init;
      newton.exact_hessian = options.hessian == FullSpaceOptions::Hessian::Exact;
      newton.derivative_test = options.ipopt_derivative_test;
      newton.print_level = options.print_level;
      newton.structured_kkt = options.kkt_solver == FullSpaceOptions::KktSolver::Structured;
      const Clock::time_point newton_start = Clock::now();
      run = options.newton_solver == FullSpaceOptions::NewtonSolver::Ipopt
                ? detail::run_ipopt(fp, x0, y0, newton, callback)
                : detail::run_block_newton(fp, x0, y0, newton, callback);
      summary.newton_seconds += seconds_since(newton_start);
      summary.iterations += run.iterations;
      summary.kkt_solves += run.hessian_evaluations;
      summary.structured_factorizations += run.structured_factorizations;
      summary.mumps_factorizations += run.mumps_factorizations;
      summary.newton_status = run.status;
      if (run.outside_newton_region && summary.restarts < options.max_restarts &&
          summary.iterations < options.max_iterations) {
        ++summary.restarts;  // more reduced iterations from where Newton stalled, then Newton again
        p = globalize(fp.parameters(run.x.data()), std::max(options.globalization_iterations, 10));
        continue;
      }
      if (!(guard_fired && run.stopped_by_callback)) {
        converged_run = run.solved;
        break;
      }
      // The iterate left its modes: keep the Newton direction in q, drop the modes (see header).
      if (summary.restarts >= options.max_restarts || summary.iterations >= options.max_iterations) {
        summary.final = last_good;
        summary.final_objective = objective.evaluate(last_good, Need::Value).value;
        return {FullSpaceStatus::WrongModes,
                "the mode guard fired " + std::to_string(summary.restarts + 1) +
                    " times (an eigenpair left its measured mode); restarts exhausted",
                {}};
      }
      ++summary.restarts;
      p = backtrack(last_good, fired_at);
    }

    // 4. Verify against a forward solve at the final parameters.
    Matrix U;
    Vector lambda;
    fp.unpack(run.x.data(), &U, &lambda, &summary.final);
    Outcome outcome;
    outcome.forward = objective.evaluate(summary.final, Need::Value);
    const Evaluation& final_forward = outcome.forward;
    summary.mode_check = check_modes(objective, fp, run.x, final_forward, options);
    summary.final_objective = final_forward.ok ? final_forward.value : NAN;
    summary.eigenvalues = lambda;
    summary.modes = U;
    summary.measured_of_mode = fp.measured_modes();
    fp.unpack_multipliers(run.y.data(), &summary.multipliers, &summary.normalization_multipliers);
    std::vector<double> errors;
    for (size_t k = attempt_start; k < summary.kkt_history.size(); ++k)  // the rate of the attempt that finished
      errors.push_back(std::max(summary.kkt_history[k].primal_infeasibility, summary.kkt_history[k].dual_infeasibility));
    summary.convergence_order = estimate_convergence_order(errors);

    if (converged_run && summary.mode_check.passed) {
      outcome.status = FullSpaceStatus::Converged;
      outcome.message = solver_name + ": " + run.status;
    } else if (converged_run) {
      outcome.status = FullSpaceStatus::WrongModes;
      outcome.message = summary.mode_check.reason;
    } else {
      outcome.status = run.max_iterations ? FullSpaceStatus::MaxIterations : FullSpaceStatus::Failed;
      outcome.message = run.max_iterations ? solver_name + ": " + run.status : run.message;
    }
    return outcome;
  };

  Outcome outcome = solve_from(globalized);
  // 5. Escape from a minimum where paired modes cross (FullSpaceOptions::max_crossing_escapes).
  for (int escape = 0; escape < options.max_crossing_escapes && weighted_eigenvalues && options.globalization_iterations > 0 &&
                       outcome.status == FullSpaceStatus::Converged;
       ++escape) {
    const std::string crossing = crossed_pairs(problem, outcome.forward.pairs);
    if (crossing.empty()) break;
    if (!escape_objective) {
      ObjectiveOptions in_order = global_objective.options();
      in_order.eigenvalues_in_frequency_order = true;
      escape_objective = std::make_unique<Objective>(eigenvalue_terms(), in_order);
    }
    const FullSpaceSummary minimum = summary;
    const Outcome minimum_outcome = outcome;
    Vector from = globalize_on(*escape_objective, summary.final, options.globalization_iterations);
    from = globalize(from, options.globalization_iterations);
    outcome = solve_from(from);
    CrossingEscape record;
    record.crossing = crossing;
    record.objective_at_minimum = minimum.final_objective;
    record.objective_after = summary.final_objective;
    record.converged = outcome.status == FullSpaceStatus::Converged;
    record.kept = record.converged && summary.final_objective < minimum.final_objective;
    if (!record.kept) {
      keep_result(minimum, &summary);
      outcome = minimum_outcome;
    }
    summary.crossing_escapes.push_back(record);
    if (!record.kept) break;
  }
  return finish(outcome.status, outcome.message);
}

}  // namespace modalcal
