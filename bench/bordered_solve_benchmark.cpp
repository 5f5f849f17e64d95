// The linear algebra of one full-space Newton iteration, two ways (issue #16, item 4):
//
// - per mode: MUMPS factors each mode's bordered eigen-block
//     B_i = [[K - lambda_i M, -M u_i], [-(M u_i)^T, 0]]
//   and solves with it, as the structured KKT solver and the block SQP do (one factorization per
//   mode, each kept for Ipopt's later solves);
// - shared: CHOLMOD factors K - sigma M once (sigma below the spectrum, so it is definite), and
//   each mode's bordered system is reduced to a deflated solve with K - lambda_i M, the machinery
//   of the reduced space's adjoint solves (objective/deflated_solve.hpp): the k computed modes
//   are treated exactly, and on the rest K - lambda_i M is definite and (K - sigma M)^{-1}
//   preconditions conjugate gradients with eigenvalues (lambda_j - lambda_i) / (lambda_j - sigma)
//   in [(lambda_{k+1} - lambda_i) / (lambda_{k+1} - sigma), 1). The reduction needs the exact
//   eigenpair; at a Newton iterate, where (lambda_i, u_i) is not one, it would serve as the
//   approximate inverse of a defect correction against the true B_i.
//
// Each case: the LFU problem at its truth on a mesh, l modes to solve with (the measured modes of a
// calibration), k >= l computed modes for the deflation; per mode, a block of right-hand sides as
// the elimination needs at a factorization (2 (m + 1) columns, m parameters) and single solves as
// Ipopt's later back-solves. Printed: the factorization and solve times of both, the iterations,
// the largest normwise backward error of the bordered systems, and the factors' storage (per mode:
// l MUMPS factors kept; shared: one Cholesky factor and the k modes).
//
//   build/bin/bordered_solve_benchmark --refinements 1,2.0003 --modes 10,20

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <string>
#include <vector>

#include "bench_util.hpp"
#include "eigen/block_lanczos.hpp"  // symmetric_times
#include "eigen/cholmod_factor.hpp"
#include "fullspace/mumps_factor.hpp"
#include "modalcal/assembly.hpp"
#include "modalcal/eigen.hpp"
#include "modalcal/problem.hpp"
#include "modalcal/problem_file.hpp"
#include "objective/deflated_solve.hpp"

using namespace modalcal;
using modalcal::bench::Clock;
using modalcal::bench::parse_list;
using modalcal::bench::seconds_since;

namespace {

struct Options {
  std::string problem = std::string(MODALCAL_SOURCE_DIR) + "/problems/lfu/synthetic.yaml";
  std::vector<double> refinements = {1.0, 2.0003};
  std::vector<double> modes = {10, 20};
  double extra_factor = 1.0;  // k = l + ceil(extra_factor * l) computed modes for the deflation
  int block_rhs = 12;         // 2 (m + 1) for the five parameters of the LFU problem
  int single_rhs = 3;         // Ipopt's back-solves after a factorization
  double tolerance = 1e-12;   // relative residual of the deflated solves
  int max_iterations = 500;
};

/// Uniform numbers in (-1, 1) from a fixed linear congruential sequence (the same on any machine).
Matrix pseudo_random(int rows, int cols, std::uint64_t seed) {
  Matrix out(rows, cols);
  std::uint64_t state = seed * 6364136223846793005ULL + 1442695040888963407ULL;
  for (int c = 0; c < cols; ++c)
    for (int r = 0; r < rows; ++r) {
      state = state * 6364136223846793005ULL + 1442695040888963407ULL;
      out(r, c) = static_cast<double>(state >> 11) / 4503599627370496.0 - 1.0;  // 2^52
    }
  return out;
}

/// Lower triangle of B_i; K and M share one pattern, so their value arrays are aligned.
SparseMatrix bordered_lower(const SparseMatrix& K, const SparseMatrix& M, double lambda, const Vector& Mu) {
  const int n = static_cast<int>(K.rows());
  std::vector<Eigen::Triplet<double, int>> entries;
  entries.reserve(K.nonZeros() / 2 + 2 * n);
  for (int c = 0; c < n; ++c)
    for (int k = K.outerIndexPtr()[c]; k < K.outerIndexPtr()[c + 1]; ++k)
      if (K.innerIndexPtr()[k] >= c) entries.emplace_back(K.innerIndexPtr()[k], c, K.valuePtr()[k] - lambda * M.valuePtr()[k]);
  for (int c = 0; c < n; ++c) entries.emplace_back(n, c, -Mu[c]);
  SparseMatrix B(n + 1, n + 1);
  B.setFromTriplets(entries.begin(), entries.end());
  return B;
}

/// The normwise backward error, max over columns of |B z - b|_inf / (|B|_inf |z|_inf + |b|_inf) for
/// z = [x; xi], b = [f; g]: rounding alone gives a few times the machine epsilon, whatever the
/// scaling of K against the border.
double bordered_residual(const SparseMatrix& K, const SparseMatrix& M, double lambda, const Vector& Mu,
                         const Matrix& X, const Matrix& R) {
  const int n = static_cast<int>(K.rows());
  double norm_B = Mu.cwiseAbs().sum();  // the border row
  for (int c = 0; c < n; ++c) {
    double column = std::abs(Mu[c]);
    for (int k = K.outerIndexPtr()[c]; k < K.outerIndexPtr()[c + 1]; ++k)
      column += std::abs(K.valuePtr()[k] - lambda * M.valuePtr()[k]);
    norm_B = std::max(norm_B, column);  // symmetric: the largest column sum is the largest row sum
  }
  const Matrix x = X.topRows(n);
  Matrix top = detail::symmetric_times(K, x) - lambda * detail::symmetric_times(M, x) - Mu * X.row(n) - R.topRows(n);
  const Eigen::RowVectorXd bottom = -Mu.transpose() * x - R.row(n);
  double worst = 0;
  for (int c = 0; c < X.cols(); ++c) {
    const double residual = std::max(top.col(c).cwiseAbs().maxCoeff(), std::abs(bottom[c]));
    worst = std::max(worst, residual / (norm_B * X.col(c).cwiseAbs().maxCoeff() + R.col(c).cwiseAbs().maxCoeff()));
  }
  return worst;
}

/// B_i^{-1} R through the forward solve's machinery (objective/deflated_solve.hpp) for an exact
/// eigenpair (lambda_i, u_i), u_i^T M u_i = 1: the first row times u_i^T gives xi = -u_i^T f
/// (u_i^T A_i = 0), and then A_i x = (I - M u_i u_i^T) f with u_i^T M x = -g, so x is the deflated
/// solve of that right-hand side (M-orthogonal to u_i) less g u_i.
Matrix bordered_solve(const SparseMatrix& K, const SparseMatrix& M, const detail::DeflationBasis& basis, int i,
                      const detail::CholmodFactor& F, const Matrix& R, const Options& options, int* iterations) {
  const int n = static_cast<int>(K.rows());
  const Vector u = basis.modes.col(i);
  const Vector Mu = basis.mass_modes.col(i);
  const Eigen::RowVectorXd xi = -u.transpose() * R.topRows(n);
  const Matrix rhs = R.topRows(n) + Mu * xi;
  const detail::DeflatedSolveResult solved = detail::solve_deflated(
      K, M, basis, std::vector<int>(R.cols(), i), rhs, [&](const Matrix& B) { return F.solve(B); },
      options.tolerance, options.max_iterations);
  if (!solved.converged) throw std::runtime_error("deflated solve: " + solved.message);
  *iterations = std::max(*iterations, solved.iterations);
  Matrix X(n + 1, R.cols());
  X.topRows(n) = solved.solution - u * R.row(n);
  X.row(n) = xi;
  return X;
}

struct PathResult {
  double factor_s = 0, block_s = 0, single_s = 0, residual = 0, storage_mb = 0;
  int max_iterations = 0;
  double total() const { return factor_s + block_s + single_s; }
};

void run_case(const Options& options, double refinement, int l) {
  Problem problem = load_problem(options.problem, LoadOptions{refinement});
  ParametricSystem system(problem.model, problem.parameter_targets());
  SparseMatrix K, M;
  system.assemble(problem.has_truth() ? problem.truth_values() : problem.initial_values(), &K, &M);
  const int n = system.num_dofs();
  const int k = l + static_cast<int>(std::ceil(options.extra_factor * l));

  // Step 1: the modes, l of them (what a calibration solves for) and k (for the deflation).
  auto forward = [&](int count, double* seconds) {
    ModalOptions modal;
    modal.num_modes = count;
    modal.max_rigid_modes = problem.expected_rigid_modes();
    const auto t0 = Clock::now();
    ModalResult result = ModalSolver(system.pattern(), modal).solve(K, M);
    *seconds = seconds_since(t0);
    if (result.status != EigenStatus::Successful) throw std::runtime_error("forward solve: " + result.message);
    return result;
  };
  double forward_l_s = 0, forward_k_s = 0;
  forward(l, &forward_l_s);
  const ModalResult modes = forward(k, &forward_k_s);

  // Step 2: per mode, MUMPS on the bordered block.
  PathResult direct, shared;
  std::vector<Matrix> blocks(l), singles(l);
  for (int i = 0; i < l; ++i) {
    blocks[i] = pseudo_random(n + 1, options.block_rhs, 1000 + i);
    singles[i] = pseudo_random(n + 1, options.single_rhs, 2000 + i);
  }
  for (int i = 0; i < l; ++i) {
    const Vector Mu = M * modes.modes.col(i);
    const double lambda = modes.eigenvalues[i];
    detail::MumpsSymmetricFactor factor;
    auto t0 = Clock::now();
    std::string why;
    if (!factor.factor(bordered_lower(K, M, lambda, Mu), &why)) throw std::runtime_error("MUMPS: " + why);
    direct.factor_s += seconds_since(t0);
    direct.storage_mb += 8e-6 * factor.factor_entries();  // kept for Ipopt's later solves
    Matrix X = blocks[i];
    t0 = Clock::now();
    factor.solve(&X);
    direct.block_s += seconds_since(t0);
    direct.residual = std::max(direct.residual, bordered_residual(K, M, lambda, Mu, X, blocks[i]));
    t0 = Clock::now();
    for (int c = 0; c < options.single_rhs; ++c) {
      Matrix x = singles[i].col(c);
      factor.solve(&x);
    }
    direct.single_s += seconds_since(t0);
  }

  // Step 3: one factorization of K - sigma M, deflated PCG per mode.
  const double sigma = -0.1 * modes.eigenvalues[0];
  auto t0 = Clock::now();
  detail::CholmodFactor F(system.pattern());
  int failed = -1;
  if (!F.factorize(K, M, sigma, &failed)) throw std::runtime_error("K - sigma M is not definite");
  shared.factor_s = seconds_since(t0);
  shared.storage_mb = 8e-6 * (F.factor_nonzeros() + static_cast<double>(n) * k);
  const detail::DeflationBasis basis{modes.modes, modes.eigenvalues, M * modes.modes};
  for (int i = 0; i < l; ++i) {
    t0 = Clock::now();
    const Matrix X = bordered_solve(K, M, basis, i, F, blocks[i], options, &shared.max_iterations);
    shared.block_s += seconds_since(t0);
    shared.residual = std::max(shared.residual, bordered_residual(K, M, modes.eigenvalues[i],
                                                                  basis.mass_modes.col(i), X, blocks[i]));
    t0 = Clock::now();
    for (int c = 0; c < options.single_rhs; ++c)
      bordered_solve(K, M, basis, i, F, singles[i].col(c), options, &shared.max_iterations);
    shared.single_s += seconds_since(t0);
  }
  std::printf("%8d %4d %4d %9.2f %9.2f | %8.2f %8.2f %8.2f %9.1e %8.0f | %8.2f %8.2f %8.2f %5d %9.1e %8.0f | %6.2f\n", n, l,
              k, forward_l_s, forward_k_s, direct.factor_s, direct.block_s, direct.single_s, direct.residual,
              direct.storage_mb, shared.factor_s, shared.block_s, shared.single_s, shared.max_iterations,
              shared.residual, shared.storage_mb,
              (shared.total() + forward_k_s - forward_l_s) / direct.total());
  std::fflush(stdout);
}

int run(int argc, char** argv) {
  Options options;
  for (int i = 1; i < argc; ++i) {
    const std::string a = argv[i];
    auto next = [&]() -> std::string {
      if (i + 1 >= argc) throw std::invalid_argument(a + " needs a value");
      return argv[++i];
    };
    if (a == "--problem") options.problem = next();
    else if (a == "--refinements") options.refinements = parse_list(next());
    else if (a == "--modes") options.modes = parse_list(next());
    else if (a == "--extra") options.extra_factor = std::stod(next());
    else if (a == "--tolerance") options.tolerance = std::stod(next());
    else {
      std::fprintf(stderr,
                   "usage: %s [--problem FILE] [--refinements 1,2.0003] [--modes 10,20] [--extra F] [--tolerance T]\n"
                   "  --extra F: deflate k = l + ceil(F l) computed modes (default 1)\n",
                   argv[0]);
      return 2;
    }
  }
  std::printf("Bordered eigen-block solves, per-mode MUMPS factorizations against one shared K - sigma M\n"
              "(CHOLMOD) preconditioning deflated CG; %s; %d + %d right-hand sides per mode\n",
              options.problem.c_str(), options.block_rhs, options.single_rhs);
  std::printf("ratio = (shared total + the k modes' extra forward-solve time) / per-mode total\n");
  std::printf("%8s %4s %4s %9s %9s | %8s %8s %8s %9s %8s | %8s %8s %8s %5s %9s %8s | %6s\n", "DOFs", "l", "k",
              "fwd(l) s", "fwd(k) s", "fact s", "block s", "single s", "residual", "store MB", "fact s", "block s",
              "single s", "its", "residual", "store MB", "ratio");
  for (double r : options.refinements)
    for (double l : options.modes) run_case(options, r, static_cast<int>(l));
  return 0;
}

}  // namespace

int main(int argc, char** argv) { return modalcal::bench::run_guarded("bordered_solve_benchmark", run, argc, argv); }
