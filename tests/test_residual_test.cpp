// The chi-square residual test: the tail function against closed forms, its false-alarm rate on
// pure noise, and its verdict on a model with a wrong parameter.

#include <cmath>

#include "modalcal/objective.hpp"
#include "modalcal/residual_test.hpp"
#include "modalcal/problem_file.hpp"
#include "support/random_draws.hpp"
#include "test_util.hpp"

namespace modalcal {

using testing::LoadProblem;
namespace {

TEST(ResidualTest, ChiSquareTailMatchesClosedForms) {
  for (double x : {0.01, 0.5, 1.0, 3.0, 7.5, 20.0, 60.0}) {
    EXPECT_CLOSE(chi_square_upper_tail(x, 1), std::erfc(std::sqrt(x / 2)), 1e-12);
    EXPECT_CLOSE(chi_square_upper_tail(x, 2), std::exp(-x / 2), 1e-12);
    EXPECT_CLOSE(chi_square_upper_tail(x, 4), std::exp(-x / 2) * (1 + x / 2), 1e-12);
  }
  EXPECT_EQ(chi_square_upper_tail(0, 3), 1.0);
  EXPECT_THROW(chi_square_upper_tail(1, 0), std::invalid_argument);
  EXPECT_THROW(chi_square_upper_tail(NAN, 3), std::invalid_argument);
}

// Measured modes of the truth model with noise drawn as the header's noise model says.
void AddNoise(Problem* problem, const MeasurementNoise& noise, detail::StandardNormal* z) {
  for (MeasuredMode& m : problem->measured) {
    m.frequency_hz *= 1 + noise.frequency * (*z)();
    const double scale = noise.shape * m.shape.cwiseAbs().maxCoeff();
    for (Eigen::Index k = 0; k < m.shape.size(); ++k) m.shape[k] += scale * (*z)();
  }
}

TEST(ResidualTest, PureNoiseIsFlaggedAtAboutTheSignificanceLevel) {
  // The portal frame: its twelve triaxial sensors tell its six modes apart under noise (the
  // every-parameter-kind test model's sensors do not, and a mispaired mode is no test of noise).
  const Problem clean = LoadProblem(testing::SourcePath("problems/portal-frame/synthetic.yaml"));
  MeasurementNoise noise;
  noise.frequency = 0.002;
  noise.shape = 0.02;
  ResidualTestOptions options;
  options.significance = 0.2;
  detail::StandardNormal rng(7);
  const int draws = 100;
  int flagged = 0;
  double mean_reduced_chi2 = 0;
  for (int d = 0; d < draws; ++d) {
    Problem noisy = clean;
    AddNoise(&noisy, noise, &rng);
    Objective objective(noisy);
    const Evaluation e = objective.evaluate(noisy.truth_values());
    ASSERT_TRUE(e.ok) << e.message;
    // At the truth nothing was fitted to this noise: all degrees of freedom remain.
    const ResidualTest t = test_residual(objective, e, noise, 0, options);
    flagged += t.model_form_error;
    mean_reduced_chi2 += t.reduced_chi2 / draws;
  }
  // Binomial(100, 0.2): mean 20, standard deviation 4; the mean of 100 reduced chi-squares
  // on about 200 degrees of freedom has standard deviation 0.01.
  EXPECT_GE(flagged, 8);
  EXPECT_LE(flagged, 32);
  EXPECT_NEAR(mean_reduced_chi2, 1.0, 0.04);
}

TEST(ResidualTest, AWrongParameterIsAModelFormErrorAndNamesItsModes) {
  Problem problem = LoadProblem(testing::WriteTempFile("model.yaml", testing::kEveryParameterKindModel));
  MeasurementNoise noise;
  noise.frequency = 0.002;
  noise.shape = 0.02;
  detail::StandardNormal rng(3);
  AddNoise(&problem, noise, &rng);
  Objective objective(problem);

  const Evaluation right = objective.evaluate(problem.truth_values());
  ASSERT_TRUE(right.ok) << right.message;
  const ResidualTest pass = test_residual(objective, right, noise, 0);
  EXPECT_FALSE(pass.model_form_error) << pass.verdict;
  EXPECT_NE(pass.verdict.find("consistent with the stated noise"), std::string::npos);
  // As many parameters as data: no test is possible, and the verdict says so.
  int data = 0;
  for (const ModeResidual& m : pass.modes) data += m.dof;
  const ResidualTest none = test_residual(objective, right, noise, data);
  EXPECT_FALSE(none.model_form_error);
  EXPECT_NE(none.verdict.find("cannot show a model-form error"), std::string::npos) << none.verdict;

  Vector wrong = problem.truth_values();
  wrong[0] *= 1.1;  // the first parameter 10 % off: far beyond 0.2 % frequency noise
  const Evaluation off = objective.evaluate(wrong);
  ASSERT_TRUE(off.ok) << off.message;
  const ResidualTest fail = test_residual(objective, off, noise, 0);
  EXPECT_TRUE(fail.model_form_error);
  EXPECT_LT(fail.p_value, 1e-6);
  int flagged = 0;
  for (const ModeResidual& m : fail.modes) flagged += m.flagged;
  EXPECT_GE(flagged, 1);
  EXPECT_NE(fail.verdict.find("model-form error is likely"), std::string::npos) << fail.verdict;
}

TEST(ResidualTest, RejectsMissingNoiseAndBadOptions) {
  const Problem problem = LoadProblem(testing::WriteTempFile("model.yaml", testing::kEveryParameterKindModel));
  Objective objective(problem);
  const Evaluation e = objective.evaluate(problem.truth_values());
  EXPECT_THROW(test_residual(objective, e, {0, 0.02}, 0), std::invalid_argument);
  ResidualTestOptions bad;
  bad.significance = 0.7;
  std::string error;
  EXPECT_FALSE(bad.IsValid(&error));
  EXPECT_NE(error.find("significance"), std::string::npos);
  EXPECT_THROW(test_residual(objective, e, {0.002, 0.02}, 0, bad), std::invalid_argument);
}

}  // namespace
}  // namespace modalcal
