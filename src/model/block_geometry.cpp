#include "modalcal/block_geometry.hpp"

#include <algorithm>
#include <cmath>

namespace modalcal {

double BlockGeometry::element_size(const Model& model, int b) const {
  return std::cbrt(volume[b] / std::max(1, model.blocks[b].num_elements()));
}

BlockGeometry block_geometry(const Model& model) {
  BlockGeometry g;
  g.blocks_of_node.resize(model.num_nodes());
  for (size_t b = 0; b < model.blocks.size(); ++b) {
    const ElementBlock& block = model.blocks[b];
    const int npe = nodes_per_element(block.type);
    double volume = 0;
    Eigen::Matrix3Xd coords(3, npe);
    for (int e = 0; e < block.num_elements(); ++e) {
      for (int k = 0; k < npe; ++k) {
        const int v = block.connectivity[e * npe + k];
        coords.col(k) = model.coordinates[v];
        std::vector<int>& of = g.blocks_of_node[v];
        if (of.empty() || of.back() != static_cast<int>(b)) of.push_back(static_cast<int>(b));
      }
      volume += solid_element_matrices(block.type, coords).mass.sum() / 3;
    }
    g.volume.push_back(volume);
  }
  return g;
}

std::vector<Vec3> element_centroids(const Model& model, const ElementBlock& block) {
  const int npe = nodes_per_element(block.type);
  std::vector<Vec3> centroids(block.num_elements(), Vec3::Zero());
  for (int e = 0; e < block.num_elements(); ++e) {
    for (int k = 0; k < npe; ++k) centroids[e] += model.coordinates[block.connectivity[e * npe + k]];
    centroids[e] /= npe;
  }
  return centroids;
}

}  // namespace modalcal
