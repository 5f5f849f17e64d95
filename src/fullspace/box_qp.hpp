#pragma once
// Internal: min 1/2 d^T H d - h^T d subject to lower <= d <= upper, for the few parameters of a
// calibration (m <= a few dozen), by a primal active-set method (Nocedal & Wright, Alg. 16.3):
// solve on the free set, step to the first blocking bound, release a bound whose multiplier has
// the wrong sign. H must be symmetric positive definite; lower <= 0 <= upper (d = 0 feasible).

#include "modalcal/types.hpp"

namespace modalcal::detail {

struct BoxQpResult {
  Vector d;
  std::vector<bool> at_bound;  ///< per parameter: the solution lies on a bound
  bool converged = false;      ///< false only if the iteration limit was hit (cycling)
};

BoxQpResult solve_box_qp(const Matrix& H, const Vector& h, const Vector& lower, const Vector& upper);

}  // namespace modalcal::detail
