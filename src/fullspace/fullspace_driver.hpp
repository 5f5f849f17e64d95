#pragma once
// Internal: the driver of minimize_fullspace (modalcal/fullspace.hpp), a class whose public
// methods are the steps of that header's list, so that each can be tested on its own.

#include <chrono>
#include <memory>
#include <optional>
#include <string>

#include "fullspace/fullspace_problem.hpp"
#include "fullspace/newton_phase.hpp"
#include "modalcal/fullspace.hpp"
#include "modalcal/objective.hpp"

namespace modalcal::detail {

/// The driver of minimize_fullspace, one method per step of fullspace.hpp's list: the objectives it
/// minimizes (the problem's, the globalization's misfit, the eigenvalue terms alone, the crossing
/// escape's), the full-space problem, and the summary it fills as it goes.
class FullSpaceDriver {
 public:
  FullSpaceDriver(Objective& objective, const Vector& p0, const FullSpaceOptions& options);
  /// The driver keeps a reference to its options: a temporary would dangle.
  FullSpaceDriver(Objective& objective, const Vector& p0, FullSpaceOptions&& options) = delete;
  /// Steps 1-5 in turn, the summary filled.
  FullSpaceSummary run();

  // The steps, public for their unit tests (tests/test_fullspace.cpp, FullSpaceDriver.*).
  struct Outcome {
    FullSpaceStatus status = FullSpaceStatus::Failed;
    std::string message;
    Evaluation forward;  // at the final parameters (when the Newton phase ended normally)
  };
  /// One Newton attempt's guard: where the iterate last had its modes and where it lost them;
  /// whether it stopped the attempt at the constraints' rounding floor (at_rounding_floor).
  struct Guard {
    Vector last_good, fired_at;
    bool fired = false;
    int offset = 0;  // Newton iterations before this attempt
    bool at_floor = false;
    double previous_primal = -1;  // the attempt's previous constraint violation (-1: none yet)
    double start_primal = -1;     // at the attempt's start, a forward solve's residual (-1: none yet)
  };

  /// 1. Reduced L-BFGS from `start` (eigenvalue terms first) until the projected gradient has
  /// fallen by globalization_reduction; returns where it ended.
  Vector globalize_from_start(const Vector& start);
  /// The Newton phase's variables and scaling, made at p; before the steps below.
  void set_up_newton(const Vector& p);
  /// 2. The Newton start at p: forward solution, signs aligned, adjoint multipliers; the reason
  /// when the forward solve fails.
  std::optional<std::string> newton_start(const Vector& p, Vector* x0, Vector* y0);
  /// 3. The per-iteration callback: records the iteration, guards it (when guard_needed).
  NewtonCallback guarded(Guard* guard);
  bool guard_needed(const Guard& guard, const KktRecord& record) const;
  /// Whether the attempt has reached the rounding floor of its constraints: gradient and
  /// complementarity converged, the constraint violation within kFloorFactor of the tolerance
  /// but above it, and either the last full step cut it less than kFloorReduction-fold, where
  /// Newton so near the solution would square it, or it is within kFloorReduction of the
  /// start's, a forward solve's residual that was itself above the tolerance (large models):
  /// the constraints are then met as well as the eigen-solve meets them. Further iterations
  /// would only chase rounding.
  bool at_rounding_floor(const Guard& guard, const KktRecord& record) const;
  static constexpr double kFloorFactor = 100, kFloorReduction = 4;
  /// 2-4. Newton from p to convergence, restarted where the guard fires, then verified.
  Outcome solve_from(Vector p);
  /// 4. The end point of a Newton attempt against a forward solve at its parameters.
  Outcome verify(const NewtonPhaseResult& run, bool converged, size_t attempt_start);
  /// 5. Escape from a converged minimum where MAC-paired modes cross.
  Outcome escape_crossings(Outcome outcome);
  const FullSpaceSummary& summary() const { return summary_; }
  FullSpaceProblem& fullspace_problem() { return *fp_; }

 private:
  Objective& global_objective() { return misfit_objective_ ? *misfit_objective_ : objective_; }
  const Problem& eigenvalue_terms();
  FullSpaceSummary finish(FullSpaceStatus status, const std::string& message);
  Vector globalize_on(Objective& on, const Vector& from, int iterations);
  Vector globalize(const Vector& from, int iterations) { return globalize_on(global_objective(), from, iterations); }
  Vector backtrack(const Vector& from, const Vector& to);
  NewtonPhaseOptions newton_options() const;

  Objective& objective_;
  const FullSpaceOptions& options_;
  const Problem& problem_;
  const std::chrono::steady_clock::time_point start_;
  const int forward_solves_before_;
  const std::optional<Vector> truth_;
  const bool weighted_shapes_, weighted_eigenvalues_;
  FullSpaceSummary summary_;
  std::unique_ptr<Objective> misfit_objective_, eigenvalue_objective_, escape_objective_;
  std::unique_ptr<Problem> eigenvalue_problem_;
  std::optional<ParameterScaling> scaling_;
  std::unique_ptr<FullSpaceProblem> fp_;
  bool shared_factorization_ = false;  // FullSpaceOptions::bordered_solves, decided for fp_'s size
};

}  // namespace modalcal::detail
