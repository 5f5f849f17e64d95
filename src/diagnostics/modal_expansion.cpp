#include "diagnostics/modal_expansion.hpp"

#include <Eigen/SVD>

#include <limits>

namespace modalcal::detail {

double condition_number(const Matrix& a) {
  const Vector s = Eigen::JacobiSVD<Matrix>(a).singularValues();
  if (s.size() == 0) return 1.0;
  return s[s.size() - 1] > 0 ? s[0] / s[s.size() - 1] : std::numeric_limits<double>::infinity();
}

// Tikhonov filter factors on the SVD A = U S V^T: c = V diag(s / (s^2 + alpha^2 s_1^2)) U^T y,
// the regularized normal equations solved without forming A^T A (which squares the condition).
ModalExpansion::ModalExpansion(const Matrix& at_sensors, double regularization, double rank_tolerance) {
  const Eigen::BDCSVD<Matrix> svd(at_sensors, Eigen::ComputeThinU | Eigen::ComputeThinV);
  const Vector& s = svd.singularValues();
  const double largest = s.size() ? s[0] : 0.0;
  const double smallest = s.size() ? s[s.size() - 1] : 0.0;
  condition_ = smallest > 0 ? largest / smallest : std::numeric_limits<double>::infinity();
  int kept = 0;
  while (kept < s.size() && s[kept] > rank_tolerance * largest) ++kept;
  left_ = svd.matrixU().leftCols(kept);
  right_ = svd.matrixV().leftCols(kept);
  const double damping = regularization * regularization * largest * largest;
  gain_ = s.head(kept).array() / (s.head(kept).array().square() + damping);
}

Vector ModalExpansion::coefficients(const Vector& readings) const {
  return right_ * gain_.cwiseProduct(left_.transpose() * readings);
}

}  // namespace modalcal::detail
