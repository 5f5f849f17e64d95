// Model changes ("effects"): the change strings' grammar, what applying a change does to the
// model (checked through the physics it assembles), and the errors that name the item and cause.
#include <gtest/gtest.h>

#include <cmath>
#include <string>
#include <vector>

#include "modalcal/assembly.hpp"
#include "modalcal/eigen.hpp"
#include "modalcal/model_change.hpp"
#include "modalcal/problem.hpp"
#include "modalcal/problem_file.hpp"
#include "modalcal/test_data.hpp"
#include "io/uff_records.hpp"
#include "support/text_util.hpp"
#include "test_util.hpp"

namespace modalcal {
namespace {

using testing::LoadProblem;
using testing::WriteTempFile;

// A cantilevered bar of one block (9 x 2 x 3 = 54 mesh nodes) with a node set at the tip, coupled
// to reference node hub (55), joined in translation to reference node arm (56) that carries a
// point mass and has its rotations fixed.
const std::string kBarWithTip = testing::CantileverBar("  arm_node: {nodes: [56]}\n",
                                                      "  - {node_set: arm_node, dofs: [rx, ry, rz]}\n") + R"(
reference_nodes:
  hub: [4.5, 0.25, 0.375]
  arm: [4.5, 0.25, 0.375]
rigid_couplings:
  - {reference: hub, node_set: tip}
joints:
  link: {nodes: [hub, arm], kx: 100, ky: 100, kz: 100}
point_masses:
  weight: {node: arm, mass: 0.1}
)";

Model LoadBar() { return LoadProblem(WriteTempFile("bar.yaml", kBarWithTip)).model; }

Vector Frequencies(const Model& model, int n) {
  ParametricSystem system(model, {});
  SparseMatrix K, M;
  system.assemble(Vector(), &K, &M);
  ModalOptions options;
  options.num_modes = n;
  options.max_rigid_modes = 0;
  ModalSolver solver(system.pattern(), options);
  const ModalResult r = solver.solve(K, M);
  EXPECT_EQ(r.status, EigenStatus::Successful) << r.message;
  return r.eigenvalues.cwiseSqrt();
}

/// apply_model_change must throw std::invalid_argument whose message holds every fragment, and
/// leave the model as it was.
void ExpectChangeError(const std::string& text, const std::vector<std::string>& fragments) {
  Model model = LoadBar();
  const size_t properties = model.properties.size(), masses = model.point_masses.size();
  try {
    apply_model_change(&model, parse_model_change(text));
    ADD_FAILURE() << "expected an error for " << text;
  } catch (const std::invalid_argument& e) {
    const std::string what = e.what();
    for (const std::string& f : fragments) EXPECT_NE(what.find(f), std::string::npos) << "'" << f << "' not in: " << what;
  }
  EXPECT_EQ(model.properties.size(), properties) << text;
  EXPECT_EQ(model.point_masses.size(), masses) << text;
}

void ExpectParseError(const std::string& text, const std::string& fragment) {
  try {
    parse_model_change(text);
    ADD_FAILURE() << "expected a parse error for " << text;
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find(fragment), std::string::npos) << e.what();
    EXPECT_NE(std::string(e.what()).find("change '"), std::string::npos) << e.what();
  }
}

TEST(ModelChange, ParsesEveryFormAndPrintsItBack) {
  ModelChange c = parse_model_change(" joint2.krx = 3.1e5 ");
  EXPECT_EQ(c.kind, ModelChange::Kind::SetProperty);
  EXPECT_EQ(c.entity, "joint2");
  EXPECT_EQ(c.property, "krx");
  EXPECT_EQ(c.value, 3.1e5);
  EXPECT_EQ(to_string(c), "joint2.krx=310000");

  c = parse_model_change("point_mass@top:mass=0.05");
  EXPECT_EQ(c.kind, ModelChange::Kind::AddPointMass);
  ASSERT_EQ(c.places.size(), 1u);
  EXPECT_EQ(c.places[0].kind, NodePlace::Kind::NodeSet);
  EXPECT_EQ(c.places[0].node_set, "top");
  EXPECT_EQ(to_string(c), "point_mass@top:mass=0.05");

  c = parse_model_change("joint@#17/[0.5, -1, 2e-3]:kx=1e6");
  EXPECT_EQ(c.kind, ModelChange::Kind::AddJoint);
  ASSERT_EQ(c.places.size(), 2u);
  EXPECT_EQ(c.places[0].kind, NodePlace::Kind::NodeId);
  EXPECT_EQ(c.places[0].node_id, 17);
  EXPECT_EQ(c.places[1].kind, NodePlace::Kind::Point);
  EXPECT_EQ(c.places[1].point, Vec3(0.5, -1, 2e-3));
  // The canonical text reads back as the same change.
  const ModelChange again = parse_model_change(to_string(c));
  EXPECT_EQ(to_string(again), to_string(c));
  EXPECT_EQ(again.places[1].point, c.places[1].point);

  EXPECT_EQ(parse_model_change("spring@base:kz=1e7").kind, ModelChange::Kind::AddSpring);
  EXPECT_EQ(to_string(parse_model_change("support@base:kx=1e8")), "support@base:kx=1e+08");
  EXPECT_EQ(parse_model_change("foam.stiffness_scale=0.6").property, "stiffness_scale");
}

TEST(ModelChange, MalformedStringsSayWhatIsExpected) {
  ExpectParseError("joint2.krx", "no '=VALUE'");
  ExpectParseError("joint2.krx=abc", "finite number");
  ExpectParseError("joint2.krx=nan", "finite number");
  ExpectParseError("joint2=5", "ENTITY.PROPERTY");
  ExpectParseError("blob@top:mass=1", "unknown kind 'blob'");
  ExpectParseError("point_mass@top=1", "no ':PROPERTY'");
  ExpectParseError("point_mass@[1,2]:mass=1", "three numbers");
  ExpectParseError("point_mass@#x:mass=1", "node id");
  ExpectParseError("", "empty");
}

TEST(NumberReading, OneGrammarForEveryReaderOfNumbers) {
  using detail::NumberRead;
  auto read = [](const std::string& text) {
    double v = -1;
    const NumberRead r = detail::read_number(text, &v);
    return std::make_pair(r, v);
  };
  EXPECT_EQ(read("2.5e3"), std::make_pair(NumberRead::kOk, 2500.0));
  EXPECT_EQ(read("+7"), std::make_pair(NumberRead::kOk, 7.0));
  EXPECT_EQ(read("-.5"), std::make_pair(NumberRead::kOk, -0.5));
  // An underflow is the tiny (or zero) number it is; an overflow is too large.
  EXPECT_EQ(read("1e-320").first, NumberRead::kOk);
  EXPECT_GT(read("1e-320").second, 0);
  EXPECT_LT(read("1e-320").second, 1e-300);
  EXPECT_EQ(read("-1e-999"), std::make_pair(NumberRead::kOk, -0.0));
  EXPECT_EQ(read("1e400").first, NumberRead::kTooLarge);
  EXPECT_EQ(read("+1e400").first, NumberRead::kTooLarge);
  EXPECT_EQ(read("nan").first, NumberRead::kNotFinite);
  EXPECT_EQ(read("-inf").first, NumberRead::kNotFinite);
  for (const char* bad : {"", "+", "-", "++1", "+-1", " 1", "1 ", "1x", "0x10", "1e", "1,5", "1e400x"})
    EXPECT_EQ(read(bad).first, NumberRead::kNotANumber) << "'" << bad << "'";

  // The readers agree: a change's value, a CSV row's and a UFF record's.
  EXPECT_EQ(parse_model_change("j.krx=+5").value, 5.0);
  EXPECT_GT(parse_model_change("j.krx=1e-320").value, 0);
  EXPECT_THROW(parse_model_change("j.krx=1e400"), std::invalid_argument);
  const TestData csv = read_test_data(
      WriteTempFile("numbers.csv", "mode,frequency_hz,node,direction,value\n1,+12.5,3,z,1e-320\n1,12.5,4,z,-1\n"));
  EXPECT_EQ(csv.modes.at(0).frequency_hz, 12.5);
  EXPECT_GT(*csv.modes.at(0).value(3, 2), 0);
  std::vector<double> numbers;
  std::string bad;
  ASSERT_TRUE(detail::parse_numbers("  1.0D+00-2.5E-320+3", &numbers, &bad)) << bad;
  ASSERT_EQ(numbers.size(), 3u);
  EXPECT_EQ(numbers[0], 1.0);
  EXPECT_LT(numbers[1], 0);
  EXPECT_EQ(numbers[2], 3.0);
  EXPECT_FALSE(detail::parse_numbers("1.0 1e400", &numbers, &bad));
  EXPECT_EQ(bad, "1e400");
}

TEST(ModelChange, SettingAnExistingPropertyRecordsBothValues) {
  Model model = LoadBar();
  const ModelEffect e = apply_model_change(&model, parse_model_change("link.kx=150"));
  EXPECT_EQ(e.name, "link.kx");
  EXPECT_EQ(e.description, "stiffness along x of joint link");
  EXPECT_EQ(e.nominal_value, 100);
  EXPECT_EQ(e.value, 150);
  EXPECT_EQ(model.properties[model.find_property("link.kx")].value, 150);
  EXPECT_EQ(describe_property(model, "bar.E"), "Young's modulus of block bar");
}

TEST(ModelChange, AbsentScaleFactorsAndComponentsAreCreatedAndAct) {
  const Model nominal = LoadBar();
  const Vector f0 = Frequencies(nominal, 4);
  // Stiffness / 4 and mass x 4 each halve every frequency of the (one-block) bar... almost: the
  // joint and point mass at the tip are not scaled, so compare with the same change of all.
  Model softer = nominal;
  ModelEffect e = apply_model_change(&softer, parse_model_change("bar.stiffness_scale=0.25"));
  EXPECT_EQ(e.name, "bar.stiffness_scale");
  EXPECT_EQ(e.nominal_value, 1);  // an absent scale factor multiplies by 1
  EXPECT_EQ(e.description, "stiffness multiplier of block bar");
  apply_model_change(&softer, parse_model_change("link.kx=25"));
  apply_model_change(&softer, parse_model_change("link.ky=25"));
  apply_model_change(&softer, parse_model_change("link.kz=25"));
  EXPECT_LT(testing::RelativeDifference(Frequencies(softer, 4), f0 / 2), 1e-9);

  Model heavier = nominal;
  apply_model_change(&heavier, parse_model_change("bar.mass_scale=4"));
  apply_model_change(&heavier, parse_model_change("weight.mass=0.4"));
  EXPECT_LT(testing::RelativeDifference(Frequencies(heavier, 4), f0 / 2), 1e-9);

  // An absent joint component is zero before: krx between the two reference nodes.
  Model twisted = nominal;
  e = apply_model_change(&twisted, parse_model_change("link.krx=5"));
  EXPECT_EQ(e.nominal_value, 0);
  EXPECT_EQ(e.description, "rotational stiffness about x of joint link");
  EXPECT_NE(twisted.joints[0].stiffness[3], kNoProperty);
}

TEST(ModelChange, RegionsScalePartOfABlockOnTopOfItsOwnMultiplier) {
  const Model nominal = LoadBar();
  const Vector f0 = Frequencies(nominal, 4);
  auto soften_joint = [](Model* m) {  // as above: the joint is not part of the block
    for (const char* c : {"link.kx=25", "link.ky=25", "link.kz=25"}) apply_model_change(m, parse_model_change(c));
  };
  // The bar's 16 elements (centroids x = 0.25 ... 3.75) in two regions at x = 2: each region's
  // stiffness / 2 and the block's / 2 make the whole bar's stiffness / 4, so every frequency halves.
  Model halves = nominal;
  soften_joint(&halves);
  apply_model_change(&halves, parse_model_change("bar.stiffness_scale=0.5"));
  const ModelEffect left = apply_model_change(&halves, parse_model_change("region@bar/[0,0,0]/[2,0.5,0.75]:stiffness_scale=0.5"));
  apply_model_change(&halves, parse_model_change("region@bar/[4,0.5,0.75]/[2,0,0]:stiffness_scale=0.5"));
  EXPECT_EQ(left.name, "bar_region_1_0p25_0p375_n8.stiffness_scale");
  EXPECT_EQ(left.nominal_value, 1);
  EXPECT_NE(left.description.find("part of block bar: its 8 elements"), std::string::npos) << left.description;
  ASSERT_EQ(halves.blocks[0].regions.size(), 2u);
  EXPECT_EQ(halves.blocks[0].regions[0].elements.size(), 8u);
  EXPECT_LT(testing::RelativeDifference(Frequencies(halves, 4), f0 / 2), 1e-9);

  // Overlapping regions multiply; the same box again is the same region, its value replaced.
  Model overlapping = nominal;
  soften_joint(&overlapping);
  apply_model_change(&overlapping, parse_model_change("region@bar/[-1,-1,-1]/[5,1,1]:stiffness_scale=0.7"));
  apply_model_change(&overlapping, parse_model_change("region@bar/[-1,-1,-1]/[5,1,1]:stiffness_scale=0.5"));
  apply_model_change(&overlapping, parse_model_change("region@bar/[0,0,0]/[4,0.5,0.75]:stiffness_scale=0.5"));
  EXPECT_EQ(overlapping.blocks[0].regions.size(), 2u);
  EXPECT_LT(testing::RelativeDifference(Frequencies(overlapping, 4), f0 / 2), 1e-9);
  // Its property is set like any other once the region exists.
  apply_model_change(&overlapping, parse_model_change("bar_region_2_0_0_n16.mass_scale=2"));
  EXPECT_NE(overlapping.blocks[0].regions[0].mass_scale, kNoProperty);

  // Part of the bar only: stiffer near the root raises the first (bending) frequency more
  // than stiffer near the tip does.
  Model root = nominal, tip = nominal;
  apply_model_change(&root, parse_model_change("region@bar/[0,0,0]/[1,0.5,0.75]:stiffness_scale=2"));
  apply_model_change(&tip, parse_model_change("region@bar/[3,0,0]/[4,0.5,0.75]:stiffness_scale=2"));
  EXPECT_GT(Frequencies(root, 1)[0], Frequencies(tip, 1)[0] * 1.01);

  ExpectChangeError("region@beam/[0,0,0]/[1,1,1]:stiffness_scale=2", {"unknown block 'beam'", "known blocks: bar"});
  ExpectChangeError("region@bar/[10,0,0]/[11,1,1]:stiffness_scale=2", {"no element of block 'bar'"});
  ExpectChangeError("region@bar/[0,0,0]/[4,1,1]:kx=2", {"no property 'kx'", "stiffness_scale, mass_scale"});
  ExpectChangeError("region@bar/[0,0,0]:stiffness_scale=2", {"region@BLOCK/[x,y,z]/[x,y,z]"});
  ExpectChangeError("region@bar/[0,0,0]/[4,1,1]:stiffness_scale=0", {"must be positive"});
}

TEST(ModelChange, PointMassOnANodeSetSitsOnEachNodeAndGrowsOnRepeat) {
  Model model = LoadBar();
  const int tip_nodes = static_cast<int>(model.find_node_set("tip")->nodes.size());
  const double mass0 = ParametricSystem(model, {}).total_mass(Vector());
  ModelEffect e = apply_model_change(&model, parse_model_change("point_mass@tip:mass=0.05"));
  EXPECT_EQ(e.name, "added_mass_tip.mass");
  EXPECT_EQ(e.nominal_value, 0);
  EXPECT_NE(e.description.find("node set tip"), std::string::npos) << e.description;
  EXPECT_NE(e.description.find(std::to_string(tip_nodes) + " nodes"), std::string::npos) << e.description;
  EXPECT_NEAR(ParametricSystem(model, {}).total_mass(Vector()), mass0 + 0.05 * tip_nodes, 1e-12);
  // The same place again changes the same entity (nothing new is added).
  const size_t masses = model.point_masses.size();
  e = apply_model_change(&model, parse_model_change("point_mass@tip:mass=0.1"));
  EXPECT_EQ(e.nominal_value, 0.05);
  EXPECT_EQ(model.point_masses.size(), masses);
  EXPECT_NEAR(ParametricSystem(model, {}).total_mass(Vector()), mass0 + 0.1 * tip_nodes, 1e-12);
  // ... and a setting by its name changes every node's share.
  apply_model_change(&model, parse_model_change("added_mass_tip.mass=0.2"));
  EXPECT_NEAR(ParametricSystem(model, {}).total_mass(Vector()), mass0 + 0.2 * tip_nodes, 1e-12);
}

TEST(ModelChange, SpringsJointsAndPointsNameTheirNodes) {
  Model model = LoadBar();
  const Vector f0 = Frequencies(model, 2);
  apply_model_change(&model, parse_model_change("spring@tip:ky=50"));
  const ModelEffect e = apply_model_change(&model, parse_model_change("spring@tip:kz=50"));
  EXPECT_EQ(e.name, "added_spring_tip.kz");
  EXPECT_EQ(e.description.rfind("added spring to ground along z at node set tip", 0), 0u) << e.description;
  ASSERT_EQ(model.ground_springs.size(), 1u);  // one spring with both components
  EXPECT_NE(model.ground_springs[0].stiffness[1], kNoProperty);
  EXPECT_NE(model.ground_springs[0].stiffness[2], kNoProperty);
  const Vector f1 = Frequencies(model, 2);
  EXPECT_GT(f1[0], f0[0]);  // supporting the tip stiffens the bending modes

  // Reference nodes hub and arm carry rotations; their ids follow the mesh nodes'.
  const long hub = model.node_ids[model.joints[0].node_a], arm = model.node_ids[model.joints[0].node_b];
  const ModelEffect j =
      apply_model_change(&model, parse_model_change("joint@#" + std::to_string(hub) + "/#" + std::to_string(arm) + ":krx=3"));
  EXPECT_EQ(j.name, "added_joint_node" + std::to_string(hub) + "_node" + std::to_string(arm) + ".krx");
  EXPECT_NE(j.description.find("rotational stiffness about x"), std::string::npos) << j.description;

  const ModelEffect p = apply_model_change(&model, parse_model_change("point_mass@[0.1,0.01,0]:mass=1"));
  EXPECT_EQ(p.name, "added_mass_node1.mass");  // node 1 is at the origin
  EXPECT_NE(p.description.find("nearest to [0.1,0.01,0]"), std::string::npos) << p.description;
}

TEST(ModelChange, FlexibleSupportReplacesAFixityBySprings) {
  const Model nominal = LoadBar();
  Model model = nominal;
  const ModelEffect e = apply_model_change(&model, parse_model_change("support@root:kx=1e6"));
  EXPECT_EQ(e.name, "support_root.kx");
  EXPECT_TRUE(std::isinf(e.nominal_value));  // the nodes were fixed: rigid
  EXPECT_EQ(e.description.rfind("flexible support along x at node set root", 0), 0u) << e.description;
  ASSERT_EQ(model.ground_springs.size(), 1u);
  EXPECT_TRUE(model.ground_springs[0].replaces_fixity);
  // x of the root is now free (held by the springs), y and z stay fixed.
  const DofMap before(nominal), after(model);
  const int root_node = nominal.find_node_set("root")->nodes.front();
  EXPECT_EQ(before.free_index(root_node, 0), -1);
  EXPECT_GE(after.free_index(root_node, 0), 0);
  EXPECT_EQ(after.free_index(root_node, 1), -1);
  EXPECT_FALSE(before == after) << "vectors on one are not vectors on the other";
  Model with_mass = nominal;
  apply_model_change(&with_mass, parse_model_change("point_mass@[0.1,0.01,0]:mass=1"));
  EXPECT_TRUE(before == DofMap(with_mass)) << "a point mass moves no DOF";
  // A stiff support is nearly rigid and a soft one lowers the axial frequency; bending is unchanged
  // to first order (the bar's first modes bend).
  Model stiff = nominal, soft = nominal;
  apply_model_change(&stiff, parse_model_change("support@root:kx=1e7"));
  apply_model_change(&soft, parse_model_change("support@root:kx=200"));
  const Vector f = Frequencies(nominal, 6), fs = Frequencies(stiff, 6), fw = Frequencies(soft, 6);
  EXPECT_LT(((fs - f).array() / f.array()).abs().maxCoeff(), 1e-3);
  EXPECT_LT(fw.minCoeff(), f.minCoeff());
  // Recorded as a hidden effect with a rigid nominal, and in words.
  const std::vector<ModelEffect> d = property_differences(nominal, model);
  ASSERT_EQ(d.size(), 1u);
  EXPECT_TRUE(std::isinf(d[0].nominal_value));
  EXPECT_EQ(d[0].description, "stiffness along x of flexible support support_root");
  EXPECT_TRUE(std::isinf(absent_property_value(model, "support_root.ky")));
  EXPECT_EQ(absent_property_value(model, "bar.stiffness_scale"), 1.0);
}

TEST(ModelChange, ErrorsNameTheItemAndLikelyCause) {
  ExpectChangeError("nosuch.kx=1", {"change 'nosuch.kx=1'", "unknown entity 'nosuch'",
                                    "known blocks, joints, springs and point masses: bar, link, weight"});
  ExpectChangeError("link.foo=1", {"joint 'link' has no property 'foo'", "its properties: kx, ky, kz, krx, kry, krz"});
  ExpectChangeError("bar.K=1", {"block 'bar' has no property 'K'", "E, nu, density, stiffness_scale, mass_scale"});
  ExpectChangeError("bar.nu=0.5", {"Poisson's ratio", "(-1, 0.5)"});
  ExpectChangeError("link.kx=-1", {"must not be negative"});
  ExpectChangeError("bar.stiffness_scale=0", {"must be positive"});
  ExpectChangeError("point_mass@nowhere:mass=1", {"unknown node set 'nowhere'", "known node sets: root, tip, top_edge, arm_node"});
  ExpectChangeError("point_mass@#99999:mass=1", {"no node with id 99999", "node ids run from 1 to"});
  ExpectChangeError("spring@root:krx=1", {"krx acts on rotations", "has none"});
  ExpectChangeError("point_mass@tip:foo=1", {"no property 'foo'", "mass, Ixx, Iyy, Izz"});
  ExpectChangeError("joint@tip/#1:kx=1", {"a joint connects two nodes", "node set 'tip' has"});
  ExpectChangeError("joint@#1:kx=1", {"joint takes 2 places"});
  ExpectChangeError("joint@#1/#1:kx=1", {"both ends of the joint are node 1"});
  ExpectChangeError("support@tip:kx=1", {"of node set tip (on each of its", "is not fixed along x", "spring@"});
  ExpectChangeError("support@root:kx=0", {"must be positive"});
}

TEST(ModelChange, ABatchOfChangesIsTheirApplicationOneAfterAnother) {
  const Model nominal = LoadBar();
  std::vector<ModelChange> changes;
  for (const char* text : {"spring@tip:ky=50", "point_mass@tip:mass=0.05", "point_mass@tip:mass=0.1", "support@root:kx=1e6",
                           "region@bar/[0,0,0]/[4,1,1]:stiffness_scale=2", "link.kx=7", "spring@tip:kz=20"})
    changes.push_back(parse_model_change(text));
  Model one_by_one = nominal, batch = nominal;
  std::vector<std::string> names;
  for (const ModelChange& c : changes) names.push_back(apply_model_change(&one_by_one, c).name);
  const std::vector<ModelEffect> effects = apply_model_changes(&batch, changes);
  ASSERT_EQ(effects.size(), changes.size());
  for (size_t k = 0; k < changes.size(); ++k) EXPECT_EQ(effects[k].name, names[k]) << k;
  EXPECT_EQ(batch.ground_springs.size(), one_by_one.ground_springs.size());
  EXPECT_EQ(batch.point_masses.size(), one_by_one.point_masses.size());
  const Vector f = Frequencies(one_by_one, 4), g = Frequencies(batch, 4);
  EXPECT_LT(((f - g).array() / f.array()).abs().maxCoeff(), 1e-12);

  // A change that fails leaves the model as it was and is named, wherever it stands in the batch.
  changes.insert(changes.begin() + 3, parse_model_change("link.kx=-1"));
  Model untouched = nominal;
  try {
    apply_model_changes(&untouched, changes);
    ADD_FAILURE() << "expected an error";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("change 'link.kx=-1'"), std::string::npos) << e.what();
  }
  EXPECT_EQ(untouched.ground_springs.size(), nominal.ground_springs.size());
  EXPECT_EQ(untouched.point_masses.size(), nominal.point_masses.size());
  EXPECT_TRUE(property_differences(nominal, untouched).empty());
}

TEST(ModelChange, PropertyDifferencesListWhatChangedExceptTheExcluded) {
  const Model nominal = LoadBar();
  Model changed = nominal;
  apply_model_change(&changed, parse_model_change("link.kx=150"));
  apply_model_change(&changed, parse_model_change("bar.mass_scale=1.1"));
  apply_model_change(&changed, parse_model_change("point_mass@tip:mass=0.05"));
  apply_model_change(&changed, parse_model_change("bar.E=900"));
  const std::vector<ModelEffect> d = property_differences(nominal, changed, {"bar.E"});
  ASSERT_EQ(d.size(), 3u);
  EXPECT_EQ(d[0].name, "link.kx");
  EXPECT_EQ(d[0].nominal_value, 100);
  EXPECT_EQ(d[1].name, "bar.mass_scale");
  EXPECT_EQ(d[1].nominal_value, 1);
  EXPECT_EQ(d[2].name, "added_mass_tip.mass");
  EXPECT_EQ(d[2].nominal_value, 0);
  EXPECT_EQ(d[2].value, 0.05);
  EXPECT_EQ(d[2].description, "mass of point mass added_mass_tip");
  EXPECT_TRUE(property_differences(nominal, nominal).empty());
}

TEST(ModelChange, ChangesFileIsReadWithLinesInErrors) {
  const std::string good = WriteTempFile("changes.yaml", "description: stiffer joint\nchanges:\n  - link.kx=150\n  - point_mass@tip:mass=0.05\n");
  const auto changes = load_model_changes(good);
  ASSERT_TRUE(changes);
  ASSERT_EQ(changes->size(), 2u);
  EXPECT_EQ(to_string((*changes)[1]), "point_mass@tip:mass=0.05");
  EXPECT_FALSE(load_model_changes(WriteTempFile("problem.yaml", kBarWithTip)));
  const std::string bad = WriteTempFile("bad.yaml", "changes:\n  - link.kx=150\n  - point_mass@tip:mass\n");
  try {
    load_model_changes(bad);
    ADD_FAILURE() << "expected a ProblemError";
  } catch (const ProblemError& e) {
    EXPECT_EQ(e.file(), bad);
    EXPECT_EQ(e.line(), 3);
    EXPECT_NE(std::string(e.what()).find("no '=VALUE'"), std::string::npos) << e.what();
  }
}

}  // namespace
}  // namespace modalcal
