// Test-analysis correlation: pairing, MAC matrix, COMAC and SEREP cross-orthogonality
// (formulas in comparison.hpp).
#include "modalcal/comparison.hpp"

#include <Eigen/SVD>

#include <algorithm>
#include <stdexcept>

#include "modalcal/objective.hpp"
#include "objective/shape_misfit.hpp"

namespace modalcal {

bool ComparisonOptions::IsValid(std::string* error) const {
  if (!(unpaired_mac >= 0 && unpaired_mac <= 1)) {
    if (error) *error = "unpaired_mac = " + std::to_string(unpaired_mac) + ": must be in [0, 1]";
    return false;
  }
  if (!(serep_condition > 0 && serep_condition < 1)) {
    if (error) *error = "serep_condition = " + std::to_string(serep_condition) + ": must be in (0, 1)";
    return false;
  }
  return true;
}

namespace {

Vector comac(const std::vector<Vector>& measured, const std::vector<Vector>& model) {
  const Eigen::Index ns = measured.front().size();
  Vector numerator = Vector::Zero(ns), measured_squares = Vector::Zero(ns), model_squares = Vector::Zero(ns);
  for (size_t i = 0; i < measured.size(); ++i) {
    const Vector scaled = measured[i] * (model[i].dot(measured[i]) / measured[i].squaredNorm());  // MSF
    numerator += scaled.cwiseProduct(model[i]).cwiseAbs();
    measured_squares += scaled.cwiseAbs2();
    model_squares += model[i].cwiseAbs2();
  }
  Vector c(ns);
  for (Eigen::Index s = 0; s < ns; ++s) {
    const double denominator = measured_squares[s] * model_squares[s];
    c[s] = denominator > 0 ? numerator[s] * numerator[s] / denominator : NAN;
  }
  return c;
}

}  // namespace

ModalComparison compare_modes(const Problem& problem, const Vector& p, const ComparisonOptions& options) {
  std::string error;
  if (!options.IsValid(&error)) throw std::invalid_argument("ComparisonOptions: " + error);
  Objective objective(problem);
  const Evaluation e = objective.evaluate(p);
  if (!e.ok) throw std::runtime_error(e.message);
  const Matrix model_at_sensors = detail::sensor_matrix(problem, objective.system().dof_map()) * e.modal.modes;
  const int num_model = static_cast<int>(e.modal.eigenvalues.size());
  const int num_measured = static_cast<int>(problem.measured.size());

  ModalComparison c;
  c.warnings = e.warnings;
  c.model_hz.resize(num_model);
  for (int k = 0; k < num_model; ++k) c.model_hz[k] = frequency_hz(e.modal.eigenvalues[k]);
  c.mac = Matrix::Constant(num_measured, num_model, NAN);
  for (int i = 0; i < num_measured; ++i)
    if (problem.measured[i].shape.size() > 0)
      for (int k = 0; k < num_model; ++k) c.mac(i, k) = mac(problem.measured[i].shape, model_at_sensors.col(k));

  std::vector<bool> paired(num_model, false);
  std::vector<Vector> measured_shapes, model_shapes;
  for (const PairedMode& pair : e.pairs) {
    ComparedPair row;
    row.measured = pair.measured;
    row.model = pair.model;
    row.measured_hz = pair.measured_hz;
    row.model_hz = pair.model_hz;
    row.error_percent = 100 * (pair.model_hz / pair.measured_hz - 1);
    row.mac = pair.mac;
    paired[pair.model] = true;
    if (row.mac >= 0) {
      if (row.mac < options.unpaired_mac) c.unpaired_measured.push_back(static_cast<int>(c.pairs.size()));
      c.shape_pairs.push_back(static_cast<int>(c.pairs.size()));
      measured_shapes.push_back(problem.measured[pair.measured].shape);
      model_shapes.push_back(model_at_sensors.col(pair.model));
    }
    c.pairs.push_back(row);
  }
  for (int k = 0; k < num_model; ++k)
    if (!paired[k]) c.unpaired_model.push_back(k);
  if (measured_shapes.empty()) {
    c.cross_orthogonality_note = "no measured shapes";
    return c;
  }
  c.comac = comac(measured_shapes, model_shapes);

  // SEREP test-analysis mass from the paired model modes.
  const Eigen::Index ns = model_at_sensors.rows(), np = static_cast<Eigen::Index>(model_shapes.size());
  if (ns < np) {
    c.cross_orthogonality_note = "SEREP needs at least as many sensor DOFs (" + std::to_string(ns) +
                                 ") as paired modes with shapes (" + std::to_string(np) + ")";
    return c;
  }
  Matrix phi_a(ns, np);
  for (Eigen::Index j = 0; j < np; ++j) phi_a.col(j) = model_shapes[static_cast<size_t>(j)];
  const Eigen::JacobiSVD<Matrix> svd(phi_a, Eigen::ComputeThinU | Eigen::ComputeThinV);
  const Vector& sigma = svd.singularValues();
  if (!(sigma[np - 1] > options.serep_condition * sigma[0])) {
    c.cross_orthogonality_note = "the paired model modes are not independent at the sensors (singular values " +
                                 std::to_string(sigma[0]) + " to " + std::to_string(sigma[np - 1]) +
                                 "): no SEREP test mass";
    return c;
  }
  const Matrix pseudo_inverse = svd.matrixV() * sigma.cwiseInverse().asDiagonal() * svd.matrixU().transpose();
  const Matrix test_mass = pseudo_inverse.transpose() * pseudo_inverse;
  c.cross_orthogonality.resize(np, np);
  for (Eigen::Index i = 0; i < np; ++i) {
    Vector phi = measured_shapes[static_cast<size_t>(i)];
    const double norm = phi.dot(test_mass * phi);
    phi /= norm > 0 ? std::sqrt(norm) : 1.0;
    if (phi.dot(test_mass * phi_a.col(i)) < 0) phi = -phi;
    c.cross_orthogonality.row(i) = (norm > 0 ? 1.0 : NAN) * (phi.transpose() * test_mass * phi_a);
    c.pairs[static_cast<size_t>(c.shape_pairs[static_cast<size_t>(i)])].cross_orthogonality = c.cross_orthogonality(i, i);
  }
  return c;
}

}  // namespace modalcal
