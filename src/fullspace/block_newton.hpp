#pragma once
// Internal: the full-space Newton phase without Ipopt - an SQP iteration whose KKT systems are
// solved by per-mode block elimination (block_kkt.hpp) instead of one factorization of the
// whole KKT matrix.
//
// Iteration k at (x, y):
//   1. build the KKT system by blocks; KKT error max(|c|_inf, |projected grad L|_inf) (bounds on
//      q only: a component pushing against its bound does not count); stop below `tolerance`;
//   2. inertia: where the reduced Hessian H has an eigenvalue below 1e-8 of its largest, shift it
//      so that its smallest is 1e-4 of the largest - H is the whole inertia test (block_kkt.hpp);
//   3. dq from the QP in q within the bounds and a trust box (box_qp.hpp), then dx, dy;
//   4. step length by Ipopt's filter line search on (|c|_1, f) (Waechter & Biegler 2006), which
//      lets the iterate leave the constraints behind while f falls - a monotone l1 merit cut the
//      steps along curved valleys of J to a crawl (docs/design.md); y <- y + alpha dy; the trust box
//      follows the accepted step;
//   5. three cut steps in a row (line search or trust box): the iterate is outside Newton's
//      region, and the driver globalizes again (NewtonPhaseResult::outside_newton_region).
// Parameters stay within their bounds at every iterate (the QP's bounds), as with Ipopt.

#include "fullspace/fullspace_problem.hpp"
#include "fullspace/newton_phase.hpp"

namespace modalcal::detail {

NewtonPhaseResult run_block_newton(FullSpaceProblem& problem, const Vector& x0, const Vector& y0,
                                   const NewtonPhaseOptions& options, const NewtonCallback& callback);

}  // namespace modalcal::detail
