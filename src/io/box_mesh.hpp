#pragma once
// Internal: the structured multi-box mesh generator behind a problem file's `mesh:` section.
#include <array>
#include <vector>

#include "modalcal/elements.hpp"
#include "modalcal/types.hpp"

namespace modalcal::detail {

/// An axis-aligned box whose elements go to block `block` (an index chosen by the caller).
struct MeshBox {
  int block = 0;
  Vec3 min = Vec3::Zero(), max = Vec3::Zero();  ///< min < max along every axis
};

struct BoxMesh {
  std::vector<Vec3> coordinates;               ///< node i has external id i + 1
  std::vector<std::vector<int>> connectivity;  ///< per block index: node indices
};

/// True if the two boxes share a volume (touching faces, edges or corners do not count).
bool boxes_overlap(const MeshBox& a, const MeshBox& b);

/// The size of the mesh generate_box_mesh would make, computed in floating point without making
/// it, so that an absurd element size or refinement can be refused before it exhausts the memory.
struct BoxMeshSize {
  double nodes = 0;        ///< about (box by box: shared faces count twice), mid-edge nodes included
  double grid_points = 0;  ///< of the common grid the generator indexes (boxes and the gaps between)
};
/// Grid planes along x, y and z beside the boxes' faces (each strictly inside the boxes' extent).
using ExtraPlanes = std::array<std::vector<double>, 3>;

BoxMeshSize estimate_box_mesh(const std::vector<MeshBox>& boxes, SolidType type, double element_size,
                              double refinement, const ExtraPlanes& extra = {});

/// Meshes non-overlapping boxes on one common grid. Along each axis the grid planes are all
/// boxes' min and max coordinates and the `extra` ones (so that what lies between two planes, a
/// node set's footprint, keeps its extent at every refinement), and each interval between planes is divided into
/// max(1, ceil(refinement * length / element_size)) equal parts, so adjacent boxes share their
/// interface nodes. Nodes exist only where a box uses them, numbered in grid order (x fastest,
/// then y, then z); tet10 mid-edge nodes follow in order of first use. Cells are visited box
/// by box, x fastest. Every element is positively oriented: hex8 in Exodus order; tets from
/// splitting each hex into 6 along its diagonal from local node 0 to node 6, which conforms
/// between neighbouring hexes because all of them are axis-aligned and oriented alike.
BoxMesh generate_box_mesh(const std::vector<MeshBox>& boxes, int num_blocks, SolidType type,
                          double element_size, double refinement, const ExtraPlanes& extra = {});

}  // namespace modalcal::detail
