// read_mesh_file(): dispatch to the format's reader, then the checks every format shares
// (unique names, element orientation) and dropping nodes no element uses.
#include "modalcal/mesh_file.hpp"

#include <algorithm>
#include <cctype>
#include <filesystem>
#include <map>
#include <sstream>

#include "io/mesh_file_readers.hpp"
#include "modalcal/problem.hpp"

namespace modalcal {

namespace detail {

void mesh_error(const std::string& path, const std::string& message) { throw ProblemError(path, 0, message); }

void require_regular_file(const std::string& path) {
  namespace fs = std::filesystem;
  std::error_code ec;
  const fs::file_status status = fs::status(path, ec);
  if (status.type() == fs::file_type::not_found) mesh_error(path, "no such mesh file");
  if (ec) mesh_error(path, "cannot open the mesh file: " + ec.message());  // e.g. a loop of symbolic links
  if (fs::is_directory(status)) mesh_error(path, "is a directory, not a mesh file");
  if (!fs::is_regular_file(status))
    mesh_error(path, "is not a regular file (a device, FIFO or socket) and cannot be a mesh file");
}

}  // namespace detail

namespace {

using detail::mesh_error;
using detail::RawMesh;

std::string quote(const std::string& s) { return "'" + s + "'"; }

// Elements whose Jacobian is not positive cannot be assembled; finding them here names the
// file, block and element rather than failing later in assembly without either. |det J| below
// 1e-12 h^3 (h the element's extent) is rounding around zero: a flat element, not an inverted one.
void check_orientation(const std::string& path, const RawMesh& mesh) {
  for (const MeshFileBlock& block : mesh.blocks) {
    const int n = nodes_per_element(block.type);
    Eigen::Matrix3Xd x(3, n);
    for (int e = 0; e < block.num_elements(); ++e) {
      for (int k = 0; k < n; ++k) x.col(k) = mesh.coordinates[block.connectivity[static_cast<size_t>(e * n + k)]];
      const double det = min_jacobian_determinant(block.type, x);
      const double extent = (x.rowwise().maxCoeff() - x.rowwise().minCoeff()).norm();
      const double zero = 1e-12 * extent * extent * extent;
      if (det > zero) continue;
      std::ostringstream nodes, value;
      for (int k = 0; k < n; ++k)
        nodes << (k ? " " : "") << mesh.node_ids[block.connectivity[static_cast<size_t>(e * n + k)]];
      value << det;
      mesh_error(path, "element " + std::to_string(block.element_ids[e]) + " of block " + quote(block.name) + " (" +
                           solid_type_name(block.type) + ", nodes " + nodes.str() + ") is " +
                           (det < -zero ? "inverted (Jacobian determinant " + value.str() +
                                          "): its nodes are not in the expected order, or a curved element folds over (with Gmsh: "
                                          "Mesh.HighOrderOptimize = 2, Mesh.SecondOrderLinear = 1 or a finer mesh at curved faces)"
                                    : "degenerate (zero volume)"));
    }
  }
}

// A coordinate that is not finite would make every element at its node "degenerate".
void check_finite_coordinates(const std::string& path, const RawMesh& mesh) {
  for (size_t v = 0; v < mesh.coordinates.size(); ++v)
    if (!mesh.coordinates[v].allFinite()) {
      std::ostringstream x;
      x << "[" << mesh.coordinates[v][0] << ", " << mesh.coordinates[v][1] << ", " << mesh.coordinates[v][2] << "]";
      mesh_error(path, "node " + std::to_string(mesh.node_ids[v]) + " has a coordinate that is not a finite number " +
                           x.str() + "; was the mesh exported from a failed computation?");
    }
}

void check_unique_ids_and_names(const std::string& path, const RawMesh& mesh) {
  std::map<long, size_t> first_of_id;
  for (size_t v = 0; v < mesh.node_ids.size(); ++v)
    if (!first_of_id.emplace(mesh.node_ids[v], v).second)
      mesh_error(path, "node id " + std::to_string(mesh.node_ids[v]) + " is given to nodes " +
                           std::to_string(first_of_id[mesh.node_ids[v]] + 1) + " and " + std::to_string(v + 1) +
                           "; node ids must be unique");
  std::map<std::string, const MeshFileBlock*> blocks;
  for (const MeshFileBlock& b : mesh.blocks)
    if (!blocks.emplace(b.name, &b).second)
      mesh_error(path, "two element blocks are named " + quote(b.name) + " (ids " +
                           std::to_string(blocks[b.name]->id) + " and " + std::to_string(b.id) +
                           "); block names must be unique");
  std::map<std::string, const MeshFileNodeSet*> sets;
  for (const MeshFileNodeSet& s : mesh.node_sets)
    if (!sets.emplace(s.name, &s).second)
      mesh_error(path, sets[s.name]->source + " and " + s.source + " are both named " + quote(s.name) +
                           "; node set names must be unique");
}

// Two elements on the same nodes would count that part's stiffness and mass twice, and two with
// one id make the messages that name elements ambiguous: both are export errors, not a model.
void check_unique_elements(const std::string& path, const RawMesh& mesh) {
  std::map<long, const MeshFileBlock*> block_of_id;
  std::map<std::vector<int>, long> id_of_nodes;
  for (const MeshFileBlock& b : mesh.blocks) {
    const size_t n = static_cast<size_t>(nodes_per_element(b.type));
    for (size_t e = 0; e < b.element_ids.size(); ++e) {
      const long id = b.element_ids[e];
      if (const auto [it, is_new] = block_of_id.emplace(id, &b); !is_new)
        mesh_error(path, "element id " + std::to_string(id) + " is given to two elements (blocks " +
                             quote(it->second->name) + " and " + quote(b.name) + "); element ids must be unique");
      std::vector<int> nodes(b.connectivity.begin() + static_cast<std::ptrdiff_t>(e * n),
                             b.connectivity.begin() + static_cast<std::ptrdiff_t>((e + 1) * n));
      std::sort(nodes.begin(), nodes.end());
      if (const auto [it, is_new] = id_of_nodes.emplace(std::move(nodes), id); !is_new)
        mesh_error(path, "elements " + std::to_string(it->second) + " and " + std::to_string(id) +
                             " have the same nodes: that part would count twice (an element exported twice?)");
    }
  }
}

// Keeps the nodes some element uses, in the reader's order; node sets lose the others.
MeshFile compact(const std::string& path, MeshFileFormat format, RawMesh raw) {
  std::vector<int> new_index(raw.coordinates.size(), -1);
  for (const MeshFileBlock& b : raw.blocks)
    for (int v : b.connectivity) new_index[v] = 0;
  MeshFile mesh;
  mesh.path = path;
  mesh.format = format;
  mesh.warnings = std::move(raw.warnings);
  for (size_t v = 0; v < raw.coordinates.size(); ++v) {
    if (new_index[v] < 0) continue;
    new_index[v] = mesh.num_nodes();
    mesh.coordinates.push_back(raw.coordinates[v]);
    mesh.node_ids.push_back(raw.node_ids[v]);
  }
  if (const size_t unused = raw.coordinates.size() - mesh.coordinates.size())
    mesh.warnings.push_back(path + ": " + std::to_string(unused) + " of its " + std::to_string(raw.coordinates.size()) +
                            " nodes belong to no solid element and are left out");
  for (MeshFileBlock& b : raw.blocks) {
    for (int& v : b.connectivity) v = new_index[v];
    mesh.blocks.push_back(std::move(b));
  }
  for (MeshFileNodeSet& s : raw.node_sets) {
    std::vector<int> kept;
    for (int v : s.nodes)
      if (new_index[v] >= 0) kept.push_back(new_index[v]);
    if (kept.size() < s.nodes.size())
      mesh.warnings.push_back(path + ": node set " + quote(s.name) + " (" + s.source + "): " +
                              std::to_string(s.nodes.size() - kept.size()) + " of its " +
                              std::to_string(s.nodes.size()) + " nodes belong to no solid element and are left out" +
                              (kept.empty() ? "; the set is empty" : ""));
    s.nodes = std::move(kept);  // increasing, as new_index keeps the order
    mesh.node_sets.push_back(std::move(s));
  }
  mesh.side_sets = std::move(raw.side_sets);
  return mesh;
}

}  // namespace

std::string to_string(MeshFileFormat format) { return format == MeshFileFormat::Gmsh ? "gmsh" : "exodus"; }

std::optional<MeshFileFormat> mesh_format_from_extension(const std::string& path) {
  std::string extension = std::filesystem::path(path).extension().string();
  std::transform(extension.begin(), extension.end(), extension.begin(),
                 [](unsigned char c) { return static_cast<char>(std::tolower(c)); });
  if (extension == ".msh") return MeshFileFormat::Gmsh;
  for (const char* exodus : {".exo", ".e", ".g", ".gen", ".exoii", ".ex2"})
    if (extension == exodus) return MeshFileFormat::Exodus;
  return std::nullopt;
}

const MeshFileBlock* MeshFile::find_block(const std::string& name) const {
  for (const MeshFileBlock& b : blocks)
    if (b.name == name) return &b;
  return nullptr;
}

const MeshFileNodeSet* MeshFile::find_node_set(const std::string& name) const {
  for (const MeshFileNodeSet& s : node_sets)
    if (s.name == name) return &s;
  return nullptr;
}

MeshFile read_mesh_file(const std::string& path, std::optional<MeshFileFormat> format) {
  if (!format) format = mesh_format_from_extension(path);
  if (!format)
    mesh_error(path, "cannot tell the mesh format from the extension " +
                         quote(std::filesystem::path(path).extension().string()) +
                         "; use .msh for Gmsh or .exo/.e/.g for Exodus II, or name the format");
  detail::require_regular_file(path);
  RawMesh raw = *format == MeshFileFormat::Gmsh ? detail::read_gmsh(path) : detail::read_exodus(path);
  if (raw.blocks.empty()) mesh_error(path, "has no solid elements");
  check_unique_ids_and_names(path, raw);
  check_unique_elements(path, raw);
  check_finite_coordinates(path, raw);
  check_orientation(path, raw);
  return compact(path, *format, std::move(raw));
}

}  // namespace modalcal
