#include "modalcal/model.hpp"

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

void Model::validate() const {
  const int n = num_nodes();
  if (static_cast<int>(node_ids.size()) != n || static_cast<int>(has_rotations.size()) != n)
    fail("model: node arrays have inconsistent sizes");
  for (int i = 0; i < n; ++i)
    if (!coordinates[i].allFinite())
      fail("node " + std::to_string(node_ids[i]) + ": coordinates are not finite");
  auto check_node = [&](int node, const std::string& where) {
    if (node < 0 || node >= n) fail(where + ": refers to a node that does not exist");
  };
  auto check_property = [&](PropertyId id, const std::string& where) {
    if (id != kNoProperty && (id < 0 || id >= static_cast<int>(properties.size())))
      fail(where + ": refers to a property that does not exist");
    if (id != kNoProperty && !std::isfinite(properties[id].value))
      fail("property '" + properties[id].name + "' is not a finite number");
  };
  for (const Property& p : properties)
    if (!std::isfinite(p.value)) fail("property '" + p.name + "' is not a finite number");

  std::set<std::string> names;
  auto unique_name = [&](const std::string& name, const std::string& kind) {
    if (name.empty()) fail(kind + " without a name");
    if (!names.insert(name).second)
      fail(kind + " '" + name + "': the name is used by another block, joint, spring or mass");
  };
  for (const ElementBlock& b : blocks) {
    const std::string where = "block '" + b.name + "'";
    unique_name(b.name, "block");
    const int npe = nodes_per_element(b.type);
    if (b.connectivity.size() % npe != 0) fail(where + ": connectivity length is not a multiple of " + std::to_string(npe));
    for (int v : b.connectivity) check_node(v, where);
    if (b.modulus_a == kNoProperty || b.modulus_b == kNoProperty || b.density == kNoProperty)
      fail(where + ": needs two elastic constants and a density");
    for (PropertyId id : {b.modulus_a, b.modulus_b, b.density, b.stiffness_scale, b.mass_scale})
      check_property(id, where);
    if (property_value(b.density) < 0) fail(where + ": density is negative");
    for (const BlockRegion& r : b.regions) {
      unique_name(r.name, "region");
      if (r.elements.empty()) fail("region '" + r.name + "' of " + where + " has no elements");
      for (size_t k = 0; k < r.elements.size(); ++k)
        if (r.elements[k] < 0 || r.elements[k] >= b.num_elements() || (k > 0 && r.elements[k] <= r.elements[k - 1]))
          fail("region '" + r.name + "' of " + where + ": element indices must be sorted, unique and below " +
               std::to_string(b.num_elements()));
      check_property(r.stiffness_scale, "region '" + r.name + "'");
      check_property(r.mass_scale, "region '" + r.name + "'");
    }
    // As the problem loader requires of the file's values; also for those set later (--set, changes).
    auto positive_modulus = [&](PropertyId id, const char* what) {
      if (!(property_value(id) > 0)) {
        char value[32];
        std::snprintf(value, sizeof value, "%g", property_value(id));
        fail(where + ": " + what + " must be positive, got " + value);
      }
    };
    if (b.form == ElasticForm::YoungPoisson) {
      positive_modulus(b.modulus_a, "Young's modulus E");
    } else {
      positive_modulus(b.modulus_a, "bulk modulus K");
      positive_modulus(b.modulus_b, "shear modulus G");
    }
    if (b.form == ElasticForm::YoungPoisson) {
      const double nu = property_value(b.modulus_b);
      if (!(nu > -1.0 && nu < 0.5))
        fail(where + ": Poisson's ratio " + std::to_string(nu) + " is outside (-1, 0.5)");
    }
  }
  for (const Joint& j : joints) {
    const std::string where = "joint '" + j.name + "'";
    unique_name(j.name, "joint");
    check_node(j.node_a, where);
    check_node(j.node_b, where);
    if (j.node_a == j.node_b) fail(where + ": both ends are the same node");
    Mat3 f = j.frame;
    if (!((f * f.transpose() - Mat3::Identity()).norm() < 1e-8 && f.determinant() > 0))
      fail(where + ": frame is not orthonormal and right-handed");
    for (int c = 0; c < 6; ++c) {
      check_property(j.stiffness[c], where);
      if (c >= 3 && j.stiffness[c] != kNoProperty &&
          !(has_rotations[j.node_a] && has_rotations[j.node_b]))
        fail(where + ": rotational stiffness " + component_name(c) +
             " needs both nodes to carry rotations (use reference nodes with rigid couplings)");
    }
  }
  for (const GroundSpring& s : ground_springs) {
    const std::string where = "spring '" + s.name + "'";
    unique_name(s.name, "spring");
    if (s.nodes.empty()) fail(where + ": has no nodes");
    for (int v : s.nodes) {
      check_node(v, where);
      for (int c = 3; c < 6; ++c)
        if (s.stiffness[c] != kNoProperty && !has_rotations[v])
          fail(where + ": rotational stiffness on node " + std::to_string(node_ids[v]) +
               ", which has no rotations");
    }
    for (PropertyId id : s.stiffness) check_property(id, where);
  }
  for (const PointMass& m : point_masses) {
    const std::string where = "point mass '" + m.name + "'";
    unique_name(m.name, "point mass");
    check_node(m.node, where);
    check_property(m.mass, where);
    if (property_value(m.mass) < 0) fail(where + ": mass is negative");
    for (PropertyId id : m.inertia) {
      check_property(id, where);
      if (id != kNoProperty && !has_rotations[m.node])
        fail(where + ": rotary inertia needs a node with rotations (a reference node)");
    }
  }
  std::vector<int> coupled_by(n, -1);
  for (size_t k = 0; k < rigid_couplings.size(); ++k) {
    const RigidCoupling& r = rigid_couplings[k];
    const std::string where = "rigid coupling '" + r.name + "'";
    check_node(r.reference, where);
    if (!has_rotations[r.reference]) fail(where + ": the reference node must carry rotations");
    if (r.nodes.empty()) fail(where + ": couples no nodes (is the node set empty?)");
    for (int v : r.nodes) {
      check_node(v, where);
      if (v == r.reference) fail(where + ": couples its own reference node");
      if (coupled_by[v] >= 0)
        fail(where + ": node " + std::to_string(node_ids[v]) + " is already coupled by '" +
             rigid_couplings[coupled_by[v]].name + "'");
      coupled_by[v] = static_cast<int>(k);
    }
  }
  for (const RigidCoupling& r : rigid_couplings)
    if (coupled_by[r.reference] >= 0)
      fail("rigid coupling '" + r.name + "': its reference node is itself coupled (chains are not supported)");
  for (const FixedDofs& f : fixed) {
    for (int v : f.nodes) {
      check_node(v, "fixed '" + f.name + "'");
      if (coupled_by[v] >= 0)
        fail("fixed '" + f.name + "': node " + std::to_string(node_ids[v]) +
             " is rigidly coupled; fix the reference node instead");
    }
  }
  for (const auto& [family, direction] : mode_families)
    if (direction < 0 || direction > 2)
      fail("mode family '" + family + "': direction must be x, y or z");
}

}  // namespace modalcal
