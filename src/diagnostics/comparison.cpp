// Test-analysis correlation: pairing, MAC matrix, COMAC and SEREP cross-orthogonality
// (formulas in comparison.hpp).
#include "modalcal/comparison.hpp"
#include "support/text_util.hpp"

#include <Eigen/SVD>

#include <algorithm>
#include <stdexcept>

#include "modalcal/assembly.hpp"
#include "modalcal/eigen.hpp"
#include "modalcal/mode_description.hpp"
#include "modalcal/objective.hpp"
#include "objective/mode_pairing.hpp"
#include "objective/shape_misfit.hpp"

namespace modalcal {

bool ComparisonOptions::IsValid(std::string* error) const {
  if (!(unpaired_mac >= 0 && unpaired_mac <= 1)) {
    if (error) *error = "unpaired_mac = " + detail::option_text(unpaired_mac) + ": must be in [0, 1]";
    return false;
  }
  if (!(serep_condition > 0 && serep_condition < 1)) {
    if (error) *error = "serep_condition = " + detail::option_text(serep_condition) + ": must be in (0, 1)";
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

namespace {

/// The columns `modes` of the model's shapes at the sensors.
Matrix columns_of(const Matrix& model_at_sensors, const std::vector<int>& modes) {
  Matrix phi_a(model_at_sensors.rows(), static_cast<Eigen::Index>(modes.size()));
  for (size_t j = 0; j < modes.size(); ++j) phi_a.col(static_cast<Eigen::Index>(j)) = model_at_sensors.col(modes[j]);
  return phi_a;
}

/// The SEREP pseudo-inverse of the model's shapes at the sensors: from every computed mode when
/// the sensors can tell them apart (then a measured shape's part outside the paired modes shows),
/// else from the paired ones. Sets c->serep_modes, or c->cross_orthogonality_note and returns
/// an empty matrix when neither basis will do.
Matrix serep_pseudo_inverse(const Matrix& model_at_sensors, const ComparisonOptions& options, ModalComparison* c) {
  const Eigen::Index ns = model_at_sensors.rows();
  std::vector<int> paired_modes;
  for (int index : c->shape_pairs) paired_modes.push_back(c->pairs[static_cast<size_t>(index)].model);
  std::vector<int> all_modes(static_cast<size_t>(model_at_sensors.cols()));
  for (size_t k = 0; k < all_modes.size(); ++k) all_modes[k] = static_cast<int>(k);
  for (const std::vector<int>& basis : {all_modes, paired_modes}) {
    const Eigen::Index nb = static_cast<Eigen::Index>(basis.size());
    if (ns < nb) {
      c->cross_orthogonality_note = "SEREP needs at least as many sensor DOFs (" + std::to_string(ns) +
                                    ") as model modes in its basis (" + std::to_string(nb) + ")";
      continue;
    }
    const Eigen::JacobiSVD<Matrix> svd(columns_of(model_at_sensors, basis), Eigen::ComputeThinU | Eigen::ComputeThinV);
    const Vector& sigma = svd.singularValues();
    if (!(sigma[nb - 1] > options.serep_condition * sigma[0])) {
      c->cross_orthogonality_note = "the " + std::to_string(nb) + " model modes of the SEREP basis are not independent " +
                                    "at the sensors (singular values " + std::to_string(sigma[0]) + " to " +
                                    std::to_string(sigma[nb - 1]) + ")";
      continue;
    }
    c->serep_modes = basis;
    c->cross_orthogonality_note.clear();
    return svd.matrixV() * sigma.cwiseInverse().asDiagonal() * svd.matrixU().transpose();
  }
  return Matrix();
}

/// Cross-orthogonality of each measured shape with the SEREP basis's model modes, in the test mass
/// of `pseudo_inverse`; each paired entry goes to its pair too.
void add_cross_orthogonality(const Matrix& model_at_sensors, const std::vector<Vector>& measured_shapes,
                             const Matrix& pseudo_inverse, ModalComparison* c) {
  const Matrix test_mass = pseudo_inverse.transpose() * pseudo_inverse;
  const Matrix phi_a = columns_of(model_at_sensors, c->serep_modes);
  c->cross_orthogonality.resize(static_cast<Eigen::Index>(c->shape_pairs.size()), phi_a.cols());
  for (size_t i = 0; i < c->shape_pairs.size(); ++i) {
    ComparedPair& pair = c->pairs[static_cast<size_t>(c->shape_pairs[i])];
    const Eigen::Index column =
        std::find(c->serep_modes.begin(), c->serep_modes.end(), pair.model) - c->serep_modes.begin();
    Vector phi = measured_shapes[i];
    const double norm = phi.dot(test_mass * phi);
    phi /= norm > 0 ? std::sqrt(norm) : 1.0;
    if (phi.dot(test_mass * phi_a.col(column)) < 0) phi = -phi;  // the sign of its pair
    const Eigen::Index row = static_cast<Eigen::Index>(i);
    c->cross_orthogonality.row(row) = (norm > 0 ? 1.0 : NAN) * (phi.transpose() * test_mass * phi_a);
    pair.cross_orthogonality = c->cross_orthogonality(row, column);
  }
}

// The forward solve at p and its pairing with the measured modes, as the objective makes them
// (objective/mode_pairing.hpp), without the objective's residuals and derivatives.
struct ForwardPairs {
  ModalResult modal;
  SparseMatrix sensors;  // free DOFs -> sensor readings
  std::vector<PairedMode> pairs;
  std::vector<std::string> warnings;
};

ForwardPairs solve_and_pair(const Problem& problem, const Vector& p) {
  if (problem.measured.empty()) throw std::invalid_argument(problem.path + ": no measured modes to compare with");
  if (p.size() != static_cast<Eigen::Index>(problem.parameters.size()) || !p.allFinite())
    throw std::runtime_error("parameter vector has wrong size or non-finite entries");
  const ObjectiveOptions defaults;
  const ParametricSystem system(problem.model, problem.parameter_targets());
  SparseMatrix K, M;
  system.assemble(p, &K, &M);
  ModalOptions options;
  options.num_modes = detail::modes_to_compute(problem, defaults.extra_modes, system.num_dofs());
  options.max_rigid_modes = problem.expected_rigid_modes();
  options.tolerance = problem.options.tolerance;
  ForwardPairs e;
  e.modal = ModalSolver(system.pattern(), options).solve(K, M);
  if (e.modal.status != EigenStatus::Successful)
    throw std::runtime_error("forward solve failed: " + system.failure_message(p, e.modal.message));
  e.sensors = detail::sensor_matrix(problem, system.dof_map());
  const detail::ModePairing pairing = detail::pair_modes(problem, e.modal, e.sensors, false,
                                                         [&] { return describe_modes(system, p, M, e.modal); });
  if (!pairing.ok()) throw std::runtime_error(pairing.message);
  e.pairs = detail::paired_modes(problem, e.modal, pairing.model_of, pairing.mac_table);
  for (std::string& warning : detail::close_eigenvalue_warnings(problem, e.modal, pairing.model_of,
                                                                defaults.close_eigenvalue_tolerance))
    e.warnings.push_back(std::move(warning) + ": its derivatives are ill defined there");
  return e;
}

}  // namespace

ModalComparison compare_modes(const Problem& problem, const Vector& p, const ComparisonOptions& options) {
  std::string error;
  if (!options.IsValid(&error)) throw std::invalid_argument("ComparisonOptions: " + error);
  const ForwardPairs e = solve_and_pair(problem, p);
  const Matrix model_at_sensors = e.sensors * e.modal.modes;
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
  const Matrix pseudo_inverse = serep_pseudo_inverse(model_at_sensors, options, &c);
  if (!c.serep_modes.empty()) add_cross_orthogonality(model_at_sensors, measured_shapes, pseudo_inverse, &c);
  return c;
}

}  // namespace modalcal
