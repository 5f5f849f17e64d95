// The KKT solvers of the full space, matrix by matrix: the block SQP's step against the whole
// KKT system, and the structured solver Ipopt calls through libpardiso.so against dense linear
// algebra - inertia (what Ipopt's inertia correction reads), the solution, a singular mode block,
// and the fallback to MUMPS on the whole matrix for every matrix that is not the registered layout;
// both again with every mode's bordered block solved through one shared factorization, and that
// solver's fallback to a factorization where its deflation basis lacks a mode.

#include <Eigen/Eigenvalues>
#include <Eigen/LU>

#include <memory>

#include "fullspace/block_elimination.hpp"
#include "fullspace/block_kkt.hpp"
#include "fullspace/fullspace_problem.hpp"
#include "fullspace/shared_shift_solve.hpp"
#include "fullspace/structured_kkt.hpp"
#include "modalcal/fullspace.hpp"
#include "modalcal/problem_file.hpp"
#include "support/random_draws.hpp"
#include "test_util.hpp"

extern "C" {  // libpardiso.so's entry points, called as Ipopt calls them
void pardisoinit(void* handle, const int* mtype, const int* solver, int* iparm, double* dparm, int* error);
void pardiso(void** handle, const int* maxfct, const int* mnum, const int* mtype, const int* phase, const int* n,
             const double* a, const int* ia, const int* ja, int* perm, const int* nrhs, int* iparm, const int* msglvl,
             double* b, double* x, int* error, double* dparm);
}

namespace modalcal {

using testing::LoadProblem;
namespace {

// The model with every parameter kind; `coarse`: on a coarser mesh with three measured modes, a
// KKT matrix of order ~1,500 that dense linear algebra checks in a second.
std::string EveryKindModel(bool coarse) {
  std::string text = testing::kEveryParameterKindModel;
  if (coarse) {
    text.replace(text.find("element_size: 0.5"), 17, "element_size: 0.625");
    text.replace(text.find("modes: [1, 2, 3, 4, 5, 6]"), 25, "modes: [1, 2, 3]");
    text.replace(text.find("at: [2.5, 1, 1.25]"), 18, "at: [3, 1, 1.25]");  // a node of the coarser mesh
  }
  return text;
}

// A full-space point away from feasibility: every parameter kind, modes and eigenvalues of the
// forward solution at 1.3 p0 perturbed by 1e-3, random multipliers.
struct PerturbedPoint {
  explicit PerturbedPoint(bool coarse) : PerturbedPoint(LoadProblem(testing::WriteTempFile("model.yaml", EveryKindModel(coarse)))) {}
  Problem problem;
  Objective objective{problem, Regularized()};
  Vector p = problem.initial_values() * 1.3;
  ParameterScaling scaling{problem.parameters};
  detail::FullSpaceProblem fp{objective, scaling, p};
  Vector x, y;
  std::vector<int> model_mode;
  Matrix forward_modes;  // every mode of the forward solve at p: the shared solves' deflation basis

  static ObjectiveOptions Regularized() {
    ObjectiveOptions options;
    options.regularization = 1e-2;  // so that the parameter block of the objective gradient is not zero
    return options;
  }
  explicit PerturbedPoint(Problem loaded) : problem(std::move(loaded)) {
    const Evaluation e = objective.evaluate(p, Need::Value);
    if (!e.ok) throw std::runtime_error(e.message);
    const int l = fp.num_modes(), n = fp.num_dofs();
    Matrix U(n, l);
    Vector lambda(l);
    for (int i = 0; i < l; ++i) {
      model_mode.push_back(e.pairs[fp.measured_of(i)].model);
      U.col(i) = e.modal.modes.col(model_mode[i]);
      lambda[i] = e.modal.eigenvalues[model_mode[i]];
    }
    forward_modes = e.modal.modes;
    detail::Uniform random_draws(7);
    x = fp.pack(U, lambda, p);
    y.resize(fp.num_constraints());
    for (int k = 0; k < fp.num_variables() - fp.num_parameters(); ++k) x[k] *= 1 + 1e-3 * random_draws(-1, 1);
    for (int k = 0; k < y.size(); ++k) y[k] = random_draws(-1, 1);
  }

  // Ipopt's KKT matrix [[W + delta_w I + diag(0, sigma_q), J^T], [J, -delta_c I]] (both
  // triangles; every diagonal entry stored, as Ipopt stores them). `without_first_border`: the
  // Jacobian without mode 1's eigenvalue column and normalization row, which makes the bordered
  // block of mode 1, and the whole matrix, exactly singular.
  SparseMatrix Kkt(double delta_w, const Vector& sigma_q, double delta_c = 0, bool without_first_border = false) {
    const int nv = fp.num_variables(), nc = fp.num_constraints();
    std::vector<int> rows(fp.jacobian_layout().nonzeros()), cols(rows.size());
    fp.jacobian_layout().structure(rows.data(), cols.data());
    Vector jv(rows.size());
    fp.jacobian_values(x.data(), jv.data());
    std::vector<int> hrows(fp.hessian_layout().nonzeros()), hcols(hrows.size());
    fp.hessian_layout().structure(hrows.data(), hcols.data());
    Vector hv(hrows.size());
    fp.hessian_values(x.data(), 1.0, y.data(), hv.data());
    std::vector<Eigen::Triplet<double, int>> entries;
    const int border = fp.mode_entry(0, fp.num_dofs());
    for (size_t k = 0; k < rows.size(); ++k) {
      if (without_first_border && (rows[k] == border || cols[k] == border)) continue;
      entries.emplace_back(nv + rows[k], cols[k], jv[k]);
      entries.emplace_back(cols[k], nv + rows[k], jv[k]);
    }
    for (size_t k = 0; k < hrows.size(); ++k) {
      entries.emplace_back(hrows[k], hcols[k], hv[k]);
      if (hrows[k] != hcols[k]) entries.emplace_back(hcols[k], hrows[k], hv[k]);
    }
    for (int k = 0; k < nv; ++k) entries.emplace_back(k, k, delta_w + (k >= fp.parameter_offset() ? sigma_q[k - fp.parameter_offset()] : 0.0));
    for (int k = 0; k < nc; ++k) entries.emplace_back(nv + k, nv + k, -delta_c);
    SparseMatrix K(nv + nc, nv + nc);
    K.setFromTriplets(entries.begin(), entries.end());
    return K;
  }
};

struct TrampolineResult {
  int error = 0;
  int negatives = 0;
  Vector solution;
};

// One factorization and solve through libpardiso.so, phase by phase as Ipopt makes them.
TrampolineResult SolveThroughTheTrampoline(const SparseMatrix& kkt, const Vector& rhs) {
  std::vector<Eigen::Triplet<double, int>> upper;
  for (int c = 0; c < kkt.outerSize(); ++c)
    for (SparseMatrix::InnerIterator it(kkt, c); it; ++it)
      if (it.row() <= c) upper.emplace_back(it.row(), c, it.value());
  Eigen::SparseMatrix<double, Eigen::RowMajor, int> csr(kkt.rows(), kkt.cols());
  csr.setFromTriplets(upper.begin(), upper.end());
  csr.makeCompressed();
  std::vector<int> ia(csr.outerIndexPtr(), csr.outerIndexPtr() + csr.rows() + 1),
      ja(csr.innerIndexPtr(), csr.innerIndexPtr() + csr.nonZeros());
  for (int& v : ia) ++v;
  for (int& v : ja) ++v;
  void* handle[64];
  int iparm[64] = {}, error = 0, perm = 0;
  double dparm[64] = {}, unused = 0;
  const int mtype = -2, solver = 0, one = 1, n = static_cast<int>(kkt.rows()), quiet = 0;
  pardisoinit(handle, &mtype, &solver, iparm, dparm, &error);
  TrampolineResult result;
  result.solution = rhs;
  auto call = [&](int phase, int nrhs) {
    pardiso(handle, &one, &one, &mtype, &phase, &n, csr.valuePtr(), ia.data(), ja.data(), &perm, &nrhs, iparm, &quiet,
            result.solution.data(), &unused, &error, dparm);
    return error;
  };
  result.error = call(11, 0);
  if (result.error == 0) result.error = call(22, 0);
  result.negatives = iparm[22];
  if (result.error == 0) call(33, 1);
  call(-1, 0);
  return result;
}

int DenseNegatives(const SparseMatrix& kkt) {
  const Eigen::SelfAdjointEigenSolver<Matrix> eigen{Matrix(kkt)};
  return static_cast<int>((eigen.eigenvalues().array() < 0).count());
}

// Normwise backward error |K x - b| / (|K| |x| + |b|) (infinity norms): a backward-stable
// solver gives a small multiple of the rounding unit whatever the conditioning (the KKT matrices
// here reach 1e9), so 1e-12 holds with a wide margin.
double BackwardError(const SparseMatrix& kkt, const Vector& solution, const Vector& rhs) {
  Vector row_sums = Vector::Zero(kkt.rows());
  for (int c = 0; c < kkt.outerSize(); ++c)
    for (SparseMatrix::InnerIterator it(kkt, c); it; ++it) row_sums[it.row()] += std::abs(it.value());
  return (kkt * solution - rhs).cwiseAbs().maxCoeff() /
         (row_sums.maxCoeff() * solution.cwiseAbs().maxCoeff() + rhs.cwiseAbs().maxCoeff());
}

// The block solver's Newton step (dq from its reduced system) in the whole KKT system
// [W A^T; A 0] (dx, dy) = -(grad L, c) at the point.
double StepBackwardError(PerturbedPoint& point, const detail::BlockKktSystem& kkt) {
  const Vector dq = kkt.reduced_hessian().fullPivLu().solve(kkt.reduced_rhs());
  Vector dx, dy;
  kkt.step(dq, &dx, &dy);
  const SparseMatrix K = point.Kkt(0, Vector::Zero(point.fp.num_parameters()));
  Vector rhs(K.rows()), step(K.rows());
  rhs << -kkt.lagrangian_gradient(), -kkt.constraints();
  step << dx, dy;
  return BackwardError(K, step, rhs);
}

TEST(BlockKkt, StepSolvesTheWholeKktSystemAndCountsEachModesIndex) {
  // For every parameter kind, the step assembled from the per-mode eliminations and the Schur
  // complement must satisfy the whole KKT system [W A^T; A 0] (dx, dy) = -(grad L, c).
  PerturbedPoint point(/*coarse=*/false);
  detail::FullSpaceProblem& fp = point.fp;
  detail::BlockKktSystem kkt(fp);
  std::string error;
  ASSERT_TRUE(kkt.build(point.x, point.y, &error)) << error;
  ASSERT_GT(kkt.constraints().cwiseAbs().maxCoeff(), 1e-6);  // the point is really infeasible
  EXPECT_LT(StepBackwardError(point, kkt), 1e-12);
  // Sylvester: B_i has one negative pivot per eigenvalue below lambda_i, plus one of the border.
  for (int i = 0; i < fp.num_modes(); ++i) EXPECT_EQ(kkt.mode_index(i), point.model_mode[i] + 1) << "mode " << i + 1;
}

TEST(BlockKkt, OneSharedFactorizationGivesTheStepAndIndexOfOneFactorizationPerMode) {
  // The point is off every eigenpair (modes and eigenvalues perturbed by 1e-3): the projected
  // bordered solve must hold for any (u_i, t_i), with the forward solve at p only as its basis.
  PerturbedPoint point(/*coarse=*/false);
  detail::FullSpaceProblem& fp = point.fp;
  fp.set_deflation_basis(point.forward_modes);
  detail::BlockKktSystem shared(fp, /*shared_factorization=*/true), per_mode(fp);
  std::string error;
  ASSERT_TRUE(shared.build(point.x, point.y, &error)) << error;
  ASSERT_TRUE(per_mode.build(point.x, point.y, &error)) << error;
  EXPECT_EQ(shared.shared_eliminations(), fp.num_modes());
  EXPECT_EQ(shared.shared_failures(), 0);
  // CG stops at a backward error of 1e-15 per bordered solve; the whole step keeps 1e-11 with a margin.
  EXPECT_LT(StepBackwardError(point, shared), 1e-11);
  const double scale = per_mode.reduced_hessian().cwiseAbs().maxCoeff();
  EXPECT_LT((shared.reduced_hessian() - per_mode.reduced_hessian()).cwiseAbs().maxCoeff(), 1e-9 * scale);
  for (int i = 0; i < fp.num_modes(); ++i) EXPECT_EQ(shared.mode_index(i), per_mode.mode_index(i)) << "mode " << i + 1;
}

TEST(BlockKkt, ABasisWithoutTheLowerModesFallsBackToFactoringTheirBlocks) {
  // Deflated by the highest forward mode alone, the blocks of the modes above the lowest are
  // indefinite beyond the basis: CG meets a negative curvature (or does not converge), and the
  // elimination factors those blocks instead - the step stays right.
  PerturbedPoint point(/*coarse=*/false);
  detail::FullSpaceProblem& fp = point.fp;
  fp.set_deflation_basis(point.forward_modes.rightCols(1));
  detail::BlockKktSystem kkt(fp, /*shared_factorization=*/true);
  std::string error;
  ASSERT_TRUE(kkt.build(point.x, point.y, &error)) << error;
  EXPECT_GT(kkt.shared_failures(), 0);
  EXPECT_EQ(kkt.shared_eliminations() + kkt.shared_failures(), fp.num_modes());
  EXPECT_LT(StepBackwardError(point, kkt), 1e-11);
}

// Mode i's blocks at the point, with made-up W_i (1e-3 A_i), C_i and P_i: what BlockElimination needs.
detail::ModeKktBlocks MadeUpBlocks(detail::FullSpaceProblem& fp, const Vector& x, int i) {
  const SparseMatrix& K = fp.stiffness_matrix(x.data());
  const SparseMatrix& M = fp.mass_matrix(x.data());
  const int n = fp.num_dofs(), m = fp.num_parameters();
  const Vector Mu = M * fp.mode_vector(x.data(), i);
  std::vector<Eigen::Triplet<double, int>> lower, hessian;
  const SparseMatrix A = K / fp.reference_eigenvalue(i) - fp.eigenvalue_ratio(x.data(), i) * M;
  for (int c = 0; c < A.outerSize(); ++c)
    for (SparseMatrix::InnerIterator it(A, c); it; ++it) {
      if (it.row() >= c) lower.emplace_back(it.row(), c, it.value());
      hessian.emplace_back(it.row(), c, 1e-3 * it.value());
    }
  for (int c = 0; c < n; ++c) lower.emplace_back(n, c, -Mu[c]);
  detail::ModeKktBlocks blocks;
  blocks.bordered.resize(n + 1, n + 1);
  blocks.bordered.setFromTriplets(lower.begin(), lower.end());
  blocks.hessian.resize(n + 1, n + 1);
  blocks.hessian.setFromTriplets(hessian.begin(), hessian.end());
  blocks.row_scale = Vector::Ones(n + 1);
  blocks.hessian_parameters = Matrix::Constant(n + 1, m, 1e-2);
  blocks.jacobian_parameters = Matrix::Zero(n + 1, m);
  for (int j = 0; j < m; ++j) blocks.jacobian_parameters.col(j) = Vector::LinSpaced(n + 1, -1.0 - j, 1.0 + j);
  return blocks;
}

TEST(BlockElimination, SharedSolvesThatFallShortInALaterSolveAreReplacedByAFactorization) {
  // Ipopt solves several right-hand sides per factorization. When the shared solves of one fall
  // short, the mode's B_i is given again and factored, and the answer is the per-mode one.
  PerturbedPoint point(/*coarse=*/true);
  detail::FullSpaceProblem& fp = point.fp;
  fp.set_deflation_basis(point.forward_modes);
  detail::SharedShiftSolver shared;
  std::string error;
  ASSERT_TRUE(detail::update_shared_shift_solver(fp, point.x.data(), &shared, &error)) << error;
  const int l = fp.num_modes(), m = fp.num_parameters(), n1 = fp.num_dofs() + 1;
  detail::BlockElimination with_shared(l, m, /*keep_factors=*/true), per_mode(l, m, /*keep_factors=*/true);
  const Matrix Wqq = Matrix::Identity(m, m);
  with_shared.begin(Wqq, nullptr, &shared);
  per_mode.begin(Wqq, nullptr);
  for (int i = 0; i < l; ++i) {
    ASSERT_TRUE(with_shared.add_mode(i, MadeUpBlocks(fp, point.x, i), nullptr, nullptr, &error)) << error;
    ASSERT_TRUE(per_mode.add_mode(i, MadeUpBlocks(fp, point.x, i), nullptr, nullptr, &error)) << error;
  }
  ASSERT_EQ(with_shared.shared_eliminations(), l);
  detail::SharedShiftOptions starved;
  starved.max_iterations = 0;  // every later solve falls short
  shared.set_options(starved);
  std::vector<Matrix> f(l, Matrix::Ones(n1, 2)), e(l, Matrix::Constant(n1, 2, 0.5)), f2 = f, e2 = e;
  Matrix fq = Matrix::Ones(m, 2), fq2 = fq;
  const Matrix H = per_mode.reduced_hessian();
  auto solve_reduced = [&](Matrix* h) { *h = H.fullPivLu().solve(*h); };
  int asked = 0;
  with_shared.solve(&f, &e, &fq, solve_reduced, {}, [&](int i) {
    ++asked;
    return MadeUpBlocks(fp, point.x, i).bordered;
  });
  per_mode.solve(&f2, &e2, &fq2, solve_reduced);
  EXPECT_EQ(asked, l);
  EXPECT_EQ(with_shared.shared_failures(), l);
  EXPECT_LT((fq - fq2).cwiseAbs().maxCoeff(), 1e-8 * fq2.cwiseAbs().maxCoeff());
  for (int i = 0; i < l; ++i) {
    EXPECT_LT((f[i] - f2[i]).cwiseAbs().maxCoeff(), 1e-8 * f2[i].cwiseAbs().maxCoeff()) << "mode " << i + 1;
    EXPECT_LT((e[i] - e2[i]).cwiseAbs().maxCoeff(), 1e-8 * e2[i].cwiseAbs().maxCoeff()) << "mode " << i + 1;
  }
}

TEST(StructuredKkt, InertiaAndSolutionMatchDenseLinearAlgebra) {
  // Ipopt's inertia correction reads the number of negative eigenvalues: it must be exact, both
  // where it is right (n_c) and where the correction has to act (more than n_c).
  PerturbedPoint point(/*coarse=*/true);
  detail::FullSpaceProblem& fp = point.fp;
  detail::KktFactorizationCounts counts;
  const detail::StructuredKktScope scope(fp, &counts);
  detail::Uniform random_draws(11);
  Vector rhs(fp.num_variables() + fp.num_constraints());
  for (int k = 0; k < rhs.size(); ++k) rhs[k] = random_draws(-1, 1);
  const int np = fp.num_parameters();
  bool saw_right = false, saw_wrong = false;
  int calls = 0;
  const std::vector<std::pair<double, double>> shifts = {{0.0, 0.0}, {1e2, 0.0}, {1e-2, 1.0}, {0.0, -1e3}};
  for (const auto& [delta_w, sigma] : shifts) {
      const SparseMatrix K = point.Kkt(delta_w, Vector::Constant(np, sigma));
      const TrampolineResult r = SolveThroughTheTrampoline(K, rhs);
      ++calls;
      ASSERT_EQ(r.error, 0) << "delta_w " << delta_w << ", sigma " << sigma;
      const int dense = DenseNegatives(K);
      EXPECT_EQ(r.negatives, dense) << "delta_w " << delta_w << ", sigma " << sigma;
      saw_right = saw_right || dense == fp.num_constraints();
      saw_wrong = saw_wrong || dense > fp.num_constraints();
      EXPECT_LT(BackwardError(K, r.solution, rhs), 1e-12) << "delta_w " << delta_w << ", sigma " << sigma;
    }
  EXPECT_TRUE(saw_right && saw_wrong);
  EXPECT_EQ(counts.structured, calls);
  EXPECT_EQ(counts.mumps, 0);
}

TEST(StructuredKkt, WithOneSharedFactorizationInertiaAndSolutionMatchDenseLinearAlgebra) {
  // As above, with the modes' bordered blocks solved by deflated CG on one factorization at the
  // point of the problem's last Jacobian (which Kkt() evaluates, as Ipopt does before factoring).
  PerturbedPoint point(/*coarse=*/true);
  detail::FullSpaceProblem& fp = point.fp;
  fp.set_deflation_basis(point.forward_modes);
  detail::KktFactorizationCounts counts;
  const detail::StructuredKktScope scope(fp, &counts, /*shared_factorization=*/true);
  detail::Uniform random_draws(13);
  Vector rhs(fp.num_variables() + fp.num_constraints());
  for (int k = 0; k < rhs.size(); ++k) rhs[k] = random_draws(-1, 1);
  const int np = fp.num_parameters();
  int calls = 0;
  for (const auto& [delta_w, sigma] : std::vector<std::pair<double, double>>{{0.0, 0.0}, {1e-2, 1.0}, {0.0, -1e3}}) {
    const SparseMatrix K = point.Kkt(delta_w, Vector::Constant(np, sigma));
    const TrampolineResult r = SolveThroughTheTrampoline(K, rhs);
    ++calls;
    ASSERT_EQ(r.error, 0) << "delta_w " << delta_w << ", sigma " << sigma;
    EXPECT_EQ(r.negatives, DenseNegatives(K)) << "delta_w " << delta_w << ", sigma " << sigma;
    EXPECT_LT(BackwardError(K, r.solution, rhs), 1e-11) << "delta_w " << delta_w << ", sigma " << sigma;
  }
  EXPECT_EQ(counts.structured, calls);
  EXPECT_EQ(counts.shared_modes, calls * fp.num_modes());
  EXPECT_EQ(counts.shared_failures, 0);
}

TEST(StructuredKkt, ASingularModeBlockIsReportedAsSingular) {
  // Without the border of mode 1's block (its eigenvalue column and normalization row) the KKT
  // matrix is singular, and Ipopt must hear PARDISO's "singular" (-4) to regularize the Jacobian.
  PerturbedPoint point(/*coarse=*/true);
  detail::FullSpaceProblem& fp = point.fp;
  detail::KktFactorizationCounts counts;
  const detail::StructuredKktScope scope(fp, &counts);
  const SparseMatrix K = point.Kkt(1e-2, Vector::Zero(fp.num_parameters()), 0, /*without_first_border=*/true);
  const Eigen::SelfAdjointEigenSolver<Matrix> dense{Matrix(K)};
  ASSERT_LT(dense.eigenvalues().cwiseAbs().minCoeff(), 1e-12 * dense.eigenvalues().cwiseAbs().maxCoeff());
  EXPECT_EQ(SolveThroughTheTrampoline(K, Vector::Ones(K.rows())).error, -4);
}

TEST(StructuredKkt, OtherLayoutsFallBackToMumpsOnTheWholeMatrix) {
  // Ipopt's restoration phase adds unknowns; a singular matrix makes Ipopt regularize the
  // Jacobian (-delta_c I); without a registered problem nothing is known. All go to MUMPS.
  PerturbedPoint point(/*coarse=*/true);
  detail::FullSpaceProblem& fp = point.fp;
  const int np = fp.num_parameters();
  Vector rhs = Vector::LinSpaced(fp.num_variables() + fp.num_constraints() + 1, -1, 1);
  SparseMatrix K = point.Kkt(1e-2, Vector::Ones(np));
  // One more unknown, coupled to the first constraint row, as a restoration slack is.
  SparseMatrix wider(K.rows() + 1, K.cols() + 1);
  std::vector<Eigen::Triplet<double, int>> entries;
  for (int c = 0; c < K.outerSize(); ++c)
    for (SparseMatrix::InnerIterator it(K, c); it; ++it) entries.emplace_back(it.row(), c, it.value());
  const int slack = static_cast<int>(K.rows()), row = fp.num_variables();
  entries.insert(entries.end(), {{slack, slack, 1.0}, {slack, row, 1.0}, {row, slack, 1.0}});
  wider.setFromTriplets(entries.begin(), entries.end());
  const SparseMatrix regularized = point.Kkt(1e-2, Vector::Ones(np), 1e-8);
  const Vector rhs_k = rhs.head(K.rows());

  detail::KktFactorizationCounts counts;
  {
    const detail::StructuredKktScope scope(fp, &counts);
    for (const SparseMatrix* matrix : std::vector<const SparseMatrix*>{&wider, &regularized}) {
      const Vector& b = matrix->rows() == rhs.size() ? rhs : rhs_k;
      const TrampolineResult r = SolveThroughTheTrampoline(*matrix, b);
      ASSERT_EQ(r.error, 0);
      EXPECT_EQ(r.negatives, DenseNegatives(*matrix));
      EXPECT_LT(BackwardError(*matrix, r.solution, b), 1e-12);
    }
  }
  EXPECT_EQ(counts.mumps, 2);
  EXPECT_EQ(counts.structured, 0);
  const TrampolineResult unregistered = SolveThroughTheTrampoline(K, rhs_k);
  ASSERT_EQ(unregistered.error, 0);
  EXPECT_LT(BackwardError(K, unregistered.solution, rhs_k), 1e-12);
}

}  // namespace
}  // namespace modalcal
