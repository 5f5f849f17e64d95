// Synthetic measured modes from a truth model with hidden effects (see synthesis.hpp).
#include "modalcal/synthesis.hpp"
#include "support/text_util.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <new>
#include <set>
#include <stdexcept>

#include "support/random_draws.hpp"
#include "modalcal/assembly.hpp"
#include "modalcal/eigen.hpp"
#include "modalcal/mode_description.hpp"

namespace modalcal {

namespace {

std::string format_point(const Vec3& x) {
  return "[" + format_round_trip(x[0]) + ", " + format_round_trip(x[1]) + ", " + format_round_trip(x[2]) + "]";
}

double model_size(const Model& model) {
  if (model.num_nodes() == 0) return 0;
  Vec3 lo = model.coordinates.front(), hi = lo;
  for (const Vec3& x : model.coordinates) {
    lo = lo.cwiseMin(x);
    hi = hi.cwiseMax(x);
  }
  return (hi - lo).norm();
}

/// (node, component) of every fixed DOF and of every DOF a flexible support holds.
std::set<std::pair<int, int>> fixed_or_supported(const Model& model) {
  std::set<std::pair<int, int>> dofs;
  for (const FixedDofs& f : model.fixed)
    for (int c = 0; c < 6; ++c)
      if (f.components[c])
        for (int v : f.nodes) dofs.insert({v, c});
  for (const GroundSpring& s : model.ground_springs)
    if (s.replaces_fixity)
      for (int c = 0; c < 6; ++c)
        if (s.stiffness[c] != kNoProperty)
          for (int v : s.nodes) dofs.insert({v, c});
  return dofs;
}

/// What distinguishes two models beyond their properties, in words.
std::string structural_differences(const Model& nominal, const Model& truth) {
  std::vector<std::string> notes;
  if (nominal.num_nodes() != truth.num_nodes()) {
    notes.push_back("the truth mesh has " + std::to_string(truth.num_nodes()) + " nodes against " +
                    std::to_string(nominal.num_nodes()));
  } else {
    const double tolerance = 1e-9 * model_size(nominal);
    for (int v = 0; v < nominal.num_nodes(); ++v)
      if ((nominal.coordinates[v] - truth.coordinates[v]).norm() > tolerance) {
        notes.push_back("node positions differ");
        break;
      }
    for (const ElementBlock& a : nominal.blocks)
      for (const ElementBlock& b : truth.blocks)
        if (a.name == b.name && (a.connectivity != b.connectivity || a.type != b.type))
          notes.push_back("the elements of block " + a.name + " differ");
    // A flexible support's springs stand for the fixity they released: that is a property.
    if (fixed_or_supported(nominal) != fixed_or_supported(truth)) notes.push_back("the fixed DOFs differ");
    auto same_coupling = [](const RigidCoupling& a, const RigidCoupling& b) {
      return a.reference == b.reference && a.nodes == b.nodes;
    };
    if (!std::equal(nominal.rigid_couplings.begin(), nominal.rigid_couplings.end(), truth.rigid_couplings.begin(),
                    truth.rigid_couplings.end(), same_coupling))
      notes.push_back("the rigid couplings differ");
    for (const Joint& a : nominal.joints)
      for (const Joint& b : truth.joints)
        if (a.name == b.name && (a.node_a != b.node_a || a.node_b != b.node_b || a.frame != b.frame))
          notes.push_back("joint " + a.name + " connects other nodes or has another frame");
    for (const GroundSpring& a : nominal.ground_springs)
      for (const GroundSpring& b : truth.ground_springs)
        if (a.name == b.name && a.nodes != b.nodes) notes.push_back("spring " + a.name + " acts on other nodes");
    for (const PointMass& a : nominal.point_masses)
      for (const PointMass& b : truth.point_masses)
        if (a.name == b.name && a.node != b.node) notes.push_back("point mass " + a.name + " sits on another node");
  }
  std::string out;
  for (const std::string& n : notes) out += (out.empty() ? "" : "; ") + n;
  return out;
}

}  // namespace

TruthModel make_truth(const Problem& nominal, const Problem* truth_file, const std::vector<ModelChange>& changes) {
  TruthModel truth;
  Problem& problem = truth.problem;
  problem.path = truth_file ? truth_file->path : nominal.path;
  problem.name = (truth_file ? truth_file->name : nominal.name) + " (truth)";
  problem.units = nominal.units;
  problem.options = truth_file ? truth_file->options : nominal.options;
  Model& model = problem.model;
  model = truth_file ? truth_file->model : nominal.model;

  std::vector<std::string> targets;  // calibrated properties: not hidden effects
  for (const Parameter& q : nominal.parameters)
    for (PropertyId t : q.targets) {
      targets.push_back(nominal.model.properties[t].name);
      const PropertyId id = model.find_property(targets.back());
      if (q.truth && id != kNoProperty) model.properties[id].value = *q.truth;
    }
  if (truth_file)
    for (const Parameter& q : truth_file->parameters)
      if (q.truth)
        for (PropertyId t : q.targets) model.properties[t].value = *q.truth;

  std::vector<ModelEffect> applied;
  for (const ModelChange& change : changes) {
    const std::string text = to_string(change);
    const ModelEffect effect = describe_model_change(model, change);
    if (std::find(targets.begin(), targets.end(), effect.name) != targets.end())
      throw std::invalid_argument("change '" + text + "': " + effect.name +
                                  " is a calibration parameter's target, so it is not hidden; give that parameter a "
                                  "'truth' value in the problem file instead");
    // Two changes of one property would leave the last one's value with no word of the first.
    for (size_t k = 0; k < applied.size(); ++k)
      if (applied[k].name == effect.name)
        throw std::invalid_argument("change '" + text + "': " + effect.name + " is already set by change '" +
                                    truth.record.changes[k] + "'; give each property once");
    applied.push_back(apply_model_change(&model, change));
    truth.record.changes.push_back(text);
  }

  SyntheticTruth& record = truth.record;
  const std::string with_changes =
      changes.empty() ? "" : " with " + std::to_string(changes.size()) + (changes.size() == 1 ? " change" : " changes");
  record.source = truth_file ? "the truth file " + truth_file->path + with_changes
                             : "the nominal model at the parameters' truth values" + with_changes;
  record.hidden_effects = property_differences(nominal.model, model, targets);
  for (ModelEffect& effect : record.hidden_effects)  // the words of the change that made it, when there is one
    for (const ModelEffect& a : applied)
      if (a.name == effect.name) effect.description = a.description;
  record.other_differences = structural_differences(nominal.model, model);
  for (const Parameter& q : nominal.parameters) {
    std::vector<double> values;
    for (PropertyId t : q.targets) {
      const PropertyId id = model.find_property(nominal.model.properties[t].name);
      if (id != kNoProperty) values.push_back(model.properties[id].value);
    }
    if (!values.empty() && values.size() == q.targets.size() &&
        std::equal(values.begin() + 1, values.end(), values.begin()))
      record.parameters.emplace_back(q.name, values.front());
  }
  return truth;
}

std::vector<SensorRecord> sensor_records(const Model& model, const std::vector<Sensor>& sensors) {
  std::vector<SensorRecord> records;
  for (const Sensor& s : sensors) records.push_back({model.node_ids[s.node], s.component, model.coordinates[s.node]});
  return records;
}

bool SynthesisOptions::IsValid(std::string* error) const {
  auto bad = [&](const std::string& message) {
    if (error) *error = message;
    return false;
  };
  if (modes.empty()) return bad("modes is empty: list the truth model's modes to measure");
  for (size_t i = 0; i < modes.size(); ++i) {
    if (modes[i] < 1) return bad("modes[" + detail::option_text(i) + "] = " + detail::option_text(modes[i]) + ": must be >= 1");
    if (std::find(modes.begin(), modes.begin() + static_cast<long>(i), modes[i]) != modes.begin() + static_cast<long>(i))
      return bad("modes[" + detail::option_text(i) + "] = " + detail::option_text(modes[i]) + ": listed twice");
  }
  std::string why;
  if (!noise.IsValid(&why)) return bad("noise." + why);
  return true;
}

MeasuredData synthesize_measured_data(const Problem& nominal, const TruthModel& truth,
                                      const std::vector<Sensor>& sensors, const SynthesisOptions& options) {
  std::string error;
  if (!options.IsValid(&error)) throw std::invalid_argument("SynthesisOptions: " + error);
  const Model& model = truth.problem.model;
  if (options.shapes && sensors.empty())
    throw std::invalid_argument("shapes are wanted but there are no sensors; give sensors or measure frequencies only");

  // The truth model may have its own mesh: find each sensor by position.
  std::vector<int> truth_nodes;
  const double tolerance = 1e-6 * model_size(nominal.model);
  for (const Sensor& s : sensors) {
    if (!options.shapes) break;
    const Vec3& x = nominal.model.coordinates[s.node];
    int best = 0;
    double distance = std::numeric_limits<double>::infinity();
    for (int v = 0; v < model.num_nodes(); ++v)
      if (const double d = (model.coordinates[v] - x).norm(); d < distance) {
        distance = d;
        best = v;
      }
    if (!(distance <= tolerance))
      throw std::invalid_argument("sensor " + s.label + " at " + format_point(x) +
                                  ": the truth model has no node there (the nearest is " + format_round_trip(distance) +
                                  " away); a truth model needs a node at every sensor position");
    truth_nodes.push_back(best);
  }

  ParametricSystem system(model, {});
  SparseMatrix K, M;
  system.assemble(Vector(), &K, &M);
  ModalOptions modal;
  modal.num_modes = std::max(*std::max_element(options.modes.begin(), options.modes.end()), truth.problem.options.num_modes);
  modal.max_rigid_modes = truth.problem.expected_rigid_modes();
  modal.tolerance = truth.problem.options.tolerance;
  ModalSolver solver(system.pattern(), modal);
  if (modal.num_modes + modal.max_rigid_modes > solver.most_modes())  // the mode numbers asked for, not the numerics
    throw std::invalid_argument("mode " + std::to_string(modal.num_modes) + " of the truth model: it has " +
                                std::to_string(system.num_dofs()) + " free DOFs, of which at most " +
                                std::to_string(solver.most_modes()) + " modes can be found");
  const ModalResult result = solver.solve(K, M);
  if (result.status != EigenStatus::Successful)
    throw std::runtime_error("the truth model's modal solve failed: " + result.message);
  const std::vector<ModeDescription> described = describe_modes(system, Vector(), M, result);

  MeasuredData data;
  data.synthesized_from = nominal.path;
  if (options.shapes) data.sensors = sensor_records(nominal.model, sensors);
  data.noise = options.noise;
  data.truth = truth.record;
  detail::StandardNormal normal(options.noise.seed);
  for (int k : options.modes) {
    const double exact_hz = frequency_hz(result.eigenvalues[k - 1]);
    MeasuredMode m;
    m.label = described[k - 1].label.empty() ? "mode " + std::to_string(k) : described[k - 1].label;
    m.frequency_hz = exact_hz * (1 + options.noise.frequency * normal());
    if (!(m.frequency_hz > 0))
      throw std::invalid_argument("mode " + std::to_string(k) + ": the noisy frequency is not positive; lower the frequency noise");
    // With shapes, pair by MAC as for real test data: index pairing would tie a measured mode to
    // whichever mode happens to be k-th while modes cross on the way from a far start.
    m.pairing.kind = options.shapes ? PairingRule::Kind::Mac : PairingRule::Kind::ModelIndex;
    m.pairing.model_index = k;
    if (options.shapes) {
      Vector shape(static_cast<Eigen::Index>(sensors.size()));
      for (size_t s = 0; s < sensors.size(); ++s)
        shape[static_cast<Eigen::Index>(s)] = system.dof_map().value(result.modes.col(k - 1), truth_nodes[s], sensors[s].component);
      Eigen::Index largest = 0;
      if (shape.cwiseAbs().maxCoeff(&largest) == 0)
        throw std::invalid_argument("mode " + std::to_string(k) + " of the truth model is zero at every sensor; choose other sensors or modes");
      shape /= shape[largest];
      for (Eigen::Index s = 0; s < shape.size(); ++s) shape[s] += options.noise.shape * normal();
      m.shape = shape;
    }
    data.modes.push_back(m);
    data.truth_modes.push_back({k, exact_hz});
  }
  return data;
}

void synthesize_measured(Problem* problem) {
  if (!problem->synthetic) return;
  const SyntheticSpec& spec = *problem->synthetic;
  auto fail = [&](const std::string& message) {
    throw ProblemError(problem->path, spec.source_line, "measured.synthetic: " + message);
  };
  if (!problem->has_truth()) fail("every parameter needs a 'truth' value to synthesize measurements");
  SynthesisOptions options;
  options.modes = spec.modes;
  options.shapes = spec.shapes;
  try {
    const TruthModel truth = make_truth(*problem, nullptr, {});
    MeasuredData data = synthesize_measured_data(*problem, truth, problem->sensors, options);
    for (MeasuredMode& m : data.modes) m.source_line = spec.source_line;
    problem->measured = std::move(data.modes);
    problem->synthetic_truth = truth.record;
  } catch (const std::bad_alloc&) {
    throw;  // not a mistake in the problem file's synthetic section
  } catch (const std::exception& e) {
    fail(e.what());
  }
}

}  // namespace modalcal
