// Problem-file loader: the mesh generator, the model and problem it builds, and its errors.
// Each test writes its problem to a temporary file, so the input is visible in the test.
// Error tests mark the line the error must point at with "# <-".
#include <algorithm>
#include <array>
#include <filesystem>
#include <fstream>
#include <map>
#include <set>
#include <string>
#include <vector>

#include <Eigen/Geometry>
#include <gtest/gtest.h>

#include "modalcal/problem.hpp"
#include "modalcal/problem_file.hpp"
#include "modalcal/synthesis.hpp"

namespace modalcal {
namespace {

namespace fs = std::filesystem;

/// Writes `text` (minus one leading newline, so a raw string's first line is line 1) to a
/// file named after the running test and returns its path.
std::string WriteProblem(std::string text) {
  if (!text.empty() && text.front() == '\n') text.erase(0, 1);
  const auto* info = ::testing::UnitTest::GetInstance()->current_test_info();
  const fs::path dir = fs::temp_directory_path() / "modalcal_test_problem";
  fs::create_directories(dir);
  const fs::path path = dir / (std::string(info->test_suite_name()) + "." + info->name() + ".yaml");
  std::ofstream(path) << text;
  return path.string();
}

/// 1-based line of the first line of `text` (as written by WriteProblem) containing `fragment`.
int LineContaining(std::string text, const std::string& fragment) {
  if (!text.empty() && text.front() == '\n') text.erase(0, 1);
  const size_t at = text.find(fragment);
  EXPECT_NE(at, std::string::npos) << "no '" << fragment << "' in the test input";
  return 1 + static_cast<int>(std::count(text.begin(), text.begin() + static_cast<long>(at), '\n'));
}

/// Loading `text` must throw a ProblemError at the line marked "# <-" whose message
/// contains every fragment.
void ExpectProblemError(const std::string& text, const std::vector<std::string>& fragments) {
  const std::string path = WriteProblem(text);
  try {
    load_problem(path);
    ADD_FAILURE() << "expected a ProblemError";
  } catch (const ProblemError& e) {
    const std::string what = e.what();
    EXPECT_EQ(e.file(), path);
    EXPECT_EQ(e.line(), LineContaining(text, "# <-")) << what;
    EXPECT_EQ(what.rfind(path + ":" + std::to_string(e.line()) + ": ", 0), 0u) << what;
    for (const std::string& fragment : fragments)
      EXPECT_NE(what.find(fragment), std::string::npos) << "'" << fragment << "' not in: " << what;
  }
}

// A unit cube of 2 x 2 x 2 hex8 elements in block "steel".
const std::string kCube = R"(
mesh:
  element_size: 0.5
  boxes:
    - {block: steel, min: [0, 0, 0], max: [1, 1, 1]}
blocks:
  steel: {E: 2.0e11, nu: 0.3, density: 7800}
)";

// Signed volume (times 6) of the tetrahedron of the first four nodes of an element.
double TetVolume6(const Model& model, const int* nodes) {
  const Vec3& a = model.coordinates[nodes[0]];
  return (model.coordinates[nodes[1]] - a)
      .cross(model.coordinates[nodes[2]] - a)
      .dot(model.coordinates[nodes[3]] - a);
}

// ---------------------------------------------------------------------------- valid input

TEST(LoadProblem, FullProblemHasTheRightModel) {
  const std::string text = R"(
name: beam
description: a cantilever with a mount
units: m, N, s
mesh:
  element: hex8
  element_size: 0.5
  boxes:
    - {block: steel, min: [0, 0, 0], max: [2, 1, 0.5]}
blocks:
  steel: {E: 2.0e11, nu: 0.3, density: 7800, stiffness_scale: 1.0}
reference_nodes:
  hub: [2.5, 0.5, 0.25]
  ground: [2.5, 0.5, 0.25]
node_sets:
  root: {box: {min: [0, 0, 0], max: [0, 1, 0.5]}}
  tip: {box: {min: [2, 0, 0], max: [2, 1, 0.5]}}
  corner: {sphere: {center: [2, 0, 0], radius: 0.1}, block: steel}
  ground_node: {nodes: [32]}
rigid_couplings:
  - {reference: hub, node_set: tip}
joints:
  mount: {nodes: [hub, ground], frame: {x: [0, 2, 0], y: [-1, 0, 0]}, kx: 1.0e6, ky: 1.0e6}
springs:
  support: {node_set: root, kx: 1.0e9, ky: 1.0e9, kz: 1.0e9}
point_masses:
  sensor: {node: hub, mass: 0.1, inertia: [1e-4, 1e-4, 1e-4]}
fixed:
  - {node_set: ground_node, dofs: [x, y, z, rx, ry, rz]}
mode_families:
  bending: z
parameters:
  E:
    targets: [steel.E]
    initial: 2.0e11
    lower: 1.0e11
    upper: 3.0e11
    truth: 2.1e11
  mount_k:
    targets: [mount.kx, mount.ky, mount.krz]
    initial: 1.0e6
    lower: 1.0e3
    upper: 1.0e9
    scaling: log
sensors:
  - {at: [2, 1, 0.5], directions: [x, y, z]}
  - {node: 1, directions: [z]}
  - {node_set: corner, directions: [z]}
measured:
  modes:
    - {frequency_hz: 100.0, pair: {family: bending, index: 1}, label: bending 1}
    - {frequency_hz: 250.0, weight: 0.5, shape: [1, 0, 0.5, 0.1, 0.2]}
    - {frequency_hz: 400.0}
options:
  num_modes: 6
  tolerance: 1.0e-8
)";
  const Problem p = load_problem(WriteProblem(text));
  const Model& m = p.model;
  EXPECT_EQ(p.name, "beam");
  EXPECT_EQ(p.units, "m, N, s");

  // 4 x 2 x 1 elements: (4+1)(2+1)(1+1) mesh nodes, then the two reference nodes.
  ASSERT_EQ(m.num_nodes(), 30 + 2);
  EXPECT_EQ(m.num_elements(), 8);
  ASSERT_EQ(m.blocks.size(), 1u);
  EXPECT_EQ(m.blocks[0].type, SolidType::Hex8);
  EXPECT_EQ(m.blocks[0].form, ElasticForm::YoungPoisson);
  EXPECT_EQ(m.properties[m.blocks[0].modulus_a].name, "steel.E");
  EXPECT_EQ(m.node_ids.front(), 1);
  EXPECT_TRUE(m.coordinates[29].isApprox(Vec3(2, 1, 0.5)));
  EXPECT_EQ(m.node_ids[30], 31);
  EXPECT_EQ(m.node_ids[31], 32);
  EXPECT_FALSE(m.has_rotations[29]);
  EXPECT_TRUE(m.has_rotations[30]);
  EXPECT_TRUE(m.has_rotations[31]);

  EXPECT_EQ(m.find_node_set("root")->nodes.size(), 6u);
  EXPECT_EQ(m.find_node_set("tip")->nodes.size(), 6u);
  EXPECT_EQ(m.find_node_set("corner")->nodes, std::vector<int>{4});
  EXPECT_EQ(m.find_node_set("ground_node")->nodes, std::vector<int>{31});
  ASSERT_EQ(m.rigid_couplings.size(), 1u);
  EXPECT_EQ(m.rigid_couplings[0].reference, 30);
  EXPECT_EQ(m.rigid_couplings[0].nodes.size(), 6u);
  ASSERT_EQ(m.joints.size(), 1u);
  EXPECT_EQ(m.joints[0].node_a, 30);
  EXPECT_EQ(m.joints[0].node_b, 31);
  EXPECT_TRUE(m.joints[0].frame.row(0).isApprox(Eigen::RowVector3d(0, 1, 0)));
  EXPECT_TRUE(m.joints[0].frame.row(2).isApprox(Eigen::RowVector3d(0, 0, 1)));
  ASSERT_EQ(m.ground_springs.size(), 1u);
  EXPECT_EQ(m.ground_springs[0].nodes.size(), 6u);
  EXPECT_EQ(m.ground_springs[0].stiffness[3], kNoProperty);
  ASSERT_EQ(m.point_masses.size(), 1u);
  EXPECT_EQ(m.properties[m.point_masses[0].inertia[2]].name, "sensor.Izz");
  ASSERT_EQ(m.fixed.size(), 1u);
  EXPECT_EQ(m.fixed[0].components, (std::array<bool, 6>{true, true, true, true, true, true}));
  EXPECT_EQ(m.mode_families.at("bending"), 2);

  // steel: E nu density stiffness_scale; mount: kx ky (+ krz created for the parameter);
  // support: kx ky kz; sensor: mass Ixx Iyy Izz.
  EXPECT_EQ(m.properties.size(), 4u + 3u + 3u + 4u);
  const PropertyId krz = m.find_property("mount.krz");
  ASSERT_NE(krz, kNoProperty);
  EXPECT_EQ(m.properties[krz].value, 0.0);
  EXPECT_EQ(m.joints[0].stiffness[5], krz);

  ASSERT_EQ(p.parameters.size(), 2u);
  EXPECT_EQ(p.parameters[0].name, "E");
  EXPECT_EQ(p.parameters[0].scaling, Scaling::Linear);
  EXPECT_EQ(p.parameters[0].reference, 2.0e11);
  EXPECT_EQ(p.parameters[0].truth, 2.1e11);
  EXPECT_EQ(p.parameters[1].scaling, Scaling::Log);
  EXPECT_EQ(p.parameters[1].targets, (std::vector<PropertyId>{m.find_property("mount.kx"),
                                                              m.find_property("mount.ky"), krz}));
  EXPECT_FALSE(p.has_truth());
  EXPECT_EQ(p.find_parameter("mount_k"), 1);
  EXPECT_EQ(p.upper_bounds()[1], 1.0e9);

  ASSERT_EQ(p.sensors.size(), 5u);
  EXPECT_EQ(p.sensors[0].node, 29);
  EXPECT_EQ(p.sensors[0].label, "node 30 +x");
  EXPECT_EQ(p.sensors[2].label, "node 30 +z");
  EXPECT_EQ(p.sensors[3].label, "node 1 +z");
  EXPECT_EQ(p.sensors[4].label, "node 5 +z");

  ASSERT_EQ(p.measured.size(), 3u);
  EXPECT_EQ(p.measured[0].label, "bending 1");
  EXPECT_EQ(p.measured[0].pairing.kind, PairingRule::Kind::Family);
  EXPECT_EQ(p.measured[0].pairing.family, "bending");
  EXPECT_EQ(p.measured[1].pairing.kind, PairingRule::Kind::Mac);
  EXPECT_EQ(p.measured[1].weight, 0.5);
  EXPECT_EQ(p.measured[1].shape.size(), 5);
  EXPECT_EQ(p.measured[2].pairing.kind, PairingRule::Kind::ModelIndex);
  EXPECT_EQ(p.measured[2].pairing.model_index, 3);
  EXPECT_EQ(p.measured[2].source_line, LineContaining(text, "frequency_hz: 400.0"));
  EXPECT_FALSE(p.synthetic);

  EXPECT_EQ(p.options.num_modes, 6);
  EXPECT_EQ(p.options.tolerance, 1.0e-8);
  EXPECT_EQ(p.expected_rigid_modes(), 0);
}

TEST(LoadProblem, MinimalProblemTakesDefaults) {
  const std::string path = WriteProblem(kCube);
  const Problem p = load_problem(path);
  EXPECT_EQ(p.path, path);
  EXPECT_EQ(p.name, fs::path(path).stem().string());
  EXPECT_EQ(p.model.num_nodes(), 27);
  EXPECT_EQ(p.model.num_elements(), 8);
  EXPECT_EQ(p.model.blocks[0].type, SolidType::Hex8);
  EXPECT_TRUE(p.parameters.empty());
  EXPECT_TRUE(p.measured.empty());
  EXPECT_FALSE(p.synthetic);
  EXPECT_EQ(p.options.num_modes, 10);
  EXPECT_EQ(p.expected_rigid_modes(), 6);
}

TEST(LoadProblem, MaxRigidModesOverridesTheSupports) {
  const Problem p = load_problem(WriteProblem(kCube + R"(
options: {max_rigid_modes: 3}
)"));
  EXPECT_EQ(p.expected_rigid_modes(), 3);
}

// Loading reads and checks the section; synthesize_measured() solves the truth model.
TEST(LoadProblem, SyntheticMeasuredModesAreSynthesizedAfterLoading) {
  const std::string text = kCube + R"(
node_sets:
  bottom: {box: {min: [0, 0, 0], max: [1, 1, 0]}}
fixed:
  - {node_set: bottom, dofs: [x, y, z]}
parameters:
  E: {targets: [steel.E], initial: 1.0e11, lower: 1.0e10, upper: 1.0e12, truth: 2.0e11}
sensors:
  - {at: [1, 1, 1], directions: [x, y, z]}
measured:
  synthetic: {modes: [1, 2], shapes: true}
options: {num_modes: 4}
)";
  Problem p = load_problem(WriteProblem(text));
  ASSERT_TRUE(p.synthetic);
  EXPECT_EQ(p.synthetic->modes, (std::vector<int>{1, 2}));
  EXPECT_TRUE(p.synthetic->shapes);
  EXPECT_EQ(p.synthetic->source_line, LineContaining(text, "synthetic:"));
  EXPECT_TRUE(p.measured.empty());
  EXPECT_FALSE(p.synthetic_truth);
  synthesize_measured(&p);
  EXPECT_EQ(p.measured.size(), 2u);
  EXPECT_TRUE(p.synthetic_truth);
  EXPECT_TRUE(p.has_truth());
  EXPECT_EQ(p.truth_values()[0], 2.0e11);
}

// A synthetic section's mistakes that need the truth model are reported by
// synthesize_measured(), at the section's line.
TEST(LoadProblem, SyntheticSectionWithoutTruthValuesFailsWhenSynthesized) {
  const std::string text = kCube + R"(
parameters:
  E: {targets: [steel.E], initial: 1.0e11, lower: 1.0e10, upper: 1.0e12}
sensors:
  - {at: [1, 1, 1], directions: [x, y, z]}
measured:
  synthetic: {modes: [1, 2], shapes: true}
)";
  Problem p = load_problem(WriteProblem(text));
  ASSERT_TRUE(p.synthetic);
  try {
    synthesize_measured(&p);
    FAIL() << "expected a ProblemError";
  } catch (const ProblemError& e) {
    EXPECT_EQ(e.line(), LineContaining(text, "synthetic:"));
    EXPECT_NE(std::string(e.what()).find("needs a 'truth' value"), std::string::npos) << e.what();
  }
}

// LoadOptions::memory_bytes stands for the machine's memory in the mesh-size check.
TEST(LoadProblem, MemoryBytesLimitsTheMesh) {
  const std::string path = WriteProblem(R"(
mesh:
  element_size: 0.05
  boxes:
    - {block: a, min: [0, 0, 0], max: [1, 1, 1]}
blocks:
  a: {E: 1, nu: 0.3, density: 1}
)");
  LoadOptions options;
  options.memory_bytes = 1e7;  // 21^3 nodes need about 4e8 bytes by the estimate
  try {
    load_problem(path, options);
    FAIL() << "expected a ProblemError";
  } catch (const ProblemError& e) {
    EXPECT_NE(std::string(e.what()).find("the memory allowed is"), std::string::npos) << e.what();
  }
  options.memory_bytes = 1e12;
  EXPECT_EQ(load_problem(path, options).model.num_elements(), 20 * 20 * 20);
}

TEST(LoadProblem, KGBlockAndIdJointNodes) {
  const Problem p = load_problem(WriteProblem(R"(
mesh:
  element_size: 1
  boxes:
    - {block: foam, min: [0, 0, 0], max: [1, 1, 1]}
blocks:
  foam: {K: 4.1e4, G: 1.6e4, density: 1.0e-5, mass_scale: 2}
joints:
  link: {nodes: [1, 8], kz: 5}
)"));
  const ElementBlock& b = p.model.blocks[0];
  EXPECT_EQ(b.form, ElasticForm::BulkShear);
  EXPECT_EQ(p.model.properties[b.modulus_b].name, "foam.G");
  EXPECT_EQ(p.model.property_value(b.mass_scale), 2.0);
  EXPECT_EQ(p.model.joints[0].node_a, 0);
  EXPECT_EQ(p.model.joints[0].node_b, 7);
}

TEST(LoadProblem, SensorAtAcceptsAGivenTolerance) {
  const Problem p = load_problem(WriteProblem(kCube + R"(
sensors:
  - {at: [0.01, 0, 0], tolerance: 0.1, directions: [y]}
)"));
  ASSERT_EQ(p.sensors.size(), 1u);
  EXPECT_EQ(p.sensors[0].label, "node 1 +y");
}

// ---------------------------------------------------------------------------- mesh

TEST(BoxMesh, AdjacentBoxesShareTheirInterfaceNodes) {
  const Problem p = load_problem(WriteProblem(R"(
mesh:
  element_size: 0.5
  boxes:
    - {block: a, min: [0, 0, 0], max: [1, 1, 1]}
    - {block: b, min: [1, 0, 0], max: [2, 1, 1]}
blocks:
  a: {E: 1, nu: 0.3, density: 1}
  b: {E: 1, nu: 0.3, density: 1}
)"));
  // One 5 x 3 x 3 grid of points, not two separate 3 x 3 x 3 ones.
  EXPECT_EQ(p.model.num_nodes(), 45);
  EXPECT_EQ(p.model.blocks[0].num_elements(), 8);
  EXPECT_EQ(p.model.blocks[1].num_elements(), 8);
}

TEST(BoxMesh, NodesExistOnlyWhereABoxIs) {
  // An L: the grid's 3 x 3 x 2 points minus the 2 at the empty corner (x = 2, y = 2).
  const Problem p = load_problem(WriteProblem(R"(
mesh:
  element_size: 1
  boxes:
    - {block: a, min: [0, 0, 0], max: [2, 1, 1]}
    - {block: a, min: [0, 1, 0], max: [1, 2, 1]}
blocks:
  a: {E: 1, nu: 0.3, density: 1}
)"));
  EXPECT_EQ(p.model.num_nodes(), 16);
  EXPECT_EQ(p.model.num_elements(), 3);
  for (const Vec3& x : p.model.coordinates)
    EXPECT_FALSE(x.x() > 1.5 && x.y() > 1.5) << x.transpose();
}

TEST(BoxMesh, EachIntervalIsDividedIntoCeilLengthOverSize) {
  // x: 0.14 / 0.02 is 7 although it computes as 7.000000000000001; y: ceil(0.05 / 0.02) = 3;
  // z: 0.01 < 0.02 still gets 1.
  const Problem p = load_problem(WriteProblem(R"(
mesh:
  element_size: 0.02
  boxes:
    - {block: a, min: [0, 0, 0], max: [0.14, 0.05, 0.01]}
blocks:
  a: {E: 1, nu: 0.3, density: 1}
)"));
  EXPECT_EQ(p.model.num_elements(), 7 * 3 * 1);
  EXPECT_EQ(p.model.num_nodes(), 8 * 4 * 2);
}

TEST(BoxMesh, Hex8ElementsArePositivelyOrientedInExodusOrder) {
  const Problem p = load_problem(WriteProblem(kCube));
  const std::vector<int>& c = p.model.blocks[0].connectivity;
  for (size_t e = 0; e < c.size(); e += 8) {
    const int corners[4] = {c[e], c[e + 1], c[e + 3], c[e + 4]};
    EXPECT_GT(TetVolume6(p.model, corners), 0) << "element " << e / 8;
    // Exodus: node 2 is diagonal to node 0 on the bottom face, node 6 on the top face.
    const Vec3 d = p.model.coordinates[c[e + 6]] - p.model.coordinates[c[e]];
    EXPECT_TRUE((d.array() > 0).all()) << "element " << e / 8;
  }
}

TEST(BoxMesh, Tet4SplitIsConformingAndPositive) {
  const Problem p = load_problem(WriteProblem(R"(
mesh:
  element: tet4
  element_size: 1
  boxes:
    - {block: a, min: [0, 0, 0], max: [2, 1, 1]}
blocks:
  a: {E: 1, nu: 0.3, density: 1}
)"));
  const std::vector<int>& c = p.model.blocks[0].connectivity;
  EXPECT_EQ(p.model.num_nodes(), 3 * 2 * 2);
  ASSERT_EQ(p.model.num_elements(), 2 * 6);
  std::map<std::set<int>, int> faces;
  for (size_t e = 0; e < c.size(); e += 4) {
    EXPECT_GT(TetVolume6(p.model, &c[e]), 1e-12) << "element " << e / 4;
    for (int skip = 0; skip < 4; ++skip) {
      std::set<int> face;
      for (int k = 0; k < 4; ++k)
        if (k != skip) face.insert(c[e + k]);
      ++faces[face];
    }
  }
  // Conforming: every triangle is shared by two tets, except the 2 per boundary square.
  int boundary = 0;
  for (const auto& [face, count] : faces) {
    EXPECT_LE(count, 2);
    boundary += count == 1;
  }
  EXPECT_EQ(boundary, 2 * 2 * (2 * 1 + 2 * 1 + 1 * 1));
}

TEST(BoxMesh, Tet10SharesMidEdgeNodes) {
  const Problem p = load_problem(WriteProblem(R"(
mesh:
  element: tet10
  element_size: 1
  boxes:
    - {block: a, min: [0, 0, 0], max: [2, 1, 1]}
blocks:
  a: {E: 1, nu: 0.3, density: 1}
)"));
  const Model& m = p.model;
  const std::vector<int>& c = m.blocks[0].connectivity;
  ASSERT_EQ(m.num_elements(), 12);
  // 12 corners + 33 edges: 20 grid edges, 11 face diagonals, 2 body diagonals.
  EXPECT_EQ(m.num_nodes(), 12 + 33);
  const int edges[6][2] = {{0, 1}, {1, 2}, {2, 0}, {0, 3}, {1, 3}, {2, 3}};
  for (size_t e = 0; e < c.size(); e += 10) {
    EXPECT_GT(TetVolume6(m, &c[e]), 1e-12) << "element " << e / 10;
    for (int k = 0; k < 6; ++k) {
      const Vec3 mid =
          0.5 * (m.coordinates[c[e + edges[k][0]]] + m.coordinates[c[e + edges[k][1]]]);
      EXPECT_TRUE(m.coordinates[c[e + 4 + k]].isApprox(mid))
          << "element " << e / 10 << " edge " << k;
    }
  }
}

TEST(BoxMesh, RefinementOverrideMultipliesDivisions) {
  const std::string path = WriteProblem(R"(
mesh:
  element_size: 0.5
  refinement: 2
  boxes:
    - {block: a, min: [0, 0, 0], max: [1, 1, 1]}
blocks:
  a: {E: 1, nu: 0.3, density: 1}
)");
  EXPECT_EQ(load_problem(path).model.num_elements(), 4 * 4 * 4);
  EXPECT_EQ(load_problem(path, LoadOptions{1.0}).model.num_elements(), 2 * 2 * 2);
  EXPECT_EQ(load_problem(path, LoadOptions{3.0}).model.num_elements(), 6 * 6 * 6);
}

TEST(BoxMesh, PlanesKeepANodeSetsFootprintAtEveryRefinement) {
  // A pad from x 0.3 to 0.7 on top of a bar meshed at 0.25: without planes the nodes inside its
  // box are whichever grid lines fall there (only x = 0.5 at refinement 1), so what the pad holds
  // changes with the mesh. With them its footprint is the same on every mesh.
  const std::string bar = R"(
mesh:
  element_size: 0.25
  boxes:
    - {block: a, min: [0, 0, 0], max: [1, 0.2, 0.2]}
PLANES
blocks:
  a: {E: 1, nu: 0.3, density: 1}
node_sets:
  pad: {box: {min: [0.3, 0, 0.2], max: [0.7, 0.2, 0.2]}}
)";
  auto extent = [](const Problem& p) {
    const auto set = std::find_if(p.model.node_sets.begin(), p.model.node_sets.end(),
                                  [](const NodeSet& s) { return s.name == "pad"; });
    double lo = INFINITY, hi = -INFINITY;
    for (int n : set->nodes) {
      lo = std::min(lo, p.model.coordinates[n][0]);
      hi = std::max(hi, p.model.coordinates[n][0]);
    }
    return std::make_pair(lo, hi);
  };
  std::string with = bar;
  with.replace(with.find("PLANES"), 6, "  planes: {x: [0.3, 0.7]}");
  const std::string path = WriteProblem(with);
  for (double refinement : {1.0, 1.5, 2.0, 3.0}) {
    const auto [lo, hi] = extent(load_problem(path, LoadOptions{refinement}));
    EXPECT_NEAR(lo, 0.3, 1e-12) << refinement;
    EXPECT_NEAR(hi, 0.7, 1e-12) << refinement;
  }
  std::string without = bar;
  without.replace(without.find("PLANES"), 6, "");
  const auto [lo, hi] = extent(load_problem(WriteProblem(without)));
  EXPECT_EQ(lo, hi);  // one grid line, x = 0.5, inside the pad's box
}

// ---------------------------------------------------------------------------- errors

TEST(ProblemErrors, FileNotFoundNamesThePath) {
  const std::string path = (fs::temp_directory_path() / "modalcal_no_such_dir" / "p.yaml").string();
  try {
    load_problem(path);
    ADD_FAILURE() << "expected a ProblemError";
  } catch (const ProblemError& e) {
    EXPECT_EQ(e.file(), path);
    EXPECT_EQ(e.line(), 0);
    EXPECT_NE(std::string(e.what()).find("'" + path + "'"), std::string::npos) << e.what();
  }
}

TEST(ProblemErrors, DirectoryIsNotAProblemFile) {
  const std::string path = fs::temp_directory_path().string();
  try {
    load_problem(path);
    ADD_FAILURE() << "expected a ProblemError";
  } catch (const ProblemError& e) {
    EXPECT_NE(std::string(e.what()).find("'" + path + "' is a directory"), std::string::npos)
        << e.what();
  }
}

TEST(ProblemErrors, YamlSyntaxErrorHasItsLine) {
  ExpectProblemError(R"(
mesh:
  element_size: 0.5
  boxes: [{block: a, min: [0, 0, 0], max: [1, 1, 1]}]
blocks:
  a: {E: 1, nu: 0.3, density: 1}
  b: E: 1   # <-
)",
                     {"YAML syntax error"});
}

TEST(ProblemErrors, EmptyFile) { ExpectProblemError("# <- nothing here\n", {"got nothing"}); }

TEST(ProblemErrors, UnknownTopLevelKeyListsTheAllowedKeys) {
  ExpectProblemError(kCube + R"(
paramters: {}   # <-
)",
                     {"unknown key 'paramters'", "allowed keys", "parameters"});
}

TEST(ProblemErrors, UnknownNestedKey) {
  ExpectProblemError(kCube + R"(
parameters:
  E:
    targets: [steel.E]
    initial: 2.0e11
    lowr: 1.0e11   # <-
    upper: 3.0e11
)",
                     {"parameter 'E'", "unknown key 'lowr'", "lower"});
}

TEST(ProblemErrors, MissingRequiredKeyPointsAtTheEntity) {
  ExpectProblemError(kCube + R"(
parameters:
  E:   # <-
    targets: [steel.E]
    initial: 2.0e11
    lower: 1.0e11
)",
                     {"parameter 'E'", "missing required key 'upper'"});
}

TEST(ProblemErrors, WrongType) {
  ExpectProblemError(kCube + R"(
parameters:
  E:
    targets: [steel.E]
    initial: 2.0e11
    lower: abc   # <-
    upper: 3.0e11
)",
                     {"expected a number for 'lower', got 'abc'"});
}

TEST(ProblemErrors, NaNIsRejectedWhereANumberIsExpected) {
  ExpectProblemError(R"(
mesh:
  element_size: 0.5
  boxes: [{block: steel, min: [0, 0, 0], max: [1, 1, 1]}]
blocks:
  steel: {E: .nan, nu: 0.3, density: 7800}   # <-
)",
                     {"block 'steel'", "'E' is NaN"});
}

TEST(ProblemErrors, NaNInAListIsRejected) {
  ExpectProblemError(R"(
mesh:
  element_size: 0.5
  boxes:
    - {block: steel, min: [0, 0, 0], max: [1, .nan, 1]}   # <-
blocks:
  steel: {E: 1, nu: 0.3, density: 7800}
)",
                     {"item 2 of 'max'", "NaN"});
}

TEST(ProblemErrors, UnknownBlockListsTheKnownOnes) {
  ExpectProblemError(R"(
mesh:
  element_size: 0.5
  boxes:
    - {block: stel, min: [0, 0, 0], max: [1, 1, 1]}   # <-
blocks:
  steel: {E: 1, nu: 0.3, density: 1}
  alu: {E: 1, nu: 0.3, density: 1}
)",
                     {"unknown block 'stel'", "known blocks: steel, alu"});
}

TEST(ProblemErrors, BlockWithoutElements) {
  ExpectProblemError(R"(
mesh:
  element_size: 0.5
  boxes:
    - {block: steel, min: [0, 0, 0], max: [1, 1, 1]}
blocks:
  steel: {E: 1, nu: 0.3, density: 1}
  alu: {E: 1, nu: 0.3, density: 1}   # <-
)",
                     {"block 'alu'", "no mesh box uses"});
}

TEST(ProblemErrors, MeshPlaneOutsideTheBoxes) {
  ExpectProblemError(R"(
mesh:
  element_size: 0.5
  boxes:
    - {block: steel, min: [0, 0, 0], max: [1, 1, 1]}
  planes:
    x: [0.5, 1.5]   # <-
blocks:
  steel: {E: 1, nu: 0.3, density: 1}
)",
                     {"plane x = 1.5", "outside the boxes' extent (0 to 1 along x)"});
}

TEST(ProblemErrors, UnknownNodeSetSaysNoneAreDefined) {
  ExpectProblemError(kCube + R"(
springs:
  support: {node_set: bottom, kx: 1}   # <-
)",
                     {"unknown node set 'bottom'", "no node sets are defined"});
}

TEST(ProblemErrors, UnknownReferenceNode) {
  ExpectProblemError(kCube + R"(
reference_nodes:
  hub: [2, 0, 0]
  ground: [2, 0, 0]
joints:
  mount:
    nodes: [hub, grund]   # <-
    kx: 1
)",
                     {"unknown reference node 'grund'", "known reference nodes: ground, hub"});
}

TEST(ProblemErrors, UnknownTargetEntity) {
  ExpectProblemError(kCube + R"(
parameters:
  E:
    targets:
      - steal.E   # <-
    initial: 2.0e11
    lower: 1.0e11
    upper: 3.0e11
)",
                     {"unknown entity 'steal'", "steel"});
}

TEST(ProblemErrors, UnknownTargetProperty) {
  ExpectProblemError(kCube + R"(
parameters:
  G: {targets: [steel.G], initial: 1, lower: 0.5, upper: 2}   # <-
)",
                     {"block 'steel' has no property 'G'", "E, nu, density"});
}

TEST(ProblemErrors, BoundsOutOfOrder) {
  ExpectProblemError(kCube + R"(
parameters:
  E:
    targets: [steel.E]
    initial: 2.0e11
    lower: 3.0e11   # <-
    upper: 1.0e11
)",
                     {"parameter 'E'", "lower bound", "below the upper bound"});
}

TEST(ProblemErrors, InitialOutsideBounds) {
  ExpectProblemError(kCube + R"(
parameters:
  E:
    targets: [steel.E]
    initial: 5.0e11   # <-
    lower: 1.0e11
    upper: 3.0e11
)",
                     {"parameter 'E'", "'initial'", "outside the bounds"});
}

TEST(ProblemErrors, TruthOutsideBounds) {
  ExpectProblemError(kCube + R"(
parameters:
  E:
    targets: [steel.E]
    initial: 2.0e11
    lower: 1.0e11
    upper: 3.0e11
    truth: 0.5e11   # <-
)",
                     {"parameter 'E'", "'truth'", "outside the bounds"});
}

TEST(ProblemErrors, LogScalingNeedsAPositiveLowerBound) {
  ExpectProblemError(kCube + R"(
parameters:
  E:
    targets: [steel.E]
    initial: 2.0e11
    lower: 0   # <-
    upper: 3.0e11
    scaling: log
)",
                     {"parameter 'E'", "log scaling"});
}

TEST(ProblemErrors, LinearScalingNeedsANonzeroReference) {
  ExpectProblemError(kCube + R"(
parameters:
  E:
    targets: [steel.E]
    initial: 0   # <-
    lower: -1
    upper: 3.0e11
)",
                     {"parameter 'E'", "reference"});
}

TEST(ProblemErrors, FrequencyMustBePositiveAndFinite) {
  for (const std::string bad : {"-5", "0", ".nan", ".inf"}) {
    SCOPED_TRACE(bad);
    ExpectProblemError(kCube + R"(
measured:
  modes:
    - {frequency_hz: 100}
    - {frequency_hz: )" + bad +
                           R"(}   # <-
)",
                       {"measured mode 2", "'frequency_hz'"});
  }
}

TEST(ProblemErrors, SensorAtWithNoNodeNearby) {
  ExpectProblemError(kCube + R"(
sensors:
  - {node: 1, directions: [x]}
  - {at: [0.25, 0, 0], directions: [x]}   # <-
)",
                     {"sensor 2", "[0.25, 0, 0]", "the nearest is node", "0.25 away"});
}

TEST(ProblemErrors, SensorOnAMissingNodeId) {
  ExpectProblemError(kCube + R"(
sensors:
  - {node: 999, directions: [x]}   # <-
)",
                     {"no node with id 999", "1..27"});
}

TEST(ProblemErrors, SensorMeasuredTwice) {
  ExpectProblemError(kCube + R"(
sensors:
  - {node: 1, directions: [x, y]}
  - {node: 1, directions: [z,
                           y]}   # <-
)",
                     {"node 1 +y", "already measured by sensor 1"});
}

TEST(ProblemErrors, ShapeLengthMustMatchTheSensors) {
  ExpectProblemError(kCube + R"(
sensors:
  - {node: 1, directions: [x, y, z]}
measured:
  modes:
    - {frequency_hz: 100, shape: [1, 0]}   # <-
)",
                     {"measured mode 1", "'shape' has 2 values", "3 DOFs"});
}

// A bound the optimizer may reach must be a valid value of every target: checked at its line.
TEST(ProblemErrors, BoundOutsideTheTargetsPhysicalRange) {
  ExpectProblemError(kCube + R"(
parameters:
  E: {targets: [steel.E], initial: 2.0e11, lower: 0, upper: 3.0e11}   # <-
)",
                     {"parameter 'E'", "lower bound 0", "'steel.E'", "E must be positive"});
  ExpectProblemError(kCube + R"(
parameters:
  nu: {targets: [steel.nu], initial: 0.3, lower: 0.2, upper: 0.5}   # <-
)",
                     {"parameter 'nu'", "upper bound 0.5", "'steel.nu'", "(-1, 0.5)"});
  ExpectProblemError(kCube + R"(
parameters:
  rho: {targets: [steel.density], initial: 7800, lower: -1, upper: 9000}   # <-
)",
                     {"parameter 'rho'", "lower bound -1", "density must not be negative"});
}

TEST(ProblemErrors, DuplicateParameterName) {
  ExpectProblemError(kCube + R"(
parameters:
  E: {targets: [steel.E], initial: 2, lower: 1, upper: 3}
  E: {targets: [steel.nu], initial: 0.3, lower: 0.2, upper: 0.4}   # <-
)",
                     {"'E' is given twice"});
}

TEST(ProblemErrors, EntityNamesAreUniqueAcrossKinds) {
  ExpectProblemError(kCube + R"(
reference_nodes:
  a: [0, 0, 0]
  b: [0, 0, 0]
joints:
  steel: {nodes: [a, b], kx: 1}   # <-
)",
                     {"joint 'steel'", "already used by block 'steel'"});
}

TEST(ProblemErrors, EmptyNodeSetNamesTheSetAndTheMeshBounds) {
  ExpectProblemError(kCube + R"(
node_sets:
  far: {box: {min: [5, 5, 5], max: [6, 6, 6]}}   # <-
)",
                     {"node set 'far'", "selects no nodes", "[0, 0, 0] to [1, 1, 1]"});
}

TEST(ProblemErrors, BoxMinMustBeBelowMax) {
  ExpectProblemError(R"(
mesh:
  element_size: 0.5
  boxes:
    - {block: steel, min: [0, 0, 1], max: [1, 1, 1]}   # <-
blocks:
  steel: {E: 1, nu: 0.3, density: 1}
)",
                     {"mesh box 1", "along z"});
}

TEST(ProblemErrors, OverlappingBoxes) {
  ExpectProblemError(R"(
mesh:
  element_size: 0.5
  boxes:
    - {block: steel, min: [0, 0, 0], max: [1, 1, 1]}
    - {block: steel, min: [1, 0, 0], max: [2, 1, 1]}
    - {block: steel, min: [1.5, 0.5, 0.5], max: [3, 1, 1]}   # <-
blocks:
  steel: {E: 1, nu: 0.3, density: 1}
)",
                     {"mesh box 3", "overlaps mesh box 2"});
}

TEST(ProblemErrors, ModeFamilyDirection) {
  ExpectProblemError(kCube + R"(
mode_families:
  axial: x
  twist: rx   # <-
)",
                     {"mode family 'twist'", "x, y, z", "'rx'"});
}

TEST(ProblemErrors, PairWithAnUnknownFamily) {
  ExpectProblemError(kCube + R"(
mode_families:
  axial: x
measured:
  modes:
    - {frequency_hz: 100, pair: {family: bending, index: 1}}   # <-
)",
                     {"unknown mode family 'bending'", "known mode families: axial"});
}

TEST(ProblemErrors, PairMacNeedsAShape) {
  ExpectProblemError(kCube + R"(
measured:
  modes:
    - {frequency_hz: 100, pair: mac}   # <-
)",
                     {"'pair: mac'", "no 'shape'"});
}

TEST(ProblemErrors, PairedModeMustBeComputed) {
  ExpectProblemError(kCube + R"(
measured:
  modes:
    - {frequency_hz: 100, pair: {model_mode: 5}}   # <-
options: {num_modes: 4}
)",
                     {"elastic mode 5", "num_modes is 4"});
}

TEST(ProblemErrors, TargetListedTwiceInOneParameter) {
  ExpectProblemError(kCube + R"(
parameters:
  E:
    targets:
      - steel.E
      - steel.E   # <-
    initial: 2
    lower: 1
    upper: 3
)",
                     {"target 'steel.E' is listed twice"});
}

TEST(ProblemErrors, TargetOfTwoParameters) {
  ExpectProblemError(kCube + R"(
parameters:
  E: {targets: [steel.E], initial: 2, lower: 1, upper: 3}
  stiffness: {targets: [steel.E], initial: 2, lower: 1, upper: 3}   # <-
)",
                     {"'steel.E' is already set by parameter 'E'"});
}

TEST(ProblemErrors, OptionOutOfRange) {
  ExpectProblemError(kCube + R"(
options:
  num_modes: 10
  max_rigid_modes: 7   # <-
)",
                     {"'max_rigid_modes' must be between 0 and 6"});
}

TEST(ProblemErrors, NodeSetIdThatDoesNotExist) {
  ExpectProblemError(kCube + R"(
node_sets:
  some: {nodes: [1, 2, 0]}   # <-
)",
                     {"node set 'some'", "no node with id 0"});
}

TEST(ProblemErrors, RotationalJointStiffnessOnMeshNodesIsReportedAtTheJoint) {
  // Model::validate finds this one; the loader must still point at the joint.
  ExpectProblemError(kCube + R"(
joints:
  weld:   # <-
    nodes: [1, 2]
    krx: 1.0e3
)",
                     {"joint 'weld'", "rotations"});
}

// ---------------------------------------------------------------------------- extends, noise, effects

TEST(LoadProblem, ExtendsChainsTakeEachSectionFromTheNearestFile) {
  const fs::path dir = fs::temp_directory_path() / "modalcal_test_problem" / "chain";
  fs::create_directories(dir / "sub");
  std::ofstream(dir / "model.yaml") << kCube << "options: {num_modes: 4}\n";
  std::ofstream(dir / "sub" / "middle.yaml") << "extends: ../model.yaml\noptions: {num_modes: 5}\n"
                                                "parameters:\n  E: {targets: [steel.E], initial: 2.0e11, lower: 1.0e11, upper: 3.0e11}\n";
  std::ofstream(dir / "top.yaml") << "extends: sub/middle.yaml\nname: top\noptions: {num_modes: 6}\n";
  const Problem top = load_problem((dir / "top.yaml").string());
  EXPECT_EQ(top.name, "top");
  EXPECT_EQ(top.options.num_modes, 6);           // its own
  EXPECT_EQ(top.parameters.size(), 1u);          // from the middle file
  EXPECT_EQ(top.model.num_elements(), 8);        // from the model file, two levels up
  EXPECT_EQ(load_problem((dir / "sub" / "middle.yaml").string()).options.num_modes, 5);
  // A loop is an error at the line that closes it.
  std::ofstream(dir / "a.yaml") << "extends: b.yaml\n";
  std::ofstream(dir / "b.yaml") << "name: b\nextends: a.yaml\n";
  try {
    load_problem((dir / "a.yaml").string());
    ADD_FAILURE() << "expected a ProblemError";
  } catch (const ProblemError& e) {
    EXPECT_EQ(e.file(), (dir / "b.yaml").string());
    EXPECT_EQ(e.line(), 2);
    EXPECT_NE(std::string(e.what()).find("loop"), std::string::npos) << e.what();
  }
}

TEST(LoadProblem, MeasuredModesStateTheirNoise) {
  const Problem p = load_problem(WriteProblem(kCube + R"(
measured:
  modes:
    - {frequency_hz: 100}
  noise: {frequency: 0.002, shape: 0.02}
)"));
  ASSERT_TRUE(p.measurement_noise);
  EXPECT_EQ(p.measurement_noise->frequency, 0.002);
  EXPECT_EQ(p.measurement_noise->shape, 0.02);
}

TEST(ProblemErrors, NoiseOutOfRange) {
  ExpectProblemError(kCube + R"(
measured:
  modes:
    - {frequency_hz: 100}
  noise: {frequency: 0.5}   # <-
)",
                     {"noise.", "frequency"});
}

const std::string kCubeOnASupport = kCube + R"(
node_sets:
  bottom: {box: {min: [0, 0, 0], max: [1, 1, 0]}}
  top: {box: {min: [0, 0, 1], max: [1, 1, 1]}}
fixed:
  - {node_set: bottom, dofs: [x, y, z]}
)";

TEST(LoadProblem, DeclaredEffectsAreReadInOrder) {
  const std::string text = kCubeOnASupport + R"(
effects:
  - {effect: "point_mass@top:mass", upper: 10, description: cables on the top}
  - {effect: steel.stiffness_scale, initial: 0.9, lower: 0.5, upper: 2, enable: true}
  - {effect: "support@bottom:kz"}
)";
  const Problem p = load_problem(WriteProblem(text));
  ASSERT_EQ(p.effects.size(), 3u);
  EXPECT_EQ(p.effects[0].effect, "point_mass@top:mass");
  EXPECT_EQ(p.effects[0].description, "cables on the top");
  EXPECT_FALSE(p.effects[0].enable);
  EXPECT_FALSE(p.effects[0].lower);
  EXPECT_EQ(*p.effects[0].upper, 10);
  EXPECT_TRUE(p.effects[1].enable);
  EXPECT_EQ(*p.effects[1].initial, 0.9);
  EXPECT_EQ(p.effects[2].source_line, LineContaining(text, "support@bottom:kz"));
}

TEST(ProblemErrors, DeclaredEffectMustApplyToTheModel) {
  ExpectProblemError(kCubeOnASupport + R"(
effects:
  - {effect: "support@top:kx"}   # <-
)",
                     {"effect 1", "is not fixed along x", "without its value"});
  ExpectProblemError(kCubeOnASupport + R"(
effects:
  - {effect: "steel.stiffness_scale=2"}   # <-
)",
                     {"without its value", "'initial'"});
  ExpectProblemError(kCubeOnASupport + R"(
parameters:
  E: {targets: [steel.E], initial: 2.0e11, lower: 1.0e11, upper: 3.0e11}
effects:
  - {effect: "steel.E"}   # <-
)",
                     {"steel.E", "parameter 'E' already calibrates"});
  ExpectProblemError(kCubeOnASupport + R"(
effects:
  - {effect: "steel.mass_scale", initial: 3, upper: 2}   # <-
)",
                     {"initial 3 lies outside its bounds"});
}

}  // namespace
}  // namespace modalcal
