#pragma once
// Internal: a refit's Gauss-Newton walk, in a span of the model when that pays; the ranking on an
// objective the loop has solved already.

#include <mutex>

#include "modalcal/effects.hpp"
#include "modalcal/objective.hpp"
#include "modalcal/reduced.hpp"

namespace modalcal::detail {

/// The walk options.refit sets (Gauss-Newton for a refit; the first calibration passes its own
/// L-BFGS) from p0: in a span of the model when it has at most
/// RankingOptions::refit_span_share of the model's DOFs (`span`, else `objective.span_at(p0)`),
/// its end then checked on the whole model and kept when the two misfits agree to the walk's
/// function tolerance and a Gauss-Newton step with the whole model's gradient would gain less
/// than that. When not, the walk goes on in the span at that end (span_at, whose forward solve
/// the check has made), checked again; then on the whole model from the last end, or from p0
/// when no span is taken. The objective is left on the whole model. Counts (iterations, solves)
/// are the walks' together.
ReducedSummary refit_walk(Objective& objective, const Vector& p0, const RankingOptions& options, Matrix span = {});

/// The span the refits of one ranking share: the ranked model's at its calibrated point
/// (Objective::span_at), extended for each refit by its effect's own directions
/// (Objective::extend_span). A refit then starts in a span without a forward solve of its own.
/// Refits may ask for theirs at once, from threads (they take turns on the one factorization).
class StepSpan {
 public:
  /// `ranked` has solved its model at `calibrated`, or solves it now. No span is kept when that
  /// fails or the span is wider than RankingOptions::refit_span_share of the DOFs.
  StepSpan(Objective& ranked, const Vector& calibrated, const RankingOptions& options);
  /// The span for `refit`, the ranked model with its effect, starting at p0; empty when there is
  /// none (see the constructor; or the effect changes the model's DOFs, as freeing a support).
  Matrix for_refit(const Objective& refit, const Vector& p0);

 private:
  Objective& ranked_;
  const Vector calibrated_;
  Matrix span_;
  std::mutex turn_;
};

/// rank_effects() on `objective`'s problem with `objective` (made with options.objective): no
/// forward solve at `calibrated` when the objective last solved there, as the loop's fit of the
/// state it screens has.
EffectRanking rank_effects_with(Objective& objective, const Vector& calibrated,
                                const std::vector<EffectCandidate>& candidates, const RankingOptions& options);

}  // namespace modalcal::detail
