// Gmsh .msh files through the Gmsh library's C++ API (gmsh.h): physical volume groups become
// element blocks, physical surface, curve and point groups node sets.
#include <algorithm>
#include <charconv>
#include <climits>
#include <cstdlib>
#include <fstream>
#include <map>
#include <mutex>
#include <sstream>
#include <string>
#include <unordered_map>
#include <vector>

#include <gmsh.h>

#include "io/mesh_file_readers.hpp"
#include "support/text_util.hpp"
#include "modalcal/problem.hpp"

namespace modalcal::detail {

namespace {

std::string quote(const std::string& s) { return "'" + s + "'"; }

// Gmsh element type codes (Gmsh reference manual, "MSH file format": element types).
constexpr int kGmshTet4 = 4, kGmshHex8 = 5, kGmshTet10 = 11;

// The Gmsh API is one global state: one caller at a time. Gmsh stays initialized between reads
// and is cleared before each: an initialize and finalize per read cost tens of milliseconds and
// leak a few kilobytes inside Gmsh 4.8 every time (docs/fuzzing.md). gmsh::initialize on an
// initialized Gmsh only warns, so a caller that finalized Gmsh in between does no harm.
class GmshSession {
 public:
  GmshSession() : lock_(mutex()) {
    gmsh::initialize(0, nullptr, /*readConfigFiles=*/false);
    gmsh::option::setNumber("General.Terminal", 0);  // messages come back as exceptions, not on stdout
    gmsh::clear();
    gmsh::logger::start();  // warnings through the logger, from this read only
  }
  ~GmshSession() {
    gmsh::logger::stop();
    gmsh::clear();  // the mesh is copied out: free Gmsh's copy now
  }
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

// Nodes per element of each MSH 2 element type (Gmsh reference manual, "MSH file format version
// 2 (legacy)"); 0 for a number that is no element type.
int msh2_nodes_per_element(long type) {
  static const std::map<long, int> nodes = {
      {1, 2},   {2, 3},   {3, 4},   {4, 4},   {5, 8},   {6, 6},   {7, 5},   {8, 3},   {9, 6},   {10, 9},  {11, 10},
      {12, 27}, {13, 18}, {14, 14}, {15, 1},  {16, 8},  {17, 20}, {18, 15}, {19, 13}, {20, 9},  {21, 10}, {22, 12},
      {23, 15}, {24, 15}, {25, 21}, {26, 4},  {27, 5},  {28, 6},  {29, 20}, {30, 35}, {31, 56}, {92, 64}, {93, 125}};
  const auto it = nodes.find(type);
  return it == nodes.end() ? 0 : it->second;
}

// A number as Gmsh reads one with strtod (so "nan" and "inf" too, refused later by name).
bool is_number(const std::string& token) {
  char* end = nullptr;
  std::strtod(token.c_str(), &end);
  return !token.empty() && end == token.c_str() + token.size();
}

bool whole_numbers(const std::string& line, std::vector<long>* out) {
  out->clear();
  std::istringstream in(line);
  std::string token;
  while (in >> token) {
    long v = 0;
    const auto [ptr, ec] = std::from_chars(token.data(), token.data() + token.size(), v);
    if (ec != std::errc() || ptr != token.data() + token.size()) return false;
    out->push_back(v);
  }
  return true;
}

// Gmsh 4.8's MSH 2 reader follows a null node, and crashes, for an element naming a node that
// $Nodes does not define, or with fewer numbers than its type has nodes (it then takes the next
// line's numbers for nodes). So an ASCII MSH 2 file has its $Nodes and $Elements lines checked
// here first: a node line is a node number and three coordinates; an element line is whole
// numbers: its number, an element type, the count of tags, the tags, and exactly as many nodes as
// the type has, each defined above. Other versions and binary files go to Gmsh as they are.
void check_msh2_ascii(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  std::string line;
  int line_number = 0;
  auto next = [&] {
    if (!std::getline(in, line)) return false;
    ++line_number;
    if (!line.empty() && line.back() == '\r') line.pop_back();
    return true;
  };
  auto fail = [&](const std::string& message) {
    if (!ends_with_a_section(path))
      throw ProblemError(path, line_number, "the file ends inside a section (its last line is no $End... line): it "
                                            "is probably truncated");
    throw ProblemError(path, line_number, message);
  };
  next();  // $MeshFormat, checked by require_msh_header
  double version = 0;
  int file_type = -1;
  if (!next() || !(std::istringstream(line) >> version >> file_type) || version < 2 || version >= 3 || file_type != 0)
    return;
  std::unordered_map<long, int> defined;  // node number -> line
  std::unordered_map<long, int> elements;  // element number -> line
  std::vector<long> numbers;
  auto count_line = [&](const std::string& section) {
    if (!next()) fail("the file ends after " + section + "; the count of its entries should follow");
    if (!whole_numbers(line, &numbers) || numbers.size() != 1 || numbers[0] < 0)
      fail(section + " should be followed by the count of its entries, found '" + excerpt(trim(line), 60) + "'");
    return numbers[0];
  };
  while (next()) {
    const std::string section = trim(line);
    if (section == "$Nodes") {
      const long count = count_line(section);
      for (long k = 0; k < count; ++k) {
        if (!next()) fail("the file ends inside $Nodes, after " + std::to_string(k) + " of its " +
                          std::to_string(count) + " nodes");
        std::istringstream fields(line);
        std::string id_text, coordinate[3], extra;
        if (!(fields >> id_text >> coordinate[0] >> coordinate[1] >> coordinate[2]) || (fields >> extra) ||
            !whole_numbers(id_text, &numbers) || !is_number(coordinate[0]) || !is_number(coordinate[1]) ||
            !is_number(coordinate[2]))
          fail("a node line is a node number and three coordinates, found '" + excerpt(trim(line), 60) + "'");
        // Gmsh's MSH 2 reader keeps node numbers in an int: a larger one wraps onto another node.
        if (numbers[0] > INT_MAX)
          fail("node number " + std::to_string(numbers[0]) + " is above 2147483647, the largest Gmsh's MSH 2 reader "
               "keeps (a larger one would wrap onto another node); renumber the nodes");
        if (const auto [it, is_new] = defined.emplace(numbers[0], line_number); !is_new)
          fail("a node id is defined twice (node " + std::to_string(numbers[0]) + ", at lines " +
               std::to_string(it->second) + " and " + std::to_string(line_number) + ")");
      }
    } else if (section == "$Elements") {
      const long count = count_line(section);
      for (long k = 0; k < count; ++k) {
        if (!next()) fail("the file ends inside $Elements, after " + std::to_string(k) + " of its " +
                          std::to_string(count) + " elements");
        if (!whole_numbers(line, &numbers) || numbers.size() < 3 || numbers[2] < 0)
          fail("an element line is whole numbers (number, type, count of tags, tags, nodes), found '" +
               excerpt(trim(line), 60) + "'");
        const long element = numbers[0], type = numbers[1], tags = numbers[2];
        // Gmsh keeps one of two elements with the same number and drops the other without a word.
        if (const auto [it, is_new] = elements.emplace(element, line_number); !is_new)
          fail("an element id is defined twice (element " + std::to_string(element) + ", at lines " +
               std::to_string(it->second) + " and " + std::to_string(line_number) + ")");
        const int nodes = msh2_nodes_per_element(type);
        if (nodes == 0) fail("element " + std::to_string(element) + " has type " + std::to_string(type) +
                             ", which is no MSH 2 element type");
        const long found = static_cast<long>(numbers.size()) - 3 - tags;  // tags >= 0: no overflow
        if (found != nodes)
          fail("element " + std::to_string(element) + " (type " + std::to_string(type) + ", " + std::to_string(tags) +
               " tags) should have " + std::to_string(nodes) + " nodes after its tags, found " +
               (found < 0 ? "fewer numbers than tags" : std::to_string(found)));
        for (size_t i = 3 + static_cast<size_t>(tags); i < numbers.size(); ++i)
          if (!defined.count(numbers[i]))
            fail("element " + std::to_string(element) + " refers to node " + std::to_string(numbers[i]) +
                 ", which $Nodes does not define");
      }
    }
  }
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
  check_msh2_ascii(path);
  GmshSession session;
  try {
    gmsh::open(path);
    return GmshReader(path).read();
  } catch (const std::string& message) {  // Gmsh's API throws its error message
    mesh_error(path, "Gmsh cannot read it: " + explain_gmsh_error(path, message));
  }
}

}  // namespace modalcal::detail
