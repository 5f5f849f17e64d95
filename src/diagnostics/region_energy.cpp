#include "diagnostics/region_energy.hpp"

#include <algorithm>
#include <map>

namespace modalcal::detail {

namespace {

std::vector<int> elements_per_node(const Model& model) {
  std::vector<int> count(model.num_nodes(), 0);
  for (const ElementBlock& block : model.blocks)
    for (int node : block.connectivity) ++count[node];
  return count;
}

}  // namespace

Vector node_energy(const DofMap& dofs, int num_nodes, const Vector& dof_energy) {
  Vector energy = Vector::Zero(num_nodes);
  for (int d = 0; d < dofs.num_free(); ++d) energy[dofs.free_owner(d).first] += dof_energy[d];
  return energy;
}

Vector mesh_node_energy(const Model& model, const Vector& node_energy) {
  const std::vector<int> count = elements_per_node(model);
  std::map<int, std::vector<int>> coupled;  // reference node -> the nodes it couples
  for (const RigidCoupling& coupling : model.rigid_couplings)
    if (count[coupling.reference] == 0)
      coupled[coupling.reference].insert(coupled[coupling.reference].end(), coupling.nodes.begin(),
                                         coupling.nodes.end());
  Vector mesh = node_energy;
  for (const auto& [reference, nodes] : coupled) {
    if (nodes.empty()) continue;
    const double each = mesh[reference] / static_cast<double>(nodes.size());
    for (int node : nodes) mesh[node] += each;
    mesh[reference] = 0;
  }
  return mesh;
}

Vector element_energy(const Model& model, const Vector& mesh_energy) {
  const std::vector<int> count = elements_per_node(model);
  Vector energy = Vector::Zero(model.num_elements());
  int element = 0;
  for (const ElementBlock& block : model.blocks) {
    const int nodes = nodes_per_element(block.type);
    for (int e = 0; e < block.num_elements(); ++e, ++element)
      for (int a = 0; a < nodes; ++a) {
        const int node = block.connectivity[e * nodes + a];
        energy[element] += mesh_energy[node] / count[node];
      }
  }
  return energy;
}

std::vector<RegionShare> rank_regions(const Model& model, const Vector& node_energy, const Vector& mesh_energy,
                                      const Vector& element_energy, double total) {
  std::vector<RegionShare> regions;
  auto add = [&](const std::string& name, const std::string& kind, double energy) {
    regions.push_back({name, kind, energy, total > 0 ? energy / total : 0.0});
  };
  auto sum = [](const Vector& energy, const std::vector<int>& nodes) {
    double s = 0;
    for (int node : nodes) s += energy[node];
    return s;
  };
  int first = 0;
  for (const ElementBlock& block : model.blocks) {
    add(block.name, "block", element_energy.segment(first, block.num_elements()).sum());
    first += block.num_elements();
  }
  // Discrete entities own the DOFs of their nodes (reference nodes included): raw node energies.
  for (const Joint& joint : model.joints) add(joint.name, "joint", sum(node_energy, {joint.node_a, joint.node_b}));
  for (const GroundSpring& spring : model.ground_springs) add(spring.name, "spring", sum(node_energy, spring.nodes));
  for (const PointMass& mass : model.point_masses) add(mass.name, "point mass", node_energy[mass.node]);
  for (const NodeSet& set : model.node_sets) add(set.name, "node set", sum(mesh_energy, set.nodes));
  std::stable_sort(regions.begin(), regions.end(),
                   [](const RegionShare& a, const RegionShare& b) { return a.share > b.share; });
  return regions;
}

}  // namespace modalcal::detail
