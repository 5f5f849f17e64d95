// The bundled LFU problems: the truth model reproduces the report's measured axial modes within
// 5 %, those modes are labelled axial, and the synthetic and experimental files load as the
// report's studies describe them.

#include <cmath>

#include "modalcal/assembly.hpp"
#include "modalcal/eigen.hpp"
#include "modalcal/mode_description.hpp"
#include "modalcal/problem.hpp"
#include "modalcal/problem_file.hpp"
#include "test_util.hpp"

namespace modalcal {
namespace {

using testing::LoadProblem;
using testing::SourcePath;

std::vector<ModeDescription> ModesAt(const Problem& problem, const Vector& p) {
  ParametricSystem system(problem.model, problem.parameter_targets());
  SparseMatrix K, M;
  system.assemble(p, &K, &M);
  ModalOptions options;
  options.num_modes = problem.options.num_modes;
  options.max_rigid_modes = problem.expected_rigid_modes();
  ModalSolver solver(system.pattern(), options);
  const ModalResult result = solver.solve(K, M);
  EXPECT_EQ(result.status, EigenStatus::Successful) << result.message;
  return describe_modes(system, p, M, result);
}

TEST(Lfu, TruthModelReproducesMeasuredAxialModesWithinFivePercent) {
  const Problem problem = LoadProblem(SourcePath("problems/lfu/synthetic.yaml"));
  ASSERT_TRUE(problem.has_truth());
  const std::vector<ModeDescription> modes = ModesAt(problem, problem.truth_values());
  const int first = find_family_mode(modes, "axial", 1), second = find_family_mode(modes, "axial", 2);
  ASSERT_GT(first, 0);
  ASSERT_GT(second, 0);
  EXPECT_LT(std::abs(modes[first - 1].frequency_hz / 1195.0 - 1), 0.05) << modes[first - 1].frequency_hz;
  EXPECT_LT(std::abs(modes[second - 1].frequency_hz / 2085.0 - 1), 0.05) << modes[second - 1].frequency_hz;
  // Axial modes move the parts along x; the others are bending, rocking or torsion.
  for (const ModeDescription& d : modes) {
    if (d.label == "axial") EXPECT_GE(d.part_translation_fraction[0], 0.5);
    else EXPECT_LT(d.part_translation_fraction[0], 0.5);
  }
}

TEST(Lfu, SyntheticStudyIsTheReportsSetUp) {
  const Problem problem = LoadProblem(SourcePath("problems/lfu/synthetic.yaml"));
  ASSERT_EQ(problem.parameters.size(), 5u);
  EXPECT_EQ(problem.model.joints.size(), 3u);
  for (const Parameter& p : problem.parameters) {
    ASSERT_TRUE(p.truth.has_value()) << p.name;
    EXPECT_CLOSE(p.initial, *p.truth / 10, 1e-12);  // 10x below the truth
    EXPECT_LT(p.lower, p.initial);
    EXPECT_GT(p.upper, *p.truth);
  }
  EXPECT_EQ(problem.measured.size(), 10u);
  EXPECT_EQ(problem.sensors.size(), 24u);
  for (const MeasuredMode& m : problem.measured) EXPECT_EQ(m.shape.size(), 24);
}

TEST(Lfu, ExperimentalCaseHasTwoAxialFrequenciesOnly) {
  const Problem problem = LoadProblem(SourcePath("problems/lfu/experimental.yaml"));
  ASSERT_EQ(problem.measured.size(), 2u);
  EXPECT_EQ(problem.measured[0].frequency_hz, 1195.0);
  EXPECT_EQ(problem.measured[1].frequency_hz, 2085.0);
  EXPECT_EQ(problem.measured[0].pairing.kind, PairingRule::Kind::Family);
  EXPECT_EQ(problem.parameters.size(), 3u);
  EXPECT_EQ(problem.parameters[0].targets.size(), 3u);  // one kx shared by the three joints
  EXPECT_TRUE(problem.sensors.empty());
}

TEST(Lfu, RefinementChangesMeshButNotPhysics) {
  const Problem coarse = LoadProblem(SourcePath("problems/lfu/lfu.yaml"));
  const Problem fine = LoadProblem(SourcePath("problems/lfu/lfu.yaml"), LoadOptions{1.5});
  EXPECT_GT(fine.model.num_elements(), 3 * coarse.model.num_elements());
  const double f_coarse = find_family_mode(ModesAt(coarse, Vector()), "axial", 1);
  EXPECT_GT(f_coarse, 0);
  const std::vector<ModeDescription> a = ModesAt(coarse, Vector()), b = ModesAt(fine, Vector());
  const int ia = find_family_mode(a, "axial", 1), ib = find_family_mode(b, "axial", 1);
  ASSERT_GT(ia, 0);
  ASSERT_GT(ib, 0);
  EXPECT_LT(std::abs(a[ia - 1].frequency_hz / b[ib - 1].frequency_hz - 1), 0.02);
}

}  // namespace
}  // namespace modalcal
