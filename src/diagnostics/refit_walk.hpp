#pragma once
// Internal: a refit's Gauss-Newton walk, in a span of the model when that pays.

#include "modalcal/effects.hpp"
#include "modalcal/objective.hpp"
#include "modalcal/reduced.hpp"

namespace modalcal::detail {

/// Gauss-Newton (options.refit) from p0: in the span `objective.span_at(p0)` gives when that is at
/// most RankingOptions::refit_span_share of the model's DOFs, its end then checked on the whole
/// model and kept when the two misfits agree to the refit's function tolerance and a Gauss-Newton
/// step with the whole model's gradient would gain less than that; on the whole model from that
/// end when not, or from p0 when no span is taken. The objective is left on the whole model.
/// Counts (iterations, solves) are the walks' together.
ReducedSummary refit_walk(Objective& objective, const Vector& p0, const RankingOptions& options);

}  // namespace modalcal::detail
