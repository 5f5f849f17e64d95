#include "modalcal/model.hpp"

#include "modalcal/model_change.hpp"
#include "support/text_util.hpp"

#include <Eigen/LU>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <set>
#include <sstream>
#include <stdexcept>

namespace modalcal {

namespace {
const char* kComponentNames[6] = {"x", "y", "z", "rx", "ry", "rz"};

[[noreturn]] void fail(const std::string& message) { throw std::invalid_argument(message); }
}  // namespace

double bounding_box_diagonal(const Model& model) {
  if (model.coordinates.empty()) return 0;
  Vec3 low = model.coordinates.front(), high = low;
  for (const Vec3& x : model.coordinates) {
    low = low.cwiseMin(x);
    high = high.cwiseMax(x);
  }
  return (high - low).norm();
}

std::string component_name(int component) {
  if (component < 0 || component > 5) return "?";
  return kComponentNames[component];
}

int component_from_name(const std::string& name) {
  for (int c = 0; c < 6; ++c)
    if (name == kComponentNames[c]) return c;
  return -1;
}

int Model::add_node(long id, const Vec3& x, bool rotations) {
  coordinates.push_back(x);
  node_ids.push_back(id);
  has_rotations.push_back(rotations);
  return num_nodes() - 1;
}

PropertyId Model::add_property(const std::string& name, double value) {
  if (find_property(name) != kNoProperty) fail("property '" + name + "' is defined twice");
  properties.push_back({name, value});
  return static_cast<PropertyId>(properties.size()) - 1;
}

PropertyId Model::find_property(const std::string& name) const {
  for (size_t i = 0; i < properties.size(); ++i)
    if (properties[i].name == name) return static_cast<PropertyId>(i);
  return kNoProperty;
}

const NodeSet* Model::find_node_set(const std::string& name) const {
  for (const NodeSet& s : node_sets)
    if (s.name == name) return &s;
  return nullptr;
}

int Model::find_node(long id) const {
  for (int i = 0; i < num_nodes(); ++i)
    if (node_ids[i] == id) return i;
  return -1;
}

int Model::num_elements() const {
  int n = 0;
  for (const ElementBlock& b : blocks) n += b.num_elements();
  return n;
}

namespace {

/// Model::validate's checks, one method per kind of entity; every failure throws
/// std::invalid_argument naming the entity.
class ModelCheck {
 public:
  explicit ModelCheck(const Model& model) : m_(model), n_(model.num_nodes()) {}
  void nodes_and_properties() const;
  void blocks();
  void joints();
  void springs_and_masses();
  void couplings_and_fixed() const;

 private:
  void node(int v, const std::string& where) const {
    if (v < 0 || v >= n_) fail(where + ": refers to a node that does not exist");
  }
  void property(PropertyId id, const std::string& where) const {
    if (id != kNoProperty && (id < 0 || id >= static_cast<int>(m_.properties.size())))
      fail(where + ": refers to a property that does not exist");
    if (id != kNoProperty && !std::isfinite(m_.properties[id].value))
      fail("property '" + m_.properties[id].name + "' is not a finite number");
  }
  void unique_name(const std::string& name, const std::string& kind) {
    if (name.empty()) fail(kind + " without a name");
    if (!names_.insert(name).second)
      fail(kind + " '" + name + "': the name is used by another block, joint, spring or mass");
  }

  const Model& m_;
  const int n_;
  std::set<std::string> names_;
};

void ModelCheck::nodes_and_properties() const {
  if (static_cast<int>(m_.node_ids.size()) != n_ || static_cast<int>(m_.has_rotations.size()) != n_)
    fail("model: node arrays have inconsistent sizes");
  for (int i = 0; i < n_; ++i)
    if (!m_.coordinates[i].allFinite()) fail("node " + std::to_string(m_.node_ids[i]) + ": coordinates are not finite");
  // The ranges the problem loader, --set and model changes check too (property_range_violation),
  // here also for values set later: parameters, refits.
  for (const Property& p : m_.properties) {
    if (!std::isfinite(p.value)) fail("property '" + p.name + "' is not a finite number");
    if (const std::string why = property_range_violation(p.name, p.value); !why.empty())
      fail("property '" + p.name + "': " + why);
  }
}

void ModelCheck::blocks() {
  for (const ElementBlock& b : m_.blocks) {
    const std::string where = "block '" + b.name + "'";
    unique_name(b.name, "block");
    const int npe = nodes_per_element(b.type);
    if (b.connectivity.size() % npe != 0) fail(where + ": connectivity length is not a multiple of " + std::to_string(npe));
    for (int v : b.connectivity) node(v, where);
    if (b.modulus_a == kNoProperty || b.modulus_b == kNoProperty || b.density == kNoProperty)
      fail(where + ": needs two elastic constants and a density");
    for (PropertyId id : {b.modulus_a, b.modulus_b, b.density, b.stiffness_scale, b.mass_scale}) property(id, where);
    for (const BlockRegion& r : b.regions) {
      unique_name(r.name, "region");
      if (r.elements.empty()) fail("region '" + r.name + "' of " + where + " has no elements");
      for (size_t k = 0; k < r.elements.size(); ++k)
        if (r.elements[k] < 0 || r.elements[k] >= b.num_elements() || (k > 0 && r.elements[k] <= r.elements[k - 1]))
          fail("region '" + r.name + "' of " + where + ": element indices must be sorted, unique and below " +
               std::to_string(b.num_elements()));
      property(r.stiffness_scale, "region '" + r.name + "'");
      property(r.mass_scale, "region '" + r.name + "'");
    }
  }
}

void ModelCheck::joints() {
  for (const Joint& j : m_.joints) {
    const std::string where = "joint '" + j.name + "'";
    unique_name(j.name, "joint");
    node(j.node_a, where);
    node(j.node_b, where);
    if (j.node_a == j.node_b) fail(where + ": both ends are the same node");
    Mat3 f = j.frame;
    if (!((f * f.transpose() - Mat3::Identity()).norm() < 1e-8 && f.determinant() > 0))
      fail(where + ": frame is not orthonormal and right-handed");
    for (int c = 0; c < 6; ++c) {
      property(j.stiffness[c], where);
      if (c >= 3 && j.stiffness[c] != kNoProperty && !(m_.has_rotations[j.node_a] && m_.has_rotations[j.node_b]))
        fail(where + ": rotational stiffness " + component_name(c) +
             " needs both nodes to carry rotations (use reference nodes with rigid couplings)");
    }
  }
}

void ModelCheck::springs_and_masses() {
  for (const GroundSpring& s : m_.ground_springs) {
    const std::string where = "spring '" + s.name + "'";
    unique_name(s.name, "spring");
    if (s.nodes.empty()) fail(where + ": has no nodes");
    for (int v : s.nodes) {
      node(v, where);
      for (int c = 3; c < 6; ++c)
        if (s.stiffness[c] != kNoProperty && !m_.has_rotations[v])
          fail(where + ": rotational stiffness on node " + std::to_string(m_.node_ids[v]) + ", which has no rotations");
    }
    for (PropertyId id : s.stiffness) property(id, where);
  }
  for (const PointMass& pm : m_.point_masses) {
    const std::string where = "point mass '" + pm.name + "'";
    unique_name(pm.name, "point mass");
    node(pm.node, where);
    property(pm.mass, where);
    if (m_.property_value(pm.mass) < 0) fail(where + ": mass is negative");
    for (PropertyId id : pm.inertia) {
      property(id, where);
      if (id != kNoProperty && !m_.has_rotations[pm.node])
        fail(where + ": rotary inertia needs a node with rotations (a reference node)");
    }
  }
}

// Rigid couplings (each node coupled once, no chains), fixed DOFs (not on coupled nodes) and
// the mode families' directions.
void ModelCheck::couplings_and_fixed() const {
  std::vector<int> coupled_by(n_, -1);
  for (size_t k = 0; k < m_.rigid_couplings.size(); ++k) {
    const RigidCoupling& r = m_.rigid_couplings[k];
    const std::string where = "rigid coupling '" + r.name + "'";
    node(r.reference, where);
    if (!m_.has_rotations[r.reference]) fail(where + ": the reference node must carry rotations");
    if (r.nodes.empty()) fail(where + ": couples no nodes (is the node set empty?)");
    for (int v : r.nodes) {
      node(v, where);
      if (v == r.reference) fail(where + ": couples its own reference node");
      if (coupled_by[v] >= 0)
        fail(where + ": node " + std::to_string(m_.node_ids[v]) + " is already coupled by '" +
             m_.rigid_couplings[coupled_by[v]].name + "'");
      coupled_by[v] = static_cast<int>(k);
    }
  }
  for (const RigidCoupling& r : m_.rigid_couplings)
    if (coupled_by[r.reference] >= 0)
      fail("rigid coupling '" + r.name + "': its reference node is itself coupled (chains are not supported)");
  for (const FixedDofs& f : m_.fixed)
    for (int v : f.nodes) {
      node(v, "fixed '" + f.name + "'");
      if (coupled_by[v] >= 0)
        fail("fixed '" + f.name + "': node " + std::to_string(m_.node_ids[v]) +
             " is rigidly coupled; fix the reference node instead");
    }
  for (const auto& [family, direction] : m_.mode_families)
    if (direction < 0 || direction > 2) fail("mode family '" + family + "': direction must be x, y or z");
}

}  // namespace

void Model::validate() const {
  ModelCheck check(*this);
  check.nodes_and_properties();
  check.blocks();
  check.joints();
  check.springs_and_masses();
  check.couplings_and_fixed();
}

}  // namespace modalcal
