#pragma once
// Internal: the structured KKT solver behind Ipopt's `linear_solver pardiso`
// (ipopt/pardiso_trampoline.h). Ipopt hands over its regularized KKT matrix
//   [[W + Sigma + delta_w I, J^T], [J, -delta_c I]]
// (upper triangle, 1-based CSR, unknowns [x | y_c]: our problem has no inequality constraints,
// only bounds on q). Where the matrix has the layout of the registered FullSpaceProblem, it is
// solved by per-mode block elimination (block_elimination.hpp): one factorization of each
// mode's bordered block (or, with shared_factorization, one factorization of K - sigma M for all
// modes: shared_shift_solve.hpp), an m x m reduced Hessian on q whose eigenvalues give the inertia
// of the whole matrix (negatives = rows of J + negatives of H). Elsewhere - another layout (Ipopt's
// restoration phase, a fixed parameter), delta_c > 0 (Ipopt's answer to a singular matrix), no
// registered problem - MUMPS factors the whole matrix, as Ipopt's own MUMPS path would.

#include "fullspace/fullspace_problem.hpp"

namespace modalcal::detail {

/// Factorizations of the KKT systems of one Ipopt run, by who did them.
struct KktFactorizationCounts {
  int structured = 0;
  int mumps = 0;  ///< whole-matrix fallbacks
  /// Mode eliminations through one shared factorization (shared_shift_solve.hpp), and modes
  /// where its solves failed and B_i was factored instead.
  int shared_modes = 0, shared_failures = 0;
};

/// While alive, Ipopt runs in this thread that use `linear_solver pardiso` get the structured
/// solver for `problem`'s layout and count their factorizations in `counts`; with
/// `shared_factorization`, the modes' bordered blocks are solved through one factorization of
/// K - sigma M at the point of the problem's last Jacobian (shared_shift_solve.hpp). Installs the
/// handler into the trampoline library.
class StructuredKktScope {
 public:
  StructuredKktScope(FullSpaceProblem& problem, KktFactorizationCounts* counts, bool shared_factorization = false);
  ~StructuredKktScope();
  StructuredKktScope(const StructuredKktScope&) = delete;
  StructuredKktScope& operator=(const StructuredKktScope&) = delete;

 private:
  const void* previous_;
};

}  // namespace modalcal::detail
