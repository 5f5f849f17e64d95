// Forward modal solve: closed-form spring-mass chains, sparse (Lanczos + CHOLMOD) against dense
// LAPACK-style solves, rigid-body modes, normalization and sign, and the failure messages; the
// block Lanczos path against Spectra, through thick restarts, deflation and a singular M.

#include <Eigen/Eigenvalues>

#include <cmath>
#include <vector>

#if defined(MODALCAL_CHOLMOD_OPENMP) && __has_include(<omp.h>)
#include <omp.h>
#define MODALCAL_TEST_OPENMP 1
#endif

#include "eigen/block_lanczos.hpp"
#include "eigen/cholmod_factor.hpp"
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

Solved SolveModel(const Model& model, int modes, int max_rigid, double tolerance = 1e-10, int block_size = 0) {
  ParametricSystem system(model, {});
  Solved s;
  system.assemble(Vector(), &s.K, &s.M);
  ModalOptions options;
  options.num_modes = modes;
  options.max_rigid_modes = max_rigid;
  options.tolerance = tolerance;
  options.block_size = block_size;
  ModalSolver solver(system.pattern(), options);
  s.result = solver.solve(s.K, s.M);
  return s;
}

// Fixed-free chain of n equal masses: omega_j = 2 sqrt(k/m) sin((2j - 1) pi / (2 (2n + 1))).
double ChainOmega(int n, double m, double k, int j) {
  return 2 * std::sqrt(k / m) * std::sin((2 * j - 1) * M_PI / (2 * (2 * n + 1)));
}

class ChainTest : public ::testing::TestWithParam<int> {};

// n = 40 takes the dense path, n = 600 the block Lanczos/CHOLMOD path.
TEST_P(ChainTest, GroundedChainMatchesClosedForm) {
  const int n = GetParam();
  const double m = 2.0, k = 3.0e4;
  const Solved s = SolveModel(MakeChain(n, m, k, true), 8, 0);
  ASSERT_EQ(s.result.status, EigenStatus::Successful) << s.result.message;
  if (n > 300) {
    EXPECT_GT(s.result.block_size, 1) << "fell back to single-vector Lanczos";
  }
  ASSERT_EQ(s.result.eigenvalues.size(), 8);
  EXPECT_EQ(s.result.rigid_eigenvalues.size(), 0);
  for (int j = 1; j <= 8; ++j) {
    EXPECT_CLOSE(std::sqrt(s.result.eigenvalues[j - 1]), ChainOmega(n, m, k, j), 1e-9);
    EXPECT_LT(s.result.residuals[j - 1], 1e-8);
  }
}
INSTANTIATE_TEST_SUITE_P(DenseAndSparse, ChainTest, ::testing::Values(40, 600));

// A free-free chain with unequal masses and stiffnesses, large enough for the Lanczos path.
Model UnevenFreeChain() {
  Model model = MakeChain(400, 1.0, 1.0e5, false);
  for (size_t i = 0; i < model.properties.size(); ++i)
    model.properties[i].value *= 1.0 + 0.5 * std::sin(0.37 * static_cast<double>(i));
  return model;
}

TEST(ModalSolver, SparseMatchesDenseGeneralizedSolve) {
  const Solved s = SolveModel(UnevenFreeChain(), 6, 1);
  ASSERT_EQ(s.result.status, EigenStatus::Successful) << s.result.message;
  EXPECT_GT(s.result.block_size, 1) << "fell back to single-vector Lanczos";
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

TEST(ModalSolver, BlockPathAgreesWithSpectra) {
  const Solved block = SolveModel(UnevenFreeChain(), 6, 1);
  const Solved spectra = SolveModel(UnevenFreeChain(), 6, 1, 1e-10, 1);
  ASSERT_EQ(block.result.status, EigenStatus::Successful) << block.result.message;
  ASSERT_EQ(spectra.result.status, EigenStatus::Successful) << spectra.result.message;
  EXPECT_GT(block.result.block_size, 1);
  EXPECT_EQ(spectra.result.block_size, 1);
  for (int j = 0; j < 6; ++j) {
    EXPECT_CLOSE(block.result.eigenvalues[j], spectra.result.eigenvalues[j], 1e-9);
    EXPECT_LT(block.result.residuals[j], 1e-8);
  }
  // Same normalization and sign rule, so the modes agree entry by entry.
  EXPECT_LT(testing::RelativeDifference(block.result.modes, spectra.result.modes), 1e-9);
  ASSERT_EQ(block.result.rigid_modes.cols(), 1);
  ASSERT_EQ(spectra.result.rigid_modes.cols(), 1);
  EXPECT_LT(testing::RelativeDifference(block.result.rigid_modes, spectra.result.rigid_modes), 1e-9);
}

TEST(ModalSolver, ToleranceBelowRoundingFallsBackToSpectra) {
  // No true residual of the 600-mass chain gets to 1e-13 |lambda| ||M u||, so the block
  // iteration gives up; Spectra's test on the shift-inverted problem can still pass.
  const Solved s = SolveModel(MakeChain(600, 2.0, 3.0e4, true), 8, 0, 1e-13);
  ASSERT_EQ(s.result.status, EigenStatus::Successful) << s.result.message;
  EXPECT_EQ(s.result.block_size, 1);
  for (int j = 1; j <= 8; ++j) EXPECT_CLOSE(std::sqrt(s.result.eigenvalues[j - 1]), ChainOmega(600, 2.0, 3.0e4, j), 1e-9);
}

// Rayleigh-Ritz: a span that holds the modes gives them as solve() does; a span of vectors near
// them gives eigenvalues from above, off by the square of the vectors' error.
TEST(ModalSolver, ASpanHoldingTheModesGivesThemAndANearbySpanBoundsThemFromAbove) {
  const Model chain = MakeChain(400, 1.0, 100.0, true);
  ParametricSystem system(chain, {});
  SparseMatrix K, M;
  system.assemble(Vector(), &K, &M);
  ModalOptions options;
  options.num_modes = 5;
  options.max_rigid_modes = 0;
  ModalSolver solver(system.pattern(), options);
  const ModalResult exact = solver.solve(K, M);
  ASSERT_EQ(exact.status, EigenStatus::Successful) << exact.message;
  Matrix V(K.rows(), 9);
  V << exact.modes, Matrix::Random(K.rows(), 4);
  const ModalResult held = solver.solve_in_span(K, M, V);
  ASSERT_EQ(held.status, EigenStatus::Successful) << held.message;
  ASSERT_EQ(held.eigenvalues.size(), 9);  // every Ritz pair
  for (int j = 0; j < 5; ++j) EXPECT_CLOSE(held.eigenvalues[j], exact.eigenvalues[j], 1e-10);
  for (int j = 0; j < 5; ++j)  // the same mode, up to the sign a near tie of extremes may flip
    EXPECT_NEAR(std::abs(held.modes.col(j).dot(M * exact.modes.col(j))), 1.0, 1e-8);
  const double error = 1e-3;
  const Matrix near = exact.modes + error * Matrix::Random(K.rows(), 5) / std::sqrt(static_cast<double>(K.rows()));
  const ModalResult bounded = solver.solve_in_span(K, M, near);
  ASSERT_EQ(bounded.status, EigenStatus::Successful) << bounded.message;
  // Off by at most the error's M-norm squared (about error^2 / 3) times the largest eigenvalue,
  // which Gershgorin bounds by 4 k / m for the chain.
  for (int j = 0; j < 5; ++j) {
    EXPECT_GE(bounded.eigenvalues[j], exact.eigenvalues[j] * (1 - 1e-12));
    EXPECT_LT(bounded.eigenvalues[j] - exact.eigenvalues[j], error * error * 4 * 100.0 / 1.0);
  }
  EXPECT_THROW(solver.solve_in_span(K, M, exact.modes.leftCols(4)), std::invalid_argument);
  // The first modes' residuals say how far they are from eigenpairs; the other Ritz pairs' are
  // not computed.
  for (int j = 0; j < 5; ++j) EXPECT_LT(held.residuals[j], 1e-8);
  for (int j = 5; j < 9; ++j) EXPECT_TRUE(std::isnan(held.residuals[j]));
  // With V^T K V and V^T M V given (the projected assembly's), the same pairs.
  const std::vector<Matrix> terms = system.project_terms(V);
  Matrix Kr, Mr;
  system.assemble_projected(Vector(), terms, &Kr, &Mr);
  const ModalResult given = solver.solve_in_span(Kr, Mr, V, K, M);
  ASSERT_EQ(given.status, EigenStatus::Successful) << given.message;
  for (int j = 0; j < 9; ++j) EXPECT_CLOSE(given.eigenvalues[j], held.eigenvalues[j], 1e-10);
  // Without residuals: the same pairs, every residual NaN.
  const ModalResult bare = solver.solve_in_span(Kr, Mr, V, K, M, /*residuals=*/false);
  ASSERT_EQ(bare.status, EigenStatus::Successful) << bare.message;
  for (int j = 0; j < 9; ++j) {
    EXPECT_CLOSE(bare.eigenvalues[j], given.eigenvalues[j], 1e-14);
    EXPECT_TRUE(std::isnan(bare.residuals[j]));
  }
  EXPECT_TRUE(bare.modes.isApprox(given.modes, 1e-12));
  EXPECT_THROW(solver.solve_in_span(Matrix(Kr.topRows(8)), Mr, V, K, M), std::invalid_argument);
}

TEST(ModalSolver, BlockPathIsDeterministic) {
  const Solved first = SolveModel(UnevenFreeChain(), 6, 1);
  const Solved second = SolveModel(UnevenFreeChain(), 6, 1);
  ASSERT_EQ(first.result.status, EigenStatus::Successful) << first.result.message;
  EXPECT_EQ(first.result.eigenvalues, second.result.eigenvalues);
  EXPECT_EQ(first.result.modes, second.result.modes);
  EXPECT_EQ(first.result.operator_solves, second.result.operator_solves);
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
  // A model refuses a negative stiffness (property_range_violation), so the indefinite K is made
  // here: K - sigma M with sigma between the first two eigenvalues has one negative eigenvalue.
  for (int n : {30, 500}) {  // dense and sparse paths
    const Model model = MakeChain(n, 1.0, 100.0, true);
    ParametricSystem system(model, {});
    SparseMatrix K, M;
    system.assemble(Vector(), &K, &M);
    const double sigma = 0.5 * (std::pow(ChainOmega(n, 1.0, 100.0, 1), 2) + std::pow(ChainOmega(n, 1.0, 100.0, 2), 2));
    const SparseMatrix shifted = K - sigma * M;
    ModalOptions options;
    options.num_modes = 3;
    options.max_rigid_modes = 0;
    ModalSolver solver(system.pattern(), options);
    const ModalResult result = solver.solve(shifted, M);
    EXPECT_NE(result.status, EigenStatus::Successful) << "n = " << n;
    EXPECT_NE(result.message.find("indefinite"), std::string::npos) << result.message;
  }
}

TEST(ModalSolver, APenaltyStiffJointIsNotTakenForASingularK) {
  // One joint 1e8 and 1e9 times stiffer than the rest, a common way to model a rigid connection:
  // the trace of K is then the joint's, and a threshold from tr(K)/tr(M) took the lowest elastic
  // modes for rigid-body ones ("K is singular"). The two stiffnesses give one limit, to the
  // penalty's first-order error lambda / k.
  for (int n : {30, 500}) {  // dense and sparse paths
    std::vector<Vector> lowest;
    for (const double penalty : {1e10, 1e11}) {
      Model model = MakeChain(n, 1.0, 100.0, true);
      model.properties[model.find_property("joint3.kx")].value = penalty;
      const Solved s = SolveModel(model, 3, 0);
      ASSERT_EQ(s.result.status, EigenStatus::Successful) << "n = " << n << ", penalty " << penalty << ": "
                                                          << s.result.message;
      lowest.push_back(s.result.eigenvalues.head(3));
    }
    EXPECT_LT((lowest[0].array() / lowest[1].array() - 1).abs().maxCoeff(), 1e-6) << "n = " << n;
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
  options.block_size = -1;
  EXPECT_FALSE(options.IsValid(&error));
  EXPECT_NE(error.find("block_size"), std::string::npos);
  options = ModalOptions();
  options.initial_shift = 1.0;
  EXPECT_FALSE(options.IsValid(&error));
  EXPECT_NE(error.find("initial_shift"), std::string::npos);
  EXPECT_THROW(ModalSolver(SparseMatrix(3, 3), options), std::invalid_argument);
}

// The block iteration on its own, for what the public interface does not show: restarts,
// deflation and the purity of the modes when M is singular.
struct Pencil {
  SparseMatrix K, M;
};

// Lowest `nev` eigenpairs of (K, M) by block Lanczos with the shift the solver would pick.
detail::BlockLanczosResult BlockSolve(const Pencil& p, detail::BlockLanczosOptions options) {
  detail::CholmodFactor factor(p.K);
  const double trace_ratio = p.K.diagonal().sum() / p.M.diagonal().sum();
  const double sigma = -1e-6 * trace_ratio;
  options.rigid_threshold = 1e-9 * trace_ratio;
  int column = -1;
  EXPECT_TRUE(factor.factorize(p.K, p.M, sigma, &column));
  return detail::block_lanczos(factor, p.K, p.M, sigma, options);
}

// max_i ||K u_i - lambda_i M u_i|| / (|lambda_i| ||M u_i||).
double WorstResidual(const Pencil& p, const detail::BlockLanczosResult& r) {
  double worst = 0;
  for (int i = 0; i < r.eigenvalues.size(); ++i) {
    const Vector Mu = p.M * r.vectors.col(i);
    worst = std::max(worst, (p.K * r.vectors.col(i) - r.eigenvalues[i] * Mu).norm() /
                                (std::abs(r.eigenvalues[i]) * Mu.norm()));
  }
  return worst;
}

// K and M on one tridiagonal pattern (M may hold explicit zeros), as the factorization needs.
Pencil Tridiagonal(const Vector& k_diag, const Vector& k_off, const Vector& m_diag) {
  const int n = static_cast<int>(k_diag.size());
  std::vector<Eigen::Triplet<double>> k, m;
  for (int i = 0; i < n; ++i) {
    k.emplace_back(i, i, k_diag[i]);
    m.emplace_back(i, i, m_diag[i]);
    if (i + 1 < n) {
      for (auto [r, c] : {std::pair{i, i + 1}, std::pair{i + 1, i}}) {
        k.emplace_back(r, c, k_off[i]);
        m.emplace_back(r, c, 0.0);
      }
    }
  }
  Pencil p{SparseMatrix(n, n), SparseMatrix(n, n)};
  p.K.setFromTriplets(k.begin(), k.end());
  p.M.setFromTriplets(m.begin(), m.end());
  return p;
}

// Fixed-free chain of n unit masses and unit springs.
Pencil UnitChain(int n) {
  Vector k_diag = Vector::Constant(n, 2.0);
  k_diag[n - 1] = 1.0;
  return Tridiagonal(k_diag, Vector::Constant(n - 1, -1.0), Vector::Ones(n));
}

#ifdef MODALCAL_TEST_OPENMP
// The factorization keeps CHOLMOD's OpenMP regions in the calling thread, and gives the thread
// back its own setting: a caller's OpenMP code runs as it would have.
TEST(CholmodFactor, LeavesTheCallersOpenMpSettingAsItFoundIt) {
  const Pencil p = UnitChain(50);
  const int before = omp_get_max_active_levels();
  omp_set_max_active_levels(3);
  detail::CholmodFactor factor(p.K);
  int column = -1;
  EXPECT_TRUE(factor.factorize(p.K, p.M, 0.0, &column));
  EXPECT_EQ(omp_get_max_active_levels(), 3);
  omp_set_max_active_levels(before);
  // x = K^{-1} b solves K x = b to rounding: the factor is the chain's.
  const Vector b = Vector::Ones(50);
  Vector x(50);
  factor.solve(b.data(), x.data());
  EXPECT_LT((p.K * x - b).norm(), 1e-10 * b.norm() * 50 * 50);
}
#endif

TEST(BlockLanczos, ThickRestartsKeepConverging) {
  const int n = 600;
  detail::BlockLanczosOptions options;
  options.nev = 8;
  options.block_size = 4;
  options.max_basis = 16;  // room for two blocks beyond the kept Ritz vectors
  const Pencil p = UnitChain(n);
  const detail::BlockLanczosResult r = BlockSolve(p, options);
  ASSERT_TRUE(r.converged);
  EXPECT_GT(r.restarts, 0);
  for (int j = 1; j <= 8; ++j) EXPECT_CLOSE(std::sqrt(r.eigenvalues[j - 1]), ChainOmega(n, 1.0, 1.0, j), 1e-9);
  EXPECT_LT(WorstResidual(p, r), 1e-8);
}

TEST(BlockLanczos, RefillsDeflatedColumns) {
  // Eigenvalues 1 and 2 three times each, 3 for the rest: the Krylov space of a 4-column block
  // has at most 3 + 3 + 4 = 10 dimensions, so the third block deflates half-way and must be
  // refilled with fresh vectors. (No Krylov method sees more copies of an eigenvalue than its
  // block has columns, so the multiplicities stay below 4.)
  const int n = 400;
  Vector k_diag = Vector::Constant(n, 3.0);
  k_diag.head(6) << 1, 1, 1, 2, 2, 2;
  const Pencil p = Tridiagonal(k_diag, Vector::Zero(n - 1), Vector::Ones(n));
  detail::BlockLanczosOptions options;
  options.nev = 8;
  options.block_size = 4;
  const detail::BlockLanczosResult r = BlockSolve(p, options);
  ASSERT_TRUE(r.converged);
  EXPECT_GT(r.deflated, 0);
  Vector expected(8);
  expected << 1, 1, 1, 2, 2, 2, 3, 3;
  for (int j = 0; j < 8; ++j) EXPECT_NEAR(r.eigenvalues[j], expected[j], 1e-12);
  const Matrix gram = r.vectors.transpose() * p.M * r.vectors;
  EXPECT_LT((gram - Matrix::Identity(8, 8)).cwiseAbs().maxCoeff(), 1e-10);
  EXPECT_LT(WorstResidual(p, r), 1e-8);
}

TEST(BlockLanczos, SingularMassGivesPureModes) {
  // A unit chain whose odd DOFs are massless: its eigenvalues are those of the chain condensed
  // to the massive DOFs, and an impure vector (with a component M does not see) would show up
  // in the residual rows of the massless DOFs.
  const int n = 400;
  Pencil p = UnitChain(n);
  Vector m_diag(n);
  for (int i = 0; i < n; ++i) m_diag[i] = i % 2 == 0 ? 1.0 : 0.0;
  p = Tridiagonal(p.K.diagonal(), -Vector::Ones(n - 1), m_diag);
  std::vector<int> massive, massless;
  for (int i = 0; i < n; ++i) (i % 2 == 0 ? massive : massless).push_back(i);
  const Matrix K = Matrix(p.K);
  const Matrix condensed = K(massive, massive) - K(massive, massless) *
                                                     K(massless, massless).llt().solve(K(massless, massive));
  Eigen::SelfAdjointEigenSolver<Matrix> dense(condensed);
  detail::BlockLanczosOptions options;
  options.nev = 6;
  options.block_size = 3;
  const detail::BlockLanczosResult r = BlockSolve(p, options);
  ASSERT_TRUE(r.converged);
  for (int j = 0; j < 6; ++j) EXPECT_CLOSE(r.eigenvalues[j], dense.eigenvalues()[j], 1e-9);
  EXPECT_LT(WorstResidual(p, r), 1e-8);
}

TEST(Frequency, RoundTripsAndKeepsSign) {
  EXPECT_CLOSE(frequency_hz(eigenvalue_of_hz(1195.0)), 1195.0, 1e-14);
  EXPECT_LT(frequency_hz(-100.0), 0.0);
}

}  // namespace
}  // namespace modalcal
