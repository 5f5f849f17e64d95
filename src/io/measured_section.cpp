// The calibration sections of a problem file: parameters, sensors, options, measured modes (inline,
// from a data file, from test data, synthetic), declared effects.
#include "io/problem_loader.hpp"

#include <algorithm>
#include <array>
#include <climits>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <functional>
#include <iomanip>
#include <iterator>
#include <limits>
#include <map>
#include <unordered_map>
#include <sstream>
#include <unistd.h>
#include <Eigen/Geometry>
#include <yaml-cpp/yaml.h>
#include "io/box_mesh.hpp"
#include "io/input_file.hpp"
#include "io/measured_test_data.hpp"
#include "support/text_util.hpp"
#include "modalcal/assembly.hpp"
#include "modalcal/mesh_file.hpp"
#include "modalcal/problem_file.hpp"

namespace modalcal::detail::loading {

void Loader::read_parameters(const Field& f) {
  std::map<PropertyId, std::string> owner;
  for (const Field& entry : named(f, "parameter")) {
    const Fields fs =
        map_of(entry, entry.what,
               {"targets", "initial", "lower", "upper", "scaling", "reference", "truth"});
    Parameter p;
    p.name = entry.key;
    const Field& targets = required(fs, "targets");
    const std::vector<Field> names =
        targets.node.IsScalar() ? std::vector<Field>{targets} : list(targets);
    if (names.empty())
      fail(targets,
           "'targets' is empty; give one or more <entity>.<property> names, e.g. joint1.kx");
    for (const Field& t : names) {
      const PropertyId id = target(t);
      const auto [it, inserted] = owner.try_emplace(id, p.name);
      if (!inserted)
        fail(t, "target " + quote(model_.properties[id].name) +
                    (it->second == p.name ? " is listed twice"
                                          : " is already set by parameter " + quote(it->second) +
                                                "; a property can belong to one parameter only"));
      p.targets.push_back(id);
    }

    const Field& lower = required(fs, "lower");
    const Field& upper = required(fs, "upper");
    const Field& initial = required(fs, "initial");
    p.lower = number(lower);
    p.upper = number(upper);
    p.initial = number(initial);
    if (!(p.lower < p.upper))
      fail(lower,
           "lower bound " + format(p.lower) + " must be below the upper bound " + format(p.upper));
    const auto check_within = [&](const Field& value_field, double value) {
      if (value < p.lower || value > p.upper)
        fail(value_field, value_field.name() + " " + format(value) + " is outside the bounds [" +
                              format(p.lower) + ", " + format(p.upper) + "]");
    };
    check_within(initial, p.initial);
    if (const Field* s = fs.find("scaling")) {
      const Scaling scalings[] = {Scaling::None, Scaling::Linear, Scaling::Log};
      std::vector<std::string> scaling_names;
      for (Scaling sc : scalings) scaling_names.push_back(to_string(sc));
      p.scaling = scalings[choice(*s, scaling_names)];
    }
    if (p.scaling == Scaling::Log && !(p.lower > 0))
      fail(lower, "log scaling needs a positive lower bound, got " + format(p.lower) +
                      "; raise 'lower' or use linear scaling");
    const Field* reference = fs.find("reference");
    p.reference = reference ? number(*reference) : p.initial;
    if (p.scaling == Scaling::Linear && p.reference == 0)
      fail(reference ? *reference : initial,
           "linear scaling divides by the reference value, which is 0; give a nonzero "
           "'reference' or use 'scaling: none'");
    if (const Field* t = fs.find("truth")) {
      p.truth = number(*t);
      check_within(*t, *p.truth);
    }
    check_parameter_bounds(p, lower, upper);
    problem_.parameters.push_back(p);
  }
}

// The optimizer may step to either bound, so a bound outside a target's physical range (a
// modulus's lower bound of 0) would fail there, after minutes and far from its cause.
void Loader::check_parameter_bounds(const Parameter& p, const Field& lower, const Field& upper) const {
  for (const auto& [field, bound] : {std::pair{&lower, p.lower}, std::pair{&upper, p.upper}})
    for (PropertyId t : p.targets)
      if (const std::string why = property_range_violation(model_.properties[t].name, bound); !why.empty())
        fail(*field, field->key + " bound " + format(bound) + " is outside the range of " +
                         quote(model_.properties[t].name) + ": " + why);
}

PropertyId Loader::target(const Field& f) {
  const std::string name = text(f);
  const size_t dot = name.rfind('.');
  if (dot == std::string::npos || dot == 0 || dot + 1 == name.size())
    fail(f, "target " + quote(name) + " is not of the form <entity>.<property>, e.g. joint1.kx");
  const std::string entity = name.substr(0, dot), property = name.substr(dot + 1);
  const auto it = entities_.find(entity);
  if (it == entities_.end()) {
    std::vector<std::string> names;
    for (const auto& [n, e] : entities_) names.push_back(n);
    fail(f, "unknown entity " + quote(entity) + " in target " + quote(name) + "; " +
                known("blocks, joints, springs and point masses", names));
  }
  if (const PropertyId id = model_.find_property(name); id != kNoProperty) return id;

  const Entity& e = it->second;
  const bool has_components = e.kind == EntityKind::Joint || e.kind == EntityKind::Spring;
  if (has_components && contains(kStiffnessComponentNames, property)) {
    // An absent component is zero; calibrating it needs the property to exist.
    const PropertyId id = add_property(name, f, 0.0);
    const auto c =
        std::find(kStiffnessComponentNames.begin(), kStiffnessComponentNames.end(), property) - kStiffnessComponentNames.begin();
    (e.kind == EntityKind::Joint ? model_.joints[e.index].stiffness
                                 : model_.ground_springs[e.index].stiffness)[c] = id;
    return id;
  }
  std::vector<std::string> properties;
  if (has_components)
    properties = kStiffnessComponentNames;
  else
    for (const Property& p : model_.properties)
      if (p.name.rfind(entity + ".", 0) == 0)
        properties.push_back(p.name.substr(entity.size() + 1));
  fail(f, kind_name(e.kind) + " " + quote(entity) + " has no property " + quote(property) +
              "; its properties: " + join(properties));
}

void Loader::read_sensors(const Field& f) {
  std::map<std::pair<int, int>, int> measured_by;  // (node, direction) -> sensor number
  for (const Field& item : list(f)) {
    const Fields fs = map_of(item, "sensor " + std::to_string(item.item),
                             {"at", "tolerance", "node", "node_set", "directions"});
    const Field& where = exactly_one(fs, {"at", "node", "node_set"});
    const Field* tolerance = fs.find("tolerance");
    if (tolerance && where.key != "at")
      fail(*tolerance, "'tolerance' applies only to a sensor placed with 'at'");
    std::vector<int> nodes;
    if (where.key == "at")
      nodes = {nearest_node(where, tolerance ? positive(*tolerance) : sensor_tolerance())};
    else if (where.key == "node")
      nodes = {node_by_id(where)};
    else
      nodes = node_set(where).nodes;

    const Field& directions = required(fs, "directions");
    const std::vector<Field> items = list(directions);
    if (items.empty()) fail(directions, "'directions' is empty; list any of x, y, z");
    for (const Field& d : items) {
      const int c = choice(d, kDirections);
      for (int v : nodes) {
        const std::string label =
            "node " + std::to_string(model_.node_ids[v]) + " +" + kDirections[c];
        const auto [it, inserted] = measured_by.try_emplace({v, c}, item.item);
        if (!inserted)
          fail(d, label + " is already measured by sensor " + std::to_string(it->second) +
                      "; measure each DOF once");
        problem_.sensors.push_back({v, c, label});
      }
    }
  }
}

int Loader::nearest_node(const Field& at, double tolerance) const {
  const Vec3 x = vec3(at);
  int best = 0;
  double best_distance = std::numeric_limits<double>::infinity();
  // Ties go to the lower index, i.e. a mesh node before a reference node at the same place.
  for (int v = 0; v < model_.num_nodes(); ++v) {
    const double d = (model_.coordinates[v] - x).norm();
    if (d < best_distance) {
      best = v;
      best_distance = d;
    }
  }
  if (best_distance > tolerance)
    fail(at, "no node within " + format(tolerance) + " of " + format(x) + "; the nearest is node " +
                 std::to_string(model_.node_ids[best]) + " at " + format(model_.coordinates[best]) +
                 ", " + format(best_distance) + " away (correct the point or raise 'tolerance')");
  return best;
}

void Loader::read_options(const Field& f) {
  const Fields fs = map_of(f, "options", {"num_modes", "max_rigid_modes", "tolerance"});
  ProblemOptions& o = problem_.options;
  if (const Field* n = fs.find("num_modes")) {
    o.num_modes = integer_in(*n, 1, INT_MAX);
    num_modes_at_ = {current_file_, n->line};
  }
  if (const Field* n = fs.find("max_rigid_modes")) o.max_rigid_modes = integer_in(*n, 0, 6);
  if (const Field* t = fs.find("tolerance")) o.tolerance = positive(*t);
}

void Loader::read_measured(const Field& f) {
  const Fields fs = map_of(f, "measured", {"modes", "synthetic", "test_data", "file", "noise"});
  const Field& which = exactly_one(fs, {"modes", "synthetic", "test_data", "file"});
  if (which.key == "synthetic") {
    problem_.synthetic = synthetic(which);
  } else if (which.key == "test_data") {
    detail::measured_from_test_data(test_data(which), &problem_);
  } else if (which.key == "file") {
    read_measured_file(which);
  } else {
    const std::vector<Field> items = list(which);
    if (items.empty()) fail(which, "'modes' is empty; list the measured modes, or leave out the 'measured' section");
    for (const Field& item : items) {
      problem_.measured.push_back(measured_mode(item, false));
      check_paired_once(item);
    }
  }
  // The noise stated here replaces what a data file records.
  if (const Field* noise = fs.find("noise")) problem_.measurement_noise = recorded_noise(*noise);
}

void Loader::read_effects(const Field& f) {
  for (const Field& item : list(f)) {
    const std::string what = "effect " + std::to_string(item.item);
    const Fields fs = map_of(item, what, {"effect", "description", "initial", "lower", "upper", "enable"});
    DeclaredEffect effect;
    const Field& text_field = required(fs, "effect");
    effect.effect = text(text_field);
    if (effect.effect.find('=') != std::string::npos)
      fail(text_field, "'" + effect.effect + "': give the effect without its value (e.g. joint2.kry); its start "
                       "value is 'initial'");
    effect.source_file = current_file_;
    effect.source_line = item.line;
    if (const Field* d = fs.find("description")) effect.description = text(*d);
    if (const Field* v = fs.find("initial")) effect.initial = number(*v);
    if (const Field* v = fs.find("lower")) effect.lower = number(*v);
    if (const Field* v = fs.find("upper")) effect.upper = number(*v);
    if (const Field* v = fs.find("enable")) effect.enable = boolean(*v);
    if (effect.lower && effect.upper && !(*effect.lower < *effect.upper))
      fail(item, what + ": lower " + format(*effect.lower) + " must be below upper " + format(*effect.upper));
    if (effect.initial && ((effect.lower && *effect.initial < *effect.lower) ||
                           (effect.upper && *effect.initial > *effect.upper)))
      fail(item, what + ": initial " + format(*effect.initial) + " lies outside its bounds");
    // The change must make sense on this model; the value only matters for its range.
    try {
      const ModelChange change = parse_model_change(effect.effect + "=" + format_round_trip(effect.initial.value_or(1)));
      const ModelEffect described = describe_model_change(model_, change);
      for (const Parameter& q : problem_.parameters)
        for (PropertyId t : q.targets)
          if (model_.properties[t].name == described.name)
            fail(text_field, "'" + effect.effect + "' sets " + described.name + ", which parameter '" + q.name +
                                 "' already calibrates");
      for (const DeclaredEffect& other : problem_.effects)
        if (other.effect == effect.effect) fail(text_field, "'" + effect.effect + "' is declared twice");
    } catch (const std::invalid_argument& e) {
      if (dynamic_cast<const ProblemError*>(&e)) throw;
      fail(text_field, std::string(e.what()) +
                           " (an effect is a change without its value, e.g. joint2.kry or point_mass@top:mass)");
    }
    check_effect_bounds(fs, effect);
    problem_.effects.push_back(effect);
  }
}

// A bound outside its property's range (a mass's upper bound of -1) would fail only when the
// diagnosis or `calibrate --add` reaches it, after the calibrations before; it fails here, at its line.
void Loader::check_effect_bounds(const Fields& fs, const DeclaredEffect& effect) const {
  for (const auto& [key, bound] : {std::pair{"lower", effect.lower}, std::pair{"upper", effect.upper}}) {
    if (!bound) continue;
    try {
      describe_model_change(model_, parse_model_change(effect.effect + "=" + format_round_trip(*bound)));
    } catch (const std::invalid_argument& e) {
      if (dynamic_cast<const ProblemError*>(&e)) throw;
      fail(*fs.find(key), std::string(key) + " " + format(*bound) + " is outside the range of '" + effect.effect +
                              "': " + e.what());
    }
  }
}

void Loader::read_measured_file(const Field& f) {
  const std::string name = text(f);
  const std::string path = (std::filesystem::path(current_file_).parent_path() / name).string();
  if (const std::string reason = detail::unreadable_reason(path, "data file", detail::kMostYamlBytes); !reason.empty())
    fail(f, ends_with(reason, "no such file")
                ? "no such data file " + quote(path) + " (the path is relative to this file's folder)"
                : reason);
  const YAML::Node root = parse(path, "data file");
  const std::string problem_file = current_file_;
  current_file_ = path;
  problem_.measured_file = path;
  problem_.source_files.push_back(path);
  if (!root.IsMap())
    fail_at(1, "", "expected a data file (a map with 'sensors' and 'modes'), got " + describe(root));
  const Fields fs = map_of({"", "", root, 1, 0}, "", {"synthesized_from", "noise", "sensors", "truth", "modes"});
  if (const Field* from = fs.find("synthesized_from")) text(*from);
  if (const Field* noise = fs.find("noise")) problem_.measurement_noise = recorded_noise(*noise);
  const Field* sensors = fs.find("sensors");
  if (sensors) read_data_sensors(*sensors);
  const Field& modes = required(fs, "modes");
  for (const Field& item : list(modes)) {
    if (!sensors && item.node.IsMap() && item.node["shape"])
      fail_at(item.line, "measured mode " + std::to_string(item.item),
              "has a 'shape' but the data file lists no 'sensors'; a data file with shapes must list the sensor "
              "DOFs they were measured at");
    problem_.measured.push_back(measured_mode(item, true));
    check_paired_once(item);
  }
  if (problem_.measured.empty()) fail(modes, "'modes' is empty; the data file has no measured modes");
  if (const Field* truth = fs.find("truth")) problem_.synthetic_truth = recorded_truth(*truth);
  current_file_ = problem_file;
}

// A data file's sensors must be the problem's, in the same order, matched by position and
// direction (node ids change with the mesh); a problem without sensors takes the data's.
void Loader::read_data_sensors(const Field& f) {
  const std::vector<Field> items = list(f);
  const bool adopt = problem_.sensors.empty();
  const std::string same_order = "the data's sensors must be the problem's, in the same order";
  if (!adopt && items.size() != problem_.sensors.size())
    fail(f, "lists " + std::to_string(items.size()) + " sensor DOFs but the problem's 'sensors' measure " +
                std::to_string(problem_.sensors.size()) + "; " + same_order +
                " (or leave out the problem's 'sensors' section to take the data's)");
  const double tolerance = sensor_tolerance();
  for (const Field& item : items) {
    const std::string what = "data sensor " + std::to_string(item.item);
    const Fields fs = map_of(item, what, {"node", "direction", "at"});
    if (const Field* id = fs.find("node")) integer(*id);
    const int c = choice(required(fs, "direction"), kDirections);
    const Field& at = required(fs, "at");
    if (adopt) {
      const int v = nearest_node(at, tolerance);
      const std::string label = "node " + std::to_string(model_.node_ids[v]) + " +" + kDirections[c];
      for (const Sensor& s : problem_.sensors)
        if (s.node == v && s.component == c) fail_at(item.line, what, label + " is listed twice; measure each DOF once");
      problem_.sensors.push_back({v, c, label});
      continue;
    }
    const Sensor& expected = problem_.sensors[item.item - 1];
    const Vec3 x = vec3(at);
    const Vec3& position = model_.coordinates[expected.node];
    if (c != expected.component || (x - position).norm() > tolerance)
      fail_at(item.line, what, "is +" + kDirections[c] + " at " + format(x) + " but the problem's sensor DOF " +
                     std::to_string(item.item) + " is " + expected.label + " at " + format(position) + "; " +
                     same_order + " (were the data made on another mesh or refinement?)");
  }
}

MeasurementNoise Loader::recorded_noise(const Field& f) const {
  const Fields fs = map_of(f, "noise", {"frequency", "shape", "seed"});
  MeasurementNoise noise;
  if (const Field* n = fs.find("frequency")) noise.frequency = non_negative(*n);
  if (const Field* n = fs.find("shape")) noise.shape = non_negative(*n);
  if (const Field* seed = fs.find("seed"))
    if (!seed->node.IsScalar() || !YAML::convert<std::uint64_t>::decode(seed->node, noise.seed))
      fail(*seed, "expected a whole number from 0 to 2^64-1 for 'seed', got " + describe(seed->node));
  std::string error;
  if (!noise.IsValid(&error)) fail(f, "noise." + error);
  return noise;
}

SyntheticTruth Loader::recorded_truth(const Field& f) {
  const Fields fs =
      map_of(f, "truth", {"source", "changes", "hidden_effects", "other_differences", "parameters"});
  SyntheticTruth truth;
  if (const Field* source = fs.find("source")) truth.source = text(*source);
  if (const Field* changes = fs.find("changes"))
    for (const Field& c : list(*changes)) truth.changes.push_back(text(c));
  if (const Field* effects = fs.find("hidden_effects"))
    for (const Field& item : list(*effects)) {
      const Fields e = map_of(item, "hidden effect " + std::to_string(item.item),
                              {"name", "description", "value", "nominal_value"});
      ModelEffect effect;
      effect.name = text(required(e, "name"));
      if (const Field* d = e.find("description")) effect.description = text(*d);
      effect.value = number(required(e, "value"));
      // .inf: a flexible support, whose nominal is rigid.
      const Field& nominal = required(e, "nominal_value");
      if (nominal.node.IsScalar() && nominal.node.Scalar() == ".inf")
        effect.nominal_value = std::numeric_limits<double>::infinity();
      else
        effect.nominal_value = number(nominal);
      truth.hidden_effects.push_back(effect);
    }
  if (const Field* other = fs.find("other_differences")) truth.other_differences = text(*other);
  if (const Field* parameters = fs.find("parameters"))
    for (const Field& entry : named(*parameters, "truth parameter")) {
      const double value = number(entry);
      truth.parameters.emplace_back(entry.key, value);
      // The data's truth completes the problem's parameters; a contradiction is a mistake.
      const int j = problem_.find_parameter(entry.key);
      if (j < 0) continue;
      Parameter& p = problem_.parameters[static_cast<size_t>(j)];
      if (!p.truth)
        p.truth = value;
      else if (std::abs(*p.truth - value) > 1e-12 * std::max(std::abs(value), std::abs(*p.truth)))
        fail(entry, "the data were made with " + quote(entry.key) + " = " + format(value) +
                        " but the problem file gives it the truth " + format(*p.truth) +
                        "; remove the problem's 'truth' or use matching data");
    }
  return truth;
}

MeasuredMode Loader::measured_mode(const Field& item, bool in_data_file) const {
  std::vector<std::string> keys = {"frequency_hz", "weight", "shape_weight", "shape", "label", "pair"};
  if (in_data_file) keys.insert(keys.end(), {"truth_mode", "truth_frequency_hz"});  // provenance, for people
  const Fields fs = map_of(item, "measured mode " + std::to_string(item.item), keys);
  if (const Field* k = fs.find("truth_mode")) integer_in(*k, 1, INT_MAX);
  if (const Field* hz = fs.find("truth_frequency_hz")) positive(*hz);
  MeasuredMode m;
  m.source_line = item.line;
  const Field* label = fs.find("label");
  m.label = label ? text(*label) : "mode " + std::to_string(item.item);
  const Field& frequency = required(fs, "frequency_hz");
  m.frequency_hz = number(frequency);
  if (const std::string reason = detail::unusable_frequency(m.frequency_hz); !reason.empty())
    fail(frequency, frequency.name() + " is " + format(m.frequency_hz) + ": " + reason);
  if (const Field* w = fs.find("weight")) m.weight = non_negative(*w);
  if (const Field* w = fs.find("shape_weight")) m.shape_weight = non_negative(*w);
  const Field* shape = fs.find("shape");
  if (shape) {
    const std::vector<Field> values = list(*shape);
    if (values.size() != problem_.sensors.size())
      fail(*shape, "'shape' has " + std::to_string(values.size()) +
                       " values but the sensors measure " +
                       std::to_string(problem_.sensors.size()) +
                       " DOFs; give one value per sensor DOF, in the order of 'sensors'");
    m.shape.resize(static_cast<Eigen::Index>(values.size()));
    for (size_t i = 0; i < values.size(); ++i)
      m.shape[static_cast<Eigen::Index>(i)] = number(values[i]);
    if (m.shape.isZero(0)) fail(*shape, "'shape' is all zeros, which pairs with nothing");
  }
  if (const Field* pair = fs.find("pair")) {
    m.pairing = pairing(*pair, shape != nullptr);
  } else if (!shape) {
    m.pairing.kind = PairingRule::Kind::ModelIndex;
    m.pairing.model_index = item.item;
    check_computed(item, item.item);
  }
  return m;
}

PairingRule Loader::pairing(const Field& f, bool has_shape) const {
  PairingRule rule;
  if (f.node.IsScalar()) {
    if (f.node.Scalar() != "mac")
      fail(f, "expected mac, {model_mode: n} or {family: name, index: n} for 'pair', got " +
                  describe(f.node));
    if (!has_shape)
      fail(f,
           "'pair: mac' pairs by shape, but this mode has no 'shape'; give a shape or pair "
           "with {model_mode: n} or {family: name, index: n}");
    return rule;
  }
  const Fields fs = map_of(f, f.what, {"model_mode", "family", "index"});
  if (const Field* n = fs.find("model_mode")) {
    if (fs.items.size() > 1)
      fail(f, "give either {model_mode: n} or {family: name, index: n} for 'pair', not both");
    rule.kind = PairingRule::Kind::ModelIndex;
    rule.model_index = integer_in(*n, 1, INT_MAX);
    check_computed(*n, rule.model_index);
    return rule;
  }
  rule.kind = PairingRule::Kind::Family;
  const Field& family = required(fs, "family");
  rule.family = text(family);
  if (!model_.mode_families.count(rule.family)) {
    std::vector<std::string> names;
    for (const auto& [name, direction] : model_.mode_families) names.push_back(name);
    fail(family,
         "unknown mode family " + quote(rule.family) + "; " + known("mode families", names));
  }
  rule.family_index = integer_in(required(fs, "index"), 1, INT_MAX);
  return rule;
}

void Loader::check_paired_once(const Field& item) const {
  check_not_repeated(item);
  const PairingRule& rule = problem_.measured.back().pairing;
  if (rule.kind == PairingRule::Kind::Mac) return;
  for (size_t k = 0; k + 1 < problem_.measured.size(); ++k) {
    const MeasuredMode& earlier = problem_.measured[k];
    const PairingRule& other = earlier.pairing;
    if (other.kind != rule.kind || other.model_index != rule.model_index || other.family != rule.family ||
        other.family_index != rule.family_index)
      continue;
    const std::string model_mode = rule.kind == PairingRule::Kind::ModelIndex
                                       ? "model mode " + std::to_string(rule.model_index)
                                       : rule.family + " mode " + std::to_string(rule.family_index);
    fail_at(item.line, "measured mode " + std::to_string(problem_.measured.size()),
            "pairs with " + model_mode + ", as measured mode " + std::to_string(k + 1) + " (line " +
                   std::to_string(earlier.source_line) + ") does; each model mode pairs with one measured mode");
  }
}

// A mode pasted twice (the same frequency and the same shape) pairs with two model modes and
// drags the calibration far off. Two modes at one frequency, a repeated root, have shapes apart.
void Loader::check_not_repeated(const Field& item) const {
  const MeasuredMode& last = problem_.measured.back();
  if (last.shape.size() == 0) return;
  for (size_t k = 0; k + 1 < problem_.measured.size(); ++k) {
    const MeasuredMode& earlier = problem_.measured[k];
    if (earlier.shape.size() != last.shape.size() ||
        !(std::abs(earlier.frequency_hz - last.frequency_hz) <= 1e-9 * last.frequency_hz))
      continue;
    const double dot = earlier.shape.dot(last.shape);
    if (dot * dot < (1 - 1e-9) * earlier.shape.squaredNorm() * last.shape.squaredNorm()) continue;
    fail_at(item.line, "measured mode " + std::to_string(problem_.measured.size()),
            "repeats measured mode " + std::to_string(k + 1) + " (line " + std::to_string(earlier.source_line) +
                "): the same frequency and shape, listed twice? (two modes at one frequency have different shapes)");
  }
}

void Loader::check_computed(const Field& f, int mode) const {
  if (mode > problem_.options.num_modes)
    fail(f, "refers to elastic mode " + std::to_string(mode) + " but options.num_modes is " +
                std::to_string(problem_.options.num_modes) + "; raise num_modes");
}

SyntheticSpec Loader::synthetic(const Field& f) const {
  const Fields fs = map_of(f, "measured synthetic", {"modes", "shapes"});
  SyntheticSpec spec;
  spec.source_line = f.line;
  const Field& modes = required(fs, "modes");
  for (const Field& m : list(modes)) {
    const int mode = integer_in(m, 1, INT_MAX);
    check_computed(m, mode);
    if (std::find(spec.modes.begin(), spec.modes.end(), mode) != spec.modes.end())
      fail(m, "mode " + std::to_string(mode) + " is listed twice");
    spec.modes.push_back(mode);
  }
  if (spec.modes.empty()) fail(modes, "'modes' is empty; list the model modes to synthesize");
  const Field* shapes = fs.find("shapes");
  if (shapes) spec.shapes = boolean(*shapes);
  if (spec.shapes && problem_.sensors.empty())
    fail(shapes ? *shapes : f,
         "synthetic shapes need sensors; add a 'sensors' section or set 'shapes: false'");
  return spec;
}

detail::TestDataSelection Loader::test_data(const Field& f) const {
  const Fields fs = map_of(f, "measured test_data",
                           {"file", "modes", "map", "tolerance", "directions", "length_unit", "scale_length"});
  if (!problem_.sensors.empty())
    fail(f, "test_data defines the sensors (matched nodes × directions); remove the 'sensors' section");
  detail::TestDataSelection s;
  s.problem_file = current_file_;
  s.line = f.line;
  const Field& file = required(fs, "file");
  s.path = (std::filesystem::path(current_file_).parent_path() / text(file)).string();
  s.file_line = file.line;
  if (const Field* modes = fs.find("modes")) {
    for (const Field& m : list(*modes)) {
      const int number = integer_in(m, 0, INT_MAX);
      if (std::find(s.modes.begin(), s.modes.end(), number) != s.modes.end())
        fail(m, "mode " + std::to_string(number) + " is listed twice");
      s.modes.push_back(number);
      s.mode_lines.push_back(m.line);
    }
    if (s.modes.empty()) fail(*modes, "'modes' is empty; list the file's mode numbers, or leave it out for all");
  }
  if (const Field* map = fs.find("map"))
    s.map.by = choice(*map, {"id", "coordinates"}) == 0 ? NodeMatchBy::Id : NodeMatchBy::Coordinates;
  if (const Field* tolerance = fs.find("tolerance")) {
    if (s.map.by != NodeMatchBy::Coordinates) fail(*tolerance, "'tolerance' applies only to 'map: coordinates'");
    s.map.tolerance = positive(*tolerance);
  }
  if (const Field* directions = fs.find("directions")) {
    s.directions.clear();
    for (const Field& d : list(*directions)) {
      const int c = choice(d, kDirections);
      if (std::find(s.directions.begin(), s.directions.end(), c) != s.directions.end())
        fail(d, "direction " + kDirections[c] + " is listed twice");
      s.directions.push_back(c);
    }
    if (s.directions.empty()) fail(*directions, "'directions' is empty; list any of x, y, z");
  }
  const Field* unit = fs.find("length_unit");
  const Field* scale = fs.find("scale_length");
  if (unit && scale) fail(*scale, "give either 'length_unit' or 'scale_length', not both");
  if (unit) {
    s.lengths.unit = text(*unit);
    if (!metres_per_length_unit(s.lengths.unit))
      fail(*unit, "unknown length unit " + quote(s.lengths.unit) + "; known: m, cm, mm, in, ft");
  }
  if (scale) s.lengths.scale = positive(*scale);
  return s;
}

}  // namespace modalcal::detail::loading
