// Exodus II files through the Exodus II C library (exodusII.h, SEACAS): element blocks, node
// sets and side sets. Every integer is read as int64_t (EX_ALL_INT64_API), whatever the file
// stores.
#include <algorithm>
#include <cctype>
#include <cstdint>
#include <fstream>
#include <set>

#include <exodusII.h>
#include <netcdf.h>  // NC_MAX_NAME

#include "io/mesh_file_readers.hpp"
#include "support/text_util.hpp"

namespace modalcal::detail {

namespace {

std::string quote(const std::string& s) { return "'" + s + "'"; }

// The header of a netCDF classic file (the layouts CDF-1, CDF-2 and CDF-5, "The NetCDF Classic
// Format Specification"), walked before the netCDF library reads it: netCDF 4.9 trusts the counts
// it finds there and allocates and clears that much (a count off by a byte ran for minutes in
// nc_get_NC). Every count must fit in the bytes left, every type be known and every dimension id
// exist, no dimension be longer than the file, and the variables Exodus reads have the shapes it
// sizes their buffers by; the variables' data is not looked at. Only the first 16 MB are read: a
// header longer than that is taken as it is.
class ClassicHeader {
 public:
  explicit ClassicHeader(const std::string& path) : path_(path) {
    std::ifstream in(path, std::ios::binary | std::ios::ate);
    file_bytes_ = static_cast<uint64_t>(std::max<std::streamoff>(in.tellg(), 0));
    in.seekg(0);
    bytes_.resize(static_cast<size_t>(std::min<uint64_t>(file_bytes_, kMostBytes)));  // not 16 MB for a small file
    in.read(bytes_.data(), static_cast<std::streamsize>(bytes_.size()));
    bytes_.resize(static_cast<size_t>(in.gcount()));
    whole_ = in.gcount() < static_cast<std::streamsize>(kMostBytes) || in.peek() == EOF;
  }

  /// Throws a ProblemError for a classic header that does not hold together; anything that is
  /// not one (netCDF-4/HDF5, or no netCDF file at all) is left to the library.
  void check() {
    if (bytes_.size() < 4 || bytes_.compare(0, 3, "CDF") != 0) return;
    version_ = bytes_[3];
    if (version_ != 1 && version_ != 2 && version_ != 5) return;  // netCDF refuses it by itself
    at_ = 4;
    size();  // numrecs (or STREAMING)
    const uint64_t dims = list(kDimension, "dimension");
    for (uint64_t d = 0; d < dims && !stop_; ++d) {
      dimensions_.push_back(name("dimension"));
      // Nodes, elements and set members have data in the file, of at least a byte each: a longer
      // dimension is damage, and the reader would allocate by it (num_elem = 5.9e8 asked for 4.7 GB).
      const uint64_t length = size();
      dimension_lengths_.push_back(length);
      if (!stop_ && length > file_bytes_)
        fail("dimension '" + excerpt(dimensions_.back(), 40) + "' has length " + std::to_string(length) +
             ", more than the file's " + std::to_string(file_bytes_) + " bytes can hold");
    }
    attributes("global attribute");
    const uint64_t vars = list(kVariable, "variable");
    for (uint64_t v = 0; v < vars && !stop_; ++v) {
      const std::string variable = name("variable");
      std::vector<std::string> shape;
      std::vector<uint64_t> lengths;
      const uint64_t rank = count("variable dimensions", version_ == 5 ? 8 : 4);
      for (uint64_t k = 0; k < rank && !stop_; ++k) {
        const uint64_t id = size();
        if (stop_) break;
        if (id >= dims)
          fail("a variable has dimension id " + std::to_string(id) + ", but the file has " + std::to_string(dims) +
               " dimensions");
        shape.push_back(dimensions_[static_cast<size_t>(id)]);
        lengths.push_back(dimension_lengths_[static_cast<size_t>(id)]);
      }
      if (!stop_) check_shape(variable, shape);
      attributes("variable attribute");
      const uint64_t bytes_per_value = type();
      size();                                                                 // vsize
      const uint64_t begin = take(version_ == 1 ? 4 : 8, "a variable's data offset");
      if (!stop_) check_data_in_file(variable, lengths, bytes_per_value, begin);
    }
    if (stop_) return;
    std::sort(dimensions_.begin(), dimensions_.end());
    if (const auto twice = std::adjacent_find(dimensions_.begin(), dimensions_.end()); twice != dimensions_.end())
      fail("two dimensions are named '" + excerpt(*twice, 60) + "'");
  }

 private:
  static constexpr size_t kMostBytes = 16000000;
  static constexpr uint32_t kDimension = 0x0A, kVariable = 0x0B, kAttribute = 0x0C;

  [[noreturn]] void fail(const std::string& message) const {
    mesh_error(path_, "its netCDF header is damaged (at byte " + std::to_string(at_) + "): " + message);
  }

  // n big-endian bytes; at the end of a cut-short buffer, stops the check instead.
  uint64_t take(size_t n, const std::string& what) {
    if (stop_) return 0;
    if (bytes_.size() - at_ < n) {
      if (!whole_) {
        stop_ = true;
        return 0;
      }
      fail("the file ends where " + what + " should be");
    }
    uint64_t v = 0;
    for (size_t k = 0; k < n; ++k) v = (v << 8) | static_cast<unsigned char>(bytes_[at_ + k]);
    at_ += n;
    return v;
  }
  uint64_t size() { return take(version_ == 5 ? 8 : 4, "a size"); }
  // A count of items of at least `least` bytes each, which must fit in the rest of the file.
  uint64_t count(const std::string& what, uint64_t least) {
    const uint64_t n = size();
    if (!stop_ && whole_ && n > (bytes_.size() - at_) / least)
      fail("it counts " + std::to_string(n) + " " + what + ", more than the " +
           std::to_string(bytes_.size() - at_) + " bytes left can hold");
    return n;
  }
  uint64_t list(uint32_t tag, const std::string& what) {
    const uint64_t found = take(4, "the " + what + " list");
    if (!stop_ && found != tag && found != 0) fail("expected the " + what + " list");
    return count(what + "s", 8);
  }
  void skip(uint64_t n, const std::string& what) {
    const uint64_t padded = (n + 3) / 4 * 4;
    if (stop_) return;
    if (padded > bytes_.size() - at_) {
      if (!whole_) {
        stop_ = true;
        return;
      }
      fail("the file ends inside " + what);
    }
    at_ += static_cast<size_t>(padded);
  }
  std::string name(const std::string& what) {
    const uint64_t n = count("characters of a " + what + " name", 1);
    const size_t start = at_;
    skip(n, "a " + what + " name");
    return stop_ ? std::string() : bytes_.substr(start, static_cast<size_t>(n));
  }

  // The Exodus library reads these variables into buffers it sizes by the dimensions of these
  // names, so a variable of another shape (or a second variable of the same name) would overrun
  // them.
  void check_shape(const std::string& variable, const std::vector<std::string>& shape) {
    if (!variables_.insert(variable).second) fail("two variables are named '" + excerpt(variable, 60) + "'");
    // The variable's name without a trailing number, and that number.
    size_t digits = variable.size();
    while (digits > 0 && std::isdigit(static_cast<unsigned char>(variable[digits - 1]))) --digits;
    const std::string stem = variable.substr(0, digits), k = variable.substr(digits);
    std::vector<std::string> expected;
    if (variable == "coordx" || variable == "coordy" || variable == "coordz" || variable == "node_num_map")
      expected = {"num_nodes"};
    else if (variable == "coord")
      expected = {"num_dim", "num_nodes"};
    else if (variable == "elem_num_map")
      expected = {"num_elem"};
    else if (stem == "connect" && !k.empty())
      expected = {"num_el_in_blk" + k, "num_nod_per_el" + k};
    else if ((stem == "node_ns" || stem == "dist_fact_ns") && !k.empty())
      expected = {"num_nod_ns" + k};
    else if ((stem == "elem_ss" || stem == "side_ss") && !k.empty())
      expected = {"num_side_ss" + k};
    else if (variable == "eb_names" || variable == "ns_names" || variable == "ss_names")
      expected = {variable == "eb_names" ? "num_el_blk" : variable == "ns_names" ? "num_node_sets" : "num_side_sets",
                  "len_name"};
    else if ((stem == "eb_prop" && !k.empty()) || variable == "eb_status")
      expected = {"num_el_blk"};
    else if ((stem == "ns_prop" && !k.empty()) || variable == "ns_status")
      expected = {"num_node_sets"};
    else if ((stem == "ss_prop" && !k.empty()) || variable == "ss_status")
      expected = {"num_side_sets"};
    else
      return;
    if (shape != expected) {
      std::string found;
      for (const std::string& d : shape) found += (found.empty() ? "" : ", ") + excerpt(d, 40);
      fail("variable '" + excerpt(variable, 40) + "' has the dimensions (" + found + "); Exodus II gives it (" +
           expected[0] + (expected.size() > 1 ? ", " + expected[1] : "") + ")");
    }
  }
  // netCDF reads a variable whose data lies past the end of a cut-short file as fill values, so
  // a truncated copy would give zero coordinates or node 0 in a connectivity, far from the cause.
  // Record variables (first dimension unlimited, of length 0 here) are not checked: Exodus keeps
  // only results there, which the reader does not use.
  void check_data_in_file(const std::string& variable, const std::vector<uint64_t>& lengths, uint64_t bytes_per_value,
                          uint64_t begin) const {
    if (!lengths.empty() && lengths.front() == 0) return;
    uint64_t bytes = bytes_per_value;  // saturates at file_bytes_ + 1: more than any file can hold
    for (const uint64_t length : lengths)
      bytes = length != 0 && bytes > file_bytes_ / length ? file_bytes_ + 1 : bytes * length;
    if (bytes == 0 || (begin <= file_bytes_ && bytes <= file_bytes_ - begin)) return;
    const std::string end = bytes > file_bytes_ || begin > file_bytes_ ? "beyond byte " + std::to_string(file_bytes_)
                                                                       : "at byte " + std::to_string(begin + bytes);
    mesh_error(path_, "is cut short (an incomplete copy or download?): the data of variable '" + excerpt(variable, 40) +
                          "' would end " + end + ", but the file has " + std::to_string(file_bytes_) + " bytes");
  }
  uint64_t type() {
    const uint64_t t = take(4, "a type");
    static const int sizes[] = {0, 1, 1, 2, 4, 4, 8, 1, 2, 4, 8, 8};
    if (!stop_ && (t < 1 || t > (version_ == 5 ? 11u : 6u))) fail("unknown data type " + std::to_string(t));
    return stop_ ? 1 : static_cast<uint64_t>(sizes[t]);
  }
  void attributes(const std::string& what) {
    const uint64_t n = list(kAttribute, what);
    for (uint64_t a = 0; a < n && !stop_; ++a) {
      const std::string attribute = name(what);
      const uint64_t bytes_per_value = type();
      const uint64_t values = count("values of a " + what, bytes_per_value);
      // ex_open reads these into one number on its stack: more values overrun it (found by fuzzing).
      if (!stop_ && what == "global attribute" && read_as_one_number(attribute) && values != 1)
        fail("global attribute '" + attribute + "' has " + std::to_string(values) +
             " values; Exodus reads it as one number");
      skip(values * bytes_per_value, "the values of a " + what);
    }
  }
  static bool read_as_one_number(const std::string& attribute) {
    static const std::set<std::string> names = {"api_version",         "api version", "version",
                                                "floating_point_word_size", "floating point word size",
                                                "file_size",           "maximum_name_length", "int64_status",
                                                "nemesis_api_version", "nemesis_file_version"};
    return names.count(attribute) > 0;
  }

  std::string path_;
  std::string bytes_;
  bool whole_ = true;  // bytes_ is the whole file
  bool stop_ = false;  // the header runs past the bytes read
  int version_ = 0;
  size_t at_ = 0;
  uint64_t file_bytes_ = 0;
  std::vector<std::string> dimensions_;  // by id
  std::vector<uint64_t> dimension_lengths_;  // by id
  std::set<std::string> variables_;
};

class ExodusFile {
 public:
  explicit ExodusFile(const std::string& path) : path_(path) {
    int cpu_word_size = sizeof(double), io_word_size = 0;
    float version = 0;
    ClassicHeader(path).check();
    id_ = ex_open(path.c_str(), EX_READ, &cpu_word_size, &io_word_size, &version);
    if (id_ < 0) fail("is not an Exodus II file, or the Exodus library cannot open it: " + last_error());
    ex_set_int64_status(id_, EX_ALL_INT64_API);
    // Names longer than the default 32 characters would otherwise come back truncated.
    const int64_t name_length = ex_inquire_int(id_, EX_INQ_DB_MAX_USED_NAME_LENGTH);
    // The attribute sizes every name buffer; 1.1e9 made each name a gigabyte (found by fuzzing).
    if (name_length > NC_MAX_NAME)
      fail("its maximum_name_length attribute is " + std::to_string(name_length) + ", but names have at most " +
           std::to_string(NC_MAX_NAME) + " characters: the file is probably damaged");
    max_name_length_ = static_cast<int>(std::max<int64_t>(name_length, 1));
    ex_set_max_name_length(id_, max_name_length_);
  }
  ~ExodusFile() {
    if (id_ >= 0) ex_close(id_);
  }
  ExodusFile(const ExodusFile&) = delete;
  ExodusFile& operator=(const ExodusFile&) = delete;

  int id() const { return id_; }
  const std::string& path() const { return path_; }

  [[noreturn]] void fail(const std::string& message) const { mesh_error(path_, message); }

  /// Fails with `what` and the library's message unless `status` is success (0) or a warning (> 0).
  void check(int status, const std::string& what) const {
    if (status < 0) fail("cannot read " + what + ": " + last_error());
  }

  std::vector<int64_t> ids(ex_entity_type type, int64_t count, const std::string& what) const {
    std::vector<int64_t> out(static_cast<size_t>(count));
    if (count > 0) check(ex_get_ids(id_, type, out.data()), what + " ids");
    return out;
  }

  /// The entities' names, "" where the file gives none.
  std::vector<std::string> names(ex_entity_type type, int64_t count, const std::string& what) const {
    std::vector<std::vector<char>> buffers(static_cast<size_t>(count), std::vector<char>(max_name_length_ + 1, '\0'));
    std::vector<char*> pointers;
    for (auto& b : buffers) pointers.push_back(b.data());
    if (count > 0) check(ex_get_names(id_, type, pointers.data()), what + " names");
    std::vector<std::string> out;
    for (const auto& b : buffers) {
      std::string name(b.data());
      while (!name.empty() && std::isspace(static_cast<unsigned char>(name.back()))) name.pop_back();
      out.push_back(name);
    }
    return out;
  }

 private:
  static std::string last_error() {
    const char* message = nullptr;
    const char* function = nullptr;
    int code = 0;
    ex_get_err(&message, &function, &code);
    std::string text = message && *message ? message : "unknown error";
    // Negative codes are netCDF's (e.g. -51: not a netCDF file). nc_strerror would name them, but
    // Debian's Exodus links the MPI build of netCDF, which has no development library to link.
    if (code < 0) text += " (netCDF error " + std::to_string(code) + ")";
    return text;
  }

  std::string path_;
  int id_ = -1;
  int max_name_length_ = 32;
};

std::string upper(std::string s) {
  std::transform(s.begin(), s.end(), s.begin(), [](unsigned char c) { return static_cast<char>(std::toupper(c)); });
  return s;
}

// Exodus names a type (HEX8, HEX, TETRA, TETRA10, TET4, ...) and gives the nodes per element.
bool solid_type_of(const std::string& exodus_type, int64_t nodes, SolidType* type) {
  const std::string name = upper(exodus_type);
  if (name.rfind("HEX", 0) == 0 && nodes == 8) *type = SolidType::Hex8;
  else if (name.rfind("TET", 0) == 0 && nodes == 4) *type = SolidType::Tet4;
  else if (name.rfind("TET", 0) == 0 && nodes == 10) *type = SolidType::Tet10;
  else return false;
  return true;
}

std::string name_or(const std::string& name, const std::string& prefix, int64_t id) {
  return name.empty() ? prefix + "_" + std::to_string(id) : name;
}

class ExodusReader {
 public:
  explicit ExodusReader(const std::string& path) : file_(path) {}

  RawMesh read() {
    ex_init_params init{};
    file_.check(ex_get_init_ext(file_.id(), &init), "the file's sizes (ex_get_init)");
    if (init.num_dim != 3)
      file_.fail("is a " + std::to_string(init.num_dim) + "-D mesh (num_dim = " + std::to_string(init.num_dim) +
                 "); modalcal needs a 3-D mesh of solid elements");
    read_nodes(init.num_nodes);
    read_blocks(init.num_elem_blk, init.num_elem);
    read_node_sets(init.num_node_sets);
    read_side_sets(init.num_side_sets);
    return std::move(mesh_);
  }

 private:
  void read_nodes(int64_t count) {
    std::vector<double> x(static_cast<size_t>(count)), y(x.size()), z(x.size());
    std::vector<int64_t> ids(x.size());
    if (count > 0) {
      file_.check(ex_get_coord(file_.id(), x.data(), y.data(), z.data()), "the node coordinates");
      file_.check(ex_get_id_map(file_.id(), EX_NODE_MAP, ids.data()), "the node number map");
    }
    for (size_t i = 0; i < x.size(); ++i) {
      mesh_.coordinates.emplace_back(x[i], y[i], z[i]);
      mesh_.node_ids.push_back(static_cast<long>(ids[i]));
    }
  }

  // 1-based node number from the file -> index, checked.
  int node_index(int64_t number, const std::string& where) const {
    if (number < 1 || number > static_cast<int64_t>(mesh_.coordinates.size()))
      file_.fail(where + " refers to node " + std::to_string(number) + ", but the file has nodes 1.." +
                 std::to_string(mesh_.coordinates.size()));
    return static_cast<int>(number - 1);
  }

  void read_blocks(int64_t count, int64_t num_elements) {
    num_elements_ = num_elements;
    std::vector<int64_t> element_ids(static_cast<size_t>(num_elements));
    if (num_elements > 0)
      file_.check(ex_get_id_map(file_.id(), EX_ELEM_MAP, element_ids.data()), "the element number map");
    const std::vector<int64_t> ids = file_.ids(EX_ELEM_BLOCK, count, "element block");
    const std::vector<std::string> names = file_.names(EX_ELEM_BLOCK, count, "element block");
    size_t first_element = 0;  // blocks number their elements consecutively, in file order
    for (size_t b = 0; b < ids.size(); ++b) {
      const std::string name = name_or(names[b], "block", ids[b]);
      const std::string what = "element block " + quote(name) + " (id " + std::to_string(ids[b]) + ")";
      char type_name[MAX_STR_LENGTH + 1] = {};
      int64_t elements = 0, nodes = 0, edges = 0, faces = 0, attributes = 0;
      file_.check(ex_get_block(file_.id(), EX_ELEM_BLOCK, ids[b], type_name, &elements, &nodes, &edges, &faces,
                               &attributes),
                  what);
      block_starts_.push_back(first_element);
      MeshFileBlock block;
      block.name = name;
      block.id = ids[b];
      if (elements > 0 && !solid_type_of(type_name, nodes, &block.type))
        file_.fail(what + " has " + std::to_string(elements) + " elements of type " + quote(type_name) + " with " +
                   std::to_string(nodes) + " nodes, which modalcal does not support; supported: HEX8, TETRA (4 nodes), "
                   "TETRA10");
      if (first_element + static_cast<size_t>(elements) > element_ids.size())
        file_.fail(what + " has elements beyond the file's " + std::to_string(num_elements) + " elements");
      std::vector<int64_t> connectivity(static_cast<size_t>(elements * nodes));
      if (elements > 0)
        file_.check(ex_get_conn(file_.id(), EX_ELEM_BLOCK, ids[b], connectivity.data(), nullptr, nullptr),
                    "the connectivity of " + what);
      for (int64_t v : connectivity) block.connectivity.push_back(node_index(v, what));
      for (int64_t e = 0; e < elements; ++e) block.element_ids.push_back(static_cast<long>(element_ids[first_element + static_cast<size_t>(e)]));
      first_element += static_cast<size_t>(elements);
      if (elements == 0)
        mesh_.warnings.push_back(file_.path() + ": " + what + " has no elements and is left out");
      block_index_.push_back(elements == 0 ? -1 : static_cast<int>(mesh_.blocks.size()));
      if (elements > 0) mesh_.blocks.push_back(std::move(block));
    }
    elements_in_blocks_ = static_cast<int64_t>(first_element);
  }

  void read_node_sets(int64_t count) {
    const std::vector<int64_t> ids = file_.ids(EX_NODE_SET, count, "node set");
    const std::vector<std::string> names = file_.names(EX_NODE_SET, count, "node set");
    for (size_t s = 0; s < ids.size(); ++s) {
      MeshFileNodeSet set;
      set.name = name_or(names[s], "nodeset", ids[s]);
      set.source = "node set " + std::to_string(ids[s]);
      const std::string what = "node set " + quote(set.name) + " (id " + std::to_string(ids[s]) + ")";
      int64_t size = 0, factors = 0;
      file_.check(ex_get_set_param(file_.id(), EX_NODE_SET, ids[s], &size, &factors), what);
      std::vector<int64_t> nodes(static_cast<size_t>(size));
      if (size > 0) file_.check(ex_get_set(file_.id(), EX_NODE_SET, ids[s], nodes.data(), nullptr), what);
      for (int64_t v : nodes) set.nodes.push_back(node_index(v, what));
      add_node_set(std::move(set));
    }
  }

  void read_side_sets(int64_t count) {
    const std::vector<int64_t> ids = file_.ids(EX_SIDE_SET, count, "side set");
    const std::vector<std::string> names = file_.names(EX_SIDE_SET, count, "side set");
    for (size_t s = 0; s < ids.size(); ++s) {
      MeshFileSideSet sides;
      sides.name = name_or(names[s], "sideset", ids[s]);
      sides.id = ids[s];
      const std::string what = "side set " + quote(sides.name) + " (id " + std::to_string(ids[s]) + ")";
      int64_t size = 0, factors = 0;
      file_.check(ex_get_set_param(file_.id(), EX_SIDE_SET, ids[s], &size, &factors), what);
      std::vector<int64_t> elements(static_cast<size_t>(size)), side_numbers(elements.size());
      if (size > 0)
        file_.check(ex_get_set(file_.id(), EX_SIDE_SET, ids[s], elements.data(), side_numbers.data()), what);
      MeshFileNodeSet set;
      set.name = sides.name;
      set.source = "side set " + std::to_string(ids[s]);
      for (size_t k = 0; k < elements.size(); ++k) {
        add_side_nodes(elements[k], side_numbers[k], what, &set.nodes);
        sides.elements.push_back(static_cast<long>(elements[k]));
        sides.sides.push_back(static_cast<int>(side_numbers[k]));
      }
      add_node_set(std::move(set));
      mesh_.side_sets.push_back(std::move(sides));
    }
  }

  // Side `side` of element `element` (1-based over all blocks): its nodes.
  void add_side_nodes(int64_t element, int64_t side, const std::string& what, std::vector<int>* nodes) const {
    if (element < 1 || element > num_elements_)
      file_.fail(what + " refers to element " + std::to_string(element) + ", but the file has elements 1.." +
                 std::to_string(num_elements_));
    if (element > elements_in_blocks_)  // num_elem counts more elements than the blocks hold
      file_.fail(what + " refers to element " + std::to_string(element) + ", but the element blocks hold elements 1.." +
                 std::to_string(elements_in_blocks_) + " (num_elem is " + std::to_string(num_elements_) + ")");
    // The last block starting at or before the element; an empty block starts where the next
    // one does, so this is never an empty block.
    const auto index = static_cast<size_t>(element - 1);
    const size_t b = static_cast<size_t>(std::upper_bound(block_starts_.begin(), block_starts_.end(), index) -
                                         block_starts_.begin()) - 1;
    const MeshFileBlock& block = mesh_.blocks[static_cast<size_t>(block_index_[b])];
    if (side < 1 || side > num_solid_sides(block.type))
      file_.fail(what + " refers to side " + std::to_string(side) + " of element " + std::to_string(element) +
                 ", but a " + solid_type_name(block.type) + " has sides 1.." + std::to_string(num_solid_sides(block.type)));
    const size_t n = static_cast<size_t>(nodes_per_element(block.type));
    for (int k : solid_side_nodes(block.type, static_cast<int>(side)))
      nodes->push_back(block.connectivity[(index - block_starts_[b]) * n + static_cast<size_t>(k)]);
  }

  void add_node_set(MeshFileNodeSet set) {
    std::sort(set.nodes.begin(), set.nodes.end());
    set.nodes.erase(std::unique(set.nodes.begin(), set.nodes.end()), set.nodes.end());
    mesh_.node_sets.push_back(std::move(set));
  }

  ExodusFile file_;
  RawMesh mesh_;
  std::vector<size_t> block_starts_;  // first element (0-based, over all blocks) of each file block
  std::vector<int> block_index_;      // each file block's index in mesh_.blocks, -1 if left out (empty)
  int64_t num_elements_ = 0;
  int64_t elements_in_blocks_ = 0;  // the blocks' elements together: side sets may name no other
};

}  // namespace

RawMesh read_exodus(const std::string& path) { return ExodusReader(path).read(); }

}  // namespace modalcal::detail
