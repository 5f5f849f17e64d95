// Test-analysis correlation: a model against its own modes is perfect by every measure, and a
// perturbed frequency, a disturbed sensor or swapped shapes show where they should.
#include <gtest/gtest.h>

#include <cmath>

#include "modalcal/comparison.hpp"
#include "modalcal/problem_file.hpp"
#include "test_util.hpp"

namespace modalcal {

using testing::LoadProblem;
namespace {

// A cantilevered bar with triaxial sensors on its top edge (9 nodes, the first at the clamped
// root) and six modes synthesized at E = 1200.
const std::string kBar = testing::CantileverBar("  corner: {box: {min: [4, 0.5, 0.75], max: [4, 0.5, 0.75]}}\n") + R"(parameters:
  E: {targets: [bar.E], initial: 1000, lower: 10, upper: 1e5, truth: 1200}
measured:
  synthetic: {modes: [1, 2, 3, 4, 5, 6]}
options: {num_modes: 8}
)";

Problem Load(const std::string& sensors = "sensors:\n  - {node_set: top_edge, directions: [x, y, z]}\n") {
  return LoadProblem(testing::WriteTempFile("bar.yaml", kBar + sensors));
}

TEST(Comparison, ModelAgainstItsOwnModesIsPerfect) {
  const Problem problem = Load();
  const ModalComparison c = compare_modes(problem, problem.truth_values());
  ASSERT_EQ(c.pairs.size(), 6u);
  for (int i = 0; i < 6; ++i) {
    const ComparedPair& pair = c.pairs[i];
    EXPECT_EQ(pair.measured, i);
    EXPECT_EQ(pair.model, i);
    EXPECT_NEAR(pair.error_percent, 0.0, 1e-7);
    EXPECT_NEAR(pair.mac, 1.0, 1e-9);
    EXPECT_NEAR(c.mac(i, i), 1.0, 1e-9);
    EXPECT_NEAR(pair.cross_orthogonality, 1.0, 1e-9);
    for (int k = 0; k < 6; ++k)
      if (k != i) {
        EXPECT_NEAR(c.cross_orthogonality(i, k), 0.0, 1e-8) << i << " " << k;
      }
  }
  EXPECT_TRUE(c.unpaired_measured.empty());
  // Every computed model mode beyond the six measured ones is unpaired.
  ASSERT_EQ(c.mac.cols(), c.model_hz.size());
  ASSERT_GT(c.model_hz.size(), 6);
  EXPECT_EQ(static_cast<Eigen::Index>(c.unpaired_model.size()), c.model_hz.size() - 6);
  EXPECT_EQ(c.unpaired_model.front(), 6);
  // COMAC is 1 at every sensor DOF, undefined at the clamped root where every shape is zero.
  ASSERT_EQ(c.comac.size(), static_cast<Eigen::Index>(problem.sensors.size()));
  for (size_t s = 0; s < problem.sensors.size(); ++s) {
    if (problem.model.coordinates[problem.sensors[s].node][0] == 0)
      EXPECT_TRUE(std::isnan(c.comac[s])) << problem.sensors[s].label;
    else
      EXPECT_NEAR(c.comac[s], 1.0, 1e-9) << problem.sensors[s].label;
  }
}

TEST(Comparison, PerturbedFrequencyAndSensorAreFound) {
  Problem problem = Load();
  problem.measured[1].frequency_hz *= 1.05;
  const Eigen::Index disturbed = 13;  // the y sensor of the fifth top-edge node
  for (MeasuredMode& m : problem.measured) m.shape[disturbed] += 0.5;
  const ModalComparison c = compare_modes(problem, problem.truth_values());
  EXPECT_NEAR(c.pairs[1].error_percent, 100 * (1 / 1.05 - 1), 1e-6);
  EXPECT_NEAR(c.pairs[0].error_percent, 0.0, 1e-7);
  Eigen::Index lowest = -1;
  for (Eigen::Index s = 0; s < c.comac.size(); ++s)
    if (std::isfinite(c.comac[s]) && (lowest < 0 || c.comac[s] < c.comac[lowest])) lowest = s;
  EXPECT_EQ(lowest, disturbed) << c.comac.transpose();
  EXPECT_LT(c.comac[disturbed], 0.9);
  for (const ComparedPair& pair : c.pairs) {
    EXPECT_LT(pair.mac, 1 - 1e-3);
    EXPECT_LT(pair.cross_orthogonality, 1 - 1e-3);  // the disturbance lies partly outside the mode
  }
}

TEST(Comparison, SwappedShapesShowInTheMacMatrix) {
  Problem problem = Load();
  std::swap(problem.measured[0].shape, problem.measured[1].shape);
  // Paired by MAC, the shapes find their model modes.
  ModalComparison c = compare_modes(problem, problem.truth_values());
  EXPECT_EQ(c.pairs[0].model, 1);
  EXPECT_EQ(c.pairs[1].model, 0);
  EXPECT_GT(std::abs(c.pairs[0].error_percent), 1.0);  // at the wrong frequency
  // Paired by mode number, the pairs' shapes disagree: both are listed as unpaired.
  for (int i : {0, 1}) {
    problem.measured[i].pairing.kind = PairingRule::Kind::ModelIndex;
    problem.measured[i].pairing.model_index = i + 1;
  }
  c = compare_modes(problem, problem.truth_values());
  EXPECT_EQ(c.unpaired_measured, (std::vector<int>{0, 1}));
  EXPECT_NEAR(c.mac(0, 1), 1.0, 1e-9);
  EXPECT_NEAR(c.mac(1, 0), 1.0, 1e-9);
  EXPECT_LT(c.pairs[0].mac, 0.5);
}

TEST(Comparison, NoTestMassWithFewerSensorDofsThanModes) {
  const Problem problem = Load("sensors:\n  - {node_set: corner, directions: [x, y, z]}\n");
  const ModalComparison c = compare_modes(problem, problem.truth_values());
  EXPECT_EQ(c.cross_orthogonality.size(), 0);
  EXPECT_NE(c.cross_orthogonality_note.find("at least as many sensor DOFs (3) as model modes in its basis (6)"),
            std::string::npos)
      << c.cross_orthogonality_note;
  for (const ComparedPair& pair : c.pairs) EXPECT_TRUE(std::isnan(pair.cross_orthogonality));
}

}  // namespace
}  // namespace modalcal
