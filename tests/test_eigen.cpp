// Forward modal solve: closed-form spring-mass chains, sparse (Lanczos + CHOLMOD) against dense
// LAPACK-style solves, rigid-body modes, normalization and sign, and the failure messages.

#include <Eigen/Eigenvalues>

#include <cmath>

#include "modalcal/assembly.hpp"
#include "modalcal/eigen.hpp"
#include "test_util.hpp"

namespace modalcal {
namespace {

using testing::MakeChain;

struct Solved {
  SparseMatrix K, M;
  ModalResult result;
};

Solved SolveModel(const Model& model, int modes, int max_rigid, double tolerance = 1e-10) {
  ParametricSystem system(model, {});
  Solved s;
  system.assemble(Vector(), &s.K, &s.M);
  ModalOptions options;
  options.num_modes = modes;
  options.max_rigid_modes = max_rigid;
  options.tolerance = tolerance;
  ModalSolver solver(system.pattern(), options);
  s.result = solver.solve(s.K, s.M);
  return s;
}

// Fixed-free chain of n equal masses: omega_j = 2 sqrt(k/m) sin((2j - 1) pi / (2 (2n + 1))).
double ChainOmega(int n, double m, double k, int j) {
  return 2 * std::sqrt(k / m) * std::sin((2 * j - 1) * M_PI / (2 * (2 * n + 1)));
}

class ChainTest : public ::testing::TestWithParam<int> {};

// n = 40 takes the dense path, n = 600 the Lanczos/CHOLMOD path.
TEST_P(ChainTest, GroundedChainMatchesClosedForm) {
  const int n = GetParam();
  const double m = 2.0, k = 3.0e4;
  const Solved s = SolveModel(MakeChain(n, m, k, true), 8, 0);
  ASSERT_EQ(s.result.status, EigenStatus::Successful) << s.result.message;
  ASSERT_EQ(s.result.eigenvalues.size(), 8);
  EXPECT_EQ(s.result.rigid_eigenvalues.size(), 0);
  for (int j = 1; j <= 8; ++j) {
    EXPECT_CLOSE(std::sqrt(s.result.eigenvalues[j - 1]), ChainOmega(n, m, k, j), 1e-9);
    EXPECT_LT(s.result.residuals[j - 1], 1e-8);
  }
}
INSTANTIATE_TEST_SUITE_P(DenseAndSparse, ChainTest, ::testing::Values(40, 600));

TEST(ModalSolver, SparseMatchesDenseGeneralizedSolve) {
  // A free-free chain with unequal masses and stiffnesses, large enough for the Lanczos path.
  Model model = MakeChain(400, 1.0, 1.0e5, false);
  for (size_t i = 0; i < model.properties.size(); ++i)
    model.properties[i].value *= 1.0 + 0.5 * std::sin(0.37 * static_cast<double>(i));
  const Solved s = SolveModel(model, 6, 1);
  ASSERT_EQ(s.result.status, EigenStatus::Successful) << s.result.message;
  Eigen::GeneralizedSelfAdjointEigenSolver<Matrix> dense(Matrix(s.K), Matrix(s.M));
  ASSERT_EQ(dense.info(), Eigen::Success);
  // Dense eigenvalue 0 is the rigid-body mode; elastic ones follow.
  ASSERT_EQ(s.result.rigid_eigenvalues.size(), 1);
  for (int j = 0; j < 6; ++j) {
    EXPECT_CLOSE(s.result.eigenvalues[j], dense.eigenvalues()[j + 1], 1e-9);
    const Vector ud = dense.eigenvectors().col(j + 1);
    const Vector us = s.result.modes.col(j);
    // Same mode up to sign, and mass-normalized.
    EXPECT_NEAR(std::abs(ud.dot(s.M * us)), 1.0, 1e-8);
    EXPECT_NEAR(us.dot(s.M * us), 1.0, 1e-12);
  }
}

TEST(ModalSolver, RigidBodyModeOfFreeChainIsReportedSeparately) {
  const Solved s = SolveModel(MakeChain(30, 1.0, 100.0, false), 4, 6);
  ASSERT_EQ(s.result.status, EigenStatus::Successful) << s.result.message;
  ASSERT_EQ(s.result.rigid_eigenvalues.size(), 1);
  EXPECT_LT(std::abs(s.result.rigid_eigenvalues[0]), 1e-8);
  // The rigid mode is a uniform translation: all entries equal.
  const Vector r = s.result.rigid_modes.col(0);
  EXPECT_LT((r.array() - r[0]).abs().maxCoeff(), 1e-8 * std::abs(r[0]));
  EXPECT_GT(s.result.eigenvalues[0], 1e-3);
}

TEST(ModalSolver, SignIsDeterministicLargestComponentPositive) {
  const Solved s = SolveModel(MakeChain(50, 1.0, 100.0, true), 5, 0);
  ASSERT_EQ(s.result.status, EigenStatus::Successful);
  for (int j = 0; j < 5; ++j) {
    Eigen::Index imax;
    s.result.modes.col(j).cwiseAbs().maxCoeff(&imax);
    EXPECT_GT(s.result.modes(imax, j), 0.0);
  }
}

TEST(ModalSolver, MissingSupportIsNamedAsLikelyCause) {
  // A free chain solved as if supported: one zero-frequency mode too many.
  const Solved s = SolveModel(MakeChain(30, 1.0, 100.0, false), 3, 0);
  EXPECT_NE(s.result.status, EigenStatus::Successful);
  EXPECT_NE(s.result.message.find("supports are missing"), std::string::npos) << s.result.message;
}

TEST(ModalSolver, NegativeStiffnessIsReportedAsIndefinite) {
  for (int n : {30, 500}) {  // dense and sparse paths
    Model model = MakeChain(n, 1.0, 100.0, true);
    model.properties[model.find_property("joint3.kx")].value = -500.0;
    const Solved s = SolveModel(model, 3, 0);
    EXPECT_NE(s.result.status, EigenStatus::Successful) << "n = " << n;
    EXPECT_NE(s.result.message.find("indefinite"), std::string::npos) << s.result.message;
  }
}

TEST(ModalSolver, InvalidOptionsNameTheField) {
  ModalOptions options;
  options.tolerance = -1;
  std::string error;
  EXPECT_FALSE(options.IsValid(&error));
  EXPECT_NE(error.find("tolerance"), std::string::npos);
  options = ModalOptions();
  options.max_rigid_modes = 7;
  EXPECT_FALSE(options.IsValid(&error));
  EXPECT_NE(error.find("max_rigid_modes"), std::string::npos);
  options = ModalOptions();
  options.initial_shift = 1.0;
  EXPECT_FALSE(options.IsValid(&error));
  EXPECT_NE(error.find("initial_shift"), std::string::npos);
  EXPECT_THROW(ModalSolver(SparseMatrix(3, 3), options), std::invalid_argument);
}

TEST(Frequency, RoundTripsAndKeepsSign) {
  EXPECT_CLOSE(frequency_hz(eigenvalue_of_hz(1195.0)), 1195.0, 1e-14);
  EXPECT_LT(frequency_hz(-100.0), 0.0);
}

}  // namespace
}  // namespace modalcal
