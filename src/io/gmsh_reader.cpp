// Gmsh .msh files through the Gmsh library's C++ API (gmsh.h): physical volume groups become
// element blocks, physical surface, curve and point groups node sets.
#include <algorithm>
#include <fstream>
#include <string>
#include <vector>
#include <map>
#include <mutex>
#include <unordered_map>

#include <gmsh.h>

#include "io/mesh_file_readers.hpp"

namespace modalcal::detail {

namespace {

std::string quote(const std::string& s) { return "'" + s + "'"; }

// Gmsh element type codes (Gmsh reference manual, "MSH file format": element types).
constexpr int kGmshTet4 = 4, kGmshHex8 = 5, kGmshTet10 = 11;

// The Gmsh API is one global state: initialize, read, finalize, one caller at a time.
class GmshSession {
 public:
  GmshSession() : lock_(mutex()) {
    gmsh::initialize(0, nullptr, /*readConfigFiles=*/false);
    gmsh::option::setNumber("General.Terminal", 0);  // messages come back as exceptions, not on stdout
    gmsh::logger::start();                            // and its warnings through the logger
  }
  ~GmshSession() { gmsh::finalize(); }
  GmshSession(const GmshSession&) = delete;
  GmshSession& operator=(const GmshSession&) = delete;

 private:
  static std::mutex& mutex() {
    static std::mutex m;
    return m;
  }
  std::lock_guard<std::mutex> lock_;
};

const char* dimension_word(int dim) {
  const char* const words[] = {"point", "curve", "surface", "volume"};
  return words[dim];
}

std::string group_name(int dim, int tag) {
  std::string name;
  gmsh::model::getPhysicalName(dim, tag, name);
  return name.empty() ? std::string(dimension_word(dim)) + "_" + std::to_string(tag) : name;
}

std::string group_source(int dim, int tag) {
  return "physical " + std::string(dimension_word(dim)) + " " + std::to_string(tag);
}

std::string element_type_name(int type) {
  std::string name;
  int dim = 0, order = 0, num_nodes = 0, num_primary = 0;
  std::vector<double> local;
  gmsh::model::mesh::getElementProperties(type, name, dim, order, num_nodes, local, num_primary);
  return name;
}

// gmsh::open runs any file that is not a mesh as a .geo script, so a .geo (or anything else)
// named .msh would load as geometry without a mesh; a mesh file starts with $MeshFormat.
void require_msh_header(const std::string& path) {
  std::ifstream in(path);
  std::string first;
  in >> first;
  if (first != "$MeshFormat")
    mesh_error(path, "is not a Gmsh mesh file: it does not start with $MeshFormat" +
                         std::string(first.empty() ? " (it is empty)" : "") +
                         "; a .geo script must be meshed first, e.g. gmsh -3 part.geo -o part.msh");
}

// Whether the file's last non-blank line closes a section ($EndElements, ...): a file cut short
// does not, and Gmsh then says only "Error loading".
bool ends_with_a_section(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  std::string line, last;
  while (std::getline(in, line))
    if (line.find_first_not_of(" \t\r") != std::string::npos) last = line;
  return last.rfind("$End", 0) == 0;
}

// Gmsh's error in words that name the cause: its last error alone ("Wrong node index 6") hides
// the warning before it that explains it ("Skipping duplicate node 5").
std::string explain_gmsh_error(const std::string& path, const std::string& error) {
  if (!ends_with_a_section(path))
    return "the file ends inside a section (its last line is no $End... line): it is probably truncated";
  std::vector<std::string> log;
  gmsh::logger::get(log);
  std::string warnings;
  for (const std::string& line : log)
    if (line.rfind("Warning: ", 0) == 0 && warnings.size() < 200)
      warnings += (warnings.empty() ? "" : "; ") + line.substr(9);
  if (warnings.find("duplicate node") != std::string::npos)
    return "a node id is defined twice (" + warnings.substr(0, 200) + "), after which Gmsh stopped at: " + error;
  return error.substr(0, 200) + (warnings.empty() ? "" : " (Gmsh warnings: " + warnings.substr(0, 200) + ")");
}

// All nodes of the mesh, ordered by tag.
void read_nodes(RawMesh* mesh, std::unordered_map<std::size_t, int>* index_of_tag) {
  std::vector<std::size_t> tags;
  std::vector<double> xyz, parametric;
  gmsh::model::mesh::getNodes(tags, xyz, parametric, -1, -1, false, false);
  std::vector<size_t> order(tags.size());
  for (size_t i = 0; i < order.size(); ++i) order[i] = i;
  std::sort(order.begin(), order.end(), [&](size_t a, size_t b) { return tags[a] < tags[b]; });
  for (size_t i : order) {
    (*index_of_tag)[tags[i]] = static_cast<int>(mesh->coordinates.size());
    mesh->coordinates.emplace_back(xyz[3 * i], xyz[3 * i + 1], xyz[3 * i + 2]);
    mesh->node_ids.push_back(static_cast<long>(tags[i]));
  }
}

size_t count_elements(int dim) {
  std::vector<int> types;
  std::vector<std::vector<std::size_t>> tags, nodes;
  gmsh::model::mesh::getElements(types, tags, nodes, dim, -1);
  size_t n = 0;
  for (const auto& t : tags) n += t.size();
  return n;
}

class GmshReader {
 public:
  explicit GmshReader(const std::string& path) : path_(path) {}

  RawMesh read() {
    read_nodes(&mesh_, &index_of_tag_);
    gmsh::vectorpair groups;
    gmsh::model::getPhysicalGroups(groups);
    require_volume_mesh(groups);
    for (const auto& [dim, tag] : groups)
      if (dim == 3) read_block(tag);
    if (const size_t left_out = count_elements(3) - owner_.size())
      mesh_.warnings.push_back(path_ + ": " + std::to_string(left_out) +
                               " volume elements belong to no physical volume group and are left out");
    for (const auto& [dim, tag] : groups)
      if (dim < 3) read_node_set(dim, tag);
    return std::move(mesh_);
  }

 private:
  [[noreturn]] void fail(const std::string& message) const { mesh_error(path_, message); }

  void require_volume_mesh(const gmsh::vectorpair& groups) const {
    if (count_elements(3) == 0) {
      if (count_elements(2) > 0)
        fail("is a 2-D mesh (surface elements only); modalcal needs a 3-D mesh of solid elements (gmsh -3)");
      fail("has no elements; was the geometry meshed (gmsh -3)?");
    }
    if (std::none_of(groups.begin(), groups.end(), [](const auto& g) { return g.first == 3; }))
      fail("has no physical volume group, so its elements have no block; name the volumes in the .geo, e.g. "
           "Physical Volume(\"part\") = {1};");
  }

  int node_index(std::size_t tag) const {
    const auto it = index_of_tag_.find(tag);
    if (it == index_of_tag_.end()) fail("an element refers to node " + std::to_string(tag) + ", which is not defined");
    return it->second;
  }

  void read_block(int tag) {
    MeshFileBlock block;
    block.name = group_name(3, tag);
    block.id = tag;
    std::string type_seen;
    std::vector<int> entities;
    gmsh::model::getEntitiesForPhysicalGroup(3, tag, entities);
    for (int entity : entities) {
      std::vector<int> types;
      std::vector<std::vector<std::size_t>> element_tags, node_tags;
      gmsh::model::mesh::getElements(types, element_tags, node_tags, 3, entity);
      for (size_t t = 0; t < types.size(); ++t) {
        const std::string where = "physical volume " + quote(block.name) + " (tag " + std::to_string(tag) + ")";
        SolidType type;
        if (types[t] == kGmshTet4)
          type = SolidType::Tet4;
        else if (types[t] == kGmshTet10)
          type = SolidType::Tet10;
        else if (types[t] == kGmshHex8)
          type = SolidType::Hex8;
        else
          fail(where + " has " + std::to_string(element_tags[t].size()) + " elements of type " +
               quote(element_type_name(types[t])) + " (Gmsh type " + std::to_string(types[t]) +
               "), which modalcal does not support; supported: 4-node and 10-node tetrahedra, 8-node hexahedra");
        if (!type_seen.empty() && type != block.type)
          fail(where + " mixes " + type_seen + " and " + solid_type_name(type) +
               " elements; put each element type in a physical volume of its own");
        block.type = type;
        type_seen = solid_type_name(type);
        add_elements(&block, element_tags[t], node_tags[t]);
      }
    }
    if (block.element_ids.empty()) {
      mesh_.warnings.push_back(path_ + ": physical volume " + quote(block.name) + " has no elements and is left out");
      return;
    }
    mesh_.blocks.push_back(std::move(block));
  }

  void add_elements(MeshFileBlock* block, const std::vector<std::size_t>& elements,
                    const std::vector<std::size_t>& nodes) {
    const size_t n = static_cast<size_t>(nodes_per_element(block->type));
    for (size_t e = 0; e < elements.size(); ++e) {
      const auto [it, inserted] = owner_.emplace(elements[e], block->name);
      if (!inserted)
        fail("element " + std::to_string(elements[e]) + " belongs to physical volumes " + quote(it->second) +
             " and " + quote(block->name) + "; an element can be in one block only");
      block->element_ids.push_back(static_cast<long>(elements[e]));
      const size_t first = block->connectivity.size();
      for (size_t k = 0; k < n; ++k) block->connectivity.push_back(node_index(nodes[e * n + k]));
      // Gmsh's 10-node tetrahedron has node 8 on edge 2-3 and node 9 on edge 1-3; ours
      // (Exodus) the other way round.
      if (block->type == SolidType::Tet10) std::swap(block->connectivity[first + 8], block->connectivity[first + 9]);
    }
  }

  void read_node_set(int dim, int tag) {
    std::vector<std::size_t> tags;
    std::vector<double> xyz;
    gmsh::model::mesh::getNodesForPhysicalGroup(dim, tag, tags, xyz);
    MeshFileNodeSet set;
    set.name = group_name(dim, tag);
    set.source = group_source(dim, tag);
    for (std::size_t t : tags) set.nodes.push_back(node_index(t));
    std::sort(set.nodes.begin(), set.nodes.end());
    set.nodes.erase(std::unique(set.nodes.begin(), set.nodes.end()), set.nodes.end());
    mesh_.node_sets.push_back(std::move(set));
  }

  std::string path_;
  RawMesh mesh_;
  std::unordered_map<std::size_t, int> index_of_tag_;
  std::map<std::size_t, std::string> owner_;  // element tag -> the block that has it
};

}  // namespace

RawMesh read_gmsh(const std::string& path) {
  require_msh_header(path);
  GmshSession session;
  try {
    gmsh::open(path);
    return GmshReader(path).read();
  } catch (const std::string& message) {  // Gmsh's API throws its error message
    mesh_error(path, "Gmsh cannot read it: " + explain_gmsh_error(path, message));
  }
}

}  // namespace modalcal::detail
