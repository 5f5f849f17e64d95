#include "io/box_mesh.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <unordered_map>

namespace modalcal::detail {

namespace {

// Local hex corners in Exodus order: bottom face counter-clockwise seen from +z, then top.
constexpr int kHexCorner[8][3] = {{0, 0, 0}, {1, 0, 0}, {1, 1, 0}, {0, 1, 0},
                                  {0, 0, 1}, {1, 0, 1}, {1, 1, 1}, {0, 1, 1}};
// The 6 tets sharing the diagonal 0-6, one per order of stepping along x, y, z from corner 0
// to corner 6; odd orders have two corners swapped so every tet has positive volume.
constexpr int kHexTets[6][4] = {{0, 1, 2, 6}, {0, 5, 1, 6}, {0, 2, 3, 6},
                                {0, 3, 7, 6}, {0, 4, 5, 6}, {0, 7, 4, 6}};
// tet10 mid-edge nodes, in connectivity order.
constexpr int kTetEdges[6][2] = {{0, 1}, {1, 2}, {2, 0}, {0, 3}, {1, 3}, {2, 3}};

// The grid lines along one axis, and where each box face lies on them.
struct Axis {
  std::vector<double> planes;   // distinct box face coordinates, ascending
  std::vector<int> plane_line;  // index in `lines` of each plane
  std::vector<double> lines;    // all grid coordinates, ascending

  // The nearest plane, because a face may have been merged into a neighbouring plane.
  int line_of(double x) const {
    auto it = std::min_element(planes.begin(), planes.end(), [x](double a, double b) {
      return std::abs(a - x) < std::abs(b - x);
    });
    return plane_line[it - planes.begin()];
  }
};

/// The distinct box faces and `extra` planes along one axis, ascending.
std::vector<double> face_planes(const std::vector<MeshBox>& boxes, int axis, const std::vector<double>& extra) {
  std::vector<double> faces = extra;
  for (const MeshBox& b : boxes) {
    faces.push_back(b.min[axis]);
    faces.push_back(b.max[axis]);
  }
  std::sort(faces.begin(), faces.end());
  // Faces that differ by rounding only are merged, or they would create sliver elements.
  const double merge_tolerance = 1e-9 * (faces.back() - faces.front());
  std::vector<double> planes;
  for (double f : faces)
    if (planes.empty() || f - planes.back() > merge_tolerance) planes.push_back(f);
  return planes;
}

/// Elements along an interval between two planes (a double: it may not fit an int).
double divisions(double length, double element_size, double refinement) {
  // Without the slack, a ratio such as 0.14/0.02, which computes as 7.000000000000001,
  // would round up to one division too many.
  return std::max(1.0, std::ceil(refinement * length / element_size - 1e-9));
}

Axis make_axis(const std::vector<MeshBox>& boxes, int axis, double element_size,
               double refinement, const std::vector<double>& extra) {
  Axis a;
  a.planes = face_planes(boxes, axis, extra);
  for (size_t k = 0; k + 1 < a.planes.size(); ++k) {
    const double length = a.planes[k + 1] - a.planes[k];
    const int parts = static_cast<int>(divisions(length, element_size, refinement));
    a.plane_line.push_back(static_cast<int>(a.lines.size()));
    for (int j = 0; j < parts; ++j) a.lines.push_back(a.planes[k] + length * j / parts);
  }
  a.plane_line.push_back(static_cast<int>(a.lines.size()));
  a.lines.push_back(a.planes.back());
  return a;
}

// A box's range of grid cells, [begin, end) along each axis.
struct CellRange {
  std::array<int, 3> begin, end;
};

}  // namespace

bool boxes_overlap(const MeshBox& a, const MeshBox& b) {
  for (int axis = 0; axis < 3; ++axis)
    if (!(a.min[axis] < b.max[axis] && b.min[axis] < a.max[axis])) return false;
  return true;
}

BoxMeshSize estimate_box_mesh(const std::vector<MeshBox>& boxes, SolidType type, double element_size,
                              double refinement, const ExtraPlanes& extra) {
  BoxMeshSize size;
  size.grid_points = 1;
  std::array<std::vector<double>, 3> planes;
  for (int axis = 0; axis < 3; ++axis) {
    planes[axis] = face_planes(boxes, axis, extra[axis]);
    double lines = 1;
    for (size_t k = 0; k + 1 < planes[axis].size(); ++k)
      lines += divisions(planes[axis][k + 1] - planes[axis][k], element_size, refinement);
    size.grid_points *= lines;
  }
  for (const MeshBox& b : boxes) {
    double nodes = 1;
    for (int axis = 0; axis < 3; ++axis) {
      double cells = 0;
      for (size_t k = 0; k + 1 < planes[axis].size(); ++k) {
        const double middle = 0.5 * (planes[axis][k] + planes[axis][k + 1]);
        if (b.min[axis] < middle && middle < b.max[axis])
          cells += divisions(planes[axis][k + 1] - planes[axis][k], element_size, refinement);
      }
      nodes *= cells + 1;
    }
    size.nodes += nodes;
  }
  // Each hex cell of the grid adds 7 tet10 mid-edge nodes (3 edges, 3 face and 1 body diagonal).
  if (type == SolidType::Tet10) size.nodes *= 8;
  return size;
}

BoxMesh generate_box_mesh(const std::vector<MeshBox>& boxes, int num_blocks, SolidType type,
                          double element_size, double refinement, const ExtraPlanes& extra) {
  std::array<Axis, 3> axes;
  for (int axis = 0; axis < 3; ++axis)
    axes[axis] = make_axis(boxes, axis, element_size, refinement, extra[axis]);
  std::vector<CellRange> ranges;
  for (const MeshBox& b : boxes) {
    CellRange r;
    for (int axis = 0; axis < 3; ++axis) {
      r.begin[axis] = axes[axis].line_of(b.min[axis]);
      r.end[axis] = axes[axis].line_of(b.max[axis]);
    }
    ranges.push_back(r);
  }

  const std::array<int, 3> points{static_cast<int>(axes[0].lines.size()),
                                  static_cast<int>(axes[1].lines.size()),
                                  static_cast<int>(axes[2].lines.size())};
  auto point_index = [&](int i, int j, int k) { return (k * points[1] + j) * points[0] + i; };
  // Grid points a box touches get a node; the rest (outside every box) do not exist.
  constexpr int kUnused = -1, kUsed = -2;
  std::vector<int> node_of(static_cast<size_t>(points[0]) * points[1] * points[2], kUnused);
  for (const CellRange& r : ranges)
    for (int k = r.begin[2]; k <= r.end[2]; ++k)
      for (int j = r.begin[1]; j <= r.end[1]; ++j)
        for (int i = r.begin[0]; i <= r.end[0]; ++i) node_of[point_index(i, j, k)] = kUsed;

  BoxMesh mesh;
  for (int k = 0; k < points[2]; ++k)
    for (int j = 0; j < points[1]; ++j)
      for (int i = 0; i < points[0]; ++i) {
        int& node = node_of[point_index(i, j, k)];
        if (node == kUnused) continue;
        node = static_cast<int>(mesh.coordinates.size());
        mesh.coordinates.emplace_back(axes[0].lines[i], axes[1].lines[j], axes[2].lines[k]);
      }

  std::unordered_map<std::uint64_t, int> mid_node;
  auto edge_mid_node = [&](int a, int b) {
    const auto key = (static_cast<std::uint64_t>(std::min(a, b)) << 32) |
                     static_cast<std::uint32_t>(std::max(a, b));
    auto [it, inserted] = mid_node.try_emplace(key, static_cast<int>(mesh.coordinates.size()));
    if (inserted) mesh.coordinates.push_back(0.5 * (mesh.coordinates[a] + mesh.coordinates[b]));
    return it->second;
  };

  mesh.connectivity.resize(num_blocks);
  for (size_t n = 0; n < boxes.size(); ++n) {
    std::vector<int>& out = mesh.connectivity[boxes[n].block];
    const CellRange& r = ranges[n];
    for (int k = r.begin[2]; k < r.end[2]; ++k)
      for (int j = r.begin[1]; j < r.end[1]; ++j)
        for (int i = r.begin[0]; i < r.end[0]; ++i) {
          std::array<int, 8> hex;
          for (int c = 0; c < 8; ++c)
            hex[c] = node_of[point_index(i + kHexCorner[c][0], j + kHexCorner[c][1],
                                         k + kHexCorner[c][2])];
          if (type == SolidType::Hex8) {
            out.insert(out.end(), hex.begin(), hex.end());
            continue;
          }
          for (const auto& tet : kHexTets) {
            std::array<int, 4> corner;
            for (int c = 0; c < 4; ++c) corner[c] = hex[tet[c]];
            out.insert(out.end(), corner.begin(), corner.end());
            if (type == SolidType::Tet10)
              for (const auto& e : kTetEdges)
                out.push_back(edge_mid_node(corner[e[0]], corner[e[1]]));
          }
        }
  }
  return mesh;
}

}  // namespace modalcal::detail
