#include "modalcal/mode_description.hpp"

namespace modalcal {

namespace {

// Part (element block) of each free DOF: a node belongs to the first block using it; a
// reference node to the part of its first coupled node (its DOFs carry that node's motion);
// anything else forms no part (-1).
std::vector<int> part_of_free_dofs(const ParametricSystem& system) {
  const Model& model = system.model();
  std::vector<int> node_part(model.num_nodes(), -1);
  for (size_t b = 0; b < model.blocks.size(); ++b)
    for (int v : model.blocks[b].connectivity)
      if (node_part[v] < 0) node_part[v] = static_cast<int>(b);
  for (const RigidCoupling& r : model.rigid_couplings)
    if (node_part[r.reference] < 0 && !r.nodes.empty()) node_part[r.reference] = node_part[r.nodes.front()];
  std::vector<int> part(system.num_dofs());
  for (int f = 0; f < system.num_dofs(); ++f) part[f] = node_part[system.dof_map().free_owner(f).first];
  return part;
}

}  // namespace

std::vector<ModeDescription> describe_modes(const ParametricSystem& system, const Vector& p,
                                            const SparseMatrix& M, const ModalResult& result) {
  const DofMap& dofs = system.dof_map();
  const int n = dofs.num_free();
  const Matrix inertia = system.rigid_body_inertia(p);
  const double total_mass = system.total_mass(p);
  const std::vector<int> part = part_of_free_dofs(system);
  const int num_parts = static_cast<int>(system.model().blocks.size());
  // Mass of each part along each direction: the rigid-translation inertia on the part's DOFs.
  std::array<Vector, 3> part_mass;
  for (int c = 0; c < 3; ++c) {
    part_mass[c] = Vector::Zero(num_parts);
    for (int f = 0; f < n; ++f)
      if (part[f] >= 0 && dofs.free_owner(f).second == c) part_mass[c][part[f]] += inertia(f, c);
  }
  std::vector<ModeDescription> out;
  for (int k = 0; k < result.eigenvalues.size(); ++k) {
    ModeDescription d;
    d.index = k + 1;
    d.frequency_hz = frequency_hz(result.eigenvalues[k]);
    const Vector u = result.modes.col(k);
    const Vector Mu = M * u;
    const double energy = u.dot(Mu);
    std::array<double, 6> share{};
    for (int f = 0; f < n; ++f) share[dofs.free_owner(f).second] += u[f] * Mu[f] / energy;
    d.rotational_fraction = share[3] + share[4] + share[5];
    std::array<Vector, 3> momentum;
    for (int c = 0; c < 3; ++c) momentum[c] = Vector::Zero(num_parts);
    for (int f = 0; f < n; ++f) {
      const int c = dofs.free_owner(f).second;
      if (part[f] >= 0 && c < 3) momentum[c][part[f]] += Mu[f];
    }
    for (int c = 0; c < 3; ++c) {
      for (int b = 0; b < num_parts; ++b)
        if (part_mass[c][b] > 0) d.part_translation_fraction[c] += momentum[c][b] * momentum[c][b] / part_mass[c][b] / energy;
      d.energy_fraction[c] = share[c];
      const double gamma = inertia.col(c).dot(u);
      d.effective_mass_fraction[c] = total_mass > 0 ? gamma * gamma / total_mass : 0.0;
      if (share[c] > share[d.dominant_direction]) d.dominant_direction = c;
    }
    for (const auto& [family, direction] : system.model().mode_families)
      if (d.part_translation_fraction[direction] >= 0.5) d.label = family;
    out.push_back(d);
  }
  return out;
}

int find_family_mode(const std::vector<ModeDescription>& modes, const std::string& family, int k) {
  int seen = 0;
  for (const ModeDescription& d : modes)
    if (d.label == family && ++seen == k) return d.index;
  return 0;
}

}  // namespace modalcal
