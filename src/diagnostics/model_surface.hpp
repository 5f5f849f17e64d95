#pragma once
// Where on a model a candidate effect or a further sensor can be: the nodes of its surfaces and
// of the interfaces between its blocks, and which DOFs its supports hold.

#include <array>
#include <vector>

#include "modalcal/model.hpp"

namespace modalcal::detail {

/// fixed[v][c]: DOF c of node v is fixed.
std::vector<std::array<bool, 6>> fixed_dofs(const Model& model);

/// The free nodes on the model's surfaces (element sides no other element shares) and on the
/// interfaces between blocks (nodes of two or more blocks), in index order.
std::vector<int> surface_and_interface_nodes(const Model& model, const std::vector<std::array<bool, 6>>& fixed);

}  // namespace modalcal::detail
