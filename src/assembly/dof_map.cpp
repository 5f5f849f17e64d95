#include <stdexcept>

#include "modalcal/assembly.hpp"

namespace modalcal {

DofMap::DofMap(const Model& model) {
  const int n = model.num_nodes();
  node_offset_.resize(n + 1);
  for (int v = 0; v < n; ++v) {
    node_offset_[v + 1] = node_offset_[v] + (model.has_rotations[v] ? 6 : 3);
    for (int c = 0; c < (model.has_rotations[v] ? 6 : 3); ++c) full_owner_.emplace_back(v, c);
  }
  const int nfull = node_offset_[n];
  std::vector<bool> fixed(nfull, false);
  for (const FixedDofs& f : model.fixed)
    for (int v : f.nodes)
      for (int c = 0; c < 6; ++c)
        if (f.components[c] && full_index(v, c) >= 0) fixed[full_index(v, c)] = true;
  std::vector<int> reference_of(n, -1);
  for (const RigidCoupling& r : model.rigid_couplings)
    for (int v : r.nodes) reference_of[v] = r.reference;

  // Independent DOFs are numbered node by node, so the DOFs of one node are consecutive:
  // assembly relies on this to place a node pair's block with a single search.
  full_to_free_.assign(nfull, -1);
  for (int f = 0; f < nfull; ++f) {
    const int v = full_owner_[f].first;
    if (!fixed[f] && reference_of[v] < 0) {
      full_to_free_[f] = static_cast<int>(free_owner_.size());
      free_owner_.push_back(full_owner_[f]);
    }
  }

  // u_s = u_r + theta_r x (x_s - x_r) for a coupled node s; its rotations (if any) follow theta_r.
  std::vector<Eigen::Triplet<double, int>> entries;
  auto add = [&](int row, int ref_node, int comp, double w) {
    const int col = full_to_free_[full_index(ref_node, comp)];
    if (col >= 0 && w != 0.0) entries.emplace_back(row, col, w);
  };
  for (int f = 0; f < nfull; ++f) {
    const auto [v, c] = full_owner_[f];
    if (full_to_free_[f] >= 0) {
      entries.emplace_back(f, full_to_free_[f], 1.0);
    } else if (reference_of[v] >= 0) {
      const int r = reference_of[v];
      const Vec3 d = model.coordinates[v] - model.coordinates[r];
      if (c >= 3) {
        add(f, r, c, 1.0);
      } else if (c == 0) {
        add(f, r, 0, 1.0); add(f, r, 4, d.z()); add(f, r, 5, -d.y());
      } else if (c == 1) {
        add(f, r, 1, 1.0); add(f, r, 5, d.x()); add(f, r, 3, -d.z());
      } else {
        add(f, r, 2, 1.0); add(f, r, 3, d.y()); add(f, r, 4, -d.x());
      }
    }
  }
  transformation_.resize(nfull, num_free());
  transformation_.setFromTriplets(entries.begin(), entries.end());
  rows_ = transformation_;
}

int DofMap::full_index(int node, int component) const {
  const int first = node_offset_[node];
  return component < node_offset_[node + 1] - first ? first + component : -1;
}

int DofMap::free_index(int node, int component) const {
  const int f = full_index(node, component);
  return f < 0 ? -1 : full_to_free_[f];
}

double DofMap::value(const Vector& u, int node, int component) const {
  const int f = full_index(node, component);
  if (f < 0) return 0.0;
  double s = 0;
  for (RowSparseMatrix::InnerIterator it(rows_, f); it; ++it) s += it.value() * u[it.col()];
  return s;
}

bool DofMap::operator==(const DofMap& other) const {
  if (node_offset_ != other.node_offset_ || full_owner_ != other.full_owner_ || free_owner_ != other.free_owner_ ||
      full_to_free_ != other.full_to_free_ || transformation_.nonZeros() != other.transformation_.nonZeros())
    return false;
  const SparseMatrix difference = transformation_ - other.transformation_;
  return difference.norm() == 0;
}

}  // namespace modalcal
