#pragma once
// Internal: from the residual energy of each free DOF to nodes, elements and the model's regions
// (blocks, joints, springs, point masses, node sets), see localization.hpp for the definitions.

#include <vector>

#include "modalcal/assembly.hpp"
#include "modalcal/localization.hpp"

namespace modalcal::detail {

/// Sum of `dof_energy` (one entry per free DOF) over the free DOFs of each node.
Vector node_energy(const DofMap& dofs, int num_nodes, const Vector& dof_energy);

/// The mesh view of node energies: the energy of a rigid coupling's reference node that belongs
/// to no element is spread equally over the nodes it couples.
Vector mesh_node_energy(const Model& model, const Vector& node_energy);

/// Energy per element (blocks in order): the mesh-view energy of its nodes, each divided by the
/// number of elements sharing the node.
Vector element_energy(const Model& model, const Vector& mesh_energy);

/// Every region with its energy and its share of `total`, largest share first.
std::vector<RegionShare> rank_regions(const Model& model, const Vector& node_energy, const Vector& mesh_energy,
                                      const Vector& element_energy, double total);

}  // namespace modalcal::detail
