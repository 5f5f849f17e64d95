// The model sections of a problem file: mesh (box mesher or mesh file), blocks, reference nodes,
// node sets, rigid couplings, joints, springs, point masses, supports and mode families.
#include "io/problem_loader.hpp"

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

namespace modalcal::detail::loading {

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
    b.modulus_a = add_property(b.name + "." + a.key, a, number(a));
    b.modulus_b = add_property(b.name + "." + m.key, m, number(m));
    b.density = add_property(b.name + ".density", rho, number(rho));
    if (const Field* s = fs.find("stiffness_scale"))
      b.stiffness_scale = add_property(b.name + ".stiffness_scale", *s, number(*s));
    if (const Field* s = fs.find("mass_scale")) b.mass_scale = add_property(b.name + ".mass_scale", *s, number(*s));
    model_.blocks.push_back(b);
  }
}

void Loader::read_mesh(const Field& f) {
  const Fields fs =
      map_of(f, "mesh", {"element", "element_size", "refinement", "boxes", "planes", "file", "format", "scale"});
  if (fs.find("file")) {
    read_mesh_file(fs);
  } else {
    for (const char* key : {"format", "scale"})
      if (const Field* k = fs.find(key)) fail(*k, quote(key) + " applies only to a mesh read from a 'file'");
    read_box_mesh(fs);
  }
  finish_mesh();
}

// `planes: {x: [..], y: [..], z: [..]}`: grid planes beside the boxes' faces, each strictly inside
// the boxes' extent, so that a footprint between two of them (a payload's feet, a pad) keeps its
// extent at every refinement instead of taking in whichever grid lines fall inside it.
detail::ExtraPlanes Loader::mesh_planes(const Field& f, const std::vector<detail::MeshBox>& boxes) const {
  const Fields fs = map_of(f, "mesh planes", {"x", "y", "z"});
  detail::ExtraPlanes planes;
  for (int axis = 0; axis < 3; ++axis) {
    const Field* along = fs.find(kDirections[axis]);
    if (!along) continue;
    double lo = boxes.front().min[axis], hi = boxes.front().max[axis];
    for (const detail::MeshBox& b : boxes) {
      lo = std::min(lo, b.min[axis]);
      hi = std::max(hi, b.max[axis]);
    }
    for (const Field& item : list(*along)) {
      const double v = number(item);
      if (!(lo < v && v < hi))
        fail(item, "plane " + kDirections[axis] + " = " + format(v) + " lies outside the boxes' extent (" +
                       format(lo) + " to " + format(hi) + " along " + kDirections[axis] + "); a plane must cut the mesh");
      planes[axis].push_back(v);
    }
  }
  return planes;
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
  const detail::ExtraPlanes planes = fs.find("planes") ? mesh_planes(*fs.find("planes"), boxes) : detail::ExtraPlanes{};

  const detail::BoxMeshSize size = detail::estimate_box_mesh(boxes, type, element_size, refinement, planes);
  check_mesh_size(size.nodes, 4 * size.grid_points, file_refinement ? *file_refinement : required(fs, "element_size"),
                  options_.refinement > 0 ? "use a smaller refinement (--refine " + format(refinement) + ")"
                                          : "use a larger element_size or a smaller refinement");
  const detail::BoxMesh mesh = detail::generate_box_mesh(
      boxes, static_cast<int>(model_.blocks.size()), type, element_size, refinement, planes);
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
  for (const char* key : {"element", "element_size", "refinement", "boxes", "planes"})
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

// Sensors that all read fixed DOFs see zero in every model shape: no shape can be compared, and
// every shape term would divide by zero (NaN results with exit 0). Some that do get a warning.
void Loader::check_sensors_move(const Field& f) {
  if (problem_.sensors.empty()) return;
  std::string first_fixed;
  size_t fixed = 0;
  for (const Sensor& s : problem_.sensors) {
    const auto fixing = std::find_if(model_.fixed.begin(), model_.fixed.end(), [&](const FixedDofs& x) {
      return x.components[static_cast<size_t>(s.component)] &&
             std::find(x.nodes.begin(), x.nodes.end(), s.node) != x.nodes.end();
    });
    if (fixing == model_.fixed.end()) continue;
    if (fixed++ == 0) first_fixed = s.label + " is fixed by '" + fixing->name + "'";
  }
  if (fixed == 0) return;
  const std::string also = fixed > 1 ? ", and so on" : "";
  if (fixed == problem_.sensors.size())
    fail(f, "every sensor reads a fixed DOF (" + first_fixed + also +
                "): the model's shapes are zero there, so none can be compared; place sensors where the model moves");
  // Some: a support that moves in the test, or sensors placed by a set that takes in a support.
  // The comparison stands, but those entries can only add misfit.
  problem_.warnings.push_back(current_file_ + ":" + std::to_string(f.line) + ": " + std::to_string(fixed) + " of " +
                              std::to_string(problem_.sensors.size()) + " sensors read a fixed DOF (" + first_fixed +
                              also + "): the model's shapes are zero there, so the measured motion there counts as misfit");
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
    locations_["reference node " + quote(entry.key)] = {current_file_, entry.line};
  }
}

// A reference node nothing acts on has DOFs without stiffness or mass, which the assembly could
// only report by node id, with no file or line; here it is named where it is declared.
void Loader::check_reference_nodes_used() const {
  auto in = [](const std::vector<int>& nodes, int node) {
    return std::find(nodes.begin(), nodes.end(), node) != nodes.end();
  };
  for (const auto& [name, node] : reference_nodes_) {
    bool used = false;
    for (const RigidCoupling& r : model_.rigid_couplings) used = used || r.reference == node || in(r.nodes, node);
    for (const Joint& j : model_.joints) used = used || j.node_a == node || j.node_b == node;
    for (const PointMass& m : model_.point_masses) used = used || m.node == node;
    for (const GroundSpring& g : model_.ground_springs) used = used || in(g.nodes, node);
    for (const FixedDofs& f : model_.fixed) used = used || in(f.nodes, node);
    if (used) continue;
    const Location& at = locations_.at("reference node " + quote(name));
    throw ProblemError(at.file, at.line,
                       "reference node " + quote(name) +
                           " is used by no rigid coupling, joint, spring, point mass or support: its DOFs would "
                           "have neither stiffness nor mass (remove it, or connect it)");
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
      ids[c] = add_property(entity + "." + k->key, *k, number(*k));
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
    m.mass = add_property(m.name + ".mass", mass, number(mass));
    if (const Field* inertia = fs.find("inertia")) {
      const std::vector<Field> items = list(*inertia);
      if (items.size() != 3)
        fail(*inertia, "expected 3 values [Ixx, Iyy, Izz] for 'inertia', got " +
                           std::to_string(items.size()));
      for (int c = 0; c < 3; ++c)
        m.inertia[c] =
            add_property(m.name + "." + kInertiaKeys[c], items[c], number(items[c]));
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

}  // namespace modalcal::detail::loading
