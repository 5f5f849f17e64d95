#pragma once
/// \file test_data.hpp
/// Measured modal data from a modal test or an FE export: universal files (UFF/UNV) and a plain
/// CSV form, the test nodes' mapping onto model nodes, and unit conversion.
///
/// Universal-file datasets read (docs/problem-format.md, "Test data files"):
/// - 151 header (kept as text for reports), 164 units (factors to SI),
/// - 18 and 2420 coordinate systems (Cartesian), 15 and 2411 nodes,
/// - 55 and 2414 mode shapes at nodes (real normal modes; complex modes are converted to real
///   ones by best_real_shape(), with a warning).
///
/// Every other dataset is skipped with a note. Shapes and coordinates are rotated into the
/// file's global frame at read time, so TestMode::values are global components.
///
/// \code
/// modalcal::TestData data = modalcal::read_test_data("modal_test.uff");
/// modalcal::scale_lengths(&data, modalcal::length_factor_to(data, "mm"));     // coordinates in mm
/// modalcal::NodeMapOptions options;
/// options.by = modalcal::NodeMatchBy::Coordinates;
/// options.tolerance = 0.5;                                       // mm
/// modalcal::NodeMapping mapping = modalcal::map_test_nodes(data, model, options);
/// std::cout << mapping.report();
/// \endcode

#include <complex>
#include <optional>
#include <string>
#include <vector>

#include "modalcal/export.hpp"
#include "modalcal/model.hpp"
#include "modalcal/types.hpp"

namespace modalcal {

/// Dataset 151: who wrote the file and when. Empty strings for records a file leaves out.
struct MODALCAL_EXPORT UffHeader {
  std::string model_name;
  std::string description;
  std::string database_program;  ///< program that created the model database
  std::string database_created;  ///< date and time, as written
  std::string database_saved;
  std::string file_program;  ///< program that wrote the universal file
  std::string file_written;  ///< date and time, as written
  int line = 0;              ///< of the dataset number, 1-based
};

/// Dataset 164: the file's unit system. A factor is the number of file units in one SI unit
/// (length: per metre, force: per newton, temperature: per kelvin), so
/// \f$x_\mathrm{SI} = x_\mathrm{file} / \mathrm{factor}\f$ (millimetres: length factor 1000).
struct MODALCAL_EXPORT UffUnits {
  int code = 1;                   ///< 1 SI, 2 BG, ..., 9 user defined (as written)
  std::string description;        ///< e.g. "SI - mks (Newton)"
  int temperature_mode = 0;       ///< 1 absolute, 2 relative, 0 not given
  double length_factor = 1;       ///< > 0
  double force_factor = 1;        ///< > 0
  double temperature_factor = 1;  ///< > 0
  double temperature_offset = 0;
  int line = 0;
};

/// A coordinate system from dataset 18 or 2420, resolved into the global frame:
/// \f$x_\mathrm{global} = o + A^T x_\mathrm{local}\f$, the rows of A being the local axes.
struct MODALCAL_EXPORT CoordinateSystem {
  int id = 0;
  std::string name;
  int type = 0;                  ///< 0 Cartesian, 1 cylindrical, 2 spherical (only 0 is usable)
  Vec3 origin = Vec3::Zero();    ///< in the global frame
  Mat3 axes = Mat3::Identity();  ///< rows: local x, y, z unit axes in global coordinates
  int dataset = 0;               ///< 18 or 2420
  int line = 0;                  ///< of the system's first record
};

/// A node of the test geometry (dataset 15 or 2411).
struct MODALCAL_EXPORT TestNode {
  long id = 0;
  Vec3 coordinates = Vec3::Zero();  ///< global frame (converted from its definition system)
  int definition_system = 0;        ///< the system the file gives the coordinates in
  int displacement_system = 0;      ///< the system the file gives its shape values in
  int dataset = 0;                  ///< 15 or 2411
  int line = 0;
};

/// One shape value: a global component (0..2 translations x, y, z; 3..5 rotations) at a node.
struct MODALCAL_EXPORT TestShapeValue {
  long node = 0;
  int component = 0;
  double value = 0;
};

/// A measured (or FE) mode.
struct MODALCAL_EXPORT TestMode {
  int number = 0;                       ///< mode number as written in the file
  double frequency_hz = 0;              ///< undamped natural frequency
  std::optional<double> damping_ratio;  ///< viscous damping ratio when the file gives one
  int values_per_node = 3;              ///< 3 (translations) or 6 (with rotations)
  std::vector<TestShapeValue> values;   ///< global frame, sorted by node, then component
  /// Set when the file held a complex shape that best_real_shape() made real.
  bool from_complex = false;
  double phase_collinearity = 1;  ///< MPC of the complex shape, 1 for real ones
  std::string description;        ///< the dataset's first ID line (empty if "NONE")
  int dataset = 0;                ///< 55, 2414, or 0 for CSV
  int line = 0;                   ///< where the mode starts in its file

  /// The value of `component` at `node`, if the mode has one.
  std::optional<double> value(long node, int component) const;
};

/// One dataset of a universal file, as met: read, or skipped with the reason.
struct MODALCAL_EXPORT UffDatasetEntry {
  int number = 0;
  int line = 0;  ///< of the dataset number
  bool read = false;
  std::string note;  ///< why it was skipped
};

/// Everything read from a test-data file.
struct MODALCAL_EXPORT TestData {
  enum class Format { Uff, Csv };
  std::string path;
  Format format = Format::Uff;
  std::optional<UffHeader> header;                   ///< dataset 151
  std::optional<UffUnits> units;                     ///< dataset 164
  std::vector<CoordinateSystem> coordinate_systems;  ///< datasets 18 and 2420
  std::vector<TestNode> nodes;                       ///< datasets 15 and 2411
  std::vector<TestMode> modes;                       ///< datasets 55 and 2414, or CSV rows
  std::vector<UffDatasetEntry> datasets;             ///< in file order
  /// What was assumed or changed and may matter (complex modes made real, shape values of
  /// nodes without geometry taken as global). Skipped datasets are in `datasets`.
  std::vector<std::string> warnings;
  double length_scale = 1;  ///< product of the factors scale_lengths() applied

  /// The geometry node with this id, or nullptr.
  const TestNode* find_node(long id) const;
  /// Ids of the nodes that carry shape values, in order of first appearance.
  std::vector<long> shape_node_ids() const;
  /// Ids of all test nodes: the geometry's in file order, then shape_node_ids() without geometry.
  std::vector<long> node_ids() const;
};

/// Reads a universal file (ASCII datasets; fixed-width Fortran fields or whitespace-separated
/// values, 'E' or 'D' exponents, LF or CRLF line ends).
/// \throws ProblemError (problem.hpp) naming the file, the line and the dataset when the file
///         is malformed: a dataset without its closing "-1", a record with too few or too many
///         values, a non-numeric field, a reference to an unknown coordinate system, a
///         non-Cartesian system in use, a node defined twice.
MODALCAL_EXPORT TestData read_uff(const std::string& path);

/// Reads the CSV form: a header line `mode,frequency_hz,node,direction,value`, then one row per
/// value; direction is x, y, z, rx, ry or rz in the global frame; blank lines and lines starting
/// with '#' are ignored. A CSV has no geometry, so its nodes can be mapped by id only.
/// \throws ProblemError naming the file and line of a bad row.
MODALCAL_EXPORT TestData read_test_csv(const std::string& path);

/// read_test_csv() for a path ending in ".csv" (any case), read_uff() otherwise.
MODALCAL_EXPORT TestData read_test_data(const std::string& path);

/// The CSV form of every mode's values (shortest round-trip number formatting).
MODALCAL_EXPORT std::string test_data_to_csv(const TestData& data);

/// Writes test_data_to_csv() to `path` atomically, refusing to overwrite any of `inputs`.
MODALCAL_EXPORT void write_test_csv(const TestData& data, const std::string& path,
                                    const std::vector<std::string>& inputs = {});

/// Complex shape made real: the mode rotated by the phase θ that maximizes the norm of its
/// real part, \f$\psi = \mathrm{Re}(e^{i\theta}\phi)\f$; with \f$\phi = a + ib\f$,
/// \f$\tan 2\theta = -2a^Tb / (a^Ta - b^Tb)\f$. ψ is the least-squares best real approximation
/// of φ up to phase. The modal phase collinearity
/// \f$\mathrm{MPC} = ((a^Ta - b^Tb)^2 + 4(a^Tb)^2)/(a^Ta + b^Tb)^2\f$ is 1 for a shape that is
/// real up to a phase and 0 for a circular one; \f$\|\psi\|^2/\|\phi\|^2 = (1+\sqrt{MPC})/2\f$.
struct MODALCAL_EXPORT RealShape {
  Vector values;            ///< ψ
  double rotation_rad = 0;  ///< θ
  double collinearity = 1;  ///< MPC in [0, 1]
};
/// \param shape any length ≥ 1; an all-zero shape gives zeros with MPC 1.
MODALCAL_EXPORT RealShape best_real_shape(const Eigen::VectorXcd& shape);

/// Metres per unit for "m", "cm", "mm", "in", "ft"; nullopt for anything else.
MODALCAL_EXPORT std::optional<double> metres_per_length_unit(const std::string& unit);

/// Factor from the file's lengths to `unit` (a name metres_per_length_unit() knows), using the
/// file's dataset 164; a file without one is taken to be in metres (SI, the universal-file
/// default) and the assumption is added to *assumption if given.
/// \throws std::invalid_argument for an unknown unit name.
MODALCAL_EXPORT double length_factor_to(const TestData& data, const std::string& unit,
                                        std::string* assumption = nullptr);

/// Multiplies node coordinates, coordinate-system origins and translational shape values by
/// `factor` (> 0; rotations are unchanged) and records it in TestData::length_scale.
MODALCAL_EXPORT void scale_lengths(TestData* data, double factor);

/// How the file's lengths become the model's: an explicit factor, or the model's length unit.
struct MODALCAL_EXPORT LengthConversion {
  std::string unit;  ///< the model's length unit (m, cm, mm, in, ft); empty: not given
  double scale = 0;  ///< > 0: model length = file length × scale (wins over `unit`)
};

/// Applies `conversion` with scale_lengths(): `scale` if set, else `unit` (via
/// length_factor_to()), else, only when the file has a units dataset (164), the first item of
/// the problem's free-text `problem_units` ("in, lbf, s" gives "in") if it names a known unit.
/// Frequencies need no conversion: universal files and CSV give them in Hz, as problems do.
/// \return what was done or assumed, for a report ("" when nothing was converted).
MODALCAL_EXPORT std::string convert_lengths(TestData* data, const LengthConversion& conversion,
                                            const std::string& problem_units);

/// How test nodes find their model nodes.
enum class NodeMatchBy { Id, Coordinates };

struct MODALCAL_EXPORT NodeMapOptions {
  NodeMatchBy by = NodeMatchBy::Id;  ///< default: same node id
  /// Coordinates: the largest accepted distance, in model units (> 0). Default (unset):
  /// 1e-6 × the diagonal of the model's bounding box, i.e. coincident nodes only.
  std::optional<double> tolerance;
  /// Names a field, its value and the violated condition when invalid.
  bool IsValid(std::string* error) const;
};

/// The outcome for one test node.
struct MODALCAL_EXPORT NodeMatch {
  long test_node = 0;
  int model_node = -1;  ///< index into Model, -1 if unmatched
  double distance = 0;  ///< to the matched (or, if unmatched, nearest) model node;
                        ///< NaN when the test node has no coordinates
  std::string reason;   ///< why it is unmatched
};

struct MODALCAL_EXPORT NodeMapping {
  std::vector<NodeMatch> matches;  ///< one per test node, in TestData::node_ids() order
  NodeMatchBy by = NodeMatchBy::Id;
  double tolerance = 0;  ///< the distance used (coordinates)
  int num_matched() const;
  /// "12 of 14 test nodes matched ...", then one line per unmatched node with its reason.
  std::string report() const;
};

/// Maps every test node (TestData::node_ids()) onto a model node: by equal id, or by the nearest
/// model node within the tolerance (coordinates in the model's units: see scale_lengths()).
/// A model node claimed by two test nodes goes to the nearer one; the other is unmatched.
/// \throws std::invalid_argument if `options` is invalid.
MODALCAL_EXPORT NodeMapping map_test_nodes(const TestData& data, const Model& model, const NodeMapOptions& options);

}  // namespace modalcal
