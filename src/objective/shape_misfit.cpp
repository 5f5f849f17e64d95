#include "objective/shape_misfit.hpp"

namespace modalcal::detail {

SparseMatrix sensor_matrix(const Problem& problem, const DofMap& dofs) {
  std::vector<Eigen::Triplet<double, int>> entries;
  for (size_t s = 0; s < problem.sensors.size(); ++s) {
    const int f = dofs.full_index(problem.sensors[s].node, problem.sensors[s].component);
    for (DofMap::RowSparseMatrix::InnerIterator it(dofs.transformation_rows(), f); it; ++it)
      entries.emplace_back(static_cast<int>(s), static_cast<int>(it.col()), it.value());
  }
  SparseMatrix P(problem.sensors.size(), dofs.num_free());
  P.setFromTriplets(entries.begin(), entries.end());
  return P;
}

ShapeMisfit::ShapeMisfit(const Vector& measured_shape, double weight)
    : phi_(measured_shape.normalized()), weight_(weight) {}

double ShapeMisfit::value(const Vector& y) const {
  const double a = phi_.dot(y);
  return 0.5 * weight_ * (1 - a * a / y.squaredNorm());
}

// With a = phi^T y and s = y^T y: dg/dy = -kappa (a phi / s - a^2 y / s^2).
Vector ShapeMisfit::gradient(const Vector& y) const {
  const double a = phi_.dot(y), s = y.squaredNorm();
  return -weight_ * (a / s * phi_ - a * a / (s * s) * y);
}

Matrix ShapeMisfit::hessian(const Vector& y) const {
  const double a = phi_.dot(y), s = y.squaredNorm();
  Matrix H = -phi_ * phi_.transpose() / s + 2 * a * (phi_ * y.transpose() + y * phi_.transpose()) / (s * s) +
             (a * a / (s * s)) * Matrix::Identity(y.size(), y.size()) - 4 * a * a * y * y.transpose() / (s * s * s);
  return weight_ * H;
}

}  // namespace modalcal::detail
