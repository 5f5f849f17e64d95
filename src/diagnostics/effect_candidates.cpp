// Candidate effects of model-form diagnosis: generated from the model's structure or declared,
// each a model change with a free value, a screening variable, a reference magnitude and bounds
// (the rules are tabulated in effects.hpp).
#include <algorithm>
#include <array>
#include <cmath>
#include <iterator>
#include <limits>
#include <map>
#include <set>
#include <stdexcept>

#include "modalcal/block_geometry.hpp"
#include "modalcal/effects.hpp"
#include "model_surface.hpp"
#include "same_change.hpp"
#include "support/text_util.hpp"

namespace modalcal {

namespace detail {

/// fixed[v][c]: DOF c of node v is fixed.
std::vector<std::array<bool, 6>> fixed_dofs(const Model& model) {
  std::vector<std::array<bool, 6>> fixed(model.num_nodes(), {false, false, false, false, false, false});
  for (const FixedDofs& f : model.fixed)
    for (int v : f.nodes)
      for (int c = 0; c < 6; ++c) fixed[v][c] = fixed[v][c] || f.components[c];
  return fixed;
}

/// The free nodes on the model's surfaces (element sides no other element shares) and on the
/// interfaces between blocks (nodes of two or more blocks), in index order.
std::vector<int> surface_and_interface_nodes(const Model& model, const std::vector<std::array<bool, 6>>& fixed) {
  std::map<std::vector<int>, int> side_count;
  std::vector<int> blocks_of_node(model.num_nodes(), -1);
  std::vector<bool> chosen(model.num_nodes(), false);
  for (size_t b = 0; b < model.blocks.size(); ++b) {
    const ElementBlock& block = model.blocks[b];
    const int npe = nodes_per_element(block.type);
    for (int e = 0; e < block.num_elements(); ++e) {
      for (int k = 0; k < npe; ++k) {
        const int v = block.connectivity[e * npe + k];
        if (blocks_of_node[v] >= 0 && blocks_of_node[v] != static_cast<int>(b)) chosen[v] = true;  // an interface
        blocks_of_node[v] = static_cast<int>(b);
      }
      for (int side = 1; side <= num_solid_sides(block.type); ++side) {
        std::vector<int> key;
        for (int k : solid_side_nodes(block.type, side)) key.push_back(block.connectivity[e * npe + k]);
        std::sort(key.begin(), key.end());
        ++side_count[key];
      }
    }
  }
  for (const auto& [nodes, count] : side_count)
    if (count == 1)
      for (int v : nodes) chosen[v] = true;
  std::vector<int> out;
  for (int v = 0; v < model.num_nodes(); ++v)
    if (chosen[v] && !(fixed[v][0] && fixed[v][1] && fixed[v][2])) out.push_back(v);
  return out;
}

}  // namespace detail

namespace {

using detail::fixed_dofs;
using detail::surface_and_interface_nodes;



/// Stiffness, mass and element size of the blocks, and which blocks each node belongs to: the
/// magnitudes the candidates' references and bounds are made of.
class ModelScales {
 public:
  explicit ModelScales(const Model& model) : model_(model) {
    BlockGeometry geometry = block_geometry(model);
    blocks_of_node_ = std::move(geometry.blocks_of_node);
    for (size_t b = 0; b < model.blocks.size(); ++b) {
      const ElementBlock& block = model.blocks[b];
      const double volume = geometry.volume[b];
      const double scale = block.stiffness_scale == kNoProperty ? 1 : model.property_value(block.stiffness_scale);
      const double mass_scale = block.mass_scale == kNoProperty ? 1 : model.property_value(block.mass_scale);
      const double a = model.property_value(block.modulus_a), m = model.property_value(block.modulus_b);
      const double young = block.form == ElasticForm::YoungPoisson ? a : 9 * a * m / (3 * a + m);
      const double h = geometry.element_size(model, static_cast<int>(b));
      node_stiffness_.push_back(scale * young * h);
      mass_.push_back(mass_scale * model.property_value(block.density) * volume);
      size_.push_back(h);
    }
    for (const RigidCoupling& c : model.rigid_couplings) coupled_[c.reference] = c.nodes;
  }

  /// The blocks of `nodes`; a reference node stands for the nodes it couples.
  std::vector<int> blocks_of(const std::vector<int>& nodes) const {
    std::set<int> blocks;
    for (int v : nodes) {
      blocks.insert(blocks_of_node_[v].begin(), blocks_of_node_[v].end());
      if (const auto it = coupled_.find(v); it != coupled_.end())
        for (int w : it->second) blocks.insert(blocks_of_node_[w].begin(), blocks_of_node_[w].end());
    }
    if (blocks.empty())  // a free-standing reference node: the whole model
      for (size_t b = 0; b < model_.blocks.size(); ++b) blocks.insert(static_cast<int>(b));
    return {blocks.begin(), blocks.end()};
  }
  /// E h of the stiffest adjoining block: the stiffness one of `nodes` has in the mesh.
  double node_stiffness(const std::vector<int>& nodes) const {
    double k = 0;
    for (int b : blocks_of(nodes)) k = std::max(k, node_stiffness_[b]);
    return k;
  }
  double element_size(const std::vector<int>& nodes) const {
    double h = 0;
    for (int b : blocks_of(nodes)) h = std::max(h, size_[b]);
    return h;
  }
  double mass(const std::vector<int>& nodes) const {
    double m = 0;
    for (int b : blocks_of(nodes)) m += mass_[b];
    return m;
  }
  double block_size(int b) const { return size_[b]; }
  /// Radius of the patch a reference node couples (RMS distance), else the element size.
  double patch_radius(int node) const {
    const auto it = coupled_.find(node);
    if (it == coupled_.end() || it->second.empty()) return element_size({node});
    double sum = 0;
    for (int w : it->second) sum += (model_.coordinates[w] - model_.coordinates[node]).squaredNorm();
    return std::sqrt(sum / it->second.size());
  }

 private:
  const Model& model_;
  std::vector<std::vector<int>> blocks_of_node_;
  std::vector<double> node_stiffness_, mass_, size_;
  std::map<int, std::vector<int>> coupled_;
};

std::string node_set_place(const NodeSet& set) { return set.name; }
std::string node_place(const Model& model, int v) { return "#" + std::to_string(model.node_ids[v]); }

const Joint* find_joint(const Model& model, const std::string& name) {
  for (const Joint& j : model.joints)
    if (j.name == name) return &j;
  return nullptr;
}

/// The nodes an entity of `model` acts on (a block or a block's region: all of its nodes; a point mass added on a
/// node set: one part per node, "<entity> (node N)").
std::vector<int> nodes_of(const Model& model, const std::string& entity) {
  for (const ElementBlock& b : model.blocks)
    if (b.name == entity) {
      std::set<int> unique(b.connectivity.begin(), b.connectivity.end());
      return {unique.begin(), unique.end()};
    }
  for (const ElementBlock& b : model.blocks)
    for (const BlockRegion& r : b.regions)
      if (r.name == entity) {
        const int npe = nodes_per_element(b.type);
        std::set<int> unique;
        for (int e : r.elements) unique.insert(b.connectivity.begin() + e * npe, b.connectivity.begin() + (e + 1) * npe);
        return {unique.begin(), unique.end()};
      }
  if (const Joint* j = find_joint(model, entity)) return {j->node_a, j->node_b};
  for (const GroundSpring& g : model.ground_springs)
    if (g.name == entity) return g.nodes;
  std::vector<int> nodes;
  for (const PointMass& m : model.point_masses)
    if (m.name == entity || m.name.rfind(entity + " (node ", 0) == 0) nodes.push_back(m.node);
  return nodes;
}

bool is_block(const Model& model, const std::string& entity) {
  return std::any_of(model.blocks.begin(), model.blocks.end(), [&](const ElementBlock& b) { return b.name == entity; });
}

std::optional<Vec3> centroid(const Model& model, const std::vector<int>& nodes) {
  if (nodes.empty()) return std::nullopt;
  Vec3 sum = Vec3::Zero();
  for (int v : nodes) sum += model.coordinates[v];
  return Vec3(sum / static_cast<double>(nodes.size()));
}

/// Turns model changes (their values ignored) into candidates with the rules of effects.hpp.
class CandidateFactory {
 public:
  CandidateFactory(const Problem& problem, const CandidateOptions& options)
      : problem_(problem), model_(problem.model), options_(options), scales_(problem.model) {
    for (const Parameter& q : problem.parameters)
      for (PropertyId t : q.targets) calibrated_.insert(model_.properties[t].name);
  }

  /// The candidate, or nullopt with the reason in *why.
  std::optional<EffectCandidate> from_change(ModelChange change, std::string* why) const {
    const auto k = std::find(std::begin(kStiffnessComponentNames), std::end(kStiffnessComponentNames), change.property);
    const int component = change.kind != ModelChange::Kind::AddPointMass && k != std::end(kStiffnessComponentNames)
                              ? static_cast<int>(k - std::begin(kStiffnessComponentNames))
                              : -1;  // a stiffness component's index, -1 for anything else
    // Apply it with a harmless value to learn its name, words, nominal value and nodes.
    change.value = change.property == "nu" ? 0.25 : 1;
    Model changed = model_;
    ModelEffect effect;
    try {
      effect = apply_model_change(&changed, change);
    } catch (const std::invalid_argument& e) {
      *why = e.what();
      return std::nullopt;
    }
    if (calibrated_.count(effect.name)) {
      *why = effect.name + " is a calibration parameter's target";
      return std::nullopt;
    }
    EffectCandidate c;
    c.name = effect.name;
    c.description = effect.description;
    c.change = change;
    const std::string entity = effect.name.substr(0, effect.name.rfind('.'));
    const std::vector<int> nodes = nodes_of(changed, entity);
    const double h = scales_.element_size(nodes);
    if (!is_block(changed, entity)) c.location = centroid(changed, nodes);
    c.neighbourhood = 2 * h;
    const bool rotational =
        component >= 3 || (change.kind == ModelChange::Kind::AddPointMass && change.property != "mass");
    const Place place{changed, entity, nodes, component, rotational ? h * h : 1};
    set_range(change, effect, place, &c);
    return c;
  }

 private:
  /// Where a candidate acts: the changed model, its entity and nodes, the stiffness component
  /// (-1: none), and the squared length that turns a force scale into a moment scale (1 if none).
  struct Place {
    const Model& changed;
    const std::string& entity;
    const std::vector<int>& nodes;
    int component;
    double length_squared;
  };

  /// The candidate's variable, nominal value, screening value, reference and bounds.
  void set_range(const ModelChange& change, const ModelEffect& effect, const Place& at, EffectCandidate* c) const {
    if (change.kind == ModelChange::Kind::FlexibleSupport) {
      const double k_ref = scales_.node_stiffness(at.nodes) * at.length_squared;
      c->variable = EffectCandidate::Variable::Compliance;
      c->nominal = std::numeric_limits<double>::infinity();
      c->reference = k_ref;
      c->screen_value = options_.rigid_support_factor * k_ref;
      c->lower = k_ref / 1000;
      c->upper = c->screen_value;
    } else if (effect.nominal_value != 0 &&
               (change.kind == ModelChange::Kind::SetProperty || change.kind == ModelChange::Kind::AddRegion)) {
      // A present property (or an absent scale factor, nominal 1): a factor of ten either way; a
      // joint's or spring's stiffness component a factor of a hundred (a loose bolt, a seized
      // bearing), so that a truth a decade off does not end its refit on a bound.
      c->variable = EffectCandidate::Variable::Log;
      c->nominal = c->screen_value = c->reference = effect.nominal_value;
      const double factor = at.component >= 0 ? 100 : 10;
      c->lower = effect.nominal_value / factor;
      c->upper = effect.nominal_value * factor;
      if (change.property == "nu") {  // bounded by physics, not by a factor
        c->variable = EffectCandidate::Variable::Linear;
        c->lower = std::max(-0.99, effect.nominal_value - 0.2);
        c->upper = std::min(0.49, effect.nominal_value + 0.2);
      }
    } else {  // absent until now: linear from 0
      c->variable = EffectCandidate::Variable::Linear;
      c->nominal = c->screen_value = 0;
      c->lower = 0;
      if (at.component >= 0) {
        c->reference = stiffness_reference(change, at);
        c->upper = 100 * c->reference;
      } else {
        const double per_node = scales_.mass(at.nodes) / std::max<size_t>(1, at.nodes.size());
        c->reference = 0.01 * per_node * at.length_squared;
        c->upper = 0.5 * per_node * at.length_squared;
      }
    }
  }

  /// The stiffness scale of an absent stiffness component: the nodes' own, a joint's present
  /// components, or for a joint between two parts the softer side's.
  double stiffness_reference(const ModelChange& change, const Place& at) const {
    if (const Joint* j = find_joint(at.changed, at.entity); j && change.kind == ModelChange::Kind::SetProperty) {
      // A joint's own translational stiffness (geometric mean of its present components) sets
      // the scale; a rotational component acts over the patches its nodes couple.
      double log_sum = 0;
      int present = 0;
      for (int t = 0; t < 3; ++t)
        if (const double k = model_.property_value(model_joint(at.entity)->stiffness[t]); k > 0) {
          log_sum += std::log(k);
          ++present;
        }
      const double k_translation = present ? std::exp(log_sum / present) : scales_.node_stiffness(at.nodes);
      const double radius = std::max(scales_.patch_radius(j->node_a), scales_.patch_radius(j->node_b));
      return at.component >= 3 ? k_translation * radius * radius : k_translation;
    }
    if (change.kind == ModelChange::Kind::AddJoint) {  // between two parts: the softer side decides
      const Joint* added = find_joint(at.changed, at.entity);
      return std::min(scales_.node_stiffness({added->node_a}), scales_.node_stiffness({added->node_b})) *
             at.length_squared;
    }
    return scales_.node_stiffness(at.nodes) * at.length_squared;
  }

 public:
  std::vector<EffectCandidate> automatic() const {
    std::vector<std::pair<ModelChange, std::string>> changes;  // with a note for the words
    auto add = [&](const std::string& text, const std::string& note = "") {
      ModelChange change = parse_model_change(text + "=1");
      changes.emplace_back(change, note);
    };
    if (options_.blocks)
      for (const ElementBlock& b : model_.blocks) {
        for (const char* property : {"stiffness_scale", "mass_scale"}) add(b.name + "." + property);
        // A material given by E and nu: its Poisson's ratio, which no scale reproduces (it
        // changes bending against shear and the cross-section's lateral strain).
        if (b.form == ElasticForm::YoungPoisson) add(model_.properties[b.modulus_b].name);
      }
    if (options_.joints) {
      for (const Joint& j : model_.joints)
        for (const std::string& key : kStiffnessComponentNames)
          if (key.size() == 2 || (model_.has_rotations[j.node_a] && model_.has_rotations[j.node_b]))
            add(j.name + "." + key);
      for (const GroundSpring& s : model_.ground_springs)
        for (int c = 0; c < 6; ++c)
          if (s.stiffness[c] != kNoProperty) add(s.name + "." + kStiffnessComponentNames[c]);
      std::set<std::string> masses;
      for (const PointMass& m : model_.point_masses)
        if (m.mass != kNoProperty && masses.insert(model_.properties[m.mass].name).second)
          add(model_.properties[m.mass].name);
    }
    const std::vector<std::array<bool, 6>> fixed = fixed_dofs(model_);
    for (const NodeSet& set : model_.node_sets) {
      std::array<bool, 6> all_fixed{true, true, true, true, true, true},
          any_free{false, false, false, false, false, false};
      for (int v : set.nodes)
        for (int c = 0; c < 6; ++c) {
          all_fixed[c] = all_fixed[c] && fixed[v][c];
          any_free[c] = any_free[c] || !fixed[v][c];
        }
      if (options_.node_sets && (any_free[0] || any_free[1] || any_free[2])) {
        for (int c = 0; c < 3; ++c)
          if (any_free[c]) add("spring@" + node_set_place(set) + ":" + kStiffnessComponentNames[c]);
        add("point_mass@" + node_set_place(set) + ":mass");
      }
      if (options_.supports && !set.nodes.empty())
        for (int c = 0; c < 6; ++c)
          if (all_fixed[c]) add("support@" + node_set_place(set) + ":" + kStiffnessComponentNames[c]);
    }
    if (options_.sensor_masses) {
      std::set<int> nodes;
      for (const Sensor& s : problem_.sensors)
        if (nodes.insert(s.node).second)
          add("point_mass@" + node_place(model_, s.node) + ":mass", "a sensor's position");
    }
    if (options_.regions)
      for (const std::string& text : region_changes()) add(text);
    if (options_.between_parts) append_between_parts(fixed, &changes);
    if (options_.spatial)
      for (int v : surface_and_interface_nodes(model_, fixed)) {
        add("point_mass@" + node_place(model_, v) + ":mass", "on a surface or interface");
        for (int c = 0; c < 3; ++c)
          if (!fixed[v][c]) add("spring@" + node_place(model_, v) + ":" + kStiffnessComponentNames[c]);
      }

    std::vector<EffectCandidate> out;
    std::set<std::string> names;
    for (const auto& [change, note] : changes) {
      std::string why;
      std::optional<EffectCandidate> c = from_change(change, &why);
      if (!c || !names.insert(c->name).second) continue;
      if (!note.empty()) c->description += " (" + note + ")";
      out.push_back(*c);
    }
    return out;
  }

 private:
  /// A spring along x, y, z between the nearest nodes of two blocks that share none but lie
  /// within gap_factor element sizes (of those nearest pairs, the one nearest their centroid).
  void append_between_parts(const std::vector<std::array<bool, 6>>& fixed,
                            std::vector<std::pair<ModelChange, std::string>>* changes) const {
    const int nb = static_cast<int>(model_.blocks.size());
    std::vector<std::vector<int>> nodes(nb);
    for (int b = 0; b < nb; ++b) {
      std::set<int> unique(model_.blocks[b].connectivity.begin(), model_.blocks[b].connectivity.end());
      for (int v : unique)
        if (!(fixed[v][0] && fixed[v][1] && fixed[v][2])) nodes[b].push_back(v);
    }
    for (int a = 0; a < nb; ++a)
      for (int b = a + 1; b < nb; ++b) {
        if (nodes[a].empty() || nodes[b].empty()) continue;
        std::vector<int> shared;
        std::set_intersection(nodes[a].begin(), nodes[a].end(), nodes[b].begin(), nodes[b].end(),
                              std::back_inserter(shared));
        if (!shared.empty()) continue;
        const double gap = options_.gap_factor * std::max(scales_.block_size(a), scales_.block_size(b));
        double best = std::numeric_limits<double>::infinity();
        for (int v : nodes[a])
          for (int w : nodes[b]) best = std::min(best, (model_.coordinates[v] - model_.coordinates[w]).norm());
        if (!(best < gap)) continue;
        std::vector<std::pair<int, int>> nearest;
        Vec3 centroid = Vec3::Zero();
        for (int v : nodes[a])
          for (int w : nodes[b])
            if ((model_.coordinates[v] - model_.coordinates[w]).norm() <= best * (1 + 1e-9)) {
              nearest.emplace_back(v, w);
              centroid += 0.5 * (model_.coordinates[v] + model_.coordinates[w]);
            }
        centroid /= static_cast<double>(nearest.size());
        auto distance = [&](const std::pair<int, int>& p) {
          return (0.5 * (model_.coordinates[p.first] + model_.coordinates[p.second]) - centroid).norm();
        };
        const auto pair = *std::min_element(nearest.begin(), nearest.end(),
                                            [&](const auto& x, const auto& y) { return distance(x) < distance(y); });
        const std::string note = "between blocks " + model_.blocks[a].name + " and " + model_.blocks[b].name + ", " +
                                 format_round_trip(best) + " apart";
        for (int c = 0; c < 3; ++c)
          changes->emplace_back(parse_model_change("joint@" + node_place(model_, pair.first) + "/" +
                                                   node_place(model_, pair.second) + ":" + kStiffnessComponentNames[c] + "=1"),
                                note);
      }
  }

  const Joint* model_joint(const std::string& name) const { return find_joint(model_, name); }

  /// The stiffness and mass scale changes of every block's regions on each grid
  /// (CandidateOptions::region_levels) and on each grid shifted (region_stagger), a box that
  /// another grid repeats screened once.
  std::vector<std::string> region_changes() const {
    std::vector<std::string> changes;
    for (size_t b = 0; b < model_.blocks.size(); ++b) {
      const std::vector<Vec3> centroids = element_centroids(model_, model_.blocks[b]);
      std::set<std::string> places;
      for (int level = 0; level < options_.region_levels; ++level)
        for (const bool shifted : {false, true}) {
          if (shifted && !options_.region_stagger) continue;
          const double elements = options_.region_elements * (1 << level);
          // Whole element sizes, so that the shifted grid's faces lie between centroids as well.
          const double shift = shifted ? std::round(0.5 * elements) : 0.0;
          for (const std::string& place : region_places(static_cast<int>(b), centroids, elements, shift))
            if (places.insert(place).second)
              for (const char* property : {"stiffness_scale", "mass_scale"})
                changes.push_back("region@" + place + ":" + property);
        }
    }
    return changes;
  }

  /// "BLOCK/[lo]/[hi]" for each region of block b (element `centroids`): the centroids binned in
  /// cubes of `elements` element sizes, the grid shifted by `shift` element sizes along every axis, each
  /// box the tight bounds of one cube's centroids (so that no centroid of another cube lies in
  /// it); none when one cube holds the whole block.
  std::vector<std::string> region_places(int b, const std::vector<Vec3>& centroids, double elements,
                                         double shift) const {
    const ElementBlock& block = model_.blocks[b];
    Vec3 lowest = Vec3::Constant(std::numeric_limits<double>::infinity());
    for (const Vec3& c : centroids) lowest = lowest.cwiseMin(c);
    const double h = scales_.block_size(b), cell = elements * h;
    lowest.array() -= (0.5 + shift) * h;  // about the block's lowest corner: cube faces between centroids
    std::map<std::array<long, 3>, std::pair<Vec3, Vec3>> boxes;  // cube -> bounds of its centroids
    for (const Vec3& c : centroids) {
      std::array<long, 3> key;
      for (int a = 0; a < 3; ++a) key[a] = static_cast<long>(std::floor((c[a] - lowest[a]) / cell));
      auto [it, fresh] = boxes.try_emplace(key, c, c);
      if (!fresh) it->second = {it->second.first.cwiseMin(c), it->second.second.cwiseMax(c)};
    }
    std::vector<std::string> places;
    if (boxes.size() < 2) return places;
    auto point = [](const Vec3& x) {
      return "[" + format_round_trip(x[0]) + "," + format_round_trip(x[1]) + "," + format_round_trip(x[2]) + "]";
    };
    for (const auto& [key, box] : boxes) places.push_back(block.name + "/" + point(box.first) + "/" + point(box.second));
    return places;
  }


  const Problem& problem_;
  const Model& model_;
  CandidateOptions options_;
  ModelScales scales_;
  std::set<std::string> calibrated_;
};

/// "text" or "text=value": the change (value 1 when absent) and the value.
ModelChange parse_effect_text(const std::string& text, std::optional<double>* value) {
  const size_t equals = text.rfind('=');
  const size_t colon = text.rfind(':');
  const bool has_value = equals != std::string::npos && (colon == std::string::npos || equals > colon);
  ModelChange change = parse_model_change(has_value ? text : text + "=1");
  if (has_value) *value = change.value;
  return change;
}

/// The name of the property a declared effect's text sets on `model` ("support_root.kx" for
/// "support@root:kx"), or none when its change does not apply to `model`.
std::optional<std::string> declared_effect_name(const Model& model, const std::string& text) {
  std::string name = text.substr(0, text.rfind('=') == std::string::npos ? text.size() : text.rfind('='));
  name = name.substr(0, name.find_last_not_of(" \t") + 1);
  if (name.find('@') == std::string::npos) return name;
  try {
    std::optional<double> value;
    return describe_model_change(model, parse_effect_text(text, &value)).name;
  } catch (const std::invalid_argument&) {
    return std::nullopt;  // make_candidate says why
  }
}

/// Whether a declared effect is already in the model as a calibration parameter's target (an
/// effect a diagnosis accepted, or one enabled and added): it is then no longer a candidate.
bool already_a_parameter(const Problem& problem, const std::string& text) {
  const std::optional<std::string> name = declared_effect_name(problem.model, text);
  if (!name) return false;
  for (const Parameter& q : problem.parameters)
    for (PropertyId t : q.targets)
      if (problem.model.properties[t].name == *name) return true;
  return false;
}

}  // namespace

bool CandidateOptions::IsValid(std::string* error) const {
  auto bad = [&](const std::string& message) {
    if (error) *error = message;
    return false;
  };
  if (!(gap_factor > 0)) return bad("gap_factor = " + detail::option_text(gap_factor) + ": must be > 0");
  if (!(region_elements >= 1 && region_elements <= 1000))
    return bad("region_elements = " + detail::option_text(region_elements) + ": must be in [1, 1000]");
  if (!(region_levels >= 1 && region_levels <= 6))
    return bad("region_levels = " + detail::option_text(region_levels) + ": must be in [1, 6]");
  if (!(rigid_support_factor >= 10 && rigid_support_factor <= 1e8))
    return bad("rigid_support_factor = " + detail::option_text(rigid_support_factor) + ": must be in [10, 1e8]");
  return true;
}

std::vector<EffectCandidate> generate_candidates(const Problem& problem, const CandidateOptions& options) {
  std::string error;
  if (!options.IsValid(&error)) throw std::invalid_argument("CandidateOptions: " + error);
  const CandidateFactory factory(problem, options);
  std::vector<EffectCandidate> candidates = factory.automatic();
  for (const DeclaredEffect& d : problem.effects) {
    if (already_a_parameter(problem, d.effect)) continue;
    EffectCandidate c = make_candidate(problem, d.effect, options);
    if (!d.description.empty()) c.description = d.description;
    if (d.initial) c.initial = d.initial;
    if (d.lower) c.lower = *d.lower;
    if (d.upper) c.upper = *d.upper;
    const auto same =
        std::find_if(candidates.begin(), candidates.end(), [&](const auto& a) { return a.name == c.name; });
    if (same != candidates.end())
      *same = c;
    else
      candidates.push_back(c);
  }
  return candidates;
}

namespace {

/// `c` declared, starting from `start` when given: a start outside the candidate's bounds is
/// refused, not moved onto the nearer bound (a calibration from there would not be the one asked for).
EffectCandidate with_start(EffectCandidate c, std::optional<double> start, const std::string& text) {
  if (start && !(*start >= c.lower && *start <= c.upper))
    throw std::invalid_argument("effect '" + text + "': the start value " + format_round_trip(*start) +
                                " lies outside the effect's range [" + format_round_trip(c.lower) + ", " +
                                format_round_trip(c.upper) + "]");
  c.initial = start;
  c.declared = true;
  return c;
}

}  // namespace

EffectCandidate make_candidate(const Problem& problem, const std::string& text, const CandidateOptions& options) {
  std::optional<double> value;
  const std::string trimmed = text.substr(0, text.rfind('=') == std::string::npos ? text.size() : text.rfind('='));
  const CandidateFactory factory(problem, options);
  // A candidate's name first (e.g. added_mass_node123.mass, which is no change text).
  const std::string name = trimmed.substr(0, trimmed.find_last_not_of(" \t") + 1);
  if (name.find('@') == std::string::npos && problem.model.find_property(name) == kNoProperty) {
    for (EffectCandidate& c : factory.automatic())
      if (c.name == name) {
        parse_effect_text(text, &value);
        return with_start(std::move(c), value, text);
      }
  }
  const ModelChange change = parse_effect_text(text, &value);
  std::string why;
  std::optional<EffectCandidate> c = factory.from_change(change, &why);
  if (!c) throw std::invalid_argument("effect '" + text + "': " + why);
  return with_start(std::move(*c), value, text);
}

std::vector<EffectCandidate> enabled_candidates(const Problem& problem, const CandidateOptions& options) {
  std::vector<EffectCandidate> out;
  for (const DeclaredEffect& d : problem.effects) {
    if (!d.enable) continue;
    EffectCandidate c = make_candidate(problem, d.effect, options);
    if (!d.description.empty()) c.description = d.description;
    if (d.initial) c.initial = d.initial;
    if (d.lower) c.lower = *d.lower;
    if (d.upper) c.upper = *d.upper;
    out.push_back(c);
  }
  return out;
}

Problem problem_with_effects(const Problem& problem, const std::vector<EffectCandidate>& candidates,
                             const std::vector<double>& values) {
  if (candidates.size() != values.size())
    throw std::invalid_argument("problem_with_effects: " + std::to_string(values.size()) + " values for " +
                                std::to_string(candidates.size()) + " candidates");
  Problem out = problem;
  std::vector<ModelChange> changes;
  for (size_t k = 0; k < candidates.size(); ++k) {
    changes.push_back(candidates[k].change);
    changes.back().value = values[k];
  }
  apply_model_changes(&out.model, changes);  // throws naming the change
  for (size_t k = 0; k < candidates.size(); ++k) {
    const EffectCandidate& c = candidates[k];
    Parameter q;
    q.name = c.name;
    q.targets = {out.model.find_property(c.name)};
    if (q.targets[0] == kNoProperty)
      throw std::logic_error("problem_with_effects: " + c.name + " is not a property after its change");
    q.initial = values[k];
    q.lower = c.lower;
    q.upper = c.upper;
    q.reference = c.reference;
    // Log scaling wherever the value is positive: an effect from 0 is then searched in decades,
    // down to a thousandth of its start (smaller is "no effect" at this start's scale).
    q.scaling = values[k] > 0 && c.lower >= 0 ? Scaling::Log : Scaling::Linear;
    if (q.scaling == Scaling::Log && !(q.lower > 0)) q.lower = std::min(1e-3 * values[k], 0.5 * q.upper);
    if (out.find_parameter(q.name) >= 0)
      throw std::invalid_argument("problem_with_effects: " + c.name + " is given twice");
    out.parameters.push_back(q);
  }
  // A declared effect that is now a parameter is no candidate any more, and on the changed model
  // some could not even be described again (a support's fixity, once released).
  out.effects.erase(std::remove_if(out.effects.begin(), out.effects.end(),
                                   [&](const DeclaredEffect& e) {
                                     const std::optional<std::string> name = declared_effect_name(problem.model, e.effect);
                                     return name && out.find_parameter(*name) >= 0;
                                   }),
                    out.effects.end());
  return out;
}

bool EffectCandidate::neighbour_of(const EffectCandidate& other) const {
  if (!location || !other.location || !detail::same_change(*this, other)) return false;
  return (*location - *other.location).norm() < std::max(neighbourhood, other.neighbourhood);
}

std::optional<Vec3> effect_location(const Model& model, const EffectCandidate& candidate) {
  if (candidate.location) return candidate.location;
  Model changed = model;
  ModelChange change = candidate.change;
  if (!(change.value > 0 && std::isfinite(change.value))) change.value = candidate.reference;
  const std::string name = apply_model_change(&changed, change).name;
  const std::string entity = name.substr(0, name.rfind('.'));
  if (is_block(changed, entity)) return std::nullopt;  // it acts on the whole block
  return centroid(changed, nodes_of(changed, entity));
}

std::optional<Vec3> effect_place(const Model& model, const EffectCandidate& candidate) {
  if (candidate.location) return candidate.location;
  // A block's property: its nodes' centroid, without the copy of the model effect_location()
  // makes to find out that the effect is block-wide (the place refits ask for every candidate).
  const std::string entity = candidate.name.substr(0, candidate.name.rfind('.'));
  if (is_block(model, entity)) return centroid(model, nodes_of(model, entity));
  return effect_location(model, candidate);
}

}  // namespace modalcal
