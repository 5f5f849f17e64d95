// Model changes ("effects"): parsing the compact change strings, applying them to a Model, and
// naming and describing properties in the words reports use (grammar in model_change.hpp).
#include "modalcal/model_change.hpp"

#include <algorithm>
#include <charconv>
#include <cmath>
#include <cstdio>
#include <limits>
#include <stdexcept>
#include <string>
#include <tuple>
#include <utility>

#include "support/text_util.hpp"
#include "modalcal/block_geometry.hpp"

namespace modalcal {

namespace {

const std::vector<std::string> kInertiaKeys{"Ixx", "Iyy", "Izz"};
const char* const kAxes[3] = {"x", "y", "z"};

[[noreturn]] void fail(const std::string& text, const std::string& message) {
  throw std::invalid_argument("change '" + detail::excerpt(text) + "': " + message);
}

std::string join(const std::vector<std::string>& items) {
  std::string out;
  for (const std::string& item : items) out += (out.empty() ? "" : ", ") + item;
  return out;
}

int index_of(const std::vector<std::string>& names, const std::string& name) {
  const auto it = std::find(names.begin(), names.end(), name);
  return it == names.end() ? -1 : static_cast<int>(it - names.begin());
}

using detail::trim;

double parse_number(const std::string& text, const std::string& token, const std::string& what) {
  const std::string t = trim(token);
  double v = 0;
  if (detail::read_number(t, &v) != detail::NumberRead::kOk)
    fail(text, "expected a finite number for " + what + ", got '" + t + "'");
  return v;
}

bool is_plain_name(const std::string& s) {
  return !s.empty() && s.find_first_of(" \t@:=/[]#,") == std::string::npos;
}

const char* const kGrammar =
    "expected ENTITY.PROPERTY=VALUE (e.g. joint2.krx=3.1e5) or KIND@PLACE:PROPERTY=VALUE with KIND "
    "point_mass, spring, joint or support and PLACE a node set, #NODE_ID or [x,y,z] (e.g. "
    "point_mass@top:mass=0.05, joint@#17/#42:kx=1e6, support@bottom:kx=1e8), or "
    "region@BLOCK/[x,y,z]/[x,y,z]:stiffness_scale=VALUE";

NodePlace parse_place(const std::string& text, const std::string& token) {
  const std::string t = trim(token);
  NodePlace place;
  if (!t.empty() && t.front() == '#') {
    place.kind = NodePlace::Kind::NodeId;
    long id = 0;
    const auto [end, error] = std::from_chars(t.data() + 1, t.data() + t.size(), id);
    if (t.size() == 1 || error != std::errc() || end != t.data() + t.size())
      fail(text, "expected a node id after '#', got '" + t + "'");
    place.node_id = id;
  } else if (!t.empty() && t.front() == '[') {
    place.kind = NodePlace::Kind::Point;
    if (t.back() != ']') fail(text, "a point is written [x,y,z]; '" + t + "' has no closing ']'");
    const std::string inner = t.substr(1, t.size() - 2);
    std::vector<std::string> parts;
    size_t start = 0;
    for (size_t comma; (comma = inner.find(',', start)) != std::string::npos; start = comma + 1)
      parts.push_back(inner.substr(start, comma - start));
    parts.push_back(inner.substr(start));
    if (parts.size() != 3) fail(text, "a point is written [x,y,z] with three numbers, got '" + t + "'");
    for (int a = 0; a < 3; ++a) place.point[a] = parse_number(text, parts[a], std::string("the point's ") + kAxes[a]);
  } else {
    if (!is_plain_name(t)) fail(text, "'" + t + "' is not a place: " + kGrammar);
    place.node_set = t;
  }
  return place;
}

std::string place_text(const NodePlace& place) {
  switch (place.kind) {
    case NodePlace::Kind::NodeSet:
      return place.node_set;
    case NodePlace::Kind::NodeId:
      return "#" + std::to_string(place.node_id);
    case NodePlace::Kind::Point:
      return "[" + format_round_trip(place.point[0]) + "," + format_round_trip(place.point[1]) + "," +
             format_round_trip(place.point[2]) + "]";
  }
  return "";
}

const char* kind_keyword(ModelChange::Kind kind) {
  switch (kind) {
    case ModelChange::Kind::AddPointMass:
      return "point_mass";
    case ModelChange::Kind::AddSpring:
      return "spring";
    case ModelChange::Kind::AddJoint:
      return "joint";
    case ModelChange::Kind::FlexibleSupport:
      return "support";
    case ModelChange::Kind::AddRegion:
      return "region";
    case ModelChange::Kind::SetProperty:
      break;
  }
  return "";
}

// ---------------------------------------------------------------------------- entities

enum class EntityKind { None, Block, Joint, Spring, PointMass, Region };

struct EntityRef {
  EntityKind kind = EntityKind::None;
  int index = -1;   ///< of the entity; of its block for a region
  int region = -1;  ///< in the block's regions
};

EntityRef find_entity(const Model& model, const std::string& name) {
  for (size_t k = 0; k < model.blocks.size(); ++k)
    if (model.blocks[k].name == name) return {EntityKind::Block, static_cast<int>(k)};
  for (size_t k = 0; k < model.joints.size(); ++k)
    if (model.joints[k].name == name) return {EntityKind::Joint, static_cast<int>(k)};
  for (size_t k = 0; k < model.ground_springs.size(); ++k)
    if (model.ground_springs[k].name == name) return {EntityKind::Spring, static_cast<int>(k)};
  for (size_t k = 0; k < model.point_masses.size(); ++k)
    if (model.point_masses[k].name == name) return {EntityKind::PointMass, static_cast<int>(k)};
  for (size_t b = 0; b < model.blocks.size(); ++b)
    for (size_t r = 0; r < model.blocks[b].regions.size(); ++r)
      if (model.blocks[b].regions[r].name == name) return {EntityKind::Region, static_cast<int>(b), static_cast<int>(r)};
  return {};
}

/// As find_entity, and a point mass added on a node set (one part per node, named
/// "<entity> (node N)") by its entity name.
EntityRef find_entity_or_part(const Model& model, const std::string& name) {
  const EntityRef e = find_entity(model, name);
  if (e.kind != EntityKind::None) return e;
  for (size_t k = 0; k < model.point_masses.size(); ++k)
    if (model.point_masses[k].name.rfind(name + " (node ", 0) == 0) return {EntityKind::PointMass, static_cast<int>(k)};
  return {};
}

std::string entity_kind_name(EntityKind kind) {
  switch (kind) {
    case EntityKind::Block:
      return "block";
    case EntityKind::Joint:
      return "joint";
    case EntityKind::Spring:
      return "spring";
    case EntityKind::PointMass:
      return "point mass";
    case EntityKind::Region:
      return "region";
    case EntityKind::None:
      break;
  }
  return "entity";
}

std::vector<std::string> entity_names(const Model& model) {
  std::vector<std::string> names;
  for (const ElementBlock& b : model.blocks) names.push_back(b.name);
  for (const ElementBlock& b : model.blocks)
    for (const BlockRegion& r : b.regions) names.push_back(r.name);
  for (const Joint& j : model.joints) names.push_back(j.name);
  for (const GroundSpring& s : model.ground_springs) names.push_back(s.name);
  for (const PointMass& m : model.point_masses) {
    const std::string entity = m.name.substr(0, m.name.find(" (node "));  // one name per node-set mass
    if (std::find(names.begin(), names.end(), entity) == names.end()) names.push_back(entity);
  }
  return names;
}

/// The properties an entity has or may be given.
std::vector<std::string> settable_properties(const Model& model, EntityRef e) {
  switch (e.kind) {
    case EntityKind::Block: {
      const bool young = model.blocks[e.index].form == ElasticForm::YoungPoisson;
      return {young ? "E" : "K", young ? "nu" : "G", "density", "stiffness_scale", "mass_scale"};
    }
    case EntityKind::Joint:
    case EntityKind::Spring:
      return kStiffnessComponentNames;
    case EntityKind::PointMass:
      return {"mass", "Ixx", "Iyy", "Izz"};
    case EntityKind::Region:
      return {"stiffness_scale", "mass_scale"};
    case EntityKind::None:
      break;
  }
  return {};
}

/// The slots of an entity that hold `property` (one per part of a point mass added on a node
/// set), so that an absent property can be created.
std::vector<PropertyId*> property_slots(Model& model, EntityRef e, const std::string& property) {
  switch (e.kind) {
    case EntityKind::Block: {
      ElementBlock& b = model.blocks[e.index];
      if (property == "stiffness_scale") return {&b.stiffness_scale};
      if (property == "mass_scale") return {&b.mass_scale};
      if (property == "density") return {&b.density};
      return {property == "E" || property == "K" ? &b.modulus_a : &b.modulus_b};
    }
    case EntityKind::Joint:
      return {&model.joints[e.index].stiffness[index_of(kStiffnessComponentNames, property)]};
    case EntityKind::Spring:
      return {&model.ground_springs[e.index].stiffness[index_of(kStiffnessComponentNames, property)]};
    case EntityKind::PointMass: {
      std::vector<PropertyId*> slots;
      const std::string name = model.point_masses[e.index].name;
      const std::string entity = name.substr(0, name.find(" (node "));
      for (PointMass& m : model.point_masses)
        if (m.name == entity || m.name.rfind(entity + " (node ", 0) == 0)
          slots.push_back(property == "mass" ? &m.mass : &m.inertia[index_of(kInertiaKeys, property)]);
      return slots;
    }
    case EntityKind::Region: {
      BlockRegion& r = model.blocks[e.index].regions[e.region];
      return {property == "stiffness_scale" ? &r.stiffness_scale : &r.mass_scale};
    }
    case EntityKind::None:
      break;
  }
  return {};
}

bool is_scale_factor(const std::string& property) {
  return property == "stiffness_scale" || property == "mass_scale";
}

/// Value of a property before it exists: scale factors multiply by 1, everything else adds 0
/// (flexible supports aside: absent_property_value).
double absent_value(const std::string& property) { return is_scale_factor(property) ? 1.0 : 0.0; }

bool is_flexible_support(const Model& model, EntityRef e) {
  return e.kind == EntityKind::Spring && model.ground_springs[e.index].replaces_fixity;
}

/// "stiffness along x", "rotational stiffness about z".
std::string component_words(int c) {
  return c < 3 ? std::string("stiffness along ") + kAxes[c] : std::string("rotational stiffness about ") + kAxes[c - 3];
}

std::string property_words(EntityKind kind, const std::string& property) {
  if (kind == EntityKind::Joint || kind == EntityKind::Spring) {
    const int c = index_of(kStiffnessComponentNames, property);
    return c >= 0 ? component_words(c) : property;
  }
  if (kind == EntityKind::PointMass) {
    const int c = index_of(kInertiaKeys, property);
    return c >= 0 ? std::string("rotary inertia about ") + kAxes[c] : property;
  }
  const std::pair<const char*, const char*> words[] = {
      {"E", "Young's modulus"}, {"nu", "Poisson's ratio"},           {"K", "bulk modulus"},
      {"G", "shear modulus"},   {"density", "density"},              {"stiffness_scale", "stiffness multiplier"},
      {"mass_scale", "mass multiplier"}};
  for (const auto& [key, text] : words)
    if (property == key) return text;
  return property;
}

/// Checks a value against the physical range of its property.
void check_value(const std::string& text, const std::string& property, double value) {
  if (const std::string why = property_range_violation(property, value); !why.empty()) fail(text, why);
}

/// Frees `component` of `nodes` wherever the model fixes it; every node must be fixed there.
void release_fixity(Model& model, const std::vector<int>& nodes, int component, const std::string& place_words,
                    const std::string& text) {
  std::vector<bool> in_place(model.num_nodes(), false), released(model.num_nodes(), false);
  for (int v : nodes) in_place[v] = true;
  std::vector<FixedDofs> fixed;
  for (const FixedDofs& f : model.fixed) {
    if (!f.components[component]) {
      fixed.push_back(f);
      continue;
    }
    FixedDofs kept = f, freed = f;
    kept.nodes.clear();
    freed.nodes.clear();
    freed.components[component] = false;
    for (int v : f.nodes) (in_place[v] ? freed : kept).nodes.push_back(v);
    for (int v : freed.nodes) released[v] = true;
    if (!kept.nodes.empty()) fixed.push_back(kept);
    if (!freed.nodes.empty() && std::find(freed.components.begin(), freed.components.end(), true) != freed.components.end())
      fixed.push_back(freed);
  }
  for (int v : nodes)
    if (!released[v])
      fail(text, "node " + std::to_string(model.node_ids[v]) + " of " + place_words + " is not fixed along " +
                     component_name(component) +
                     "; a support change makes a fixity flexible (add a spring to ground with spring@... instead)");
  model.fixed = std::move(fixed);
}

// ---------------------------------------------------------------------------- places

struct ResolvedPlace {
  std::vector<int> nodes;
  std::string tag;    ///< for entity names: the node set's name or "node<id>"
  std::string words;  ///< "node set top (12 nodes)", "node 17 (nearest to [..], 0.003 away)"
};

ResolvedPlace resolve(const Model& model, const NodePlace& place, const std::string& text) {
  ResolvedPlace r;
  if (place.kind == NodePlace::Kind::NodeSet) {
    const NodeSet* set = model.find_node_set(place.node_set);
    if (!set) {
      std::vector<std::string> names;
      for (const NodeSet& s : model.node_sets) names.push_back(s.name);
      fail(text, "unknown node set '" + place.node_set + "'; " +
                     (names.empty() ? std::string("the model has no node sets") : "known node sets: " + join(names)) +
                     " (or give a node as #ID or a point as [x,y,z])");
    }
    r.nodes = set->nodes;
    r.tag = set->name;
    r.words = "node set " + set->name;
    if (r.nodes.size() > 1) r.words += " (on each of its " + std::to_string(r.nodes.size()) + " nodes)";
    return r;
  }
  int node = -1;
  if (place.kind == NodePlace::Kind::NodeId) {
    node = model.find_node(place.node_id);
    if (node < 0) {
      const auto [lo, hi] = std::minmax_element(model.node_ids.begin(), model.node_ids.end());
      fail(text, "there is no node with id " + std::to_string(place.node_id) +
                     (model.node_ids.empty() ? std::string("; the model has no nodes")
                                             : "; node ids run from " + std::to_string(*lo) + " to " + std::to_string(*hi)));
    }
  } else {
    if (model.num_nodes() == 0) fail(text, "the model has no nodes");
    double best = std::numeric_limits<double>::infinity();
    for (int v = 0; v < model.num_nodes(); ++v) {
      const double d = (model.coordinates[v] - place.point).norm();
      if (d < best) {
        best = d;
        node = v;
      }
    }
    // Coordinates near the double range make every distance overflow: no node is nearer than another.
    if (node < 0) fail(text, "the point " + place_text(place) + " lies too far from the model for any node to be nearest");
  }
  const std::string id = std::to_string(model.node_ids[node]);
  r.nodes = {node};
  r.tag = "node" + id;
  r.words = "node " + id;
  if (place.kind == NodePlace::Kind::Point) {
    const double d = (model.coordinates[node] - place.point).norm();
    r.words += " (nearest to " + place_text(place) + (d > 0 ? ", " + format_round_trip(d) + " away)" : ")");
  }
  return r;
}

// ---------------------------------------------------------------------------- applying

ModelEffect set_property(Model& model, const ModelChange& change, const std::string& text) {
  const EntityRef e = find_entity_or_part(model, change.entity);
  if (e.kind == EntityKind::None) {
    const std::vector<std::string> names = entity_names(model);
    fail(text, "unknown entity '" + change.entity + "'; " +
                   (names.empty() ? std::string("the model has no blocks, joints, springs or point masses")
                                  : "known blocks, joints, springs and point masses: " + join(names)));
  }
  const std::vector<std::string> allowed = settable_properties(model, e);
  if (index_of(allowed, change.property) < 0)
    fail(text, entity_kind_name(e.kind) + " '" + change.entity + "' has no property '" + change.property +
                   "'; its properties: " + join(allowed));
  check_value(text, change.property, change.value);
  ModelEffect effect;
  effect.name = change.entity + "." + change.property;
  effect.description = describe_property(model, effect.name);
  effect.value = change.value;
  const PropertyId id = model.find_property(effect.name);
  if (id != kNoProperty) {
    effect.nominal_value = model.properties[id].value;
    model.properties[id].value = change.value;
    return effect;
  }
  effect.nominal_value = absent_value(change.property);
  const PropertyId created = model.add_property(effect.name, change.value);
  for (PropertyId* slot : property_slots(model, e, change.property)) *slot = created;
  return effect;
}

/// The component (index in the property names) an addition sets, after the checks every addition
/// passes: a known property, a usable value, rotational components only on nodes with rotations.
int checked_component(const Model& model, const ModelChange& change, const std::vector<ResolvedPlace>& places,
                      const std::string& text) {
  const bool is_mass = change.kind == ModelChange::Kind::AddPointMass;
  const std::vector<std::string> keys = is_mass ? std::vector<std::string>{"mass", "Ixx", "Iyy", "Izz"} : kStiffnessComponentNames;
  const int component = index_of(keys, change.property);
  if (component < 0)
    fail(text, "an added " + std::string(is_mass ? "point mass" : kind_keyword(change.kind)) + " has no property '" +
                   change.property + "'; its properties: " + join(keys));
  check_value(text, change.property, change.value);
  if (change.kind == ModelChange::Kind::FlexibleSupport && !(change.value > 0))
    fail(text, "a flexible support's stiffness must be positive (0 would leave the nodes free), got " +
                   format_round_trip(change.value));
  const bool rotational = is_mass ? component > 0 : component >= 3;
  for (const ResolvedPlace& place : places)
    for (int v : place.nodes)
      if (rotational && !model.has_rotations[v])
        fail(text, change.property + " acts on rotations, but node " + std::to_string(model.node_ids[v]) +
                       " has none (only reference nodes do); place it on a reference node");
  return component;
}

/// The added entity's name and the effect's description in words.
std::pair<std::string, std::string> addition_name(const ModelChange& change, const std::vector<ResolvedPlace>& places,
                                                  int component, const std::string& text) {
  switch (change.kind) {
    case ModelChange::Kind::AddPointMass:
      return {"added_mass_" + places[0].tag, component == 0 ? "added point mass at " + places[0].words
                                                            : "rotary inertia about " + std::string(kAxes[component - 1]) +
                                                                  " of an added point mass at " + places[0].words};
    case ModelChange::Kind::AddSpring:
      return {"added_spring_" + places[0].tag,
              "added " + std::string(component >= 3 ? "rotational spring to ground about " : "spring to ground along ") +
                  kAxes[component % 3] + " at " + places[0].words};
    case ModelChange::Kind::FlexibleSupport:
      return {"support_" + places[0].tag, "flexible support " + std::string(component >= 3 ? "about " : "along ") +
                                              kAxes[component % 3] + " at " + places[0].words +
                                              ": a spring to ground in place of the fixity"};
    default:
      break;
  }
  for (const ResolvedPlace& place : places)
    if (place.nodes.size() != 1)
      fail(text, "a joint connects two nodes, but node set '" + place.tag + "' has " +
                     std::to_string(place.nodes.size()) + "; give #ID or [x,y,z]");
  if (places[0].nodes[0] == places[1].nodes[0]) fail(text, "both ends of the joint are " + places[0].words);
  return {"added_joint_" + places[0].tag + "_" + places[1].tag,
          "added joint between " + places[0].words + " and " + places[1].words + ", " + component_words(component)};
}

/// Adds the entity named `entity` unless an earlier change added it at the same place (then it
/// must be of the same kind); a flexible support also releases the fixity it replaces.
void find_or_create_entity(Model& model, const ModelChange& change, const std::vector<ResolvedPlace>& places,
                           const std::string& entity, int component, const std::string& text) {
  const bool is_support = change.kind == ModelChange::Kind::FlexibleSupport;
  const EntityRef other = find_entity_or_part(model, entity);
  auto clash = [&](EntityKind kind) {
    if (other.kind != EntityKind::None && other.kind != kind)
      fail(text, "the name '" + entity + "' is already used by " + entity_kind_name(other.kind) + " '" + entity +
                     "'; rename that entity in the problem file");
  };
  if (change.kind == ModelChange::Kind::AddPointMass) {
    clash(EntityKind::PointMass);
    if (other.kind == EntityKind::None)
      for (int v : places[0].nodes) {
        PointMass m;
        m.name = places[0].nodes.size() == 1 ? entity : entity + " (node " + std::to_string(model.node_ids[v]) + ")";
        m.node = v;
        model.point_masses.push_back(m);
      }
  } else if (change.kind == ModelChange::Kind::AddSpring || is_support) {
    clash(EntityKind::Spring);
    if (other.kind == EntityKind::None) {
      GroundSpring s;
      s.name = entity;
      s.nodes = places[0].nodes;
      s.replaces_fixity = is_support;
      model.ground_springs.push_back(s);
    } else if (model.ground_springs[other.index].replaces_fixity != is_support) {
      fail(text, "'" + entity + "' is " + (is_support ? "an added spring, not a flexible support" : "a flexible support"));
    }
    if (is_support) release_fixity(model, places[0].nodes, component, places[0].words, text);
  } else {
    clash(EntityKind::Joint);
    if (other.kind == EntityKind::None) {
      Joint j;
      j.name = entity;
      j.node_a = places[0].nodes[0];
      j.node_b = places[1].nodes[0];
      model.joints.push_back(j);
    }
  }
}

ModelEffect add_entity(Model& model, const ModelChange& change, const std::string& text) {
  const size_t expected_places = change.kind == ModelChange::Kind::AddJoint ? 2 : 1;
  if (change.places.size() != expected_places)
    fail(text, std::string(kind_keyword(change.kind)) + " takes " + std::to_string(expected_places) + " place" +
                   (expected_places > 1 ? "s separated by '/'" : "") + ", got " + std::to_string(change.places.size()));
  std::vector<ResolvedPlace> places;
  for (const NodePlace& p : change.places) places.push_back(resolve(model, p, text));
  const int component = checked_component(model, change, places, text);
  ModelEffect effect;
  std::string entity;
  std::tie(entity, effect.description) = addition_name(change, places, component, text);
  effect.name = entity + "." + change.property;
  effect.value = change.value;
  find_or_create_entity(model, change, places, entity, component, text);
  const PropertyId existing = model.find_property(effect.name);
  effect.nominal_value = existing != kNoProperty ? model.properties[existing].value
                         : change.kind == ModelChange::Kind::FlexibleSupport ? std::numeric_limits<double>::infinity()
                                                                             : 0.0;
  const PropertyId id = existing == kNoProperty ? model.add_property(effect.name, change.value) : existing;
  model.properties[id].value = change.value;
  // Point masses on a node set share one property.
  for (PropertyId* slot : property_slots(model, find_entity_or_part(model, entity), change.property)) *slot = id;
  return effect;
}

/// "0p05", "m1p2e-05": a coordinate as a name may carry it.
std::string name_tag(double x) {
  char buffer[32];
  std::snprintf(buffer, sizeof buffer, "%.6g", x == 0 ? 0.0 : x);  // no "-0"
  std::string tag;
  for (const char* c = buffer; *c; ++c) tag += *c == '.' ? std::string("p") : *c == '-' ? std::string("m") : *c == '+' ? std::string() : std::string(1, *c);
  return tag;
}

/// The elements of `block` whose centroid lies in the box [lo, hi] (a relative 1e-9 of slack).
std::vector<int> elements_in_box(const Model& model, const ElementBlock& block, const Vec3& lo, const Vec3& hi) {
  const double slack = 1e-9 * ((hi - lo).norm() + std::max(lo.cwiseAbs().maxCoeff(), hi.cwiseAbs().maxCoeff()));
  const std::vector<Vec3> centroids = element_centroids(model, block);
  std::vector<int> elements;
  for (size_t e = 0; e < centroids.size(); ++e) {
    const Vec3& c = centroids[e];
    if (((c - lo).array() >= -slack).all() && ((hi - c).array() >= -slack).all()) elements.push_back(static_cast<int>(e));
  }
  return elements;
}

/// The block a region change names, checking the places' form.
int region_block(const Model& model, const ModelChange& change, const std::string& text) {
  const auto& p = change.places;
  if (change.kind != ModelChange::Kind::AddRegion || p.size() != 3 || p[0].kind != NodePlace::Kind::NodeSet ||
      p[1].kind != NodePlace::Kind::Point || p[2].kind != NodePlace::Kind::Point)
    fail(text, "a region is written region@BLOCK/[x,y,z]/[x,y,z]: a block and two corners of a box");
  const EntityRef block = find_entity(model, p[0].node_set);
  if (block.kind != EntityKind::Block) {
    std::vector<std::string> names;
    for (const ElementBlock& b : model.blocks) names.push_back(b.name);
    fail(text, "unknown block '" + p[0].node_set + "'; known blocks: " + join(names));
  }
  return block.index;
}

ModelEffect add_region(Model& model, const ModelChange& change, const std::string& text) {
  const auto& p = change.places;
  const EntityRef block{EntityKind::Block, region_block(model, change, text)};
  if (!is_scale_factor(change.property))
    fail(text, "a region has no property '" + change.property + "'; its properties: stiffness_scale, mass_scale");
  check_value(text, change.property, change.value);
  ElementBlock& b = model.blocks[block.index];
  const Vec3 lo = p[1].point.cwiseMin(p[2].point), hi = p[1].point.cwiseMax(p[2].point);
  const Vec3 centre = 0.5 * (lo + hi);
  const std::vector<int> elements = elements_in_box(model, b, lo, hi);
  if (elements.empty())
    fail(text, "no element of block '" + b.name + "' has its centroid in the box " + place_text(p[1]) + " to " +
                   place_text(p[2]));
  // The centre and the element count tell regions apart (two boxes about one centre differ in it).
  const std::string name = b.name + "_region_" + name_tag(centre[0]) + "_" + name_tag(centre[1]) + "_" +
                           name_tag(centre[2]) + "_n" + std::to_string(elements.size());
  const EntityRef existing = find_entity(model, name);
  if (existing.kind != EntityKind::None && existing.kind != EntityKind::Region)
    fail(text, "the name '" + name + "' is already used by " + entity_kind_name(existing.kind) + " '" + name + "'");
  if (existing.kind == EntityKind::Region && model.blocks[existing.index].regions[existing.region].elements != elements)
    fail(text, "region '" + name + "' exists with other elements (another box about the same centre); give this "
                   "box other corners");
  if (existing.kind == EntityKind::None) b.regions.push_back({name, elements});
  const BlockRegion& region = *std::find_if(b.regions.begin(), b.regions.end(), [&](const BlockRegion& r) { return r.name == name; });
  ModelEffect effect;
  effect.name = name + "." + change.property;
  effect.description = property_words(EntityKind::Block, change.property) + " of part of block " + b.name + ": its " +
                       std::to_string(region.elements.size()) + " elements in " + place_text(p[1]) + " to " +
                       place_text(p[2]);
  effect.value = change.value;
  PropertyId id = model.find_property(effect.name);
  effect.nominal_value = id == kNoProperty ? 1.0 : model.properties[id].value;
  if (id == kNoProperty) id = model.add_property(effect.name, change.value);
  model.properties[id].value = change.value;
  for (PropertyId* slot : property_slots(model, find_entity(model, name), change.property)) *slot = id;
  return effect;
}

}  // namespace

std::string format_round_trip(double value) {
  char buffer[64];
  const auto result = std::to_chars(buffer, buffer + sizeof buffer, value);
  return std::string(buffer, result.ptr);
}

std::string property_range_violation(const std::string& property, double value) {
  const std::string key = property.substr(property.rfind('.') + 1);
  const bool positive = key == "E" || key == "K" || key == "G" || is_scale_factor(key);
  if (positive && !(value > 0)) return key + " must be positive, got " + format_round_trip(value);
  if (key == "nu" && !(value > -1 && value < 0.5))
    return "Poisson's ratio must lie in (-1, 0.5), got " + format_round_trip(value);
  if (!positive && key != "nu" && !(value >= 0)) return key + " must not be negative, got " + format_round_trip(value);
  if (std::isfinite(value) && std::abs(value) > kLargestInputMagnitude)
    return key + " = " + format_round_trip(value) + " is larger than any value a problem takes (at most " +
           format_round_trip(kLargestInputMagnitude) + ")";
  return "";
}

ModelChange parse_model_change(const std::string& raw) {
  const std::string text = trim(raw);
  if (text.empty()) fail(raw, std::string("empty; ") + kGrammar);
  ModelChange change;
  const size_t at = text.find('@');
  const size_t equals = text.rfind('=');
  if (equals == std::string::npos) fail(text, std::string("no '=VALUE'; ") + kGrammar);
  change.value = parse_number(text, text.substr(equals + 1), "the value");
  if (at != std::string::npos && at < equals) {
    const std::string kind = trim(text.substr(0, at));
    const std::pair<const char*, ModelChange::Kind> kinds[] = {{"point_mass", ModelChange::Kind::AddPointMass},
                                                               {"spring", ModelChange::Kind::AddSpring},
                                                               {"joint", ModelChange::Kind::AddJoint},
                                                               {"support", ModelChange::Kind::FlexibleSupport},
                                                               {"region", ModelChange::Kind::AddRegion}};
    bool known = false;
    for (const auto& [keyword, k] : kinds)
      if (kind == keyword) {
        change.kind = k;
        known = true;
      }
    if (!known)
      fail(text, "unknown kind '" + kind + "' before '@'; expected point_mass, spring, joint, support or region");
    const size_t colon = text.find(':', at);
    if (colon == std::string::npos || colon > equals)
      fail(text, "no ':PROPERTY' after the place; e.g. " + kind + "@top:" +
                     (kind == "point_mass" ? "mass" : kind == "region" ? "stiffness_scale" : "kz") + "=...");
    const std::string places = text.substr(at + 1, colon - at - 1);
    size_t start = 0;
    for (size_t slash; (slash = places.find('/', start)) != std::string::npos; start = slash + 1)
      change.places.push_back(parse_place(text, places.substr(start, slash - start)));
    change.places.push_back(parse_place(text, places.substr(start)));
    change.property = trim(text.substr(colon + 1, equals - colon - 1));
    if (!is_plain_name(change.property)) fail(text, "'" + change.property + "' is not a property name");
    return change;
  }
  const std::string name = trim(text.substr(0, equals));
  const size_t dot = name.rfind('.');
  if (dot == std::string::npos || dot == 0 || dot + 1 == name.size())
    fail(text, "'" + name + "' is not of the form ENTITY.PROPERTY; " + kGrammar);
  change.entity = trim(name.substr(0, dot));
  change.property = trim(name.substr(dot + 1));
  if (!is_plain_name(change.entity) || !is_plain_name(change.property))
    fail(text, "'" + name + "' is not of the form ENTITY.PROPERTY; " + kGrammar);
  return change;
}

std::string to_string(const ModelChange& change) {
  const std::string value = "=" + format_round_trip(change.value);
  if (change.kind == ModelChange::Kind::SetProperty) return change.entity + "." + change.property + value;
  std::string places;
  for (const NodePlace& p : change.places) places += (places.empty() ? "" : "/") + place_text(p);
  return std::string(kind_keyword(change.kind)) + "@" + places + ":" + change.property + value;
}

namespace {

/// `change` made on `changed`, which may be left half changed when it throws.
ModelEffect make_change(Model& changed, const ModelChange& change, const std::string& text) {
  return change.kind == ModelChange::Kind::SetProperty ? set_property(changed, change, text)
         : change.kind == ModelChange::Kind::AddRegion ? add_region(changed, change, text)
                                                       : add_entity(changed, change, text);
}

}  // namespace

ModelEffect apply_model_change(Model* model, const ModelChange& change) {
  const std::string text = to_string(change);
  Model changed = *model;
  const ModelEffect effect = make_change(changed, change, text);
  try {
    changed.validate();
  } catch (const std::invalid_argument& e) {
    fail(text, e.what());
  }
  *model = std::move(changed);
  return effect;
}

std::vector<ModelEffect> apply_model_changes(Model* model, const std::vector<ModelChange>& changes) {
  Model changed = *model;
  std::vector<ModelEffect> effects;
  effects.reserve(changes.size());
  for (const ModelChange& change : changes) effects.push_back(make_change(changed, change, to_string(change)));
  try {
    changed.validate();
  } catch (const std::invalid_argument&) {
    // Which change made the model invalid: one at a time, as apply_model_change() says it.
    Model one_by_one = *model;
    for (const ModelChange& change : changes) apply_model_change(&one_by_one, change);
    throw;
  }
  *model = std::move(changed);
  return effects;
}

std::pair<int, std::vector<int>> region_elements(const Model& model, const ModelChange& change) {
  const int b = region_block(model, change, to_string(change));
  const Vec3 &a = change.places[1].point, &c = change.places[2].point;
  return {b, elements_in_box(model, model.blocks[b], a.cwiseMin(c), a.cwiseMax(c))};
}

ModelEffect describe_model_change(const Model& model, const ModelChange& change) {
  Model copy = model;
  return apply_model_change(&copy, change);
}

std::string describe_property(const Model& model, const std::string& property_name) {
  const size_t dot = property_name.rfind('.');
  if (dot == std::string::npos) return property_name;
  const std::string entity = property_name.substr(0, dot), property = property_name.substr(dot + 1);
  const EntityRef e = find_entity_or_part(model, entity);
  if (e.kind == EntityKind::None) return property_name;
  return property_words(e.kind, property) + " of " +
         (is_flexible_support(model, e) ? std::string("flexible support") : entity_kind_name(e.kind)) + " " + entity;
}

double absent_property_value(const Model& model, const std::string& property_name) {
  const size_t dot = property_name.rfind('.');
  const std::string property = property_name.substr(dot == std::string::npos ? 0 : dot + 1);
  if (dot != std::string::npos && is_flexible_support(model, find_entity(model, property_name.substr(0, dot))))
    return std::numeric_limits<double>::infinity();
  return absent_value(property);
}

std::vector<ModelEffect> property_differences(const Model& nominal, const Model& changed,
                                              const std::vector<std::string>& excluded) {
  std::vector<ModelEffect> effects;
  auto consider = [&](const Model& described, const std::string& name, double nominal_value, double value) {
    if (index_of(excluded, name) >= 0 || nominal_value == value) return;
    effects.push_back({name, describe_property(described, name), value, nominal_value});
  };
  for (const Property& p : changed.properties) {
    const PropertyId id = nominal.find_property(p.name);
    consider(changed, p.name, id == kNoProperty ? absent_property_value(changed, p.name) : nominal.properties[id].value,
             p.value);
  }
  for (const Property& p : nominal.properties)
    if (changed.find_property(p.name) == kNoProperty)
      consider(nominal, p.name, p.value, absent_property_value(nominal, p.name));
  return effects;
}

}  // namespace modalcal
