// Universal-file reader: datasets 151, 164, 18, 2420, 15, 2411, 55 and 2414 into TestData,
// with coordinates and shapes rotated into the global frame. Record layouts follow the I-DEAS
// universal-file descriptions; the checks follow what real exports (LMS Test.Lab, Permas,
// Simcenter, operational-modal-analysis tools) actually write.
#include <Eigen/Geometry>
#include <Eigen/LU>
#include <algorithm>
#include <cmath>
#include <complex>
#include <fstream>
#include <iterator>
#include <map>
#include <set>

#include "support/text_util.hpp"
#include "io/uff_records.hpp"
#include "modalcal/problem.hpp"
#include "modalcal/test_data.hpp"

namespace modalcal {

namespace {

using detail::UffBlock;
using detail::UffRecords;

using detail::number_text;
using detail::trim;

const char* dataset_name(int number) {
  static const std::map<int, const char*> names = {
      {15, "nodes"},           {18, "coordinate systems"},
      {55, "data at nodes"},   {58, "function data (FRFs, time histories)"},
      {82, "trace lines"},     {151, "header"},
      {164, "units"},          {2400, "model header"},
      {2411, "nodes"},         {2412, "elements"},
      {2414, "analysis data"}, {2420, "coordinate systems"},
      {2467, "groups"},        {2477, "groups"}};
  const auto it = names.find(number);
  return it == names.end() ? "unknown to this reader" : it->second;
}

const char* analysis_name(int type) {
  static const char* const names[] = {"unknown",      "static",
                                      "normal modes", "complex eigenvalues (first order)",
                                      "transient",    "frequency response",
                                      "buckling",     "complex eigenvalues (second order)"};
  return type >= 0 && type <= 7 ? names[type] : "not a known type";
}

/// A coordinate system as written: by three points in a reference system (dataset 18) or by
/// its global axes and origin (dataset 2420).
struct PendingSystem {
  CoordinateSystem system;  ///< axes and origin final when reference < 0
  int reference = -1;       ///< dataset 18: the system the points are given in
  Vec3 origin, on_x, in_xz;
};

/// A mode's header and its values per node, in the nodes' displacement systems.
struct PendingMode {
  TestMode mode;
  bool is_complex = false;
  std::string eigenvalue_note;  ///< how frequency and damping came from a complex eigenvalue
  std::vector<long> nodes;
  std::vector<int> node_lines;
  std::vector<std::vector<double>> values;  ///< per node: NDV reals or NDV (re, im) pairs
};

/// The record-6 (55) / record-9 (2414) description of a result: what decides whether it is a
/// mode shape this reader takes.
struct ResultKind {
  int analysis = 0, characteristic = 0, data_type = 0, values_per_node = 0;
};

class UffReader {
 public:
  UffReader(const std::string& path, const std::vector<std::string>& lines, const std::map<int, long>& binary)
      : path_(path), lines_(lines), binary_(binary) {
    data_.path = path;
    data_.format = TestData::Format::Uff;
  }
  TestData read();

 private:
  void read_header(UffRecords& r, const UffBlock& b);
  void read_units(UffRecords& r, const UffBlock& b);
  void read_systems_18(UffRecords& r);
  void read_systems_2420(UffRecords& r);
  void add_system(const PendingSystem& s, UffRecords& r);
  void read_nodes(UffRecords& r, const UffBlock& b);
  /// Returns the reason a dataset 55/2414 is skipped, or "" if it was read.
  std::string read_dataset_55(UffRecords& r, const UffBlock& b);
  std::string read_dataset_2414(UffRecords& r, const UffBlock& b);
  std::string skip_reason(UffRecords& r, int line, const ResultKind& kind) const;
  void read_mode_header(const std::vector<double>& reals, const ResultKind& kind, int frequency_index,
                        int eigenvalue_index, int viscous_damping_index, PendingMode* m) const;
  void read_node_values(UffRecords& r, const ResultKind& kind, int kind_line, PendingMode* m) const;

  const CoordinateSystem& resolve_system(int id);
  const CoordinateSystem& cartesian_system(int id, const std::string& user, int dataset, int line);
  void resolve_nodes();
  void resolve_modes();
  /// The mode's values per node, real: as written, or a complex shape made real (with a warning).
  std::vector<Vector> real_values(PendingMode& m);
  void number_modes_uniquely();
  [[noreturn]] void fail(int dataset, int line, const std::string& message) const {
    throw ProblemError(path_, line, "dataset " + std::to_string(dataset) + ": " + message);
  }

  std::string path_;
  const std::vector<std::string>& lines_;
  const std::map<int, long>& binary_;  ///< binary datasets skipped by their byte count (uff_lines)
  TestData data_;
  std::map<int, PendingSystem> pending_systems_;
  std::map<int, int> system_state_;  ///< 1 being resolved, 2 resolved
  std::map<int, CoordinateSystem> systems_;
  std::map<long, int> node_index_;
  std::vector<PendingMode> modes_;
};

TestData UffReader::read() {
  const std::vector<UffBlock> blocks = detail::split_uff(path_, lines_, binary_);
  if (blocks.empty())
    throw ProblemError(path_, 0, "no datasets found (a universal file is a sequence of datasets between '-1' lines)");
  for (const UffBlock& b : blocks) {
    UffRecords r(path_, lines_, b);
    UffDatasetEntry entry{b.number, b.number_line, true, ""};
    if (b.binary_bytes >= 0) {
      entry.read = false;
      entry.note = "binary " + std::string(dataset_name(b.number)) + " (" + std::to_string(b.number) + "b), its " +
                   std::to_string(b.binary_bytes) + " bytes skipped: not needed for modal test data";
      data_.datasets.push_back(entry);
      continue;
    }
    switch (b.number) {
      case 151:
        read_header(r, b);
        break;
      case 164:
        read_units(r, b);
        break;
      case 18:
        read_systems_18(r);
        break;
      case 2420:
        read_systems_2420(r);
        break;
      case 15:
      case 2411:
        read_nodes(r, b);
        break;
      case 55:
        entry.note = read_dataset_55(r, b);
        break;
      case 2414:
        entry.note = read_dataset_2414(r, b);
        break;
      default:
        entry.note = std::string(dataset_name(b.number)) + ": not needed for modal test data";
    }
    entry.read = entry.note.empty();
    data_.datasets.push_back(entry);
  }
  resolve_nodes();
  resolve_modes();
  for (const auto& [id, pending] : pending_systems_) data_.coordinate_systems.push_back(resolve_system(id));
  return data_;
}

void UffReader::read_header(UffRecords& r, const UffBlock& b) {
  if (data_.header) {
    data_.warnings.push_back("a second header (dataset 151, line " + std::to_string(b.number_line) +
                             ") is ignored; the first is at line " + std::to_string(data_.header->line));
    return;
  }
  UffHeader h;
  h.line = b.number_line;
  std::string* fields[] = {&h.model_name,     &h.description,  &h.database_program, &h.database_created,
                           &h.database_saved, &h.file_program, &h.file_written};
  // Writers differ in how many of the seven text records they fill; the header is only shown.
  for (std::string* field : fields)
    if (!r.at_end()) *field = trim(r.text("header text"));
  data_.header = h;
}

void UffReader::read_units(UffRecords& r, const UffBlock& b) {
  if (data_.units)
    r.fail(b.number_line,
           "a second unit system; the first is at line " + std::to_string(data_.units->line) + " and a file has one");
  UffUnits u;
  u.line = b.number_line;
  // Record 1 is FORMAT(I10,20A1,I10): code, description, temperature mode, by column.
  const int line1 = r.line();
  const std::string record1 = r.text("record 1 (units code, description, temperature mode)");
  std::vector<double> code;
  std::string bad;
  // Whole and within an int's range (10 columns hold more), to convert.
  auto is_int = [](double v) { return v == std::floor(v) && std::abs(v) <= 2e9; };
  if (!detail::parse_numbers(record1.substr(0, 10), &code, &bad) || code.size() != 1 || !is_int(code[0]))
    r.fail(line1, "record 1: expected the units code in columns 1-10, found '" + trim(record1.substr(0, 10)) + "'");
  u.code = static_cast<int>(code[0]);
  if (record1.size() > 10) u.description = trim(record1.substr(10, 20));
  std::vector<double> mode;
  if (record1.size() > 30 && detail::parse_numbers(record1.substr(30), &mode, &bad) && mode.size() == 1 &&
      is_int(mode[0]))
    u.temperature_mode = static_cast<int>(mode[0]);
  const int line2 = r.line();
  const std::vector<double> factors = r.numbers(3, "record 2 (length, force and temperature factors)");
  for (int k = 0; k < 3; ++k)
    if (!(factors[k] > 0))
      r.fail(line2, std::string("record 2: the ") +
                        (k == 0   ? "length"
                         : k == 1 ? "force"
                                  : "temperature") +
                        " factor must be positive, got " + number_text(factors[k]));
  u.length_factor = factors[0];
  u.force_factor = factors[1];
  u.temperature_factor = factors[2];
  if (!r.at_end()) u.temperature_offset = r.numbers(1, "record 3 (temperature offset)")[0];
  data_.units = u;
}

void UffReader::add_system(const PendingSystem& s, UffRecords& r) {
  const auto [it, inserted] = pending_systems_.try_emplace(s.system.id, s);
  if (!inserted)
    r.fail(s.system.line, "coordinate system " + std::to_string(s.system.id) + " is defined twice (first at line " +
                              std::to_string(it->second.system.line) + ")");
}

void UffReader::read_systems_18(UffRecords& r) {
  while (!r.at_end()) {
    PendingSystem s;
    s.system.dataset = 18;
    s.system.line = r.line();
    const std::vector<double> h =
        r.whole_numbers(5, "record 1 (system number, type, reference system, color, method of definition)");
    s.system.id = static_cast<int>(h[0]);
    s.system.type = static_cast<int>(h[1]);
    s.reference = static_cast<int>(h[2]);
    if (h[4] != 1)
      r.fail(s.system.line, "coordinate system " + std::to_string(s.system.id) + ": method of definition " +
                                number_text(h[4]) +
                                " is not read (only 1: origin, a point on +x, a point in the +xz plane)");
    s.system.name = trim(r.text("record 2 (system name)"));
    const std::vector<double> p = r.numbers(9, "records 3-4 (origin, point on +x axis, point in the +xz plane)", 6);
    s.origin = Vec3(p[0], p[1], p[2]);
    s.on_x = Vec3(p[3], p[4], p[5]);
    s.in_xz = Vec3(p[6], p[7], p[8]);
    const Vec3 x = s.on_x - s.origin, v = s.in_xz - s.origin;
    const double scale = std::max(x.norm(), v.norm());
    if (!(x.norm() > 1e-12 * std::max(scale, 1.0)) || !(v.cross(x).norm() > 1e-9 * x.norm() * v.norm()))
      r.fail(s.system.line,
             "coordinate system " + std::to_string(s.system.id) +
                 ": its three points do not span a plane (coincident or collinear), so they define no axes");
    add_system(s, r);
  }
}

void UffReader::read_systems_2420(UffRecords& r) {
  r.whole_numbers(1, "record 1 (part UID)");
  r.text("record 2 (part name)");
  while (!r.at_end()) {
    PendingSystem s;
    s.system.dataset = 2420;
    s.system.line = r.line();
    // FORMAT(3I10) in the description; some writers add a fourth field.
    const size_t fields = std::clamp<size_t>(r.peek("record 3").size(), 3, 4);
    const std::vector<double> h = r.whole_numbers(static_cast<int>(fields), "record 3 (system label, type, color)");
    s.system.id = static_cast<int>(h[0]);
    s.system.type = static_cast<int>(h[1]);
    s.system.name = trim(r.text("record 4 (system name)"));
    const std::vector<double> m = r.numbers(12, "records 5-8 (transformation matrix rows 1-4)", 3);
    for (int i = 0; i < 3; ++i)
      for (int j = 0; j < 3; ++j) s.system.axes(i, j) = m[3 * i + j];
    s.system.origin = Vec3(m[9], m[10], m[11]);
    const double error = (s.system.axes * s.system.axes.transpose() - Mat3::Identity()).cwiseAbs().maxCoeff();
    if (error > 1e-4 || s.system.axes.determinant() < 0)
      r.fail(s.system.line,
             "coordinate system " + std::to_string(s.system.id) +
                 ": rows 1-3 of the transformation matrix are not a right-handed rotation (|A Aᵀ - I| = " +
                 number_text(error) + ", det = " + number_text(s.system.axes.determinant()) + ")");
    add_system(s, r);
  }
}

const CoordinateSystem& UffReader::resolve_system(int id) {
  if (const auto done = systems_.find(id); done != systems_.end()) return done->second;
  const auto it = pending_systems_.find(id);
  if (it == pending_systems_.end()) {
    if (id != 0) throw std::out_of_range("unknown system");
    CoordinateSystem global;  // system 0 is the global frame unless a file defines it
    global.name = "global";
    return systems_[0] = global;
  }
  PendingSystem& s = it->second;
  if (s.reference < 0) return systems_[id] = s.system;
  if (system_state_[id] == 1)
    fail(18, s.system.line,
         "coordinate system " + std::to_string(id) + " is defined relative to itself through its reference systems");
  system_state_[id] = 1;
  const CoordinateSystem& ref =
      cartesian_system(s.reference, "coordinate system " + std::to_string(id), 18, s.system.line);
  // Axes from the three points, in the reference system: x towards the +x point, y normal to
  // the plane of x and the +xz point, z = x × y (so the +xz point has z > 0).
  const Vec3 x = (s.on_x - s.origin).normalized();
  const Vec3 y = (s.in_xz - s.origin).cross(x).normalized();
  Mat3 local;
  local.row(0) = x;
  local.row(1) = y;
  local.row(2) = x.cross(y);
  CoordinateSystem out = s.system;
  out.origin = ref.origin + ref.axes.transpose() * s.origin;
  out.axes = local * ref.axes;
  system_state_[id] = 2;
  return systems_[id] = out;
}

const CoordinateSystem& UffReader::cartesian_system(int id, const std::string& user, int dataset, int line) {
  const CoordinateSystem* system = nullptr;
  try {
    system = &resolve_system(id);
  } catch (const std::out_of_range&) {
    fail(dataset, line,
         user + " refers to coordinate system " + std::to_string(id) +
             ", which no dataset 18 or 2420 in the file defines");
  }
  if (system->type != 0)
    fail(dataset, line,
         user + " uses coordinate system " + std::to_string(id) + " '" + system->name + "' (dataset " +
             std::to_string(system->dataset) + ", line " + std::to_string(system->line) + "), which is " +
             (system->type == 1   ? "cylindrical"
              : system->type == 2 ? "spherical"
                                  : "of unknown type " + std::to_string(system->type)) +
             "; only Cartesian systems are supported");
  return *system;
}

void UffReader::read_nodes(UffRecords& r, const UffBlock& b) {
  while (!r.at_end()) {
    TestNode node;
    node.dataset = b.number;
    node.line = r.line();
    std::vector<double> v;
    if (b.number == 15) {
      v = r.numbers(7, "node record (label, definition system, displacement system, color, x, y, z)");
      for (int k = 0; k < 4; ++k)
        if (v[k] != std::floor(v[k]) || std::abs(v[k]) > 2e9)  // as whole_numbers(): it must convert to an int
          r.fail(node.line, "node record: field " + std::to_string(k + 1) + " (" + number_text(v[k]) +
                                ") should be a whole number of at most 2e9");
    } else {
      v = r.whole_numbers(4, "record 1 (node label, export system, displacement system, color)");
      const std::vector<double> x = r.numbers(3, "record 2 (coordinates)");
      v.insert(v.end(), x.begin(), x.end());
    }
    node.id = static_cast<long>(v[0]);
    node.definition_system = static_cast<int>(v[1]);
    node.displacement_system = static_cast<int>(v[2]);
    node.coordinates = Vec3(v[4], v[5], v[6]);
    const auto [it, inserted] = node_index_.try_emplace(node.id, static_cast<int>(data_.nodes.size()));
    if (!inserted)
      r.fail(node.line, "node " + std::to_string(node.id) + " is defined twice (first in dataset " +
                            std::to_string(data_.nodes[it->second].dataset) + " at line " +
                            std::to_string(data_.nodes[it->second].line) + ")");
    data_.nodes.push_back(node);
  }
}

std::string UffReader::skip_reason(UffRecords& r, int line, const ResultKind& kind) const {
  if (kind.analysis != 2 && kind.analysis != 3 && kind.analysis != 7)
    return "analysis type " + std::to_string(kind.analysis) + " (" + analysis_name(kind.analysis) +
           ") holds no mode shape";
  if (kind.characteristic != 2 && kind.characteristic != 3)
    return "data characteristic " + std::to_string(kind.characteristic) +
           " is not a 3- or 6-component displacement vector (2 or 3), so it gives no directions";
  const int expected = kind.characteristic == 2 ? 3 : 6;
  if (kind.values_per_node != expected)
    r.fail(line, "data characteristic " + std::to_string(kind.characteristic) + " (" + std::to_string(expected) +
                     " components per node) but " + std::to_string(kind.values_per_node) +
                     " values per node (last field); the two disagree");
  if (kind.data_type != 2 && kind.data_type != 4 && kind.data_type != 5 && kind.data_type != 6)
    r.fail(line, "data type " + std::to_string(kind.data_type) + " is neither real (2, 4) nor complex (5, 6)");
  return "";
}

ResultKind result_kind(const std::vector<double>& h) {
  return {static_cast<int>(h[1]), static_cast<int>(h[2]), static_cast<int>(h[4]), static_cast<int>(h[5])};
}

void UffReader::read_mode_header(const std::vector<double>& reals, const ResultKind& kind, int frequency_index,
                                 int eigenvalue_index, int viscous_damping_index, PendingMode* m) const {
  m->is_complex = kind.data_type == 5 || kind.data_type == 6;
  if (kind.analysis == 2) {
    m->mode.frequency_hz = reals[frequency_index];
    const double damping = reals[viscous_damping_index];
    if (damping != 0) m->mode.damping_ratio = damping;
    return;
  }
  // Complex eigenvalue λ = σ + iω_d in rad/s: ω_n = |λ|, ζ = -σ/|λ|.
  const std::complex<double> lambda(reals[eigenvalue_index], reals[eigenvalue_index + 1]);
  const double omega = std::abs(lambda);
  m->mode.frequency_hz = omega / (2 * M_PI);
  if (omega > 0) m->mode.damping_ratio = -lambda.real() / omega;
  m->eigenvalue_note =
      "frequency |λ|/2π and damping ratio -Re λ/|λ| from the eigenvalue λ = " + number_text(lambda.real()) +
      (lambda.imag() < 0 ? "" : "+") + number_text(lambda.imag()) + "i (taken as rad/s)";
}

void UffReader::read_node_values(UffRecords& r, const ResultKind& kind, int kind_line, PendingMode* m) const {
  const bool is_complex = kind.data_type == 5 || kind.data_type == 6;
  const int count = kind.values_per_node * (is_complex ? 2 : 1);
  // FORMAT(6E13.5) for single precision (data types 2, 5), FORMAT(3D25.16) for double (4, 6).
  const int per_line = kind.data_type == 4 || kind.data_type == 6 ? 3 : 6;
  std::set<long> seen;
  while (!r.at_end()) {
    const int line = r.line();
    const long node = static_cast<long>(r.whole_numbers(1, "node number")[0]);
    if (!seen.insert(node).second) r.fail(line, "node " + std::to_string(node) + " appears twice in this mode");
    m->values.push_back(r.numbers(count,
                                  "values of node " + std::to_string(node) + " (" +
                                      std::to_string(kind.values_per_node) + (is_complex ? " complex" : "") +
                                      " values per node, by the record at line " + std::to_string(kind_line) + ")",
                                  per_line));
    m->nodes.push_back(node);
    m->node_lines.push_back(line);
  }
}

std::string UffReader::read_dataset_55(UffRecords& r, const UffBlock& b) {
  PendingMode m;
  m.mode.dataset = 55;
  m.mode.line = b.number_line;
  for (int k = 1; k <= 5; ++k) {
    const std::string id_line = trim(r.text("ID line " + std::to_string(k)));
    if (k == 1 && id_line != "NONE") m.mode.description = id_line;
  }
  const int kind_line = r.line();
  const ResultKind kind = result_kind(r.whole_numbers(
      6, "record 6 (model type, analysis type, data characteristic, specific data type, data type, values per node)"));
  if (std::string reason = skip_reason(r, kind_line, kind); !reason.empty()) return reason;
  const int ints_line = r.line();
  const std::vector<double> first = r.peek("record 7");
  // At most 1e6 integers: more than any dataset has, and the count must convert to an int.
  if (first.size() < 2 || first[0] < 2 || first[0] > 1e6 || first[0] != std::floor(first[0]))
    r.fail(ints_line,
           "record 7 must start with the number of integer values (at least 2: load case, mode number) and of real "
           "values");
  const std::vector<double> ints =
      r.whole_numbers(2 + static_cast<int>(first[0]), "record 7 (value counts, load case, mode number)", 8);
  const int num_reals = static_cast<int>(ints[1]);
  const int needed = kind.analysis == 2 ? 3 : 2;  // frequency..viscous damping, or the eigenvalue
  if (num_reals < needed)
    r.fail(ints_line, "record 7 gives " + std::to_string(num_reals) + " real values; " + analysis_name(kind.analysis) +
                          " need at least " + std::to_string(needed));
  m.mode.number = static_cast<int>(ints[3]);
  const std::vector<double> reals = r.numbers(
      num_reals,
      "record 8 (" + std::string(kind.analysis == 2 ? "frequency, modal mass, damping" : "eigenvalue, modal A and B") +
          ")",
      6);
  read_mode_header(reals, kind, 0, 0, 2, &m);
  m.mode.values_per_node = kind.values_per_node;
  read_node_values(r, kind, kind_line, &m);
  if (m.nodes.empty()) return "mode " + std::to_string(m.mode.number) + " has no node values";
  modes_.push_back(m);
  return "";
}

std::string UffReader::read_dataset_2414(UffRecords& r, const UffBlock& b) {
  PendingMode m;
  m.mode.dataset = 2414;
  m.mode.line = b.number_line;
  r.whole_numbers(1, "record 1 (analysis dataset label)");
  m.mode.description = trim(r.text("record 2 (analysis dataset name)"));
  const int location = static_cast<int>(r.whole_numbers(1, "record 3 (dataset location)")[0]);
  if (location != 1)
    return "data location " + std::to_string(location) +
           " (not at nodes: 2 on elements, 3 at element nodes, 5 at points)";
  for (int k = 1; k <= 5; ++k) r.text("ID line " + std::to_string(k));
  const int kind_line = r.line();
  const ResultKind kind = result_kind(r.whole_numbers(
      6, "record 9 (model type, analysis type, data characteristic, result type, data type, values per node)"));
  if (std::string reason = skip_reason(r, kind_line, kind); !reason.empty()) return reason;
  const std::vector<double> ints =
      r.whole_numbers(10,
                      "records 10-11 (design set, iteration, solution set, boundary condition, load set, mode, time "
                      "step, frequency, creation option, number retained)",
                      8);
  m.mode.number = static_cast<int>(ints[5]);
  const std::vector<double> reals = r.numbers(
      12, "records 12-13 (time, frequency, eigenvalue, modal mass, damping, complex eigenvalue, modal A and B)", 6);
  read_mode_header(reals, kind, 1, 6, 4, &m);
  // Some writers leave the frequency field empty and give the eigenvalue ω².
  if (kind.analysis == 2 && m.mode.frequency_hz == 0 && reals[2] > 0)
    m.mode.frequency_hz = std::sqrt(reals[2]) / (2 * M_PI);
  m.mode.values_per_node = kind.values_per_node;
  read_node_values(r, kind, kind_line, &m);
  if (m.nodes.empty()) return "mode " + std::to_string(m.mode.number) + " has no node values";
  modes_.push_back(m);
  return "";
}

void UffReader::resolve_nodes() {
  for (TestNode& node : data_.nodes) {
    const std::string user = "node " + std::to_string(node.id);
    const CoordinateSystem& def = cartesian_system(node.definition_system, user, node.dataset, node.line);
    node.coordinates = def.origin + def.axes.transpose() * node.coordinates;
    cartesian_system(node.displacement_system, user, node.dataset, node.line);
  }
}

/// Whether a complex mode has an imaginary part at all: exporters write real modes as complex
/// with zero imaginary parts, which are real as they are (no rotation to report).
bool has_imaginary_part(const PendingMode& m) {
  for (const std::vector<double>& values : m.values)
    for (size_t k = 1; k < values.size(); k += 2)
      if (values[k] != 0) return true;
  return false;
}

std::vector<Vector> UffReader::real_values(PendingMode& m) {
  const int n = m.mode.values_per_node;
  std::vector<Vector> real_values(m.nodes.size(), Vector(n));
  if (!m.is_complex) {
    for (size_t k = 0; k < m.nodes.size(); ++k) real_values[k] = Eigen::Map<const Vector>(m.values[k].data(), n);
    return real_values;
  }
  const std::string mode = "mode " + std::to_string(m.mode.number) + " (dataset " + std::to_string(m.mode.dataset) +
                           ", line " + std::to_string(m.mode.line) + ")";
  if (!has_imaginary_part(m)) {
    for (size_t k = 0; k < m.nodes.size(); ++k)
      for (int c = 0; c < n; ++c) real_values[k][c] = m.values[k][2 * c];
    if (!m.eigenvalue_note.empty()) data_.warnings.push_back(mode + ": " + m.eigenvalue_note);
    return real_values;
  }
  Eigen::VectorXcd shape(static_cast<Eigen::Index>(m.nodes.size() * n));
  for (size_t k = 0; k < m.nodes.size(); ++k)
    for (int c = 0; c < n; ++c)
      shape[static_cast<Eigen::Index>(k * n + c)] = {m.values[k][2 * c], m.values[k][2 * c + 1]};
  const RealShape real = best_real_shape(shape);
  for (size_t k = 0; k < m.nodes.size(); ++k) real_values[k] = real.values.segment(static_cast<Eigen::Index>(k * n), n);
  m.mode.from_complex = true;
  m.mode.phase_collinearity = real.collinearity;
  data_.warnings.push_back(mode + " is complex: made real by rotating it " +
                           number_text(real.rotation_rad * 180 / M_PI) +
                           "° to maximize its real part (least-squares best real approximation); phase collinearity "
                           "MPC = " + number_text(real.collinearity) + " (1 = real up to a phase)" +
                           (m.eigenvalue_note.empty() ? "" : "; " + m.eigenvalue_note));
  return real_values;
}

void UffReader::resolve_modes() {
  std::vector<long> without_geometry;
  for (PendingMode& m : modes_) {
    const int n = m.mode.values_per_node;
    const std::vector<Vector> real_values = this->real_values(m);
    for (size_t k = 0; k < m.nodes.size(); ++k) {
      const auto it = node_index_.find(m.nodes[k]);
      Mat3 to_global = Mat3::Identity();
      if (it == node_index_.end()) {
        if (std::find(without_geometry.begin(), without_geometry.end(), m.nodes[k]) == without_geometry.end())
          without_geometry.push_back(m.nodes[k]);
      } else {
        const TestNode& node = data_.nodes[it->second];
        to_global = cartesian_system(node.displacement_system, "node " + std::to_string(node.id), m.mode.dataset,
                                     m.node_lines[k])
                        .axes.transpose();
      }
      // Translations and rotations are both vectors in the displacement system.
      for (int part = 0; part < n; part += 3) {
        const Vec3 global = to_global * real_values[k].segment<3>(part);
        for (int c = 0; c < 3; ++c) m.mode.values.push_back({m.nodes[k], part + c, global[c]});
      }
    }
    std::sort(m.mode.values.begin(), m.mode.values.end(), [](const TestShapeValue& a, const TestShapeValue& b) {
      return a.node != b.node ? a.node < b.node : a.component < b.component;
    });
    data_.modes.push_back(m.mode);
  }
  number_modes_uniquely();
  if (without_geometry.empty()) return;
  std::string examples;
  for (size_t k = 0; k < std::min<size_t>(5, without_geometry.size()); ++k)
    examples += (k ? ", " : "") + std::to_string(without_geometry[k]);
  if (without_geometry.size() > 5) examples += ", ...";
  data_.warnings.push_back(data_.nodes.empty()
                               ? "the file has no node geometry (dataset 15 or 2411): shape values are taken as global "
                                 "components, and nodes can be mapped by id only"
                               : std::to_string(without_geometry.size()) +
                                     " node(s) with shape values have no geometry (dataset 15 or 2411): " + examples +
                                     "; their values are taken as global components");
}

void UffReader::number_modes_uniquely() {
  std::map<int, const TestMode*> first;
  for (const TestMode& m : data_.modes) {
    const auto [it, inserted] = first.try_emplace(m.number, &m);
    if (inserted) continue;
    // Modes are selected and written (CSV) by number, so numbers must identify them.
    data_.warnings.push_back("mode number " + std::to_string(m.number) + " is used twice (datasets at lines " +
                             std::to_string(it->second->line) + " and " + std::to_string(m.line) +
                             "); the modes are numbered 1.." + std::to_string(data_.modes.size()) +
                             " in file order instead");
    for (size_t k = 0; k < data_.modes.size(); ++k) data_.modes[k].number = static_cast<int>(k + 1);
    return;
  }
}

}  // namespace

TestData read_uff(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  if (!in) throw ProblemError(path, 0, "cannot open the test-data file '" + path + "'");
  const std::string text{std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()};
  if (in.bad()) throw ProblemError(path, 0, "cannot read the test-data file '" + path + "'");
  std::map<int, long> binary;
  const std::vector<std::string> lines = detail::uff_lines(text, &binary);
  return UffReader(path, lines, binary).read();
}

}  // namespace modalcal
