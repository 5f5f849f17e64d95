#pragma once
// Internal: the mode-shape misfit at the sensors, shared by the reduced objective and the
// full-space problem so that both minimize the same function.

#include "modalcal/assembly.hpp"
#include "modalcal/problem.hpp"

namespace modalcal::detail {

/// P: free DOFs -> sensor readings (rows of T for the sensor DOFs), so a reading is P u.
SparseMatrix sensor_matrix(const Problem& problem, const DofMap& dofs);

/// \f$ g(y) = \frac{\kappa}{2}\big(1 - \mathrm{MAC}(y, \phi)\big) = \frac{\kappa}{2}\Big(1 - \frac{(\hat\phi^T y)^2}{y^T y}\Big) \f$
/// for the sensor readings y = P u of a model mode: invariant to the sign and scale of both y and
/// the measured shape phi.
class ShapeMisfit {
 public:
  ShapeMisfit(const Vector& measured_shape, double weight);
  double value(const Vector& y) const;
  Vector gradient(const Vector& y) const;
  Matrix hessian(const Vector& y) const;

 private:
  Vector phi_;  // unit
  double weight_;
};

}  // namespace modalcal::detail
