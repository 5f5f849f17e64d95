#pragma once
/// \file block_geometry.hpp
/// Volumes of a model's element blocks and which blocks each node belongs to: the magnitudes that
/// candidate effects and generated cases are scaled by.

#include <vector>

#include "modalcal/export.hpp"
#include "modalcal/model.hpp"

namespace modalcal {

struct MODALCAL_EXPORT BlockGeometry {
  std::vector<double> volume;                     ///< per block
  std::vector<std::vector<int>> blocks_of_node;   ///< per node: the blocks using it, ascending
  /// Mean element edge length of block b: cbrt(volume / elements).
  double element_size(const Model& model, int b) const;
};

/// One pass over every element. The volume of an element is its consistent mass matrix at unit
/// density summed over all entries, divided by 3 (sum of N^T N over the three directions).
MODALCAL_EXPORT BlockGeometry block_geometry(const Model& model);

/// The centroid (mean of its nodes) of every element of `block`, in element order: what regions
/// and generated parts of a block are chosen by.
MODALCAL_EXPORT std::vector<Vec3> element_centroids(const Model& model, const ElementBlock& block);

}  // namespace modalcal
