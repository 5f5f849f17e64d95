#pragma once
/// \file vtu.hpp
/// Results for ParaView: VTK XML UnstructuredGrid (.vtu) files of the model with its element
/// blocks, block properties, mode shapes and per-element indicators, a file of the sensor points
/// with the measured shapes, and a .pvd collection that opens both at once.
///
/// Files are ASCII VTK XML (format version 1.0, 64-bit offsets), written atomically (temporary
/// file + rename, see output.hpp) and never over an input. Cell types: hex8 as VTK_HEXAHEDRON
/// (12), tet4 as VTK_TETRA (10), tet10 as VTK_QUADRATIC_TETRA (24); VTK's node orders are the
/// Exodus orders the model uses (tet10 mid-edge nodes on edges 01, 12, 20, 03, 13, 23), so the
/// connectivity is written as it is.
///
/// \code
/// modalcal::ParametricSystem system(problem.model, problem.parameter_targets());
/// modalcal::VtuFields fields;
/// fields.shapes.push_back({"mode_1_22.73Hz", 22.73, result.modes.col(0)});
/// modalcal::write_vtu_set("out/vtu", "modes", problem, system, p, fields);
/// \endcode

#include <string>
#include <vector>

#include "modalcal/assembly.hpp"
#include "modalcal/eigen.hpp"
#include "modalcal/export.hpp"
#include "modalcal/problem.hpp"
#include "modalcal/types.hpp"

namespace modalcal {

/// VTK cell type numbers (vtkCellType.h).
enum class VtkCellType : int { Vertex = 1, Tetra = 10, Hexahedron = 12, QuadraticTetra = 24 };

/// A named data array: `values` holds `components` numbers per tuple (point, cell, or free for
/// field data). `integer` arrays are written as Int64.
struct MODALCAL_EXPORT VtkArray {
  std::string name;
  int components = 1;
  std::vector<double> values;
  bool integer = false;
};

/// A string array of the field data (VTK writes each string as character codes ending in 0).
struct MODALCAL_EXPORT VtkStringArray {
  std::string name;
  std::vector<std::string> values;
};

/// An unstructured grid as the .vtu file stores it.
struct MODALCAL_EXPORT VtkGrid {
  Eigen::Matrix3Xd points;
  std::vector<long> connectivity;    ///< point indices of all cells, one after the other
  std::vector<VtkCellType> types;    ///< one per cell
  std::vector<int> cell_sizes;       ///< points per cell
  std::vector<VtkArray> point_data;  ///< points.cols() tuples each
  std::vector<VtkArray> cell_data;   ///< types.size() tuples each
  std::vector<VtkArray> field_data;
  std::vector<VtkStringArray> field_strings;
};

/// The .vtu document of `grid`.
/// \throws std::invalid_argument if an array's size does not match its points or cells.
MODALCAL_EXPORT std::string vtu_document(const VtkGrid& grid);

/// A .pvd collection listing `files` (relative to the .pvd) as parts 0, 1, ...
MODALCAL_EXPORT std::string pvd_document(const std::vector<std::string>& files);

/// A free-DOF vector (a mode shape) to show as a nodal displacement field.
struct MODALCAL_EXPORT ShapeField {
  std::string name;        ///< e.g. "mode_3_80.28Hz"
  double frequency_hz = 0;
  Vector shape;            ///< on the free DOFs of the system
};

/// What write_vtu_set puts on the model besides its blocks and properties.
struct MODALCAL_EXPORT VtuFields {
  /// Point vectors (x, y, z translation of every node, rigidly coupled and fixed nodes
  /// included); their frequencies go to the field data `frequencies_hz`, their names to
  /// `shape_names`, in this order.
  std::vector<ShapeField> shapes;
  std::vector<VtkArray> element_data;  ///< one value per element (blocks in model order)
  std::vector<VtkArray> node_data;     ///< one value per model node
};

/// The model as a grid: every model node a point (reference nodes included; they belong to no
/// cell), every solid element a cell, with cell data `block_id` (index into the field data
/// string array `block_names`) and the block's material properties at parameters p (`E`, `nu`,
/// `K`, `G`, `density`, `stiffness_scale`, `mass_scale`, each derived when the block gives the
/// other pair), point data `node_id` (external id), field data `parameter_<name>` per
/// calibration parameter, and `fields`.
/// \throws std::invalid_argument if a field's size does not fit the model or system.
MODALCAL_EXPORT VtkGrid model_grid(const Problem& problem, const ParametricSystem& system, const Vector& p,
                                   const VtuFields& fields);

/// The sensor points as VTK_VERTEX cells, one per sensed node, with point data `node_id` and
/// each measured shape as a 3-vector (unmeasured directions 0) named
/// `measured_<i>_<f>Hz`, and `measured_directions` (the number of directions sensed at the node).
MODALCAL_EXPORT VtkGrid sensor_grid(const Problem& problem);

/// Writes `<stem>.vtu` (model_grid), `<stem>_sensors.vtu` (sensor_grid, when the problem has
/// sensors) and `<stem>.pvd` listing them into `directory` (created if missing), each
/// atomically; refuses to overwrite the problem file. Returns the paths written.
/// \throws std::invalid_argument for a file that is an input, std::runtime_error if one cannot
///         be written.
MODALCAL_EXPORT std::vector<std::string> write_vtu_set(const std::string& directory, const std::string& stem,
                                                       const Problem& problem, const ParametricSystem& system,
                                                       const Vector& p, const VtuFields& fields);

/// Appends the first `count` elastic modes of `modal` (all if count < 0) as shape fields named
/// shape_field_name("mode", k, f).
MODALCAL_EXPORT void add_mode_fields(const ModalResult& modal, int count, VtuFields* fields);

/// Name of a shape field: `<prefix>_<index>_<frequency with 2 decimals>Hz`, e.g. "mode_3_80.28Hz".
MODALCAL_EXPORT std::string shape_field_name(const std::string& prefix, int index, double frequency_hz);

}  // namespace modalcal
