#pragma once
// Internal: least-squares expansion of sensor readings on a basis of model modes (SEREP when
// unregularized), see localization.hpp for the formula.

#include "modalcal/types.hpp"

namespace modalcal::detail {

/// \f$\sigma_{max}/\sigma_{min}\f$ of a matrix with at least as many rows as columns (infinite if
/// rank deficient).
double condition_number(const Matrix& a);

class ModalExpansion {
 public:
  /// `at_sensors` is \f$P\Phi\f$ (readings x basis modes). `regularization` is alpha relative to
  /// the largest singular value; singular values below `rank_tolerance` times the largest are
  /// dropped.
  ModalExpansion(const Matrix& at_sensors, double regularization, double rank_tolerance);

  /// Basis coefficients c minimizing \f$\|P\Phi c - y\|^2 + \alpha^2\sigma_1^2\|c\|^2\f$.
  Vector coefficients(const Vector& readings) const;
  /// \f$\sigma_{max}/\sigma_{min}\f$ of \f$P\Phi\f$ (infinite if a column combination is unseen).
  double condition() const { return condition_; }

 private:
  Matrix left_, right_;  // singular vectors kept
  Vector gain_;          // filtered inverse singular values sigma / (sigma^2 + alpha^2 sigma_1^2)
  double condition_ = 0;
};

}  // namespace modalcal::detail
