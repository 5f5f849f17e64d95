// Meshes from files (read_mesh_file, `mesh: {file: ...}`): Gmsh and Exodus II meshes written
// here with the Gmsh and Exodus libraries are read back and compared item by item, models
// from them have the box mesher's frequencies where the meshes coincide, tet10 mid-nodes are
// where our (Exodus) node order says, and malformed files fail naming the file and the fault.
#include <algorithm>
#include <cstdint>
#include <filesystem>
#include <fstream>
#include <map>
#include <set>
#include <string>
#include <vector>

#include <exodusII.h>
#include <gmsh.h>
#include <gtest/gtest.h>

#include "io/box_mesh.hpp"
#include "modalcal/assembly.hpp"
#include "modalcal/eigen.hpp"
#include "modalcal/mesh_file.hpp"
#include "modalcal/problem.hpp"
#include "modalcal/problem_file.hpp"
#include "test_util.hpp"

namespace modalcal {
namespace {

using testing::LoadProblem;
using testing::WriteTempFile;

// ---------------------------------------------------------------------------- writers

/// Builds a Gmsh model through the Gmsh API and writes it; Gmsh's state is global, so the
/// session ends (finalize) before anything reads the file.
class GmshWriter {
 public:
  GmshWriter() {
    gmsh::initialize(0, nullptr, false);
    gmsh::option::setNumber("General.Terminal", 0);
    gmsh::model::add("test");
  }
  ~GmshWriter() { gmsh::finalize(); }
  GmshWriter(const GmshWriter&) = delete;
  GmshWriter& operator=(const GmshWriter&) = delete;

  void Write(const std::string& path, double version = 4.1, bool binary = false) {
    gmsh::option::setNumber("Mesh.MshFileVersion", version);
    gmsh::option::setNumber("Mesh.Binary", binary ? 1 : 0);
    gmsh::write(path);
  }
};

int AddPhysical(int dim, const std::vector<int>& tags, const std::string& name) {
  const int tag = gmsh::model::addPhysicalGroup(dim, tags);
  if (!name.empty()) gmsh::model::setPhysicalName(dim, tag, name);
  return tag;
}

/// Entities of dimension `dim` inside a box (bounds widened by 1e-6).
std::vector<int> EntitiesIn(int dim, const Vec3& lo, const Vec3& hi) {
  gmsh::vectorpair found;
  const double e = 1e-6;
  gmsh::model::getEntitiesInBoundingBox(lo.x() - e, lo.y() - e, lo.z() - e, hi.x() + e, hi.y() + e, hi.z() + e, found, dim);
  std::vector<int> tags;
  for (const auto& [d, t] : found) tags.push_back(t);
  return tags;
}

/// A structured hex8 mesh of [0, size] by extruding a point, a line and a square with
/// `divisions` layers (the grid the box mesher makes). Returns the volume's tag.
int ExtrudeHexBox(const Vec3& size, const std::array<int, 3>& divisions, bool recombine = true) {
  gmsh::vectorpair line, surface, volume;
  const int p = gmsh::model::geo::addPoint(0, 0, 0);
  gmsh::model::geo::extrude({{0, p}}, size.x(), 0, 0, line, {divisions[0]}, {}, true);
  gmsh::model::geo::extrude({line[1]}, 0, size.y(), 0, surface, {divisions[1]}, {}, recombine);
  gmsh::model::geo::extrude({surface[1]}, 0, 0, size.z(), volume, {divisions[2]}, {}, recombine);
  gmsh::model::geo::synchronize();
  return volume[1].second;
}

/// An Exodus II mesh as the writer takes it: 1-based node numbers, as in the file.
struct ExodusBlock {
  std::string name;
  int64_t id = 0;
  std::string type;  // HEX8, TETRA, TETRA10, ...
  int nodes_per_element = 0;
  std::vector<int64_t> connectivity;
};
struct ExodusSet {
  std::string name;
  int64_t id = 0;
  std::vector<int64_t> entries;  // node numbers, or element numbers of a side set
  std::vector<int64_t> sides;    // side sets only
};
struct ExodusMesh {
  int dim = 3;
  std::vector<Vec3> coordinates;
  std::vector<int64_t> node_ids;  // the node number map; empty: none
  std::vector<ExodusBlock> blocks;
  std::vector<ExodusSet> node_sets, side_sets;
};

void PutNames(int exo, ex_entity_type type, const std::vector<std::string>& names) {
  std::vector<char*> pointers;
  for (const std::string& n : names) pointers.push_back(const_cast<char*>(n.c_str()));
  ASSERT_GE(ex_put_names(exo, type, pointers.data()), 0);
}

void PutSets(int exo, ex_entity_type type, const std::vector<ExodusSet>& sets) {
  std::vector<std::string> names;
  for (const ExodusSet& s : sets) {
    ASSERT_GE(ex_put_set_param(exo, type, s.id, static_cast<int64_t>(s.entries.size()), 0), 0);
    ASSERT_GE(ex_put_set(exo, type, s.id, s.entries.data(), type == EX_SIDE_SET ? s.sides.data() : nullptr), 0);
    names.push_back(s.name);
  }
  if (!sets.empty()) PutNames(exo, type, names);
}

/// Writes `mesh` with the Exodus II C API (int64 throughout).
void WriteExodus(const std::string& path, const ExodusMesh& mesh) {
  int cpu_word_size = sizeof(double), io_word_size = sizeof(double);
  const int exo = ex_create(path.c_str(), EX_CLOBBER, &cpu_word_size, &io_word_size);
  ASSERT_GE(exo, 0) << path;
  ex_set_int64_status(exo, EX_ALL_INT64_API);
  int64_t elements = 0;
  for (const ExodusBlock& b : mesh.blocks) elements += static_cast<int64_t>(b.connectivity.size()) / b.nodes_per_element;
  ASSERT_GE(ex_put_init(exo, "modalcal test mesh", mesh.dim, static_cast<int64_t>(mesh.coordinates.size()), elements,
                        static_cast<int64_t>(mesh.blocks.size()), static_cast<int64_t>(mesh.node_sets.size()),
                        static_cast<int64_t>(mesh.side_sets.size())),
            0);
  std::vector<double> x, y, z;
  for (const Vec3& p : mesh.coordinates) {
    x.push_back(p.x());
    y.push_back(p.y());
    z.push_back(p.z());
  }
  ASSERT_GE(ex_put_coord(exo, x.data(), y.data(), mesh.dim == 3 ? z.data() : nullptr), 0);
  if (!mesh.node_ids.empty()) {
    ASSERT_GE(ex_put_id_map(exo, EX_NODE_MAP, mesh.node_ids.data()), 0);
  }
  std::vector<std::string> names;
  for (const ExodusBlock& b : mesh.blocks) {
    const int64_t n = static_cast<int64_t>(b.connectivity.size()) / b.nodes_per_element;
    ASSERT_GE(ex_put_block(exo, EX_ELEM_BLOCK, b.id, b.type.c_str(), n, b.nodes_per_element, 0, 0, 0), 0);
    ASSERT_GE(ex_put_conn(exo, EX_ELEM_BLOCK, b.id, b.connectivity.data(), nullptr, nullptr), 0);
    names.push_back(b.name);
  }
  PutNames(exo, EX_ELEM_BLOCK, names);
  PutSets(exo, EX_NODE_SET, mesh.node_sets);
  PutSets(exo, EX_SIDE_SET, mesh.side_sets);
  ex_close(exo);
}

// Exodus side numbering as the Exodus II manual draws it (tet sides 1-4: corners 1-2-4, 2-3-4,
// 1-4-3, 1-3-2; hex sides 1-6: 1-2-6-5, 2-3-7-6, 3-4-8-7, 1-5-8-4, 1-4-3-2, 5-6-7-8), 0-based.
const std::vector<std::vector<int>> kExodusTetSides = {{0, 1, 3}, {1, 2, 3}, {0, 3, 2}, {0, 2, 1}};
const std::vector<std::vector<int>> kExodusHexSides = {{0, 1, 5, 4}, {1, 2, 6, 5}, {2, 3, 7, 6},
                                                       {0, 4, 7, 3}, {0, 3, 2, 1}, {4, 5, 6, 7}};

/// The box mesher's mesh of `boxes` as an Exodus mesh: one block per box block, node ids
/// 1001, 1002, ..., a node set of the nodes at x = 0 and a side set of the element sides on the
/// plane coordinate[axis] = value, found by looking for the side whose corners lie on it.
ExodusMesh BoxMeshAsExodus(const std::vector<detail::MeshBox>& boxes, const std::vector<std::string>& block_names,
                           SolidType type, double element_size, int side_axis, double side_value) {
  const detail::BoxMesh box = detail::generate_box_mesh(boxes, static_cast<int>(block_names.size()), type, element_size, 1.0);
  ExodusMesh mesh;
  mesh.coordinates = box.coordinates;
  ExodusSet left{"left_end", 10, {}, {}}, side{"far_side", 20, {}, {}};
  for (size_t v = 0; v < box.coordinates.size(); ++v) {
    mesh.node_ids.push_back(1001 + static_cast<int64_t>(v));
    if (std::abs(box.coordinates[v].x()) < 1e-12) left.entries.push_back(static_cast<int64_t>(v) + 1);
  }
  const int n = nodes_per_element(type);
  const auto& sides = type == SolidType::Hex8 ? kExodusHexSides : kExodusTetSides;
  int64_t element = 0;
  for (size_t b = 0; b < block_names.size(); ++b) {
    ExodusBlock block{block_names[b], 100 + static_cast<int64_t>(b),
                      type == SolidType::Hex8 ? "HEX8" : type == SolidType::Tet4 ? "TETRA" : "TETRA10", n, {}};
    const std::vector<int>& conn = box.connectivity[b];
    for (size_t e = 0; e < conn.size() / n; ++e) {
      ++element;
      for (int k = 0; k < n; ++k) block.connectivity.push_back(conn[e * n + k] + 1);
      for (size_t s = 0; s < sides.size(); ++s)
        if (std::all_of(sides[s].begin(), sides[s].end(), [&](int corner) {
              return std::abs(box.coordinates[conn[e * n + corner]][side_axis] - side_value) < 1e-12;
            })) {
          side.entries.push_back(element);
          side.sides.push_back(static_cast<int64_t>(s) + 1);
        }
    }
    mesh.blocks.push_back(block);
  }
  mesh.node_sets = {left};
  mesh.side_sets = {side};
  return mesh;
}

// ---------------------------------------------------------------------------- helpers

/// External ids of a node set's nodes.
std::set<long> IdsOf(const MeshFile& mesh, const std::vector<int>& nodes) {
  std::set<long> ids;
  for (int v : nodes) ids.insert(mesh.node_ids[v]);
  return ids;
}

/// Nodes of the mesh whose coordinate[axis] equals value.
std::set<long> IdsOnPlane(const MeshFile& mesh, int axis, double value) {
  std::set<long> ids;
  for (int v = 0; v < mesh.num_nodes(); ++v)
    if (std::abs(mesh.coordinates[v][axis] - value) < 1e-9) ids.insert(mesh.node_ids[v]);
  return ids;
}

/// The lowest elastic frequencies of a problem at its initial parameter values.
std::vector<double> Frequencies(const Problem& problem, int count) {
  ParametricSystem system(problem.model, problem.parameter_targets());
  SparseMatrix K, M;
  system.assemble(problem.initial_values(), &K, &M);
  ModalOptions options;
  options.num_modes = count;
  options.max_rigid_modes = problem.expected_rigid_modes();
  ModalSolver solver(system.pattern(), options);
  const ModalResult result = solver.solve(K, M);
  EXPECT_EQ(result.status, EigenStatus::Successful) << result.message;
  std::vector<double> hz;
  for (Eigen::Index i = 0; i < result.eigenvalues.size(); ++i) hz.push_back(frequency_hz(result.eigenvalues[i]));
  return hz;
}

void ExpectSameFrequencies(const std::vector<double>& a, const std::vector<double>& b) {
  ASSERT_EQ(a.size(), b.size());
  for (size_t i = 0; i < a.size(); ++i) EXPECT_TRUE(testing::IsClose(a[i], b[i], 1e-9)) << "mode " << i + 1;
}

/// read_mesh_file(path) must throw a ProblemError for `path` whose message has every fragment.
void ExpectMeshError(const std::string& path, const std::vector<std::string>& fragments) {
  try {
    read_mesh_file(path);
    ADD_FAILURE() << "expected a ProblemError for " << path;
  } catch (const ProblemError& e) {
    EXPECT_EQ(e.file(), path);
    const std::string what = e.what();
    EXPECT_EQ(what.rfind(path + ": ", 0), 0u) << what;
    for (const std::string& f : fragments) EXPECT_NE(what.find(f), std::string::npos) << "'" << f << "' not in: " << what;
  }
}

const char* const kSteel = "  steel: {E: 2.0e11, nu: 0.3, density: 7800}\n";

// ---------------------------------------------------------------------------- Gmsh

// Blocks, connectivity and node sets as Gmsh itself lists them before writing.
TEST(GmshMesh, HexBoxRoundTripKeepsNodesElementsAndPhysicalGroups) {
  const std::string path = WriteTempFile("box.msh", "");
  std::vector<std::size_t> element_tags, element_nodes, left_nodes, edge_nodes, corner_nodes;
  int left_tag = 0, edge_tag = 0;
  {
    GmshWriter gmsh;
    const int volume = ExtrudeHexBox({1.0, 0.2, 0.1}, {10, 2, 1});
    AddPhysical(3, {volume}, "steel");
    const int left = left_tag = AddPhysical(2, EntitiesIn(2, {0, 0, 0}, {0, 0.2, 0.1}), "left");
    const int edge = edge_tag = AddPhysical(1, EntitiesIn(1, {0, 0, 0}, {1, 0, 0}), "");  // unnamed
    const int corner = AddPhysical(0, EntitiesIn(0, {1, 0.2, 0.1}, {1, 0.2, 0.1}), "tip");
    gmsh::model::mesh::generate(3);
    std::vector<double> xyz;
    gmsh::model::mesh::getElementsByType(5, element_tags, element_nodes);
    gmsh::model::mesh::getNodesForPhysicalGroup(2, left, left_nodes, xyz);
    gmsh::model::mesh::getNodesForPhysicalGroup(1, edge, edge_nodes, xyz);
    gmsh::model::mesh::getNodesForPhysicalGroup(0, corner, corner_nodes, xyz);
    gmsh.Write(path);
  }
  const MeshFile mesh = read_mesh_file(path);
  EXPECT_EQ(mesh.format, MeshFileFormat::Gmsh);
  EXPECT_EQ(mesh.num_nodes(), 11 * 3 * 2);
  EXPECT_TRUE(mesh.warnings.empty()) << mesh.warnings.front();
  ASSERT_EQ(mesh.blocks.size(), 1u);
  const MeshFileBlock& block = mesh.blocks[0];
  EXPECT_EQ(block.name, "steel");
  EXPECT_EQ(block.type, SolidType::Hex8);
  ASSERT_EQ(block.num_elements(), 20);
  // Hex8 node order is the same in Gmsh and Exodus: connectivity is passed through.
  for (int e = 0; e < block.num_elements(); ++e) {
    EXPECT_EQ(block.element_ids[e], static_cast<long>(element_tags[e]));
    for (int k = 0; k < 8; ++k) EXPECT_EQ(mesh.node_ids[block.connectivity[8 * e + k]], static_cast<long>(element_nodes[8 * e + k]));
  }
  ASSERT_EQ(mesh.node_sets.size(), 3u);
  const MeshFileNodeSet* left = mesh.find_node_set("left");
  ASSERT_NE(left, nullptr);
  EXPECT_EQ(left->source, "physical surface " + std::to_string(left_tag));
  EXPECT_EQ(IdsOf(mesh, left->nodes), std::set<long>(left_nodes.begin(), left_nodes.end()));
  EXPECT_EQ(IdsOf(mesh, left->nodes), IdsOnPlane(mesh, 0, 0.0));
  const MeshFileNodeSet* edge = mesh.find_node_set("curve_" + std::to_string(edge_tag));  // unnamed: named after its tag
  ASSERT_NE(edge, nullptr);
  EXPECT_EQ(IdsOf(mesh, edge->nodes), std::set<long>(edge_nodes.begin(), edge_nodes.end()));
  EXPECT_EQ(edge->nodes.size(), 11u);
  const MeshFileNodeSet* tip = mesh.find_node_set("tip");
  ASSERT_NE(tip, nullptr);
  ASSERT_EQ(tip->nodes.size(), 1u);
  EXPECT_TRUE(mesh.coordinates[tip->nodes[0]].isApprox(Vec3(1, 0.2, 0.1)));
  EXPECT_EQ(mesh.side_sets.size(), 0u);
}

// The library reads the older 2.2 format and binary files the same way.
TEST(GmshMesh, Version22AndBinaryFilesReadTheSame) {
  const std::string v41 = WriteTempFile("box41.msh", ""), v22 = WriteTempFile("box22.msh", ""),
                    binary = WriteTempFile("box_binary.msh", "");
  {
    GmshWriter gmsh;
    AddPhysical(3, {ExtrudeHexBox({1.0, 0.2, 0.1}, {5, 2, 1})}, "steel");
    AddPhysical(2, EntitiesIn(2, {0, 0, 0}, {0, 0.2, 0.1}), "left");
    gmsh::model::mesh::generate(3);
    gmsh.Write(v41);
    gmsh.Write(v22, 2.2);
    gmsh.Write(binary, 4.1, true);
  }
  const MeshFile a = read_mesh_file(v41);
  for (const std::string& other : {v22, binary}) {
    const MeshFile b = read_mesh_file(other);
    EXPECT_EQ(b.node_ids, a.node_ids) << other;
    EXPECT_EQ(b.coordinates, a.coordinates) << other;
    ASSERT_EQ(b.blocks.size(), 1u) << other;
    EXPECT_EQ(b.blocks[0].connectivity, a.blocks[0].connectivity) << other;
    ASSERT_NE(b.find_node_set("left"), nullptr) << other;
    EXPECT_EQ(b.find_node_set("left")->nodes, a.find_node_set("left")->nodes) << other;
  }
}

// Gmsh numbers the tet10 mid-edge nodes 4-9 on edges 01, 12, 20, 03, 23, 13; elements.hpp
// (Exodus) wants 01, 12, 20, 03, 13, 23. On a box every edge is straight, so each mid-node read
// must lie at the middle of the edge our order assigns it.
TEST(GmshMesh, Tet10MidNodesSitOnTheEdgesOfTheExodusOrder) {
  const std::string path = WriteTempFile("tet10.msh", "");
  {
    GmshWriter gmsh;
    const int box = gmsh::model::occ::addBox(0, 0, 0, 1.0, 0.5, 0.3);
    gmsh::model::occ::synchronize();
    AddPhysical(3, {box}, "part");
    gmsh::option::setNumber("Mesh.MeshSizeMax", 0.25);
    gmsh::model::mesh::generate(3);
    gmsh::model::mesh::setOrder(2);
    gmsh.Write(path);
  }
  const MeshFile mesh = read_mesh_file(path);
  ASSERT_EQ(mesh.blocks.size(), 1u);
  const MeshFileBlock& block = mesh.blocks[0];
  ASSERT_EQ(block.type, SolidType::Tet10);
  ASSERT_GT(block.num_elements(), 20);
  const int edges[6][2] = {{0, 1}, {1, 2}, {2, 0}, {0, 3}, {1, 3}, {2, 3}};
  double worst = 0;
  for (int e = 0; e < block.num_elements(); ++e) {
    auto x = [&](int k) { return mesh.coordinates[block.connectivity[10 * e + k]]; };
    for (int m = 0; m < 6; ++m) worst = std::max(worst, (x(4 + m) - 0.5 * (x(edges[m][0]) + x(edges[m][1]))).norm());
  }
  EXPECT_LT(worst, 1e-12);
}

// The same hex grid from Gmsh and from the box mesher is the same model: same frequencies.
TEST(GmshMesh, ModesEqualTheBoxMeshersOnTheSameGrid) {
  const std::string msh = WriteTempFile("beam.msh", "");
  {
    GmshWriter gmsh;
    AddPhysical(3, {ExtrudeHexBox({1.0, 0.2, 0.1}, {10, 2, 1})}, "steel");
    AddPhysical(2, EntitiesIn(2, {0, 0, 0}, {0, 0.2, 0.1}), "left");
    gmsh::model::mesh::generate(3);
    gmsh.Write(msh);
  }
  const std::string from_file = WriteTempFile("from_file.yaml", std::string("mesh: {file: beam.msh}\nblocks:\n") + kSteel +
                                                                    "fixed:\n  - {node_set: left, dofs: [x, y, z]}\n");
  const std::string from_boxes = WriteTempFile("from_boxes.yaml", std::string(R"(
mesh:
  element_size: 0.1
  boxes: [{block: steel, min: [0, 0, 0], max: [1, 0.2, 0.1]}]
node_sets:
  left: {box: {min: [0, 0, 0], max: [0, 0.2, 0.1]}}
fixed:
  - {node_set: left, dofs: [x, y, z]}
blocks:
)") + kSteel);
  const Problem a = LoadProblem(from_file), b = LoadProblem(from_boxes);
  ASSERT_EQ(a.model.num_nodes(), b.model.num_nodes());
  ASSERT_EQ(a.model.num_elements(), b.model.num_elements());
  ExpectSameFrequencies(Frequencies(a, 6), Frequencies(b, 6));
}

// ---------------------------------------------------------------------------- Exodus

// Everything written comes back: ids from the node number map, block names and types,
// connectivity, node sets, and side sets both as element sides and as the nodes on them.
TEST(ExodusMesh, RoundTripKeepsBlocksNodeSetsAndSideSets) {
  for (SolidType type : {SolidType::Hex8, SolidType::Tet4, SolidType::Tet10}) {
    SCOPED_TRACE(solid_type_name(type));
    const std::vector<detail::MeshBox> boxes = {{0, {0, 0, 0}, {0.4, 0.2, 0.1}}, {1, {0.4, 0, 0}, {0.6, 0.2, 0.1}}};
    const ExodusMesh written = BoxMeshAsExodus(boxes, {"base", "tip"}, type, 0.1, 2, 0.0);  // sides on z = 0
    const std::string path = WriteTempFile(solid_type_name(type) + ".exo", "");
    WriteExodus(path, written);
    const MeshFile mesh = read_mesh_file(path);
    EXPECT_EQ(mesh.format, MeshFileFormat::Exodus);
    EXPECT_TRUE(mesh.warnings.empty()) << mesh.warnings.front();
    ASSERT_EQ(mesh.num_nodes(), static_cast<int>(written.coordinates.size()));
    for (int v = 0; v < mesh.num_nodes(); ++v) {
      EXPECT_EQ(mesh.node_ids[v], written.node_ids[v]);
      EXPECT_EQ(mesh.coordinates[v], written.coordinates[v]);
    }
    ASSERT_EQ(mesh.blocks.size(), 2u);
    long element = 0;
    for (size_t b = 0; b < 2; ++b) {
      EXPECT_EQ(mesh.blocks[b].name, written.blocks[b].name);
      EXPECT_EQ(mesh.blocks[b].id, written.blocks[b].id);
      EXPECT_EQ(mesh.blocks[b].type, type);
      ASSERT_EQ(mesh.blocks[b].connectivity.size(), written.blocks[b].connectivity.size());
      for (size_t k = 0; k < written.blocks[b].connectivity.size(); ++k)
        EXPECT_EQ(mesh.blocks[b].connectivity[k] + 1, written.blocks[b].connectivity[k]);
      for (long id : mesh.blocks[b].element_ids) EXPECT_EQ(id, ++element);  // no element map: 1, 2, ...
    }
    const MeshFileNodeSet* left = mesh.find_node_set("left_end");
    ASSERT_NE(left, nullptr);
    EXPECT_EQ(left->source, "node set 10");
    EXPECT_EQ(IdsOf(mesh, left->nodes), IdsOnPlane(mesh, 0, 0.0));
    ASSERT_EQ(mesh.side_sets.size(), 1u);
    EXPECT_EQ(mesh.side_sets[0].name, "far_side");
    EXPECT_EQ(mesh.side_sets[0].elements, std::vector<long>(written.side_sets[0].entries.begin(), written.side_sets[0].entries.end()));
    EXPECT_EQ(mesh.side_sets[0].sides, std::vector<int>(written.side_sets[0].sides.begin(), written.side_sets[0].sides.end()));
    // The side set's nodes, mid-edge nodes included, are exactly the nodes on z = 0.
    const MeshFileNodeSet* bottom = mesh.find_node_set("far_side");
    ASSERT_NE(bottom, nullptr);
    EXPECT_EQ(bottom->source, "side set 20");
    EXPECT_EQ(IdsOf(mesh, bottom->nodes), IdsOnPlane(mesh, 2, 0.0));
  }
}

// The same tet10 mesh from an Exodus file and from the box mesher gives the same frequencies;
// supports on the file's node set and springs on its side set, a sensor by the file's node id.
TEST(ExodusMesh, ModesEqualTheBoxMeshersAndFileIdsNameNodes) {
  const std::vector<detail::MeshBox> boxes = {{0, {0, 0, 0}, {0.4, 0.2, 0.1}}, {1, {0.4, 0, 0}, {0.6, 0.2, 0.1}}};
  const ExodusMesh written = BoxMeshAsExodus(boxes, {"base", "tip"}, SolidType::Tet10, 0.1, 0, 0.6);  // sides on x = 0.6
  WriteExodus(WriteTempFile("beam.exo", ""), written);
  const std::string blocks = R"(
blocks:
  base: {E: 7.0e10, nu: 0.33, density: 2700}
  tip: {E: 2.0e11, nu: 0.3, density: 7800}
fixed:
  - {node_set: left_end, dofs: [x, y, z]}
springs:
  end_support: {node_set: far_side, kz: 1.0e5}
)";
  const std::string from_file = WriteTempFile("from_file.yaml", "mesh: {file: beam.exo}" + blocks);
  const std::string from_boxes = WriteTempFile("from_boxes.yaml", R"(
mesh:
  element: tet10
  element_size: 0.1
  boxes:
    - {block: base, min: [0, 0, 0], max: [0.4, 0.2, 0.1]}
    - {block: tip, min: [0.4, 0, 0], max: [0.6, 0.2, 0.1]}
node_sets:
  left_end: {box: {min: [0, 0, 0], max: [0, 0.2, 0.1]}}
  far_side: {box: {min: [0.6, 0, 0], max: [0.6, 0.2, 0.1]}}
)" + blocks);
  const Problem a = LoadProblem(from_file), b = LoadProblem(from_boxes);
  ASSERT_EQ(a.model.num_nodes(), b.model.num_nodes());
  EXPECT_EQ(a.model.find_node_set("far_side")->nodes, b.model.find_node_set("far_side")->nodes);
  ExpectSameFrequencies(Frequencies(a, 6), Frequencies(b, 6));

  // Node ids are the file's (1001, ...): a sensor and a reference node see them.
  const std::string with_sensor = WriteTempFile(
      "sensor.yaml", "mesh: {file: beam.exo}" + blocks + "reference_nodes:\n  hub: [0.7, 0.1, 0.05]\n" +
                         "point_masses:\n  hub_mass: {node: hub, mass: 0.1, inertia: [1e-4, 1e-4, 1e-4]}\n" +
                         "sensors:\n  - {node: 1005, directions: [z]}\n");
  const Problem c = LoadProblem(with_sensor);
  ASSERT_EQ(c.sensors.size(), 1u);
  EXPECT_EQ(c.model.coordinates[c.sensors[0].node], written.coordinates[4]);
  EXPECT_EQ(c.model.node_ids.back(), 1001 + static_cast<long>(written.coordinates.size()));  // the reference node
}

// ---------------------------------------------------------------------------- malformed files

TEST(MeshFileErrors, GmshFilesThatAreNotUsableMeshes) {
  const std::string two_d = WriteTempFile("plate.msh", ""), unnamed = WriteTempFile("unnamed.msh", ""),
                    hex27 = WriteTempFile("hex27.msh", ""), shared = WriteTempFile("shared.msh", ""),
                    mixed = WriteTempFile("mixed.msh", ""), same_name = WriteTempFile("same_name.msh", "");
  {
    GmshWriter gmsh;
    AddPhysical(2, {gmsh::model::occ::addRectangle(0, 0, 0, 1, 1)}, "plate");
    gmsh::model::occ::synchronize();
    gmsh::model::mesh::generate(2);
    gmsh.Write(two_d);
  }
  {
    GmshWriter gmsh;  // no physical groups: Gmsh saves every element, none has a block
    gmsh::model::occ::addBox(0, 0, 0, 1, 1, 1);
    gmsh::model::occ::synchronize();
    gmsh::option::setNumber("Mesh.MeshSizeMax", 0.5);
    gmsh::model::mesh::generate(3);
    gmsh.Write(unnamed);
  }
  {
    GmshWriter gmsh;
    AddPhysical(3, {ExtrudeHexBox({1, 1, 1}, {2, 2, 2})}, "part");
    gmsh::model::mesh::generate(3);
    gmsh::model::mesh::setOrder(2);  // 27-node hexahedra
    gmsh.Write(hex27);
  }
  {
    GmshWriter gmsh;
    const int volume = ExtrudeHexBox({1, 1, 1}, {2, 2, 2});
    AddPhysical(3, {volume}, "inner");
    AddPhysical(3, {volume}, "outer");
    gmsh::model::mesh::generate(3);
    gmsh.Write(shared);
  }
  {
    GmshWriter gmsh;
    const int hexes = ExtrudeHexBox({1, 1, 1}, {2, 2, 2});
    gmsh::vectorpair square, tets;  // a second, separate cube meshed with tetrahedra
    const int p = gmsh::model::geo::addPoint(3, 0, 0);
    gmsh::vectorpair line;
    gmsh::model::geo::extrude({{0, p}}, 1, 0, 0, line);
    gmsh::model::geo::extrude({line[1]}, 0, 1, 0, square);
    gmsh::model::geo::extrude({square[1]}, 0, 0, 1, tets);
    gmsh::model::geo::synchronize();
    AddPhysical(3, {hexes, tets[1].second}, "part");
    gmsh::model::mesh::generate(3);
    gmsh.Write(mixed);
  }
  {
    GmshWriter gmsh;
    AddPhysical(3, {ExtrudeHexBox({1, 1, 1}, {2, 2, 2})}, "part");
    AddPhysical(2, EntitiesIn(2, {0, 0, 0}, {0, 1, 1}), "end");
    AddPhysical(1, EntitiesIn(1, {0, 0, 0}, {1, 0, 0}), "end");
    gmsh::model::mesh::generate(3);
    gmsh.Write(same_name);
  }
  ExpectMeshError(two_d, {"is a 2-D mesh"});
  ExpectMeshError(unnamed, {"no physical volume group", "Physical Volume("});
  ExpectMeshError(hex27, {"physical volume 'part'", "'Hexahedron 27'", "Gmsh type 12", "does not support",
                          "supported: 4-node and 10-node tetrahedra, 8-node hexahedra"});
  ExpectMeshError(shared, {"belongs to physical volumes 'inner' and 'outer'"});
  ExpectMeshError(mixed, {"physical volume 'part'", "mixes hex8 and tet4"});
  ExpectMeshError(same_name, {"physical surface", "physical curve", "are both named 'end'"});

  // Damaged files: cut in the middle, not a mesh at all, a .geo script named .msh.
  std::ifstream in(hex27);
  const std::string text{std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()};
  ExpectMeshError(WriteTempFile("cut.msh", text.substr(0, text.size() / 2)), {"Gmsh cannot read it"});
  ExpectMeshError(WriteTempFile("empty.msh", ""), {"does not start with $MeshFormat", "(it is empty)"});
  ExpectMeshError(WriteTempFile("script.msh", "Point(1) = {0, 0, 0};\n"), {"does not start with $MeshFormat", "gmsh -3"});
  ExpectMeshError(WriteTempFile("no_such_dir_below", "") + "/missing.msh", {"no such mesh file"});
  ExpectMeshError(WriteTempFile("part.stl", "solid x\n"), {"cannot tell the mesh format", "'.stl'"});
}

TEST(MeshFileErrors, DamagedExodusHeadersFoundByFuzzingNameTheirCause) {
  // Each file once crashed or hung the reader (docs/fuzzing.md); copied to a .exo name.
  auto regression = [](const std::string& name) {
    std::ifstream in(testing::SourcePath("fuzz/regressions/exodus/" + name), std::ios::binary);
    const std::string bytes{std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()};
    EXPECT_FALSE(bytes.empty()) << name;
    return WriteTempFile(name + ".exo", bytes);
  };
  // int64_status with 135 values: Exodus's ex_open read them onto one int on its stack.
  ExpectMeshError(regression("global_int64_status_with_135_values"),
                  {"global attribute 'int64_status' has 135 values", "Exodus reads it as one number"});
  // maximum_name_length 1.1e9: every name buffer was a gigabyte.
  ExpectMeshError(regression("maximum_name_length_of_a_gigabyte"),
                  {"maximum_name_length attribute is 1124073534", "at most 256 characters"});
  // A side set naming an element num_elem counts but no block holds: an index before the blocks.
  ExpectMeshError(regression("side_set_element_beyond_the_blocks"), {"but the element blocks hold elements 1.."});
}

TEST(MeshFileErrors, ExodusFilesThatAreNotUsableMeshes) {
  // One tet: fine as written, inverted with two nodes swapped, flat with its apex in the base plane.
  ExodusMesh tet;
  tet.coordinates = {{0, 0, 0}, {1, 0, 0}, {0, 1, 0}, {0, 0, 1}};
  tet.blocks = {{"solid", 1, "TETRA", 4, {1, 2, 3, 4}}};
  const std::string good = WriteTempFile("good.exo", "");
  WriteExodus(good, tet);
  EXPECT_EQ(read_mesh_file(good).blocks.at(0).type, SolidType::Tet4);

  ExodusMesh inverted = tet;
  inverted.blocks[0].connectivity = {1, 3, 2, 4};
  const std::string inverted_path = WriteTempFile("inverted.exo", "");
  WriteExodus(inverted_path, inverted);
  ExpectMeshError(inverted_path, {"element 1 of block 'solid'", "tet4, nodes 1 3 2 4", "is inverted"});

  ExodusMesh flat = tet;
  flat.coordinates[3] = {0.3, 0.3, 0};
  const std::string flat_path = WriteTempFile("flat.exo", "");
  WriteExodus(flat_path, flat);
  ExpectMeshError(flat_path, {"element 1 of block 'solid'", "degenerate (zero volume)"});

  // A tet10 whose mid-node of edge 0-1 sits at 0.8 of the edge: the edge folds back at corner 1
  // (dx/dxi = 3 - 4 * 0.8 < 0 there) although det J is positive at every quadrature point.
  ExodusMesh folded;
  folded.coordinates = {{0, 0, 0}, {1, 0, 0}, {0, 1, 0}, {0, 0, 1}, {0.8, 0, 0}, {0.5, 0.5, 0},
                        {0, 0.5, 0}, {0, 0, 0.5}, {0.5, 0, 0.5}, {0, 0.5, 0.5}};
  folded.blocks = {{"curved", 1, "TETRA10", 10, {1, 2, 3, 4, 5, 6, 7, 8, 9, 10}}};
  const std::string folded_path = WriteTempFile("folded.exo", "");
  WriteExodus(folded_path, folded);
  ExpectMeshError(folded_path, {"element 1 of block 'curved' (tet10", "is inverted", "curved element folds over"});

  ExodusMesh wedge = tet;
  wedge.coordinates.push_back({1, 0, 1});
  wedge.coordinates.push_back({0, 1, 1});
  wedge.blocks = {{"", 7, "WEDGE", 6, {1, 2, 3, 4, 5, 6}}};  // unnamed: block_7
  const std::string wedge_path = WriteTempFile("wedge.exo", "");
  WriteExodus(wedge_path, wedge);
  ExpectMeshError(wedge_path, {"element block 'block_7' (id 7)", "type 'WEDGE' with 6 nodes", "does not support",
                               "supported: HEX8, TETRA (4 nodes), TETRA10"});

  ExodusMesh bad_side = tet;
  bad_side.side_sets = {{"face", 3, {1}, {5}}};
  const std::string bad_side_path = WriteTempFile("bad_side.exo", "");
  WriteExodus(bad_side_path, bad_side);
  ExpectMeshError(bad_side_path, {"side set 'face' (id 3)", "side 5 of element 1", "tet4 has sides 1..4"});

  ExodusMesh repeated = tet;
  repeated.node_ids = {7, 8, 7, 9};
  const std::string repeated_path = WriteTempFile("repeated_ids.exo", "");
  WriteExodus(repeated_path, repeated);
  ExpectMeshError(repeated_path, {"node id 7 is given to nodes 1 and 3"});

  ExodusMesh plane;
  plane.dim = 2;
  plane.coordinates = {{0, 0, 0}, {1, 0, 0}, {1, 1, 0}, {0, 1, 0}};
  plane.blocks = {{"sheet", 1, "QUAD4", 4, {1, 2, 3, 4}}};
  const std::string plane_path = WriteTempFile("plane.exo", "");
  WriteExodus(plane_path, plane);
  ExpectMeshError(plane_path, {"is a 2-D mesh (num_dim = 2)"});

  ExpectMeshError(WriteTempFile("text.exo", "not a netCDF file\n"), {"is not an Exodus II file"});

  // A copy cut short inside its data: netCDF reads the missing values as fill values, which
  // showed up as "refers to node 0" or zero coordinates, far from the cause.
  std::ifstream in(good, std::ios::binary);
  const std::string whole{std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()};
  for (const size_t cut : {size_t{4}, size_t{40}})
    ExpectMeshError(WriteTempFile("cut_short.exo", whole.substr(0, whole.size() - cut)),
                    {"is cut short", "would end at byte", "but the file has " + std::to_string(whole.size() - cut)});
}

// ---------------------------------------------------------------------------- problem files

/// A one-tet Exodus file "tet.exo" next to the problem files of the running test.
void WriteOneTet() {
  ExodusMesh tet;
  tet.coordinates = {{0, 0, 0}, {1, 0, 0}, {0, 1, 0}, {0, 0, 1}};
  tet.blocks = {{"solid", 1, "TETRA", 4, {1, 2, 3, 4}}};
  tet.node_sets = {{"base", 1, {1, 2, 3}, {}}};
  WriteExodus(WriteTempFile("tet.exo", ""), tet);
}

/// Loading `text` (a problem next to tet.exo) must fail at the line marked "# <-" with every fragment.
void ExpectProblemError(const std::string& text, const std::vector<std::string>& fragments, double refinement = 0) {
  WriteOneTet();
  const std::string path = WriteTempFile("problem.yaml", text);
  const std::string marked = text.substr(0, text.find("# <-"));
  const int line = 1 + static_cast<int>(std::count(marked.begin(), marked.end(), '\n'));
  try {
    LoadProblem(path, LoadOptions{refinement});
    ADD_FAILURE() << "expected a ProblemError";
  } catch (const ProblemError& e) {
    EXPECT_EQ(e.file(), path);
    EXPECT_EQ(e.line(), line) << e.what();
    for (const std::string& f : fragments)
      EXPECT_NE(std::string(e.what()).find(f), std::string::npos) << "'" << f << "' not in: " << e.what();
  }
}

TEST(MeshFileProblemErrors, BlocksMustMatchTheFilesBlocks) {
  ExpectProblemError("mesh: {file: tet.exo}\nblocks:\n  solid: {E: 1, nu: 0.3, density: 1}\n  steel: {E: 1, nu: 0.3, density: 1}  # <-\n",
                     {"block 'steel'", "tet.exo' has no block of this name", "known blocks: solid"});
}

TEST(MeshFileProblemErrors, FileBlockWithoutMaterial) {
  WriteOneTet();
  ExodusMesh two;
  two.coordinates = {{0, 0, 0}, {1, 0, 0}, {0, 1, 0}, {0, 0, 1}, {0, 0, -1}};
  two.blocks = {{"solid", 1, "TETRA", 4, {1, 2, 3, 4}}, {"cap", 2, "TETRA", 4, {1, 3, 2, 5}}};
  WriteExodus(WriteTempFile("two.exo", ""), two);
  const std::string path = WriteTempFile("problem.yaml", "mesh:\n  file: two.exo\nblocks:\n  solid: {E: 1, nu: 0.3, density: 1}\n");
  try {
    LoadProblem(path);
    ADD_FAILURE() << "expected a ProblemError";
  } catch (const ProblemError& e) {
    EXPECT_EQ(e.line(), 2) << e.what();
    EXPECT_NE(std::string(e.what()).find("has block 'cap' (id 2, 1 tet4 elements), which 'blocks' gives no material"),
              std::string::npos)
        << e.what();
  }
}

TEST(MeshFileProblemErrors, FileProblemsNameTheProblemLineAndTheMeshFile) {
  ExpectProblemError("mesh:\n  file: nowhere.msh  # <-\nblocks:\n  solid: {E: 1, nu: 0.3, density: 1}\n",
                     {"nowhere.msh: no such mesh file", "relative to this file's folder"});
  ExpectProblemError("mesh:\n  file: tet.exo\n  element_size: 0.1  # <-\nblocks:\n  solid: {E: 1, nu: 0.3, density: 1}\n",
                     {"'element_size' applies only to a generated mesh"});
  ExpectProblemError("mesh:\n  file: tet.exo  # <-\nblocks:\n  solid: {E: 1, nu: 0.3, density: 1}\n",
                     {"--refine", "applies only to a generated mesh"}, 2.0);
  ExpectProblemError("mesh:\n  file: tet.exo\nblocks:\n  solid: {E: 1, nu: 0.3, density: 1}\nnode_sets:\n  base: {nodes: [1]}  # <-\n",
                     {"node set 'base' is already defined by the mesh file"});
  ExpectProblemError("mesh:\n  file: tet.exo\n  format: abaqus  # <-\nblocks:\n  solid: {E: 1, nu: 0.3, density: 1}\n",
                     {"expected one of gmsh, exodus"});
}

// `scale` converts the file's lengths (a CAD mesh in mm into a model in m).
TEST(MeshFileProblem, ScaleMultipliesCoordinates) {
  WriteOneTet();
  const Problem p = LoadProblem(WriteTempFile(
      "problem.yaml", "mesh: {file: tet.exo, scale: 1.0e-3}\nblocks:\n  solid: {E: 1, nu: 0.3, density: 1}\n"));
  EXPECT_EQ(p.model.coordinates[3], Vec3(0, 0, 1e-3));
  EXPECT_EQ(p.model.find_node_set("base")->nodes, (std::vector<int>{0, 1, 2}));
}

}  // namespace
}  // namespace modalcal
