// Reads a problem file (docs/problem-format.md) into a Problem, checking everything it can
// against the file so that each mistake is reported at its line.
#include "io/problem_loader.hpp"

#include <algorithm>
#include <array>
#include <climits>
#include <cmath>
#include <cstdio>
#include <cstdlib>
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
#include "modalcal/model_change.hpp"
#include "modalcal/problem_file.hpp"

namespace modalcal {
namespace detail::loading {

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

std::string kind_name(EntityKind kind) {
  const char* const names[] = {"block", "joint", "spring", "point mass"};
  return names[static_cast<int>(kind)];
}

std::vector<Field> Loader::entries(const Field& f, const std::string& what) const {
  std::vector<Field> out;
  const std::string where = f.key.empty() ? "the file's top level" : f.name();  // the root has no key
  for (const auto& kv : f.node) {
    const int line = kv.first.Mark().line + 1;
    if (!kv.first.IsScalar())
      fail_at(line, what, "keys must be plain names, got " + describe(kv.first) + " in " + where);
    if (kv.first.Scalar().empty())
      fail_at(line, what, "an empty name as a key in " + where + "; every key and name has at least one character");
    for (const Field& other : out)
      if (other.key == kv.first.Scalar())
        fail_at(line, what,
                quote(other.key) + " is given twice in " + where + " (first at line " +
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
  if (f.node.IsScalar() && !YAML::convert<double>::decode(f.node, v)) v = out_of_range_number(f);
  else if (!f.node.IsScalar()) fail(f, "expected a number for " + f.name() + ", got " + describe(f.node));
  if (!std::isfinite(v))
    fail(f,
         f.name() + " is " + (std::isnan(v) ? "NaN" : "infinite") + "; expected a finite number");
  if (std::abs(v) > kLargestInputMagnitude)
    fail(f, f.name() + " = " + format(v) + " is larger than any value a problem takes (at most " +
                format(kLargestInputMagnitude) + "): the assembly, eigen-solve or misfit would overflow");
  return v;
}

// yaml-cpp refuses a number beyond a double's range as no number at all: an overflow is named as
// such, and an underflow (1e-320) is the tiny value it is.
double Loader::out_of_range_number(const Field& f) const {
  const std::string& text = f.node.Scalar();
  double v = 0;
  const detail::NumberRead read = detail::read_number(text, &v);
  if (read == detail::NumberRead::kOk) return v;
  if (read == detail::NumberRead::kTooLarge)
    fail(f, f.name() + " = " + excerpt(text, 60) + " lies beyond the range of a double (magnitudes up to about 1.8e308)");
  fail(f, "expected a number for " + f.name() + ", got " + describe(f.node));
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
  if (v < lo || v > hi) {
    // An open range names only the bound that was crossed: "at least 1" beside 2^31 would puzzle.
    const std::string range = hi != INT_MAX ? "between " + std::to_string(lo) + " and " + std::to_string(hi)
                              : v < lo      ? "at least " + std::to_string(lo)
                                            : "at most " + std::to_string(hi);
    fail(f, f.name() + " must be " + range + ", got " + std::to_string(v));
  }
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

  check_model();
  if (const Field* f = top.find("sensors") ? top.find("sensors") : top.find("measured")) {
    enter(*f);
    check_sensors_move(*f);
  }
  // Effects act on the finished model.
  if (const Field* f = top.find("effects")) {
    enter(*f);
    read_effects(*f);
  }
}

// The finished model, its errors placed at the line of what they name.
void Loader::check_model() {
  try {
    model_.validate();
  } catch (const std::invalid_argument& e) {
    const Location at = location_of_model_error(e.what());
    throw ProblemError(at.file.empty() ? path_ : at.file, at.line, e.what());
  }
  check_reference_nodes_used();
  check_free_dofs();
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

// Every property's range is checked here, by the one statement of the ranges that --set, model
// changes and parameter bounds use too.
PropertyId Loader::add_property(const std::string& name, const Field& source, double value) {
  if (const std::string why = property_range_violation(name, value); !why.empty()) fail(source, why);
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

}  // namespace detail::loading

Problem load_problem(const std::string& path, const LoadOptions& options) {
  using detail::loading::describe;
  using detail::loading::ends_with;
  using detail::loading::format;
  using detail::loading::Loader;
  using detail::loading::parse;
  using detail::loading::quote;
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
    // A NUL would end the name at the system's call and open another file than the one written.
    if (extends.Scalar().find('\0') != std::string::npos)
      throw ProblemError(file, line, "'extends' holds a NUL character; name the problem file plainly");
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
