#pragma once
// Internal: one Ipopt solve of a FullSpaceProblem. This header is free of Ipopt types so that
// only ipopt_adapter.cpp sees Ipopt (the modalcal_ipopt target, linked privately).

#include "fullspace/fullspace_problem.hpp"
#include "fullspace/newton_phase.hpp"

namespace modalcal::detail {

/// Solves from the primal-dual point (x0, y0) (warm start; bound multipliers mu/(x - bound)).
NewtonPhaseResult run_ipopt(FullSpaceProblem& problem, const Vector& x0, const Vector& y0,
                            const NewtonPhaseOptions& options, const NewtonCallback& callback);

}  // namespace modalcal::detail
