// Reads a problem file (docs/problem-format.md) into a Problem, checking everything it can
// against the file so that each mistake is reported at its line.
#include "modalcal/problem.hpp"

#include <algorithm>
#include <array>
#include <climits>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <functional>
#include <iomanip>
#include <iterator>
#include <limits>
#include <map>
#include <unordered_map>
#include <sstream>
#include <unistd.h>

#include <Eigen/Geometry>
#include <yaml-cpp/yaml.h>

#include "io/box_mesh.hpp"
#include "io/input_file.hpp"
#include "io/measured_test_data.hpp"
#include "support/text_util.hpp"
#include "modalcal/assembly.hpp"
#include "modalcal/mesh_file.hpp"
#include "modalcal/problem_file.hpp"

namespace modalcal {

namespace {

const std::vector<std::string> kInertiaKeys{"Ixx", "Iyy", "Izz"};
const std::vector<std::string> kDirections{"x", "y", "z"};

std::string quote(const std::string& s) { return "'" + detail::excerpt(s) + "'"; }

bool ends_with(const std::string& s, const std::string& end) {
  return s.size() >= end.size() && s.compare(s.size() - end.size(), end.size(), end) == 0;
}

std::string join(const std::vector<std::string>& items) {
  std::string out;
  for (const std::string& item : items) out += (out.empty() ? "" : ", ") + item;
  return out;
}

std::string format(double v) {
  std::ostringstream s;
  s << std::setprecision(10) << v;
  return s.str();
}

std::string format(const Vec3& v) {
  return "[" + format(v[0]) + ", " + format(v[1]) + ", " + format(v[2]) + "]";
}

/// A size for messages, in 3 significant digits ("1.2e+06").
std::string rounded(double v) {
  char text[32];
  std::snprintf(text, sizeof text, "%.3g", v);
  return text;
}

/// The memory the forward solve of a model with `dofs` degrees of freedom needs, about: the
/// sparse factorization's fill grows like dofs^(4/3) on a 3D mesh (measured: 15 KB per DOF at
/// 14 000 DOFs, 14 KB at 66 000, hex8; the estimate errs above).
double estimated_solve_bytes(double dofs) { return 1e4 * dofs * std::max(1.0, std::cbrt(dofs / 1e4)); }

double physical_memory_bytes() {
  const long pages = ::sysconf(_SC_PHYS_PAGES), page_size = ::sysconf(_SC_PAGESIZE);
  return pages > 0 && page_size > 0 ? static_cast<double>(pages) * static_cast<double>(page_size)
                                     : std::numeric_limits<double>::infinity();
}

/// Ends an "unknown ..." message: "known node sets: a, b" or "no node sets are defined".
std::string known(const std::string& plural, const std::vector<std::string>& names) {
  return names.empty() ? "no " + plural + " are defined" : "known " + plural + ": " + join(names);
}

std::string describe(const YAML::Node& node) {
  switch (node.Type()) {
    case YAML::NodeType::Scalar:
      return quote(node.Scalar());
    case YAML::NodeType::Sequence:
      return "a list of " + std::to_string(node.size()) + " items";
    case YAML::NodeType::Map:
      return "a map";
    default:
      return "nothing";
  }
}

std::vector<std::string> with_stiffness(std::vector<std::string> keys) {
  keys.insert(keys.end(), kStiffnessComponentNames.begin(), kStiffnessComponentNames.end());
  return keys;
}

bool contains(const std::vector<std::string>& names, const std::string& name) {
  return std::find(names.begin(), names.end(), name) != names.end();
}

/// A value in the file with what it belongs to, for messages.
struct Field {
  std::string what;  ///< the entity it is part of, e.g. "parameter 'kx'"; empty at top level
  std::string key;
  YAML::Node node;
  int line = 0;  ///< of the key: a null value's own mark points past it
  int item = 0;  ///< 1-based position in a list, 0 if not a list item

  std::string name() const {
    return item ? "item " + std::to_string(item) + " of " + quote(key) : quote(key);
  }
};

/// The checked keys of one map.
struct Fields {
  std::string what;
  int line = 0;
  std::vector<Field> items;

  const Field* find(const std::string& key) const {
    for (const Field& f : items)
      if (f.key == key) return &f;
    return nullptr;
  }
};

enum class EntityKind { Block, Joint, Spring, PointMass };

std::string kind_name(EntityKind kind) {
  const char* const names[] = {"block", "joint", "spring", "point mass"};
  return names[static_cast<int>(kind)];
}

struct Entity {
  EntityKind kind;
  int index;  ///< into the Model's vector of that kind
  int line;
  std::string file;  ///< the file it is defined in (a problem may extend another file)
};

/// Where something was written: the file and line.
struct Location {
  std::string file;
  int line = 0;
};

/// Reads a YAML file; `what` names it in messages ("problem file", "data file").
YAML::Node parse(const std::string& path, const std::string& what);

class Loader {
 public:
  Loader(const std::string& path, const LoadOptions& options, Problem& problem)
      : path_(path), current_file_(path), options_(options), problem_(problem), model_(problem.model) {}

  /// Reads `root`; sections it lacks come from the files it extends (`bases`, nearest first:
  /// the file `extends` names, then the one that file extends, ...).
  void load(const YAML::Node& root, const std::vector<std::pair<YAML::Node, std::string>>& bases);

 private:
  [[noreturn]] void fail_at(int line, const std::string& what, const std::string& message) const {
    throw ProblemError(current_file_, line, what.empty() ? message : what + ": " + message);
  }
  [[noreturn]] void fail(const Field& f, const std::string& message) const {
    fail_at(f.line, f.what, message);
  }
  [[noreturn]] void fail(const Fields& fs, const std::string& message) const {
    fail_at(fs.line, fs.what, message);
  }

  std::vector<Field> entries(const Field& f, const std::string& what) const;
  Fields map_of(const Field& f, const std::string& what,
                const std::vector<std::string>& allowed) const;
  std::vector<Field> named(const Field& f, const std::string& kind) const;
  std::vector<Field> list(const Field& f) const;
  const Field& required(const Fields& fs, const std::string& key) const;
  const Field& exactly_one(const Fields& fs, const std::vector<std::string>& keys) const;
  double number(const Field& f) const;
  double positive(const Field& f) const;
  double non_negative(const Field& f) const;
  long integer(const Field& f) const;
  int integer_in(const Field& f, int lo, int hi) const;
  bool boolean(const Field& f) const;
  std::string text(const Field& f) const;
  Vec3 vec3(const Field& f) const;
  int choice(const Field& f, const std::vector<std::string>& options) const;

  void read_blocks(const Field& f);
  void read_mesh(const Field& f);
  void read_box_mesh(const Fields& fs);
  void read_mesh_file(const Fields& fs);
  void check_free_dofs();
  void check_mesh_size(double nodes, double extra_bytes, const Field& at, const std::string& remedy) const;
  void add_mesh_node(long id, const Vec3& x);
  void finish_mesh();
  void read_reference_nodes(const Field& f);
  void read_node_sets(const Field& f);
  void read_rigid_couplings(const Field& f);
  void read_joints(const Field& f);
  void read_springs(const Field& f);
  void read_point_masses(const Field& f);
  void read_fixed(const Field& f);
  void read_mode_families(const Field& f);
  void read_parameters(const Field& f);
  void read_sensors(const Field& f);
  void read_options(const Field& f);
  void read_measured(const Field& f);
  void read_effects(const Field& f);
  void read_measured_file(const Field& f);
  void read_data_sensors(const Field& f);
  SyntheticTruth recorded_truth(const Field& f);
  MeasurementNoise recorded_noise(const Field& f) const;

  std::function<bool(const Vec3&)> region(const Field& how) const;
  Mat3 frame(const Field& f) const;
  std::array<PropertyId, 6> stiffness(const std::string& entity, const Fields& fs);
  MeasuredMode measured_mode(const Field& item, bool in_data_file) const;
  PairingRule pairing(const Field& f, bool has_shape) const;
  void check_computed(const Field& f, int mode) const;
  SyntheticSpec synthetic(const Field& f) const;
  detail::TestDataSelection test_data(const Field& f) const;

  int block_index(const Field& f) const;
  const NodeSet& node_set(const Field& f) const;
  int reference_node(const Field& f) const;
  int node_by_id(const Field& f) const;
  int node(const Field& f) const;
  int nearest_node(const Field& at, double tolerance) const;
  /// How far a sensor placed at a point may lie from its node: 1e-6 of the model's size, or any
  /// distance for a refined copy of a problem (LoadOptions::nearest_sensor_nodes).
  double sensor_tolerance() const {
    return options_.nearest_sensor_nodes ? std::numeric_limits<double>::infinity() : 1e-6 * model_size_;
  }
  PropertyId target(const Field& f);
  PropertyId add_property(const std::string& name, const Field& source, double value);
  void add_entity(const Field& entry, EntityKind kind, size_t index);
  Location location_of_model_error(const std::string& message) const;

  std::string path_;
  std::string current_file_;  ///< file of the section being read, for messages
  LoadOptions options_;
  Problem& problem_;
  Model& model_;
  int num_mesh_nodes_ = 0;
  std::unordered_map<long, int> node_of_id_;  ///< external id -> node index
  long next_node_id_ = 1;                     ///< for reference nodes: after every mesh id
  Vec3 mesh_min_ = Vec3::Zero(), mesh_max_ = Vec3::Zero();
  double model_size_ = 0;  ///< bounding-box diagonal of the mesh
  std::map<std::string, int> reference_nodes_;
  std::map<std::string, Entity> entities_;
  /// "block 'foam'" -> location: Model::validate names entities this way but knows no lines.
  std::map<std::string, Location> locations_;
  Location fixed_at_, num_modes_at_;  ///< of the sections check_free_dofs names
};

std::vector<Field> Loader::entries(const Field& f, const std::string& what) const {
  std::vector<Field> out;
  for (const auto& kv : f.node) {
    const int line = kv.first.Mark().line + 1;
    if (!kv.first.IsScalar())
      fail_at(line, what,
              "keys must be plain names, got " + describe(kv.first) + " in " + f.name());
    for (const Field& other : out)
      if (other.key == kv.first.Scalar())
        fail_at(line, what,
                quote(other.key) + " is given twice in " + f.name() + " (first at line " +
                    std::to_string(other.line) + "); keys and names must be unique");
    out.push_back({what, kv.first.Scalar(), kv.second, line, 0});
  }
  return out;
}

Fields Loader::map_of(const Field& f, const std::string& what,
                      const std::vector<std::string>& allowed) const {
  if (!f.node.IsMap())
    fail(f, "expected a map (key: value pairs) for " + f.name() + ", got " + describe(f.node));
  Fields fs{what, f.line, entries(f, what)};
  for (const Field& item : fs.items)
    if (!contains(allowed, item.key))
      fail(item, "unknown key " + quote(item.key) + "; allowed keys: " + join(allowed));
  return fs;
}

std::vector<Field> Loader::named(const Field& f, const std::string& kind) const {
  if (!f.node.IsMap())
    fail(f, "expected a map of " + kind + " names to their definitions for " + f.name() + ", got " +
                describe(f.node));
  std::vector<Field> out = entries(f, f.what);
  for (Field& entry : out) entry.what = kind + " " + quote(entry.key);
  return out;
}

std::vector<Field> Loader::list(const Field& f) const {
  if (!f.node.IsSequence())
    fail(f, "expected a list for " + f.name() + ", got " + describe(f.node));
  std::vector<Field> out;
  for (const YAML::Node& item : f.node) {
    const YAML::Mark mark = item.Mark();
    out.push_back({f.what, f.key, item, mark.is_null() ? f.line : mark.line + 1,
                   static_cast<int>(out.size()) + 1});
  }
  return out;
}

const Field& Loader::required(const Fields& fs, const std::string& key) const {
  const Field* f = fs.find(key);
  if (!f) fail(fs, "missing required key " + quote(key));
  return *f;
}

const Field& Loader::exactly_one(const Fields& fs, const std::vector<std::string>& keys) const {
  const Field* found = nullptr;
  for (const Field& f : fs.items) {
    if (!contains(keys, f.key)) continue;
    if (found)
      fail(f, "give only one of " + join(keys) + ", not both " + quote(found->key) + " and " +
                  quote(f.key));
    found = &f;
  }
  if (!found) fail(fs, "needs one of " + join(keys));
  return *found;
}

double Loader::number(const Field& f) const {
  double v = 0;
  if (!f.node.IsScalar() || !YAML::convert<double>::decode(f.node, v))
    fail(f, "expected a number for " + f.name() + ", got " + describe(f.node));
  if (!std::isfinite(v))
    fail(f,
         f.name() + " is " + (std::isnan(v) ? "NaN" : "infinite") + "; expected a finite number");
  return v;
}

double Loader::positive(const Field& f) const {
  const double v = number(f);
  if (!(v > 0)) fail(f, f.name() + " must be positive, got " + format(v));
  return v;
}

double Loader::non_negative(const Field& f) const {
  const double v = number(f);
  if (v < 0) fail(f, f.name() + " must not be negative, got " + format(v));
  return v;
}

long Loader::integer(const Field& f) const {
  long v = 0;
  if (!f.node.IsScalar() || !YAML::convert<long>::decode(f.node, v))
    fail(f, "expected a whole number for " + f.name() + ", got " + describe(f.node));
  return v;
}

int Loader::integer_in(const Field& f, int lo, int hi) const {
  const long v = integer(f);
  if (v < lo || v > hi)
    fail(f, f.name() + " must be " +
                (hi == INT_MAX ? "at least " + std::to_string(lo)
                               : "between " + std::to_string(lo) + " and " + std::to_string(hi)) +
                ", got " + std::to_string(v));
  return static_cast<int>(v);
}

bool Loader::boolean(const Field& f) const {
  bool v = false;
  if (!f.node.IsScalar() || !YAML::convert<bool>::decode(f.node, v))
    fail(f, "expected true or false for " + f.name() + ", got " + describe(f.node));
  return v;
}

std::string Loader::text(const Field& f) const {
  if (!f.node.IsScalar())
    fail(f, "expected a text value for " + f.name() + ", got " + describe(f.node));
  return f.node.Scalar();
}

Vec3 Loader::vec3(const Field& f) const {
  if (!f.node.IsSequence() || f.node.size() != 3)
    fail(f, "expected a list of 3 numbers [x, y, z] for " + f.name() + ", got " + describe(f.node));
  const std::vector<Field> items = list(f);
  return {number(items[0]), number(items[1]), number(items[2])};
}

int Loader::choice(const Field& f, const std::vector<std::string>& options) const {
  const std::string value = text(f);
  for (size_t i = 0; i < options.size(); ++i)
    if (options[i] == value) return static_cast<int>(i);
  fail(f, "expected one of " + join(options) + " for " + f.name() + ", got " + quote(value));
}

void Loader::load(const YAML::Node& root, const std::vector<std::pair<YAML::Node, std::string>>& bases) {
  const std::vector<std::string> keys = {
      "name", "description", "units", "extends", "mesh", "blocks", "node_sets", "reference_nodes",
      "rigid_couplings", "joints", "springs", "point_masses", "fixed", "mode_families",
      "parameters", "sensors", "measured", "options", "effects"};
  auto sections_of = [&](const YAML::Node& node) {
    if (!node.IsMap())
      fail_at(1, "", "expected a map of the problem's sections (mesh, blocks, ...), got " + describe(node));
    return map_of({"", "", node, 1, 0}, "", keys);
  };
  Fields top = sections_of(root);
  // A section the file itself gives replaces the base file's whole section.
  std::map<std::string, std::string> file_of;
  for (const Field& f : top.items) file_of[f.key] = path_;
  for (const auto& [base, base_path] : bases) {
    current_file_ = base_path;
    const Fields inherited = sections_of(base);
    for (const Field& f : inherited.items) {
      // A base's own name and description are not inherited, but must be what they claim to be.
      if (f.key == "name" || f.key == "description") text(f);
      if (!top.find(f.key) && f.key != "name" && f.key != "description" && f.key != "extends") {
        top.items.push_back(f);
        file_of[f.key] = base_path;
      }
    }
    current_file_ = path_;
  }
  auto enter = [&](const Field& f) { current_file_ = file_of.at(f.key); };
  const Field* name = top.find("name");
  problem_.name = name ? text(*name) : std::filesystem::path(path_).stem().string();
  if (const Field* f = top.find("description")) problem_.description = text(*f);
  if (const Field* f = top.find("units")) {
    enter(*f);
    problem_.units = text(*f);
  }

  // Each section only refers to sections read before it.
  using Section = void (Loader::*)(const Field&);
  const std::pair<const char*, Section> sections[] = {
      {"reference_nodes", &Loader::read_reference_nodes},
      {"node_sets", &Loader::read_node_sets},
      {"rigid_couplings", &Loader::read_rigid_couplings},
      {"joints", &Loader::read_joints},
      {"springs", &Loader::read_springs},
      {"point_masses", &Loader::read_point_masses},
      {"fixed", &Loader::read_fixed},
      {"mode_families", &Loader::read_mode_families},
      {"parameters", &Loader::read_parameters},
      {"sensors", &Loader::read_sensors},
      {"options", &Loader::read_options},
      {"measured", &Loader::read_measured}};
  const Field& blocks = required(top, "blocks");
  const Field& mesh = required(top, "mesh");
  enter(blocks);
  read_blocks(blocks);
  enter(mesh);
  read_mesh(mesh);
  for (const auto& [key, read] : sections)
    if (const Field* f = top.find(key)) {
      enter(*f);
      (this->*read)(*f);
    }

  try {
    model_.validate();
  } catch (const std::invalid_argument& e) {
    const Location at = location_of_model_error(e.what());
    throw ProblemError(at.file.empty() ? path_ : at.file, at.line, e.what());
  }
  check_free_dofs();
  // Effects act on the finished model.
  if (const Field* f = top.find("effects")) {
    enter(*f);
    read_effects(*f);
  }
}

void Loader::read_blocks(const Field& f) {
  for (const Field& entry : named(f, "block")) {
    const Fields fs = map_of(entry, entry.what,
                             {"E", "nu", "K", "G", "density", "stiffness_scale", "mass_scale"});
    add_entity(entry, EntityKind::Block, model_.blocks.size());
    ElementBlock b;
    b.name = entry.key;
    const bool young = fs.find("E") || fs.find("nu");
    if (young == (fs.find("K") || fs.find("G")))
      fail(entry,
           "give either E and nu (Young's modulus and Poisson's ratio) or K and G (bulk "
           "and shear modulus)");
    b.form = young ? ElasticForm::YoungPoisson : ElasticForm::BulkShear;
    const Field& a = required(fs, young ? "E" : "K");
    const Field& m = required(fs, young ? "nu" : "G");
    const Field& rho = required(fs, "density");
    b.modulus_a = add_property(b.name + "." + a.key, a, positive(a));
    b.modulus_b = add_property(b.name + "." + m.key, m, young ? number(m) : positive(m));
    b.density = add_property(b.name + ".density", rho, non_negative(rho));
    if (const Field* s = fs.find("stiffness_scale"))
      b.stiffness_scale = add_property(b.name + ".stiffness_scale", *s, positive(*s));
    if (const Field* s = fs.find("mass_scale"))
      b.mass_scale = add_property(b.name + ".mass_scale", *s, positive(*s));
    model_.blocks.push_back(b);
  }
}

void Loader::read_mesh(const Field& f) {
  const Fields fs = map_of(f, "mesh", {"element", "element_size", "refinement", "boxes", "file", "format", "scale"});
  if (fs.find("file")) {
    read_mesh_file(fs);
  } else {
    for (const char* key : {"format", "scale"})
      if (const Field* k = fs.find(key)) fail(*k, quote(key) + " applies only to a mesh read from a 'file'");
    read_box_mesh(fs);
  }
  finish_mesh();
}

void Loader::read_box_mesh(const Fields& fs) {
  SolidType type = SolidType::Hex8;
  if (const Field* e = fs.find("element")) {
    const std::vector<SolidType> types{SolidType::Hex8, SolidType::Tet4, SolidType::Tet10};
    std::vector<std::string> names;
    for (SolidType t : types) names.push_back(solid_type_name(t));
    type = types[choice(*e, names)];
  }
  const double element_size = positive(required(fs, "element_size"));
  const Field* file_refinement = fs.find("refinement");
  double refinement = file_refinement ? positive(*file_refinement) : 1.0;
  if (options_.refinement > 0) refinement = options_.refinement;
  problem_.mesh_refinement = refinement;

  const Field& boxes_field = required(fs, "boxes");
  std::vector<detail::MeshBox> boxes;
  std::vector<int> box_lines;
  for (const Field& item : list(boxes_field)) {
    const Fields b = map_of(item, "mesh box " + std::to_string(item.item), {"block", "min", "max"});
    detail::MeshBox box;
    box.block = block_index(required(b, "block"));
    const Field& min = required(b, "min");
    box.min = vec3(min);
    box.max = vec3(required(b, "max"));
    for (int axis = 0; axis < 3; ++axis)
      if (!(box.min[axis] < box.max[axis]))
        fail(min, "min " + format(box.min) + " must be below max " + format(box.max) +
                      " along every axis, but is not along " + kDirections[axis]);
    for (size_t k = 0; k < boxes.size(); ++k)
      if (detail::boxes_overlap(boxes[k], box))
        fail(b, "overlaps mesh box " + std::to_string(k + 1) + " (line " +
                    std::to_string(box_lines[k]) + "); boxes may share faces but not volume");
    boxes.push_back(box);
    box_lines.push_back(item.line);
  }
  if (boxes.empty()) fail(boxes_field, "'boxes' is empty; the mesh needs at least one box");

  const detail::BoxMeshSize size = detail::estimate_box_mesh(boxes, type, element_size, refinement);
  check_mesh_size(size.nodes, 4 * size.grid_points, file_refinement ? *file_refinement : required(fs, "element_size"),
                  options_.refinement > 0 ? "use a smaller refinement (--refine " + format(refinement) + ")"
                                          : "use a larger element_size or a smaller refinement");
  const detail::BoxMesh mesh = detail::generate_box_mesh(
      boxes, static_cast<int>(model_.blocks.size()), type, element_size, refinement);
  for (size_t i = 0; i < mesh.coordinates.size(); ++i) add_mesh_node(static_cast<long>(i) + 1, mesh.coordinates[i]);
  for (size_t k = 0; k < model_.blocks.size(); ++k) {
    ElementBlock& block = model_.blocks[k];
    if (mesh.connectivity[k].empty()) {
      current_file_ = entities_.at(block.name).file;
      fail_at(entities_.at(block.name).line, "block " + quote(block.name),
              "no mesh box uses this block; add a box for it or remove it");
    }
    block.type = type;
    block.connectivity = mesh.connectivity[k];
  }
}

// A mesh made by another program: its blocks get the materials of the problem's blocks of the
// same name, its node sets join the problem's.
void Loader::read_mesh_file(const Fields& fs) {
  for (const char* key : {"element", "element_size", "refinement", "boxes"})
    if (const Field* k = fs.find(key))
      fail(*k, quote(key) + " applies only to a generated mesh ('boxes'); a mesh read from a 'file' is used as it is");
  const Field& file = required(fs, "file");
  if (options_.refinement > 0)
    fail(file, "refinement (--refine) applies only to a generated mesh ('boxes'); this mesh is read from " +
                   quote(text(file)) + " (remesh it finer instead)");
  std::optional<MeshFileFormat> mesh_format;
  if (const Field* f = fs.find("format"))
    mesh_format = choice(*f, {"gmsh", "exodus"}) == 0 ? MeshFileFormat::Gmsh : MeshFileFormat::Exodus;
  const double scale = fs.find("scale") ? positive(*fs.find("scale")) : 1.0;
  const std::string path = (std::filesystem::path(current_file_).parent_path() / text(file)).string();
  MeshFile mesh;
  problem_.source_files.push_back(path);
  try {
    mesh = modalcal::read_mesh_file(path, mesh_format);
  } catch (const ProblemError& e) {
    fail(file, std::string(e.what()) + (e.message() == "no such mesh file" ? " (the path is relative to this file's folder)" : ""));
  }
  check_mesh_size(mesh.num_nodes(), 0, file, "remesh it coarser");
  for (int v = 0; v < mesh.num_nodes(); ++v) add_mesh_node(mesh.node_ids[v], scale * mesh.coordinates[v]);

  std::vector<std::string> file_blocks;
  for (const MeshFileBlock& b : mesh.blocks) file_blocks.push_back(b.name);
  for (ElementBlock& block : model_.blocks) {
    const MeshFileBlock* from = mesh.find_block(block.name);
    if (!from) {
      current_file_ = entities_.at(block.name).file;
      fail_at(entities_.at(block.name).line, "block " + quote(block.name),
              "mesh file " + quote(path) + " has no block of this name; " + known("blocks", file_blocks));
    }
    block.type = from->type;
    block.connectivity = from->connectivity;
  }
  for (const MeshFileBlock& b : mesh.blocks)
    if (std::none_of(model_.blocks.begin(), model_.blocks.end(), [&](const ElementBlock& m) { return m.name == b.name; }))
      fail(file, "mesh file " + quote(path) + " has block " + quote(b.name) + " (id " + std::to_string(b.id) + ", " +
                     std::to_string(b.num_elements()) + " " + solid_type_name(b.type) +
                     " elements), which 'blocks' gives no material; add " + b.name + ": {E: ..., nu: ..., density: ...}");
  for (const MeshFileNodeSet& set : mesh.node_sets) model_.node_sets.push_back({set.name, set.nodes});
  for (const std::string& warning : mesh.warnings) problem_.warnings.push_back(warning);
}

// The modal solver needs free DOFs, and at least as many as the modes it is asked for: a model
// without them is a mistake in the file, named here at its section rather than by the solver.
void Loader::check_free_dofs() {
  const int free = DofMap(model_).num_free();
  if (free == 0) {
    current_file_ = fixed_at_.file.empty() ? path_ : fixed_at_.file;
    fail_at(fixed_at_.line, "fixed", "the supports and couplings leave no degree of freedom free: nothing can vibrate");
  }
  const int rigid = problem_.expected_rigid_modes(), wanted = problem_.options.num_modes + rigid;
  // The default num_modes matters only to a problem meant to be solved: one given its modes or data.
  const bool meant = num_modes_at_.line > 0 || !problem_.measured.empty() || problem_.synthetic;
  if (wanted <= free || !meant) return;
  current_file_ = num_modes_at_.file.empty() ? path_ : num_modes_at_.file;
  fail_at(num_modes_at_.line, "options",
          "num_modes " + std::to_string(problem_.options.num_modes) +
              (num_modes_at_.line ? "" : " (the default)") +
              (rigid ? " and up to " + std::to_string(rigid) + " rigid-body modes" : "") + " ask for " +
              std::to_string(wanted) + " modes, but the model has only " + std::to_string(free) +
              " free DOFs; lower options.num_modes or refine the mesh");
}

// Refuses, before it is made, a mesh whose modal solve would exhaust the memory (or overflow the
// indices): such a run would otherwise grow for minutes and end killed, without a word.
void Loader::check_mesh_size(double nodes, double extra_bytes, const Field& at, const std::string& remedy) const {
  constexpr double kMostNodes = 1e8;  // 3 DOFs each must index an int, with room to spare
  const double dofs = 3 * nodes, bytes = estimated_solve_bytes(dofs) + extra_bytes,
               memory = options_.memory_bytes > 0 ? options_.memory_bytes : physical_memory_bytes();
  if (nodes <= kMostNodes && bytes <= memory) return;
  fail(at, "not enough memory for a mesh of about " + rounded(nodes) + " nodes (" + rounded(dofs) +
               " DOFs): its modal solve needs an estimated " + rounded(bytes / 1e9) + " GB and " +
           (options_.memory_bytes > 0 ? "the memory allowed is " : "this machine has ") +
           rounded(memory / 1e9) + " GB; " + remedy);
}

void Loader::add_mesh_node(long id, const Vec3& x) {
  node_of_id_[id] = model_.add_node(id, x);
  next_node_id_ = std::max(next_node_id_, id + 1);
}

void Loader::finish_mesh() {
  num_mesh_nodes_ = model_.num_nodes();
  mesh_min_ = mesh_max_ = model_.coordinates.front();
  for (const Vec3& x : model_.coordinates) {
    mesh_min_ = mesh_min_.cwiseMin(x);
    mesh_max_ = mesh_max_.cwiseMax(x);
  }
  model_size_ = (mesh_max_ - mesh_min_).norm();
}

void Loader::read_reference_nodes(const Field& f) {
  for (const Field& entry : named(f, "reference node")) {
    // Ids continue after the mesh's, so every node keeps the id it is created with.
    const long id = next_node_id_++;
    reference_nodes_[entry.key] = node_of_id_[id] = model_.add_node(id, vec3(entry), true);
  }
}

void Loader::read_node_sets(const Field& f) {
  for (const Field& entry : named(f, "node set")) {
    const Fields fs = map_of(entry, entry.what, {"box", "sphere", "nodes", "block"});
    if (model_.find_node_set(entry.key))
      fail(entry, "a node set " + quote(entry.key) + " is already defined by the mesh file; choose another name");
    const Field& how = exactly_one(fs, {"box", "sphere", "nodes"});
    const Field* block = fs.find("block");
    NodeSet set{entry.key, {}};
    if (how.key == "nodes") {
      if (block) fail(*block, "'block' restricts only 'box' and 'sphere' selections");
      for (const Field& id : list(how)) set.nodes.push_back(node_by_id(id));
    } else {
      // Geometric selections take mesh nodes only: a reference node placed on a face must
      // not end up rigidly coupled or fixed along with it.
      std::vector<bool> candidate(num_mesh_nodes_, block == nullptr);
      if (block)
        for (int v : model_.blocks[block_index(*block)].connectivity) candidate[v] = true;
      const auto inside = region(how);
      for (int v = 0; v < num_mesh_nodes_; ++v)
        if (candidate[v] && inside(model_.coordinates[v])) set.nodes.push_back(v);
    }
    std::sort(set.nodes.begin(), set.nodes.end());
    set.nodes.erase(std::unique(set.nodes.begin(), set.nodes.end()), set.nodes.end());
    if (set.nodes.empty())
      fail(entry, "selects no nodes; check the coordinates against the mesh bounds " +
                      format(mesh_min_) + " to " + format(mesh_max_) +
                      (block ? " and the block " + quote(text(*block)) : ""));
    model_.node_sets.push_back(set);
  }
}

std::function<bool(const Vec3&)> Loader::region(const Field& how) const {
  // Bounds are inclusive up to rounding in the generated coordinates.
  const double tolerance = 1e-9 * model_size_;
  if (how.key == "box") {
    const Fields b = map_of(how, how.what, {"min", "max"});
    const Field& min = required(b, "min");
    const Vec3 lo = vec3(min), hi = vec3(required(b, "max"));
    if (!(lo.array() <= hi.array()).all())
      fail(min, "min " + format(lo) + " must not exceed max " + format(hi) + " along any axis");
    return [=](const Vec3& x) {
      return (x.array() >= lo.array() - tolerance).all() &&
             (x.array() <= hi.array() + tolerance).all();
    };
  }
  const Fields s = map_of(how, how.what, {"center", "radius"});
  const Vec3 center = vec3(required(s, "center"));
  const double radius = positive(required(s, "radius"));
  return [=](const Vec3& x) { return (x - center).norm() <= radius + tolerance; };
}

void Loader::read_rigid_couplings(const Field& f) {
  for (const Field& item : list(f)) {
    const Fields fs =
        map_of(item, "rigid coupling " + std::to_string(item.item), {"reference", "node_set"});
    const Field& reference = required(fs, "reference");
    RigidCoupling r;
    r.reference = reference_node(reference);
    const NodeSet& set = node_set(required(fs, "node_set"));
    r.nodes = set.nodes;
    r.name = set.name + " to " + text(reference);
    locations_.emplace("rigid coupling " + quote(r.name), Location{current_file_, item.line});
    model_.rigid_couplings.push_back(r);
  }
}

void Loader::read_joints(const Field& f) {
  for (const Field& entry : named(f, "joint")) {
    const Fields fs = map_of(entry, entry.what, with_stiffness({"nodes", "frame"}));
    add_entity(entry, EntityKind::Joint, model_.joints.size());
    Joint j;
    j.name = entry.key;
    const Field& nodes = required(fs, "nodes");
    const std::vector<Field> ends = list(nodes);
    if (ends.size() != 2)
      fail(nodes, "expected 2 nodes for 'nodes', got " + std::to_string(ends.size()));
    j.node_a = node(ends[0]);
    j.node_b = node(ends[1]);
    if (const Field* fr = fs.find("frame")) j.frame = frame(*fr);
    j.stiffness = stiffness(j.name, fs);
    model_.joints.push_back(j);
  }
}

Mat3 Loader::frame(const Field& f) const {
  const Fields fs = map_of(f, f.what, {"x", "y"});
  Mat3 m;
  for (int r = 0; r < 2; ++r) {
    const Field& axis = required(fs, kDirections[r]);
    const Vec3 v = vec3(axis);
    if (v.norm() == 0) fail(axis, "the frame's " + kDirections[r] + " axis is zero");
    m.row(r) = v.normalized();
  }
  const double cosine = m.row(0).dot(m.row(1));
  if (std::abs(cosine) > 1e-8)
    fail(f, "frame axes x and y must be perpendicular, but the cosine of their angle is " +
                format(cosine));
  m.row(2) = m.row(0).cross(m.row(1));
  return m;
}

std::array<PropertyId, 6> Loader::stiffness(const std::string& entity, const Fields& fs) {
  std::array<PropertyId, 6> ids;
  ids.fill(kNoProperty);
  for (int c = 0; c < 6; ++c)
    if (const Field* k = fs.find(kStiffnessComponentNames[c]))
      ids[c] = add_property(entity + "." + k->key, *k, non_negative(*k));
  return ids;
}

void Loader::read_springs(const Field& f) {
  for (const Field& entry : named(f, "spring")) {
    const Fields fs = map_of(entry, entry.what, with_stiffness({"node_set"}));
    add_entity(entry, EntityKind::Spring, model_.ground_springs.size());
    GroundSpring s;
    s.name = entry.key;
    s.nodes = node_set(required(fs, "node_set")).nodes;
    s.stiffness = stiffness(s.name, fs);
    model_.ground_springs.push_back(s);
  }
}

void Loader::read_point_masses(const Field& f) {
  for (const Field& entry : named(f, "point mass")) {
    const Fields fs = map_of(entry, entry.what, {"node", "mass", "inertia"});
    add_entity(entry, EntityKind::PointMass, model_.point_masses.size());
    PointMass m;
    m.name = entry.key;
    m.node = node(required(fs, "node"));
    const Field& mass = required(fs, "mass");
    m.mass = add_property(m.name + ".mass", mass, non_negative(mass));
    if (const Field* inertia = fs.find("inertia")) {
      const std::vector<Field> items = list(*inertia);
      if (items.size() != 3)
        fail(*inertia, "expected 3 values [Ixx, Iyy, Izz] for 'inertia', got " +
                           std::to_string(items.size()));
      for (int c = 0; c < 3; ++c)
        m.inertia[c] =
            add_property(m.name + "." + kInertiaKeys[c], items[c], non_negative(items[c]));
    }
    model_.point_masses.push_back(m);
  }
}

void Loader::read_fixed(const Field& f) {
  fixed_at_ = {current_file_, f.line};
  std::vector<std::string> dof_names;
  for (int c = 0; c < 6; ++c) dof_names.push_back(component_name(c));
  for (const Field& item : list(f)) {
    const Fields fs = map_of(item, "fixed " + std::to_string(item.item), {"node_set", "dofs"});
    const NodeSet& set = node_set(required(fs, "node_set"));
    FixedDofs fixed;
    fixed.name = set.name;
    fixed.nodes = set.nodes;
    const Field& dofs = required(fs, "dofs");
    const std::vector<Field> items = list(dofs);
    if (items.empty()) fail(dofs, "'dofs' is empty; list any of " + join(dof_names));
    for (const Field& dof : items) {
      const int c = choice(dof, dof_names);
      fixed.components[c] = true;
      if (c < 3) continue;
      for (int v : set.nodes)
        if (!model_.has_rotations[v])
          fail(dof, "node " + std::to_string(model_.node_ids[v]) + " of node set " +
                        quote(set.name) + " has no rotations to fix (only reference nodes do)");
    }
    locations_.emplace("fixed " + quote(fixed.name), Location{current_file_, item.line});
    model_.fixed.push_back(fixed);
  }
}

void Loader::read_mode_families(const Field& f) {
  for (const Field& entry : named(f, "mode family")) {
    model_.mode_families[entry.key] = choice(entry, kDirections);
    locations_[entry.what] = {current_file_, entry.line};
  }
}

void Loader::read_parameters(const Field& f) {
  std::map<PropertyId, std::string> owner;
  for (const Field& entry : named(f, "parameter")) {
    const Fields fs =
        map_of(entry, entry.what,
               {"targets", "initial", "lower", "upper", "scaling", "reference", "truth"});
    Parameter p;
    p.name = entry.key;
    const Field& targets = required(fs, "targets");
    const std::vector<Field> names =
        targets.node.IsScalar() ? std::vector<Field>{targets} : list(targets);
    if (names.empty())
      fail(targets,
           "'targets' is empty; give one or more <entity>.<property> names, e.g. joint1.kx");
    for (const Field& t : names) {
      const PropertyId id = target(t);
      const auto [it, inserted] = owner.try_emplace(id, p.name);
      if (!inserted)
        fail(t, "target " + quote(model_.properties[id].name) +
                    (it->second == p.name ? " is listed twice"
                                          : " is already set by parameter " + quote(it->second) +
                                                "; a property can belong to one parameter only"));
      p.targets.push_back(id);
    }

    const Field& lower = required(fs, "lower");
    const Field& upper = required(fs, "upper");
    const Field& initial = required(fs, "initial");
    p.lower = number(lower);
    p.upper = number(upper);
    p.initial = number(initial);
    if (!(p.lower < p.upper))
      fail(lower,
           "lower bound " + format(p.lower) + " must be below the upper bound " + format(p.upper));
    const auto check_within = [&](const Field& value_field, double value) {
      if (value < p.lower || value > p.upper)
        fail(value_field, value_field.name() + " " + format(value) + " is outside the bounds [" +
                              format(p.lower) + ", " + format(p.upper) + "]");
    };
    check_within(initial, p.initial);
    if (const Field* s = fs.find("scaling")) {
      const Scaling scalings[] = {Scaling::None, Scaling::Linear, Scaling::Log};
      std::vector<std::string> scaling_names;
      for (Scaling sc : scalings) scaling_names.push_back(to_string(sc));
      p.scaling = scalings[choice(*s, scaling_names)];
    }
    if (p.scaling == Scaling::Log && !(p.lower > 0))
      fail(lower, "log scaling needs a positive lower bound, got " + format(p.lower) +
                      "; raise 'lower' or use linear scaling");
    const Field* reference = fs.find("reference");
    p.reference = reference ? number(*reference) : p.initial;
    if (p.scaling == Scaling::Linear && p.reference == 0)
      fail(reference ? *reference : initial,
           "linear scaling divides by the reference value, which is 0; give a nonzero "
           "'reference' or use 'scaling: none'");
    if (const Field* t = fs.find("truth")) {
      p.truth = number(*t);
      check_within(*t, *p.truth);
    }
    problem_.parameters.push_back(p);
  }
}

PropertyId Loader::target(const Field& f) {
  const std::string name = text(f);
  const size_t dot = name.rfind('.');
  if (dot == std::string::npos || dot == 0 || dot + 1 == name.size())
    fail(f, "target " + quote(name) + " is not of the form <entity>.<property>, e.g. joint1.kx");
  const std::string entity = name.substr(0, dot), property = name.substr(dot + 1);
  const auto it = entities_.find(entity);
  if (it == entities_.end()) {
    std::vector<std::string> names;
    for (const auto& [n, e] : entities_) names.push_back(n);
    fail(f, "unknown entity " + quote(entity) + " in target " + quote(name) + "; " +
                known("blocks, joints, springs and point masses", names));
  }
  if (const PropertyId id = model_.find_property(name); id != kNoProperty) return id;

  const Entity& e = it->second;
  const bool has_components = e.kind == EntityKind::Joint || e.kind == EntityKind::Spring;
  if (has_components && contains(kStiffnessComponentNames, property)) {
    // An absent component is zero; calibrating it needs the property to exist.
    const PropertyId id = add_property(name, f, 0.0);
    const auto c =
        std::find(kStiffnessComponentNames.begin(), kStiffnessComponentNames.end(), property) - kStiffnessComponentNames.begin();
    (e.kind == EntityKind::Joint ? model_.joints[e.index].stiffness
                                 : model_.ground_springs[e.index].stiffness)[c] = id;
    return id;
  }
  std::vector<std::string> properties;
  if (has_components)
    properties = kStiffnessComponentNames;
  else
    for (const Property& p : model_.properties)
      if (p.name.rfind(entity + ".", 0) == 0)
        properties.push_back(p.name.substr(entity.size() + 1));
  fail(f, kind_name(e.kind) + " " + quote(entity) + " has no property " + quote(property) +
              "; its properties: " + join(properties));
}

void Loader::read_sensors(const Field& f) {
  std::map<std::pair<int, int>, int> measured_by;  // (node, direction) -> sensor number
  for (const Field& item : list(f)) {
    const Fields fs = map_of(item, "sensor " + std::to_string(item.item),
                             {"at", "tolerance", "node", "node_set", "directions"});
    const Field& where = exactly_one(fs, {"at", "node", "node_set"});
    const Field* tolerance = fs.find("tolerance");
    if (tolerance && where.key != "at")
      fail(*tolerance, "'tolerance' applies only to a sensor placed with 'at'");
    std::vector<int> nodes;
    if (where.key == "at")
      nodes = {nearest_node(where, tolerance ? positive(*tolerance) : sensor_tolerance())};
    else if (where.key == "node")
      nodes = {node_by_id(where)};
    else
      nodes = node_set(where).nodes;

    const Field& directions = required(fs, "directions");
    const std::vector<Field> items = list(directions);
    if (items.empty()) fail(directions, "'directions' is empty; list any of x, y, z");
    for (const Field& d : items) {
      const int c = choice(d, kDirections);
      for (int v : nodes) {
        const std::string label =
            "node " + std::to_string(model_.node_ids[v]) + " +" + kDirections[c];
        const auto [it, inserted] = measured_by.try_emplace({v, c}, item.item);
        if (!inserted)
          fail(d, label + " is already measured by sensor " + std::to_string(it->second) +
                      "; measure each DOF once");
        problem_.sensors.push_back({v, c, label});
      }
    }
  }
}

int Loader::nearest_node(const Field& at, double tolerance) const {
  const Vec3 x = vec3(at);
  int best = 0;
  double best_distance = std::numeric_limits<double>::infinity();
  // Ties go to the lower index, i.e. a mesh node before a reference node at the same place.
  for (int v = 0; v < model_.num_nodes(); ++v) {
    const double d = (model_.coordinates[v] - x).norm();
    if (d < best_distance) {
      best = v;
      best_distance = d;
    }
  }
  if (best_distance > tolerance)
    fail(at, "no node within " + format(tolerance) + " of " + format(x) + "; the nearest is node " +
                 std::to_string(model_.node_ids[best]) + " at " + format(model_.coordinates[best]) +
                 ", " + format(best_distance) + " away (correct the point or raise 'tolerance')");
  return best;
}

void Loader::read_options(const Field& f) {
  const Fields fs = map_of(f, "options", {"num_modes", "max_rigid_modes", "tolerance"});
  ProblemOptions& o = problem_.options;
  if (const Field* n = fs.find("num_modes")) {
    o.num_modes = integer_in(*n, 1, INT_MAX);
    num_modes_at_ = {current_file_, n->line};
  }
  if (const Field* n = fs.find("max_rigid_modes")) o.max_rigid_modes = integer_in(*n, 0, 6);
  if (const Field* t = fs.find("tolerance")) o.tolerance = positive(*t);
}

void Loader::read_measured(const Field& f) {
  const Fields fs = map_of(f, "measured", {"modes", "synthetic", "test_data", "file", "noise"});
  const Field& which = exactly_one(fs, {"modes", "synthetic", "test_data", "file"});
  if (which.key == "synthetic") {
    problem_.synthetic = synthetic(which);
  } else if (which.key == "test_data") {
    detail::measured_from_test_data(test_data(which), &problem_);
  } else if (which.key == "file") {
    read_measured_file(which);
  } else {
    for (const Field& item : list(which)) problem_.measured.push_back(measured_mode(item, false));
  }
  // The noise stated here replaces what a data file records.
  if (const Field* noise = fs.find("noise")) problem_.measurement_noise = recorded_noise(*noise);
}

void Loader::read_effects(const Field& f) {
  for (const Field& item : list(f)) {
    const std::string what = "effect " + std::to_string(item.item);
    const Fields fs = map_of(item, what, {"effect", "description", "initial", "lower", "upper", "enable"});
    DeclaredEffect effect;
    const Field& text_field = required(fs, "effect");
    effect.effect = text(text_field);
    if (effect.effect.find('=') != std::string::npos)
      fail(text_field, "'" + effect.effect + "': give the effect without its value (e.g. joint2.kry); its start "
                       "value is 'initial'");
    effect.source_file = current_file_;
    effect.source_line = item.line;
    if (const Field* d = fs.find("description")) effect.description = text(*d);
    if (const Field* v = fs.find("initial")) effect.initial = number(*v);
    if (const Field* v = fs.find("lower")) effect.lower = number(*v);
    if (const Field* v = fs.find("upper")) effect.upper = number(*v);
    if (const Field* v = fs.find("enable")) effect.enable = boolean(*v);
    if (effect.lower && effect.upper && !(*effect.lower < *effect.upper))
      fail(item, what + ": lower " + format(*effect.lower) + " must be below upper " + format(*effect.upper));
    if (effect.initial && ((effect.lower && *effect.initial < *effect.lower) ||
                           (effect.upper && *effect.initial > *effect.upper)))
      fail(item, what + ": initial " + format(*effect.initial) + " lies outside its bounds");
    // The change must make sense on this model; the value only matters for its range.
    try {
      const ModelChange change = parse_model_change(effect.effect + "=" + format_round_trip(effect.initial.value_or(1)));
      const ModelEffect described = describe_model_change(model_, change);
      for (const Parameter& q : problem_.parameters)
        for (PropertyId t : q.targets)
          if (model_.properties[t].name == described.name)
            fail(text_field, "'" + effect.effect + "' sets " + described.name + ", which parameter '" + q.name +
                                 "' already calibrates");
      for (const DeclaredEffect& other : problem_.effects)
        if (other.effect == effect.effect) fail(text_field, "'" + effect.effect + "' is declared twice");
    } catch (const std::invalid_argument& e) {
      if (dynamic_cast<const ProblemError*>(&e)) throw;
      fail(text_field, std::string(e.what()) +
                           " (an effect is a change without its value, e.g. joint2.kry or point_mass@top:mass)");
    }
    problem_.effects.push_back(effect);
  }
}

void Loader::read_measured_file(const Field& f) {
  const std::string name = text(f);
  const std::string path = (std::filesystem::path(current_file_).parent_path() / name).string();
  if (const std::string reason = detail::unreadable_reason(path, "data file", detail::kMostYamlBytes); !reason.empty())
    fail(f, ends_with(reason, "no such file")
                ? "no such data file " + quote(path) + " (the path is relative to this file's folder)"
                : reason);
  const YAML::Node root = parse(path, "data file");
  const std::string problem_file = current_file_;
  current_file_ = path;
  problem_.measured_file = path;
  problem_.source_files.push_back(path);
  if (!root.IsMap())
    fail_at(1, "", "expected a data file (a map with 'sensors' and 'modes'), got " + describe(root));
  const Fields fs = map_of({"", "", root, 1, 0}, "", {"synthesized_from", "noise", "sensors", "truth", "modes"});
  if (const Field* from = fs.find("synthesized_from")) text(*from);
  if (const Field* noise = fs.find("noise")) problem_.measurement_noise = recorded_noise(*noise);
  const Field* sensors = fs.find("sensors");
  if (sensors) read_data_sensors(*sensors);
  const Field& modes = required(fs, "modes");
  for (const Field& item : list(modes)) {
    if (!sensors && item.node.IsMap() && item.node["shape"])
      fail_at(item.line, "measured mode " + std::to_string(item.item),
              "has a 'shape' but the data file lists no 'sensors'; a data file with shapes must list the sensor "
              "DOFs they were measured at");
    problem_.measured.push_back(measured_mode(item, true));
  }
  if (problem_.measured.empty()) fail(modes, "'modes' is empty; the data file has no measured modes");
  if (const Field* truth = fs.find("truth")) problem_.synthetic_truth = recorded_truth(*truth);
  current_file_ = problem_file;
}

// A data file's sensors must be the problem's, in the same order, matched by position and
// direction (node ids change with the mesh); a problem without sensors takes the data's.
void Loader::read_data_sensors(const Field& f) {
  const std::vector<Field> items = list(f);
  const bool adopt = problem_.sensors.empty();
  const std::string same_order = "the data's sensors must be the problem's, in the same order";
  if (!adopt && items.size() != problem_.sensors.size())
    fail(f, "lists " + std::to_string(items.size()) + " sensor DOFs but the problem's 'sensors' measure " +
                std::to_string(problem_.sensors.size()) + "; " + same_order +
                " (or leave out the problem's 'sensors' section to take the data's)");
  const double tolerance = sensor_tolerance();
  for (const Field& item : items) {
    const std::string what = "data sensor " + std::to_string(item.item);
    const Fields fs = map_of(item, what, {"node", "direction", "at"});
    if (const Field* id = fs.find("node")) integer(*id);
    const int c = choice(required(fs, "direction"), kDirections);
    const Field& at = required(fs, "at");
    if (adopt) {
      const int v = nearest_node(at, tolerance);
      const std::string label = "node " + std::to_string(model_.node_ids[v]) + " +" + kDirections[c];
      for (const Sensor& s : problem_.sensors)
        if (s.node == v && s.component == c) fail_at(item.line, what, label + " is listed twice; measure each DOF once");
      problem_.sensors.push_back({v, c, label});
      continue;
    }
    const Sensor& expected = problem_.sensors[item.item - 1];
    const Vec3 x = vec3(at);
    const Vec3& position = model_.coordinates[expected.node];
    if (c != expected.component || (x - position).norm() > tolerance)
      fail_at(item.line, what, "is +" + kDirections[c] + " at " + format(x) + " but the problem's sensor DOF " +
                     std::to_string(item.item) + " is " + expected.label + " at " + format(position) + "; " +
                     same_order + " (were the data made on another mesh or refinement?)");
  }
}

MeasurementNoise Loader::recorded_noise(const Field& f) const {
  const Fields fs = map_of(f, "noise", {"frequency", "shape", "seed"});
  MeasurementNoise noise;
  if (const Field* n = fs.find("frequency")) noise.frequency = non_negative(*n);
  if (const Field* n = fs.find("shape")) noise.shape = non_negative(*n);
  if (const Field* seed = fs.find("seed"))
    if (!seed->node.IsScalar() || !YAML::convert<std::uint64_t>::decode(seed->node, noise.seed))
      fail(*seed, "expected a whole number from 0 to 2^64-1 for 'seed', got " + describe(seed->node));
  std::string error;
  if (!noise.IsValid(&error)) fail(f, "noise." + error);
  return noise;
}

SyntheticTruth Loader::recorded_truth(const Field& f) {
  const Fields fs =
      map_of(f, "truth", {"source", "changes", "hidden_effects", "other_differences", "parameters"});
  SyntheticTruth truth;
  if (const Field* source = fs.find("source")) truth.source = text(*source);
  if (const Field* changes = fs.find("changes"))
    for (const Field& c : list(*changes)) truth.changes.push_back(text(c));
  if (const Field* effects = fs.find("hidden_effects"))
    for (const Field& item : list(*effects)) {
      const Fields e = map_of(item, "hidden effect " + std::to_string(item.item),
                              {"name", "description", "value", "nominal_value"});
      ModelEffect effect;
      effect.name = text(required(e, "name"));
      if (const Field* d = e.find("description")) effect.description = text(*d);
      effect.value = number(required(e, "value"));
      // .inf: a flexible support, whose nominal is rigid.
      const Field& nominal = required(e, "nominal_value");
      if (nominal.node.IsScalar() && nominal.node.Scalar() == ".inf")
        effect.nominal_value = std::numeric_limits<double>::infinity();
      else
        effect.nominal_value = number(nominal);
      truth.hidden_effects.push_back(effect);
    }
  if (const Field* other = fs.find("other_differences")) truth.other_differences = text(*other);
  if (const Field* parameters = fs.find("parameters"))
    for (const Field& entry : named(*parameters, "truth parameter")) {
      const double value = number(entry);
      truth.parameters.emplace_back(entry.key, value);
      // The data's truth completes the problem's parameters; a contradiction is a mistake.
      const int j = problem_.find_parameter(entry.key);
      if (j < 0) continue;
      Parameter& p = problem_.parameters[static_cast<size_t>(j)];
      if (!p.truth)
        p.truth = value;
      else if (std::abs(*p.truth - value) > 1e-12 * std::max(std::abs(value), std::abs(*p.truth)))
        fail(entry, "the data were made with " + quote(entry.key) + " = " + format(value) +
                        " but the problem file gives it the truth " + format(*p.truth) +
                        "; remove the problem's 'truth' or use matching data");
    }
  return truth;
}

MeasuredMode Loader::measured_mode(const Field& item, bool in_data_file) const {
  std::vector<std::string> keys = {"frequency_hz", "weight", "shape_weight", "shape", "label", "pair"};
  if (in_data_file) keys.insert(keys.end(), {"truth_mode", "truth_frequency_hz"});  // provenance, for people
  const Fields fs = map_of(item, "measured mode " + std::to_string(item.item), keys);
  if (const Field* k = fs.find("truth_mode")) integer_in(*k, 1, INT_MAX);
  if (const Field* hz = fs.find("truth_frequency_hz")) positive(*hz);
  MeasuredMode m;
  m.source_line = item.line;
  const Field* label = fs.find("label");
  m.label = label ? text(*label) : "mode " + std::to_string(item.item);
  const Field& frequency = required(fs, "frequency_hz");
  m.frequency_hz = number(frequency);
  if (const std::string reason = detail::unusable_frequency(m.frequency_hz); !reason.empty())
    fail(frequency, frequency.name() + " is " + format(m.frequency_hz) + ": " + reason);
  if (const Field* w = fs.find("weight")) m.weight = non_negative(*w);
  if (const Field* w = fs.find("shape_weight")) m.shape_weight = non_negative(*w);
  const Field* shape = fs.find("shape");
  if (shape) {
    const std::vector<Field> values = list(*shape);
    if (values.size() != problem_.sensors.size())
      fail(*shape, "'shape' has " + std::to_string(values.size()) +
                       " values but the sensors measure " +
                       std::to_string(problem_.sensors.size()) +
                       " DOFs; give one value per sensor DOF, in the order of 'sensors'");
    m.shape.resize(static_cast<Eigen::Index>(values.size()));
    for (size_t i = 0; i < values.size(); ++i)
      m.shape[static_cast<Eigen::Index>(i)] = number(values[i]);
    if (m.shape.isZero(0)) fail(*shape, "'shape' is all zeros, which pairs with nothing");
  }
  if (const Field* pair = fs.find("pair")) {
    m.pairing = pairing(*pair, shape != nullptr);
  } else if (!shape) {
    m.pairing.kind = PairingRule::Kind::ModelIndex;
    m.pairing.model_index = item.item;
    check_computed(item, item.item);
  }
  return m;
}

PairingRule Loader::pairing(const Field& f, bool has_shape) const {
  PairingRule rule;
  if (f.node.IsScalar()) {
    if (f.node.Scalar() != "mac")
      fail(f, "expected mac, {model_mode: n} or {family: name, index: n} for 'pair', got " +
                  describe(f.node));
    if (!has_shape)
      fail(f,
           "'pair: mac' pairs by shape, but this mode has no 'shape'; give a shape or pair "
           "with {model_mode: n} or {family: name, index: n}");
    return rule;
  }
  const Fields fs = map_of(f, f.what, {"model_mode", "family", "index"});
  if (const Field* n = fs.find("model_mode")) {
    if (fs.items.size() > 1)
      fail(f, "give either {model_mode: n} or {family: name, index: n} for 'pair', not both");
    rule.kind = PairingRule::Kind::ModelIndex;
    rule.model_index = integer_in(*n, 1, INT_MAX);
    check_computed(*n, rule.model_index);
    return rule;
  }
  rule.kind = PairingRule::Kind::Family;
  const Field& family = required(fs, "family");
  rule.family = text(family);
  if (!model_.mode_families.count(rule.family)) {
    std::vector<std::string> names;
    for (const auto& [name, direction] : model_.mode_families) names.push_back(name);
    fail(family,
         "unknown mode family " + quote(rule.family) + "; " + known("mode families", names));
  }
  rule.family_index = integer_in(required(fs, "index"), 1, INT_MAX);
  return rule;
}

void Loader::check_computed(const Field& f, int mode) const {
  if (mode > problem_.options.num_modes)
    fail(f, "refers to elastic mode " + std::to_string(mode) + " but options.num_modes is " +
                std::to_string(problem_.options.num_modes) + "; raise num_modes");
}

SyntheticSpec Loader::synthetic(const Field& f) const {
  const Fields fs = map_of(f, "measured synthetic", {"modes", "shapes"});
  SyntheticSpec spec;
  spec.source_line = f.line;
  const Field& modes = required(fs, "modes");
  for (const Field& m : list(modes)) {
    const int mode = integer_in(m, 1, INT_MAX);
    check_computed(m, mode);
    if (std::find(spec.modes.begin(), spec.modes.end(), mode) != spec.modes.end())
      fail(m, "mode " + std::to_string(mode) + " is listed twice");
    spec.modes.push_back(mode);
  }
  if (spec.modes.empty()) fail(modes, "'modes' is empty; list the model modes to synthesize");
  const Field* shapes = fs.find("shapes");
  if (shapes) spec.shapes = boolean(*shapes);
  if (spec.shapes && problem_.sensors.empty())
    fail(shapes ? *shapes : f,
         "synthetic shapes need sensors; add a 'sensors' section or set 'shapes: false'");
  return spec;
}

detail::TestDataSelection Loader::test_data(const Field& f) const {
  const Fields fs = map_of(f, "measured test_data",
                           {"file", "modes", "map", "tolerance", "directions", "length_unit", "scale_length"});
  if (!problem_.sensors.empty())
    fail(f, "test_data defines the sensors (matched nodes × directions); remove the 'sensors' section");
  detail::TestDataSelection s;
  s.problem_file = current_file_;
  s.line = f.line;
  const Field& file = required(fs, "file");
  s.path = (std::filesystem::path(current_file_).parent_path() / text(file)).string();
  s.file_line = file.line;
  if (const Field* modes = fs.find("modes")) {
    for (const Field& m : list(*modes)) {
      const int number = integer_in(m, 0, INT_MAX);
      if (std::find(s.modes.begin(), s.modes.end(), number) != s.modes.end())
        fail(m, "mode " + std::to_string(number) + " is listed twice");
      s.modes.push_back(number);
      s.mode_lines.push_back(m.line);
    }
    if (s.modes.empty()) fail(*modes, "'modes' is empty; list the file's mode numbers, or leave it out for all");
  }
  if (const Field* map = fs.find("map"))
    s.map.by = choice(*map, {"id", "coordinates"}) == 0 ? NodeMatchBy::Id : NodeMatchBy::Coordinates;
  if (const Field* tolerance = fs.find("tolerance")) {
    if (s.map.by != NodeMatchBy::Coordinates) fail(*tolerance, "'tolerance' applies only to 'map: coordinates'");
    s.map.tolerance = positive(*tolerance);
  }
  if (const Field* directions = fs.find("directions")) {
    s.directions.clear();
    for (const Field& d : list(*directions)) {
      const int c = choice(d, kDirections);
      if (std::find(s.directions.begin(), s.directions.end(), c) != s.directions.end())
        fail(d, "direction " + kDirections[c] + " is listed twice");
      s.directions.push_back(c);
    }
    if (s.directions.empty()) fail(*directions, "'directions' is empty; list any of x, y, z");
  }
  const Field* unit = fs.find("length_unit");
  const Field* scale = fs.find("scale_length");
  if (unit && scale) fail(*scale, "give either 'length_unit' or 'scale_length', not both");
  if (unit) {
    s.lengths.unit = text(*unit);
    if (!metres_per_length_unit(s.lengths.unit))
      fail(*unit, "unknown length unit " + quote(s.lengths.unit) + "; known: m, cm, mm, in, ft");
  }
  if (scale) s.lengths.scale = positive(*scale);
  return s;
}

int Loader::block_index(const Field& f) const {
  const std::string name = text(f);
  std::vector<std::string> names;
  for (size_t k = 0; k < model_.blocks.size(); ++k) {
    if (model_.blocks[k].name == name) return static_cast<int>(k);
    names.push_back(model_.blocks[k].name);
  }
  fail(f, "unknown block " + quote(name) + "; " + known("blocks", names));
}

const NodeSet& Loader::node_set(const Field& f) const {
  const std::string name = text(f);
  if (const NodeSet* set = model_.find_node_set(name)) return *set;
  std::vector<std::string> names;
  for (const NodeSet& s : model_.node_sets) names.push_back(s.name);
  fail(f, "unknown node set " + quote(name) + "; " + known("node sets", names));
}

int Loader::reference_node(const Field& f) const {
  const std::string name = text(f);
  const auto it = reference_nodes_.find(name);
  if (it != reference_nodes_.end()) return it->second;
  std::vector<std::string> names;
  for (const auto& [n, index] : reference_nodes_) names.push_back(n);
  fail(f, "unknown reference node " + quote(name) + "; " + known("reference nodes", names));
}

int Loader::node_by_id(const Field& f) const {
  const long id = integer(f);
  const auto it = node_of_id_.find(id);
  if (it != node_of_id_.end()) return it->second;
  const auto [lo, hi] = std::minmax_element(model_.node_ids.begin(), model_.node_ids.begin() + num_mesh_nodes_);
  std::string ids = "mesh nodes are " + std::to_string(*lo) + ".." + std::to_string(*hi);
  if (*hi - *lo + 1 != num_mesh_nodes_) ids += " (with gaps)";
  if (model_.num_nodes() > num_mesh_nodes_)
    ids += ", reference nodes are " + std::to_string(model_.node_ids[num_mesh_nodes_]) + ".." +
           std::to_string(model_.node_ids.back());
  fail(f, "there is no node with id " + std::to_string(id) + "; " + ids);
}

int Loader::node(const Field& f) const {
  long id = 0;
  const bool is_id = f.node.IsScalar() && YAML::convert<long>::decode(f.node, id);
  return is_id ? node_by_id(f) : reference_node(f);
}

PropertyId Loader::add_property(const std::string& name, const Field& source, double value) {
  locations_["property " + quote(name)] = {current_file_, source.line};
  return model_.add_property(name, value);
}

void Loader::add_entity(const Field& entry, EntityKind kind, size_t index) {
  const auto [it, inserted] =
      entities_.try_emplace(entry.key, Entity{kind, static_cast<int>(index), entry.line, current_file_});
  if (!inserted)
    fail(entry, "the name is already used by " + kind_name(it->second.kind) + " " +
                    quote(entry.key) + " (line " + std::to_string(it->second.line) +
                    "); names must be unique across blocks, joints, springs and point masses");
  locations_[entry.what] = {current_file_, entry.line};
}

Location Loader::location_of_model_error(const std::string& message) const {
  size_t first = std::string::npos;
  Location location;
  for (const auto& [phrase, phrase_location] : locations_) {
    const size_t at = message.find(phrase);
    if (at < first) {
      first = at;
      location = phrase_location;
    }
  }
  return location;
}

YAML::Node parse(const std::string& path, const std::string& what) { return detail::load_yaml_file(path, what); }

}  // namespace

Problem load_problem(const std::string& path, const LoadOptions& options) {
  if (!(options.refinement >= 0) || !std::isfinite(options.refinement))
    throw std::invalid_argument("LoadOptions::refinement must be a finite number >= 0 (0: the problem file's), got " +
                                format(options.refinement));
  const YAML::Node root = parse(path, "problem file");
  // The chain of extended files, nearest first; each path is relative to the file naming it.
  std::vector<std::pair<YAML::Node, std::string>> bases;
  std::error_code ec;
  std::vector<std::string> visited = {std::filesystem::weakly_canonical(path, ec).string()};
  // (yaml-cpp nodes are references: assigning one node to another would overwrite the first's
  // content, so each file's node is only ever created, never assigned.)
  for (;;) {
    const YAML::Node& node = bases.empty() ? root : bases.back().first;
    const std::string& file = bases.empty() ? path : bases.back().second;
    if (!node.IsMap() || !node["extends"]) break;
    const YAML::Node extends = node["extends"];
    const int line = extends.Mark().line + 1;
    if (!extends.IsScalar())
      throw ProblemError(file, line, "'extends' must name a problem file, got " + describe(extends));
    const std::string base_path = (std::filesystem::path(file).parent_path() / extends.Scalar()).string();
    if (const std::string reason = detail::unreadable_reason(base_path, "problem file", detail::kMostYamlBytes);
        !reason.empty())
      throw ProblemError(file, line,
                         "extends " + quote(extends.Scalar()) + ": " + reason +
                             (ends_with(reason, "no such file") ? " (the path is relative to this file's folder)"
                                                                : ""));
    const std::string canonical = std::filesystem::weakly_canonical(base_path, ec).string();  // ec: above
    if (std::find(visited.begin(), visited.end(), canonical) != visited.end())
      throw ProblemError(file, line, "extends " + quote(extends.Scalar()) + ", which is already in the chain of "
                                     "extended files: the files extend each other in a loop");
    visited.push_back(canonical);
    bases.emplace_back(parse(base_path, "problem file"), base_path);
  }
  Problem problem;
  problem.path = path;
  problem.source_files.push_back(path);
  for (const auto& [base, base_path] : bases) problem.source_files.push_back(base_path);
  Loader(path, options, problem).load(root, bases);
  return problem;
}

}  // namespace modalcal
