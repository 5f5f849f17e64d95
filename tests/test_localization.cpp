// Model-form diagnosis: expansion of measured shapes on model modes, residual forces with the
// measured eigenvalues, and the ranking of regions by residual energy.

#include <gtest/gtest.h>

#include <algorithm>
#include <functional>

#include "diagnostics/region_energy.hpp"
#include "modalcal/synthesis.hpp"
#include "modalcal/localization.hpp"
#include "modalcal/problem_file.hpp"
#include "test_util.hpp"

namespace modalcal {
namespace {

using testing::LoadProblem;
using testing::SourcePath;

Problem PortalFrame() {
  return LoadProblem(SourcePath("problems/portal-frame/synthetic.yaml"));
}

void ScaleBlockStiffness(Model* model, const std::string& block, double factor) {
  for (ElementBlock& b : model->blocks)
    if (b.name == block) b.stiffness_scale = model->add_property(block + ".stiffness_scale", factor);
}

// Changes one property of the test article. A property that a calibration parameter sets is
// first released from it (at the parameter's truth value), so that the change reaches the
// article alone.
void ChangeArticle(Problem* article, const std::string& property, double factor) {
  const PropertyId id = article->model.find_property(property);
  ASSERT_NE(id, kNoProperty) << property;
  for (auto q = article->parameters.begin(); q != article->parameters.end(); ++q) {
    const auto target = std::find(q->targets.begin(), q->targets.end(), id);
    if (target == q->targets.end()) continue;
    article->model.properties[id].value = *q->truth;
    q->targets.erase(target);
    if (q->targets.empty()) article->parameters.erase(q);
    break;
  }
  article->model.properties[id].value *= factor;
}

// `problem` with "measured" modes from a test article that differs from the model as `change`
// says; the model itself, at its truth parameters, does not know.
Problem MeasuredOn(Problem problem, const std::function<void(Problem*)>& change) {
  Problem article = problem;
  change(&article);
  synthesize_measured(&article);
  problem.measured = article.measured;
  return problem;
}

Problem PortalFrameMeasuredOn(const std::function<void(Problem*)>& change) { return MeasuredOn(PortalFrame(), change); }

double Share(const Localization& result, const std::string& region) {
  for (const RegionShare& r : result.ranking)
    if (r.name == region) return r.share;
  ADD_FAILURE() << "no region " << region;
  return 0;
}

TEST(Localization, ExpansionReproducesTheModelModesWhenTheModelIsRight) {
  Problem problem = PortalFrame();  // measured = the model's own modes 1-6 at the truth
  const Localization as_synthesized = localize_model_error(problem, problem.truth_values());
  ASSERT_TRUE(as_synthesized.ok) << as_synthesized.message;
  for (MeasuredMode& m : problem.measured) m.shape *= -2.5;  // test data: any sign and unit
  const Localization result = localize_model_error(problem, problem.truth_values());
  ASSERT_TRUE(result.ok) << result.message;
  ASSERT_EQ(result.modes.size(), 6u);
  for (const ExpandedMode& m : result.modes) {
    EXPECT_EQ(m.model_mode, m.measured);
    EXPECT_CLOSE(m.scale_factor, as_synthesized.modes[m.measured].scale_factor / -2.5, 1e-12);
    EXPECT_LT(m.sensor_misfit, 1e-12);
    EXPECT_LT(testing::RelativeDifference(m.shape, result.modal.modes.col(m.model_mode)), 1e-9)
        << "measured mode " << m.measured + 1;
  }
}

TEST(Localization, ResidualEnergyVanishesWhenTheModelIsRightAndNotOtherwise) {
  Problem problem = PortalFrame();
  const Localization right = localize_model_error(problem, problem.truth_values());
  ASSERT_TRUE(right.ok) << right.message;
  // Rounding level: K u carries an error of about 1e-16 K_dd u_d, and K_dd / (lambda M_dd)
  // reaches 1e8 at the connections (1e8 N/m), so the floor is about (1e-16 1e8)^2.
  EXPECT_LT(right.total_energy, 1e-14);
  // A 1 % stiffer column in the test article stands far above it.
  const Localization wrong = localize_model_error(
      PortalFrameMeasuredOn([](Problem* a) { ScaleBlockStiffness(&a->model, "column_2", 1.01); }),
      problem.truth_values());
  ASSERT_TRUE(wrong.ok) << wrong.message;
  EXPECT_GT(wrong.total_energy, 1e6 * right.total_energy) << right.total_energy;
  EXPECT_EQ(wrong.ranking[0].name, "column_2");
}

TEST(Localization, RegularizationLeavesAModelThatFitsFreeOfResidual) {
  Problem problem = PortalFrame();
  LocalizationOptions options;
  options.regularization = 0.1;
  options.basis_modes = 40;  // more than the 36 readings: allowed with regularization
  const Localization result = localize_model_error(problem, problem.truth_values(), options);
  ASSERT_TRUE(result.ok) << result.message;
  EXPECT_EQ(result.basis_size, 40);
  EXPECT_LT(result.total_energy, 1e-14);
}

// The test article differs from the model in one block: that block must rank first.
TEST(Localization, AChangedBlockRanksFirst) {
  const Vector truth = PortalFrame().truth_values();
  const struct {
    const char* block;
    std::function<void(Problem*)> change;
  } cases[] = {
      {"column_2", [](Problem* a) { ScaleBlockStiffness(&a->model, "column_2", 0.7); }},
      {"column_1", [](Problem* a) { ScaleBlockStiffness(&a->model, "column_1", 1.3); }},
      {"beam", [](Problem* a) { ScaleBlockStiffness(&a->model, "beam", 0.8); }},
      {"beam", [](Problem* a) { ChangeArticle(a, "beam.density", 1.2); }},
      {"column_1", [](Problem* a) { ChangeArticle(a, "column_1.density", 1.3); }},
  };
  for (const auto& c : cases) {
    const Localization result = localize_model_error(PortalFrameMeasuredOn(c.change), truth);
    ASSERT_TRUE(result.ok) << result.message;
    EXPECT_EQ(result.ranking[0].name, c.block) << format_ranking(result, 5);
    EXPECT_GT(result.ranking[0].share, 0.5) << format_ranking(result, 5);
  }
}

// A joint has almost no mass of its own: its residual shows in the blocks it connects. The
// ranking must start there, and must tell the changed connection from its mirror image.
TEST(Localization, AChangedJointShowsOnItsOwnSide) {
  const Vector truth = PortalFrame().truth_values();
  const struct {
    const char *joint, *column, *other_joint, *other_column;
    std::function<void(Problem*)> change;
  } cases[] = {
      {"conn_1", "column_1", "conn_2", "column_2", [](Problem* a) { ChangeArticle(a, "conn_1.kry", 0.3); }},
      {"conn_2", "column_2", "conn_1", "column_1", [](Problem* a) { ChangeArticle(a, "conn_2.krx", 3); }},
      {"conn_1", "column_1", "conn_2", "column_2", [](Problem* a) { ChangeArticle(a, "conn_1.kz", 0.01); }},
  };
  for (const auto& c : cases) {
    const Localization result = localize_model_error(PortalFrameMeasuredOn(c.change), truth);
    ASSERT_TRUE(result.ok) << result.message;
    const std::string top = result.ranking[0].name;
    EXPECT_TRUE(top == c.joint || top == c.column || top == "beam") << c.joint << ": " << format_ranking(result, 5);
    EXPECT_GT(Share(result, c.column), Share(result, c.other_column)) << c.joint;
    EXPECT_GT(Share(result, c.joint), Share(result, c.other_joint)) << c.joint;
  }
}

TEST(Localization, IndicatorDoesNotDependOnTheMeasuredShapesScaleOrSign) {
  Problem problem = PortalFrameMeasuredOn([](Problem* a) { ScaleBlockStiffness(&a->model, "beam", 0.9); });
  const Localization a = localize_model_error(problem, problem.truth_values());
  problem.measured[2].shape *= -1e3;
  problem.measured[4].shape *= 1e-4;
  const Localization b = localize_model_error(problem, problem.truth_values());
  ASSERT_TRUE(a.ok && b.ok);
  EXPECT_LT(testing::RelativeDifference(b.element_indicator, a.element_indicator), 1e-9);
  EXPECT_CLOSE(b.total_energy, a.total_energy, 1e-9);
}

TEST(Localization, ElementIndicatorAddsUpToTheBlockShares) {
  const Problem problem = PortalFrameMeasuredOn([](Problem* a) { ChangeArticle(a, "conn_1.kry", 0.5); });
  const Localization result = localize_model_error(problem, problem.truth_values());
  ASSERT_TRUE(result.ok) << result.message;
  ASSERT_EQ(result.element_indicator.size(), problem.model.num_elements());
  EXPECT_GE(result.element_indicator.minCoeff(), 0.0);
  int first = 0;
  double blocks = 0;
  for (const ElementBlock& block : problem.model.blocks) {
    const double sum = result.element_indicator.segment(first, block.num_elements()).sum();
    EXPECT_CLOSE(sum, Share(result, block.name), 1e-12) << block.name;
    blocks += sum;
    first += block.num_elements();
  }
  // Everything but the joints' and payload's own reference nodes reaches the mesh: those pass
  // their energy on to the faces they are coupled to.
  EXPECT_CLOSE(blocks, 1.0, 1e-12);
}

TEST(Localization, MeshViewSpreadsReferenceNodesAndSplitsSharedNodes) {
  // Two hex8 elements along x sharing the face at x = 1, and a reference node coupled to the
  // face at x = 2. Node energies: 1 on every mesh node, 8 on the reference node.
  Model model;
  for (int i = 0; i < 12; ++i) model.add_node(i + 1, Vec3(i / 4, (i % 4 == 1 || i % 4 == 2), i % 4 >= 2));
  const int reference = model.add_node(13, Vec3(2.5, 0.5, 0.5), true);
  ElementBlock block;
  block.name = "bar";
  for (int e = 0; e < 2; ++e)
    for (int corner : {0, 4, 5, 1, 3, 7, 6, 2}) block.connectivity.push_back(4 * e + corner);
  model.blocks.push_back(block);
  model.rigid_couplings.push_back({"tip", reference, {8, 9, 10, 11}});
  Vector energy = Vector::Ones(13);
  energy[reference] = 8;
  const Vector mesh = detail::mesh_node_energy(model, energy);
  EXPECT_EQ(mesh[reference], 0.0);
  EXPECT_EQ(mesh[8], 3.0);
  EXPECT_EQ(mesh[0], 1.0);
  const Vector elements = detail::element_energy(model, mesh);
  EXPECT_DOUBLE_EQ(elements[0], 4 * 1.0 + 4 * 0.5);  // shared face split in two
  EXPECT_DOUBLE_EQ(elements[1], 4 * 0.5 + 4 * 3.0);
}

TEST(Localization, FreeFreeModelsExpandWithTheirRigidBodyModes) {
  // A free-free bar of two blocks, sensed along two opposite edges.
  std::string text = R"(
mesh:
  element: hex8
  element_size: 0.5
  boxes:
    - {block: a, min: [0, 0, 0], max: [3, 0.5, 1]}
    - {block: b, min: [3, 0, 0], max: [6, 0.5, 1]}
blocks:
  a: {E: 1000, nu: 0.3, density: 1.0}
  b: {E: 1000, nu: 0.3, density: 1.0}
parameters:
  E: {targets: [a.E, b.E], initial: 1000, lower: 10, upper: 1e5, truth: 1000}
measured:
  synthetic: {modes: [1, 2, 3, 4], shapes: true}
options:
  num_modes: 6
sensors:
)";
  for (int x = 0; x <= 6; ++x)
    for (const char* edge : {"0.5, 1", "0, 0"})
      text += "  - {at: [" + std::to_string(x) + ", " + edge + "], directions: [x, y, z]}\n";
  const Problem problem = LoadProblem(testing::WriteTempFile("free.yaml", text));
  const Localization right = localize_model_error(problem, problem.truth_values());
  ASSERT_TRUE(right.ok) << right.message;
  EXPECT_EQ(right.modal.rigid_modes.cols(), 6);
  EXPECT_GE(right.basis_size, 6 + 4);
  EXPECT_LT(right.total_energy, 1e-20);
  const Localization wrong =
      localize_model_error(MeasuredOn(problem, [](Problem* a) { ChangeArticle(a, "b.density", 0.8); }),
                           problem.truth_values());
  ASSERT_TRUE(wrong.ok) << wrong.message;
  EXPECT_EQ(wrong.ranking[0].name, "b") << format_ranking(wrong, 2);
}

TEST(Localization, OptionsAndInputsAreChecked) {
  std::string error;
  LocalizationOptions options;
  EXPECT_TRUE(options.IsValid(&error));
  options.regularization = 1.5;
  EXPECT_FALSE(options.IsValid(&error));
  EXPECT_NE(error.find("regularization = 1.5"), std::string::npos) << error;
  options = {};
  options.max_frequency_ratio = 0.5;
  EXPECT_FALSE(options.IsValid(&error));
  EXPECT_NE(error.find("max_frequency_ratio"), std::string::npos) << error;

  Problem problem = PortalFrame();
  const Vector truth = problem.truth_values();
  options = {};
  options.basis_modes = 40;  // 36 readings
  EXPECT_THROW(localize_model_error(problem, truth, options), std::invalid_argument);
  options.basis_modes = 4;  // leaves out the paired modes 5 and 6
  EXPECT_THROW(localize_model_error(problem, truth, options), std::invalid_argument);
  EXPECT_THROW(localize_model_error(problem, Vector::Ones(2)), std::invalid_argument);
  for (MeasuredMode& m : problem.measured) m.shape.resize(0);
  EXPECT_THROW(localize_model_error(problem, truth), std::invalid_argument);
}

}  // namespace
}  // namespace modalcal
