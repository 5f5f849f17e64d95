// What further measurement would tell an accepted effect from an alternative that fits the same
// data about as well: the two refits' models, solved, compared at every reading a sensor could
// take and at every mode the test did not measure.

#include <algorithm>
#include <cmath>
#include <set>
#include <stdexcept>

#include "modalcal/assembly.hpp"
#include "modalcal/diagnosis.hpp"
#include "modalcal/objective.hpp"
#include "model_surface.hpp"

namespace modalcal {

namespace {

/// One refit's model, solved at its parameters.
struct SolvedRefit {
  Problem problem;
  Evaluation evaluation;
  DofMap dofs;
};

SolvedRefit solve_refit(const Problem& problem, const RankedEffect& refit) {
  const Eigen::Index np = static_cast<Eigen::Index>(problem.parameters.size());
  if (refit.parameters.size() != np + 1)
    throw std::invalid_argument("tell_apart: the refit of " + refit.candidate.name + " has " +
                                std::to_string(refit.parameters.size()) + " parameters, the problem " +
                                std::to_string(np) + " and the effect 1");
  Problem with = problem_with_effects(problem, {refit.candidate}, {refit.parameters[np]});
  Objective objective(with);
  Evaluation e = objective.evaluate(refit.parameters);
  if (!e.ok) throw std::runtime_error("tell_apart: the model with " + refit.candidate.name + " cannot be solved: " + e.message);
  DofMap dofs(with.model);
  return {std::move(with), std::move(e), std::move(dofs)};
}

/// The model mode paired with measured mode `measured`, -1 if none.
int paired_model_mode(const Evaluation& e, int measured) {
  for (const PairedMode& p : e.pairs)
    if (p.measured == measured) return p.model;
  return -1;
}

/// Model mode `k`'s values at the problem's sensors.
Vector at_sensors(const SolvedRefit& s, int k) {
  Vector v(static_cast<Eigen::Index>(s.problem.sensors.size()));
  for (size_t j = 0; j < s.problem.sensors.size(); ++j)
    v[static_cast<Eigen::Index>(j)] = s.dofs.value(s.evaluation.modal.modes.col(k), s.problem.sensors[j].node,
                                                    s.problem.sensors[j].component);
  return v;
}

/// The reading (surface node, direction, measured mode) where the two models' shapes, each scaled
/// to a largest value of 1 at the sensors and signed alike there, differ most.
void best_reading(const SolvedRefit& a, const SolvedRefit& b, const std::vector<int>& nodes, double shape_noise,
                  TellApart* out) {
  const Model& model = a.problem.model;
  std::set<std::pair<int, int>> measured_readings;  // a reading the test already takes is no advice
  for (const Sensor& s : a.problem.sensors) measured_readings.insert({s.node, s.component});
  for (size_t i = 0; i < a.problem.measured.size(); ++i) {
    if (a.problem.measured[i].shape.size() == 0) continue;
    const int ka = paired_model_mode(a.evaluation, static_cast<int>(i)), kb = paired_model_mode(b.evaluation, static_cast<int>(i));
    if (ka < 0 || kb < 0) continue;
    const Vector sa = at_sensors(a, ka), sb = at_sensors(b, kb);
    const double scale_a = sa.cwiseAbs().maxCoeff(), scale_b = sb.cwiseAbs().maxCoeff();
    if (!(scale_a > 0 && scale_b > 0)) continue;
    const double sign = sa.dot(sb) < 0 ? -1.0 : 1.0;
    for (int v : nodes)
      for (int c = 0; c < 3; ++c) {
        if (a.dofs.free_index(v, c) < 0 || b.dofs.free_index(v, c) < 0 || measured_readings.count({v, c})) continue;
        const double da = a.dofs.value(a.evaluation.modal.modes.col(ka), v, c) / scale_a;
        const double db = sign * b.dofs.value(b.evaluation.modal.modes.col(kb), v, c) / scale_b;
        const double separation = std::abs(da - db) / shape_noise;
        if (separation > out->shape_separation) {
          out->shape_separation = separation;
          out->node = v;
          out->component = c;
          out->location = model.coordinates[v];
          out->measured = static_cast<int>(i);
        }
      }
  }
}

/// The elastic mode paired with no measured one whose frequency differs most between the two
/// models (the same index in both: the effects are small enough to keep the order).
void best_unmeasured_mode(const SolvedRefit& a, const SolvedRefit& b, double frequency_noise, TellApart* out) {
  const Vector& la = a.evaluation.modal.eigenvalues;
  const Vector& lb = b.evaluation.modal.eigenvalues;
  for (Eigen::Index k = 0; k < std::min(la.size(), lb.size()); ++k) {
    const bool measured = std::any_of(a.evaluation.pairs.begin(), a.evaluation.pairs.end(),
                                      [&](const PairedMode& p) { return p.model == k; });
    if (measured || !(la[k] > 0 && lb[k] > 0)) continue;
    const double fa = frequency_hz(la[k]), fb = frequency_hz(lb[k]);
    const double separation = std::abs(fa - fb) / fa / frequency_noise;
    if (separation > out->frequency_separation) {
      out->frequency_separation = separation;
      out->model_mode = static_cast<int>(k);
      out->model_hz = fa;
    }
  }
}

/// The noise the separations are measured in.
const MeasurementNoise& stated_noise(const Problem& problem) {
  if (!problem.measurement_noise)
    throw std::invalid_argument("tell_apart: the measured data state no noise to measure a separation in");
  return *problem.measurement_noise;
}

/// The candidate places of a further sensor on `a`'s model.
std::vector<int> sensor_places(const SolvedRefit& a) {
  return detail::surface_and_interface_nodes(a.problem.model, detail::fixed_dofs(a.problem.model));
}

TellApart compare(const SolvedRefit& a, const SolvedRefit& b, const std::string& alternative,
                  const std::vector<int>& nodes, const MeasurementNoise& noise) {
  TellApart out;
  out.alternative = alternative;
  if (noise.shape > 0) best_reading(a, b, nodes, noise.shape, &out);
  if (noise.frequency > 0) best_unmeasured_mode(a, b, noise.frequency, &out);
  return out;
}

}  // namespace

TellApart tell_apart(const Problem& problem, const RankedEffect& accepted, const RankedEffect& alternative) {
  const MeasurementNoise& noise = stated_noise(problem);
  const SolvedRefit a = solve_refit(problem, accepted), b = solve_refit(problem, alternative);
  return compare(a, b, alternative.candidate.name, sensor_places(a), noise);
}

std::vector<TellApart> tell_apart(const Problem& problem, const RankedEffect& accepted,
                                  const std::vector<RankedEffect>& alternatives) {
  const MeasurementNoise& noise = stated_noise(problem);
  const SolvedRefit a = solve_refit(problem, accepted);
  const std::vector<int> nodes = sensor_places(a);
  std::vector<TellApart> out;
  for (const RankedEffect& alternative : alternatives) {
    try {
      out.push_back(compare(a, solve_refit(problem, alternative), alternative.candidate.name, nodes, noise));
    } catch (const std::exception&) {  // advice only: an entry that names nothing
      TellApart none;
      none.alternative = alternative.candidate.name;
      out.push_back(none);
    }
  }
  return out;
}

}  // namespace modalcal
