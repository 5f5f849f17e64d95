#pragma once
// Internal: the full-space Newton phase without Ipopt - an SQP iteration whose KKT systems are
// solved by per-mode block elimination (block_kkt.hpp) instead of one factorization of the
// whole KKT matrix.
//
// Iteration k at (x, y):
//   1. build the KKT system by blocks; KKT error max(|c|_inf, |projected grad L|_inf) (bounds on
//      q only: a component pushing against its bound does not count); stop below `tolerance`;
//   2. inertia: H + delta I positive definite (Cholesky, delta from 0, then 1e-8 |H| up by 10x),
//      which is the whole inertia test (block_kkt.hpp);
//   3. dq from the bound-constrained reduced QP (box_qp.hpp), then dx, dy;
//   4. step length by backtracking on the l1 merit f + nu |c|_1 (Armijo); the full step is also
//      taken when it halves the constraint violation relative to the KKT error without raising f
//      by more than that error (the Maratos effect would otherwise reject the full steps that
//      converge quadratically); y <- y + alpha dy.
// Parameters stay within their bounds at every iterate (the QP's bounds), as with Ipopt.

#include "fullspace/fullspace_problem.hpp"
#include "fullspace/newton_phase.hpp"

namespace modalcal::detail {

NewtonPhaseResult run_block_newton(FullSpaceProblem& problem, const Vector& x0, const Vector& y0,
                                   const NewtonPhaseOptions& options, const NewtonCallback& callback);

}  // namespace modalcal::detail
