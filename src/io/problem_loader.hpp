#pragma once
// Internal: the problem-file loader, one class whose sections are read in three files:
// problem_loader.cpp (fields and their checks, the order of sections, lookups, load_problem),
// model_section.cpp (mesh, blocks, node sets, joints, springs, masses, supports) and
// measured_section.cpp (parameters, sensors, options, measured modes, effects, data files).

#include <array>
#include <functional>
#include <limits>
#include <map>
#include <string>
#include <unordered_map>
#include <utility>
#include <vector>

#include <yaml-cpp/yaml.h>

#include "io/box_mesh.hpp"
#include "io/measured_test_data.hpp"
#include "modalcal/model.hpp"
#include "modalcal/problem.hpp"
#include "modalcal/problem_file.hpp"

namespace modalcal::detail::loading {

inline const std::vector<std::string> kInertiaKeys{"Ixx", "Iyy", "Izz"};
inline const std::vector<std::string> kDirections{"x", "y", "z"};

std::string quote(const std::string& s);
bool ends_with(const std::string& s, const std::string& end);
std::string join(const std::vector<std::string>& items);
std::string format(double v);
std::string format(const Vec3& v);
/// A size for messages, in 3 significant digits ("1.2e+06").
std::string rounded(double v);
/// The memory the forward solve of a model with `dofs` degrees of freedom needs, about: the
/// sparse factorization's fill grows like dofs^(4/3) on a 3D mesh (measured: 15 KB per DOF at
/// 14 000 DOFs, 14 KB at 66 000, hex8; the estimate errs above).
double estimated_solve_bytes(double dofs);
double physical_memory_bytes();
/// Ends an "unknown ..." message: "known node sets: a, b" or "no node sets are defined".
std::string known(const std::string& plural, const std::vector<std::string>& names);
std::string describe(const YAML::Node& node);
std::vector<std::string> with_stiffness(std::vector<std::string> keys);
bool contains(const std::vector<std::string>& names, const std::string& name);

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

std::string kind_name(EntityKind kind);

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
  double out_of_range_number(const Field& f) const;
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
  detail::ExtraPlanes mesh_planes(const Field& f, const std::vector<detail::MeshBox>& boxes) const;
  void read_mesh_file(const Fields& fs);
  void check_model();
  void check_free_dofs();
  void check_reference_nodes_used() const;
  void check_sensors_move(const Field& f);
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
  void check_effect_bounds(const Fields& fs, const DeclaredEffect& effect) const;
  void check_parameter_bounds(const Parameter& p, const Field& lower, const Field& upper) const;
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
  /// Fails at `item` when the last measured mode pairs by index with a model mode an earlier one pairs with.
  void check_paired_once(const Field& item) const;
  /// Fails at `item` when the last measured mode has an earlier one's frequency and shape (pasted twice).
  void check_not_repeated(const Field& item) const;
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

}  // namespace modalcal::detail::loading
