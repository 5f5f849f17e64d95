#include "modalcal/localization.hpp"
#include "support/text_util.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <memory>
#include <optional>
#include <sstream>

#include "diagnostics/modal_expansion.hpp"
#include "diagnostics/region_energy.hpp"
#include "modalcal/objective.hpp"
#include "objective/shape_misfit.hpp"

namespace modalcal {

bool LocalizationOptions::IsValid(std::string* error) const {
  auto bad = [&](const std::string& message) {
    if (error) *error = message;
    return false;
  };
  if (basis_modes < 0) return bad("basis_modes = " + detail::option_text(basis_modes) + ": must be >= 0");
  if (max_automatic_basis < 1)
    return bad("max_automatic_basis = " + detail::option_text(max_automatic_basis) + ": must be >= 1");
  if (!(regularization >= 0 && regularization < 1))
    return bad("regularization = " + detail::option_text(regularization) + ": must be in [0, 1)");
  if (!(max_frequency_ratio >= 1))
    return bad("max_frequency_ratio = " + detail::option_text(max_frequency_ratio) + ": must be >= 1");
  if (!(max_condition > 1)) return bad("max_condition = " + detail::option_text(max_condition) + ": must be > 1");
  if (!(rank_tolerance > 0 && rank_tolerance <= 1e-2))
    return bad("rank_tolerance = " + detail::option_text(rank_tolerance) + ": must be in (0, 1e-2]");
  return true;
}

namespace {

// The calibration objective's pairing of measured and model modes at p, from a forward solve
// with enough modes for the basis: the requested number, or (automatic basis) every mode up to
// the frequency cutoff, found by doubling the number of modes until the last one lies above it.
struct Pairing {
  Problem problem;  // the objective refers to it
  std::unique_ptr<Objective> objective;
  Evaluation evaluation;
};

void pair_modes(const Problem& problem, const Vector& p, const LocalizationOptions& options, double cutoff_hz,
                Pairing* pairing) {
  pairing->problem = problem;
  // Checked before the modal solve, which would otherwise fail for a basis larger than the model.
  const int readings = static_cast<int>(problem.sensors.size());
  if (options.basis_modes > readings && options.regularization == 0)
    throw std::invalid_argument("LocalizationOptions: basis_modes = " + std::to_string(options.basis_modes) +
                                " is more than the " + std::to_string(readings) +
                                " sensor readings can tell apart; use fewer basis modes or a regularization > 0");
  const int limit = std::max(1, std::min(options.max_automatic_basis,
                                         static_cast<int>(problem.sensors.size()) - problem.expected_rigid_modes()));
  int wanted = options.basis_modes > 0 ? options.basis_modes : std::min(limit, 2 * problem.options.num_modes);
  while (true) {
    pairing->problem.options.num_modes = std::max(problem.options.num_modes, wanted);
    pairing->objective = std::make_unique<Objective>(pairing->problem);
    pairing->evaluation = pairing->objective->evaluate(p, Need::Value);
    const Vector& hz = pairing->evaluation.modal.eigenvalues;
    if (options.basis_modes > 0 || !pairing->evaluation.ok || wanted >= limit || hz.size() < wanted ||
        frequency_hz(hz[hz.size() - 1]) > cutoff_hz)
      return;
    wanted = std::min(limit, 2 * wanted);
  }
}

// Elastic modes of the automatic basis, from `first` on: those up to the cutoff that the
// sensors tell apart, no more columns than readings. Singular values interlace, so the condition
// number grows with every mode added and the first one past the limit ends the search.
int automatic_basis(const Matrix& at_sensors, int rigid, int first, const Vector& eigenvalues, double cutoff_hz,
                    double max_condition) {
  const int available = static_cast<int>(eigenvalues.size());
  const int readings = static_cast<int>(at_sensors.rows());
  int elastic = first;
  while (elastic < available && rigid + elastic < readings && frequency_hz(eigenvalues[elastic]) <= cutoff_hz &&
         detail::condition_number(at_sensors.leftCols(rigid + elastic + 1)) <= max_condition)
    ++elastic;
  return elastic;
}

/// The highest frequency of a measured mode with a shape.
/// \throws std::invalid_argument when no measured mode has one.
double highest_shape_hz(const Problem& problem) {
  double highest = 0;
  for (const MeasuredMode& m : problem.measured)
    if (m.shape.size() > 0) highest = std::max(highest, m.frequency_hz);
  if (highest == 0)
    throw std::invalid_argument(problem.path + ": no measured mode has a shape; localization needs shapes at sensors");
  return highest;
}

/// The modes the measured shapes are expanded on: the rigid-body modes, then options.basis_modes
/// elastic ones, or (0) the paired ones and more up to the cutoff while the sensors tell them
/// apart; a warning when they barely tell the paired ones apart.
Matrix expansion_basis(const Problem& problem, const Evaluation& evaluation, const SparseMatrix& sensors,
                       const LocalizationOptions& options, double cutoff_hz, std::vector<std::string>* warnings) {
  const ModalResult& modal = evaluation.modal;
  int highest_paired = 0;
  for (const PairedMode& pair : evaluation.pairs)
    if (problem.measured[pair.measured].shape.size() > 0) highest_paired = std::max(highest_paired, pair.model + 1);
  if (options.basis_modes > 0 && options.basis_modes < highest_paired)
    throw std::invalid_argument("LocalizationOptions: basis_modes = " + std::to_string(options.basis_modes) +
                                " leaves out model mode " + std::to_string(highest_paired) +
                                ", which a measured shape is paired with");
  const int rigid = static_cast<int>(modal.rigid_modes.cols());
  const int available = static_cast<int>(modal.modes.cols());
  Matrix candidates(modal.modes.rows(), rigid + available);  // rigid-body modes first
  candidates << modal.rigid_modes, modal.modes;
  int elastic = std::min(options.basis_modes, available);
  if (options.basis_modes == 0) {
    const Matrix at_sensors = sensors * candidates;
    elastic = std::max(highest_paired, 1);
    const double condition = detail::condition_number(at_sensors.leftCols(rigid + elastic));
    if (condition > options.max_condition) {
      std::ostringstream warning;
      warning << "the sensors barely tell the paired model modes apart (condition number " << condition
              << " of the basis at the sensors, above " << options.max_condition
              << "); the expansion may amplify measurement noise: add sensors where these modes differ";
      warnings->push_back(warning.str());
    }
    elastic = automatic_basis(at_sensors, rigid, elastic, modal.eigenvalues, cutoff_hz, options.max_condition);
  }
  const int readings = static_cast<int>(problem.sensors.size());
  if (rigid + elastic > readings && options.regularization == 0)
    throw std::invalid_argument("LocalizationOptions: the expansion basis has " + std::to_string(rigid + elastic) +
                                " modes but there are only " + std::to_string(readings) +
                                " sensor readings; use fewer basis modes or a regularization > 0");
  return candidates.leftCols(rigid + elastic);
}

/// What expanding one measured shape needs: the model at the parameters, the sensors and the basis.
struct Expander {
  const Problem& problem;
  const ModalResult& modal;
  const SparseMatrix& sensors;
  const Matrix& basis;
  const detail::ModalExpansion& expansion;
  SparseMatrix K, M;
  Vector mass;  // M's diagonal, floored so that a DOF without mass shows its residual

  /// The measured shape of `pair` expanded on the basis, mass-normalized, with its residual force
  /// and energy per DOF (*energy); nullopt when it cannot be normalized.
  std::optional<ExpandedMode> expand(const PairedMode& pair, Vector* energy) const {
    const MeasuredMode& measured = problem.measured[pair.measured];
    ExpandedMode mode;
    mode.measured = pair.measured;
    mode.model_mode = pair.model;
    mode.measured_hz = pair.measured_hz;
    mode.model_hz = pair.model_hz;
    mode.mac = pair.mac;
    const Vector model_readings = sensors * modal.modes.col(pair.model);
    mode.scale_factor = model_readings.dot(measured.shape) / measured.shape.squaredNorm();
    const Vector readings_scaled = mode.scale_factor * measured.shape;
    // Regularized toward the paired model mode (coordinate e_k), not toward zero: a model that
    // reproduces the measured shape must expand it to itself and leave no residual.
    Vector paired = Vector::Zero(basis.cols());
    paired[modal.rigid_modes.cols() + pair.model] = 1.0;
    const Vector c = paired + expansion.coefficients(readings_scaled - model_readings);
    mode.shape = basis * c;
    mode.sensor_misfit = (sensors * mode.shape - readings_scaled).norm() / readings_scaled.norm();
    const double mass_norm = std::sqrt(mode.shape.dot(M * mode.shape));
    if (!(mass_norm > 0) || !std::isfinite(mass_norm)) return std::nullopt;
    mode.shape /= mass_norm;
    // r_d^2 / (lambda^2 M_dd): the residual force's energy per DOF.
    const double lambda = eigenvalue_of_hz(measured.frequency_hz);
    mode.residual = K * mode.shape - lambda * (M * mode.shape);
    *energy = mode.residual.array().square() / (mass.array() * lambda * lambda);
    mode.energy = energy->sum();
    return mode;
  }
};

}  // namespace

Localization localize_model_error(const Problem& problem, const Vector& p, const LocalizationOptions& options) {
  std::string error;
  if (!options.IsValid(&error)) throw std::invalid_argument("LocalizationOptions: " + error);
  if (p.size() != static_cast<Eigen::Index>(problem.parameters.size()))
    throw std::invalid_argument("localize_model_error: " + std::to_string(p.size()) + " parameter values for " +
                                std::to_string(problem.parameters.size()) + " parameters");
  const double cutoff_hz = options.max_frequency_ratio * highest_shape_hz(problem);
  Pairing pairing;
  pair_modes(problem, p, options, cutoff_hz, &pairing);
  const Evaluation& evaluation = pairing.evaluation;
  Localization result;
  result.warnings = evaluation.warnings;
  if (!evaluation.ok) {
    result.message = evaluation.message;
    return result;
  }
  const ParametricSystem& system = pairing.objective->system();
  const SparseMatrix sensors = detail::sensor_matrix(problem, system.dof_map());
  const Matrix basis = expansion_basis(problem, evaluation, sensors, options, cutoff_hz, &result.warnings);
  const detail::ModalExpansion expansion(sensors * basis, options.regularization, options.rank_tolerance);
  result.basis_size = static_cast<int>(basis.cols());
  result.basis_condition = expansion.condition();
  Expander expander{problem, evaluation.modal, sensors, basis, expansion, {}, {}, {}};
  system.assemble(p, &expander.K, &expander.M);
  expander.mass = expander.M.diagonal();
  expander.mass = expander.mass.cwiseMax(1e-12 * expander.mass.cwiseAbs().maxCoeff());

  Vector dof_energy = Vector::Zero(system.num_dofs());
  for (const PairedMode& pair : evaluation.pairs) {
    if (problem.measured[pair.measured].shape.size() == 0) continue;
    Vector energy;
    std::optional<ExpandedMode> mode = expander.expand(pair, &energy);
    if (!mode) {
      result.message = "measured mode " + std::to_string(pair.measured + 1) +
                       ": its shape is orthogonal to the paired model mode at the sensors (MAC " +
                       std::to_string(pair.mac) + "), so it cannot be expanded; check the sensor order";
      return result;
    }
    dof_energy += energy;
    result.modes.push_back(std::move(*mode));
  }
  const Model& model = problem.model;
  result.node_energy = detail::node_energy(system.dof_map(), model.num_nodes(), dof_energy);
  result.total_energy = result.node_energy.sum();
  const Vector mesh = detail::mesh_node_energy(model, result.node_energy);
  const Vector elements = detail::element_energy(model, mesh);
  result.element_indicator = result.total_energy > 0 ? Vector(elements / result.total_energy) : elements;
  result.ranking = detail::rank_regions(model, result.node_energy, mesh, elements, result.total_energy);
  result.modal = evaluation.modal;
  result.ok = true;
  return result;
}

std::string format_ranking(const Localization& result, int max_rows) {
  std::ostringstream out;
  char line[256];
  std::snprintf(line, sizeof line, "%-9s %11s %6s %11s %6s %9s %10s\n", "measured", "meas [Hz]", "model",
                "model [Hz]", "MAC", "misfit", "energy");
  out << line;
  for (const ExpandedMode& m : result.modes) {
    std::snprintf(line, sizeof line, "%-9d %11.3f %6d %11.3f %6.3f %9.1e %10.3e\n", m.measured + 1, m.measured_hz,
                  m.model_mode + 1, m.model_hz, m.mac, m.sensor_misfit, m.energy);
    out << line;
  }
  std::snprintf(line, sizeof line, "basis: %d model modes (condition %.2g at the sensors); total energy %.3e\n",
                result.basis_size, result.basis_condition, result.total_energy);
  out << line;
  std::snprintf(line, sizeof line, "%4s  %-24s %-10s %8s\n", "rank", "region", "kind", "share");
  out << line;
  const int rows = std::min<int>(max_rows, static_cast<int>(result.ranking.size()));
  for (int r = 0; r < rows; ++r) {
    const RegionShare& region = result.ranking[r];
    std::snprintf(line, sizeof line, "%4d  %-24s %-10s %7.2f %%\n", r + 1, region.name.c_str(), region.kind.c_str(),
                  100 * region.share);
    out << line;
  }
  return out.str();
}

}  // namespace modalcal
