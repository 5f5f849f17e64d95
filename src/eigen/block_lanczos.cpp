#include "eigen/block_lanczos.hpp"

#include <Eigen/Eigenvalues>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <limits>
#include <random>
#include <vector>

namespace modalcal::detail {

namespace {

using Clock = std::chrono::steady_clock;
using RowMajorMatrix = Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>;

// A column that Gram-Schmidt shrinks below this fraction of its norm, or a direction of a block
// whose singular value (columns scaled to unit M-norm) is below it, lies numerically in the span
// of the basis: what is left is rounding noise (relative size eps / kDeflation ~ 2e-9) rather
// than a Krylov direction, so it is dropped and replaced by a fresh vector.
constexpr double kDeflation = 1e-7;
// SVQB of a block whose scaled Gram matrix has smallest eigenvalue mu loses M-orthogonality to
// the basis like eps / sqrt(mu) and within the block like eps / mu (Stathopoulos & Wu 2002,
// "A block orthogonalization procedure with constant synchronization requirements"): below this
// mu the block goes through Gram-Schmidt and SVQB once more.
constexpr double kReorthogonalize = 1e-2;
// Rounds of (Gram-Schmidt twice + SVQB) per block before it is taken as it is.
constexpr int kMaxRounds = 3;
// Attempts to refill a block narrowed by deflation before continuing with a narrower one.
constexpr int kMaxRefills = 2;
// True-residual checks in a row that fail to halve the worst residual before giving up (and
// leaving the modes to the Spectra fallback): the tolerance is then below what rounding allows.
constexpr int kMaxStalls = 3;

class ScopedTimer {
 public:
  explicit ScopedTimer(double* total) : total_(total), t0_(Clock::now()) {}
  ~ScopedTimer() { *total_ += std::chrono::duration<double>(Clock::now() - t0_).count(); }
  ScopedTimer(const ScopedTimer&) = delete;
  ScopedTimer& operator=(const ScopedTimer&) = delete;

 private:
  double* total_;
  Clock::time_point t0_;
};

// ||A||_1 (= ||A||_inf for symmetric A), an upper bound of ||A||_2.
double norm1(const SparseMatrix& A) {
  double best = 0;
  for (int j = 0; j < A.outerSize(); ++j) {
    double sum = 0;
    for (SparseMatrix::InnerIterator it(A, j); it; ++it) sum += std::abs(it.value());
    best = std::max(best, sum);
  }
  return best;
}

// Y = A X on `Width` columns of row-major X and Y (row stride `stride`), A symmetric in full
// storage: row j of Y is column j of A against rows of X, so A is read once for all the columns,
// and a compile-time width keeps the sums in registers (2-4x faster than Eigen's sparse-dense
// product, which reads A once per column).
template <int Width>
void times_columns(const SparseMatrix& A, const double* X, double* Y, int stride) {
  const int* start = A.outerIndexPtr();
  const int* row = A.innerIndexPtr();
  const double* value = A.valuePtr();
  for (int j = 0; j < A.outerSize(); ++j) {
    double sum[Width] = {};
    for (int k = start[j]; k < start[j + 1]; ++k) {
      const double* x = X + static_cast<Eigen::Index>(row[k]) * stride;
      for (int c = 0; c < Width; ++c) sum[c] += value[k] * x[c];
    }
    double* y = Y + static_cast<Eigen::Index>(j) * stride;
    for (int c = 0; c < Width; ++c) y[c] = sum[c];
  }
}

// Keeps the columns of X flagged in `keep`, in order.
Matrix select_columns(const Matrix& X, const std::vector<bool>& keep) {
  Matrix out(X.rows(), std::count(keep.begin(), keep.end(), true));
  for (int j = 0, k = 0; j < X.cols(); ++j)
    if (keep[j]) out.col(k++) = X.col(j);
  return out;
}

class BlockLanczos {
 public:
  BlockLanczos(const CholmodFactor& factor, const SparseMatrix& K, const SparseMatrix& M, double sigma,
               const BlockLanczosOptions& options);
  BlockLanczosResult run();

 private:
  Matrix apply(const Matrix& MX);
  Matrix fresh_block(int cols);
  Matrix append_pending_block(const Matrix& W);
  void next_block(const Matrix& W_raw, const Matrix& C);
  void orthonormalize(Matrix W, Vector reference);
  void project_out(Matrix* W) const;
  double svqb(Matrix* W, Matrix* MW) const;
  void rayleigh_ritz();
  bool converged();
  void thick_restart();

  const CholmodFactor& factor_;
  const SparseMatrix& K_;
  const SparseMatrix& M_;
  const double sigma_;
  const BlockLanczosOptions options_;
  const int n_;
  const int max_basis_;
  std::mt19937_64 rng_;
  Matrix V_, MV_;  // M-orthonormal basis and M V, the first m_ columns in use
  Matrix H_;       // V^T M S V, the projection of S (block tridiagonal up to rounding)
  int m_ = 0;
  int last_width_ = 0;  // columns of the block appended last
  Matrix P_, MP_;       // next block: M-orthonormal and M-orthogonal to V
  Matrix coupling_;     // P^T M S (last block): the off-diagonal block of the Lanczos relation
  Vector theta_;        // Ritz values of S, descending
  Matrix Y_;            // their eigenvectors of H
  double norm_K_;
  double worst_failed_ = std::numeric_limits<double>::infinity();
  int stalls_ = 0;
  BlockLanczosResult result_;
};

BlockLanczos::BlockLanczos(const CholmodFactor& factor, const SparseMatrix& K, const SparseMatrix& M, double sigma,
                           const BlockLanczosOptions& options)
    : factor_(factor),
      K_(K),
      M_(M),
      sigma_(sigma),
      options_(options),
      n_(static_cast<int>(K.rows())),
      max_basis_(std::min(options.max_basis, n_ - options.block_size)),
      rng_(options.seed),
      norm_K_(norm1(K)) {}

// S X = (K - sigma M)^{-1} (M X), one block solve.
Matrix BlockLanczos::apply(const Matrix& MX) {
  ScopedTimer timer(&result_.seconds_solve);
  result_.solves += static_cast<int>(MX.cols());
  ++result_.blocks;
  return factor_.solve(MX);
}

// S R for a uniform random R: applying S keeps the vectors in the range of S, where the
// M-inner product is definite even for a singular M (massless rotations); a raw random vector
// would carry a null-space component of M that no M-norm sees ("purification", Nour-Omid,
// Parlett, Ericsson & Jensen 1987). The generator's raw 64-bit output is mapped to [-1, 1)
// by hand so that the block does not depend on the standard library's distributions.
Matrix BlockLanczos::fresh_block(int cols) {
  Matrix R(n_, cols);
  for (int j = 0; j < cols; ++j)
    for (int i = 0; i < n_; ++i) R(i, j) = static_cast<double>(rng_() >> 11) * 0x1.0p-52 - 1.0;
  return apply(symmetric_times(M_, R));
}

// Moves the pending block into the basis and fills the new column block of H with
// C = V^T M (S P) = (M V)^T W (the new rows follow by the M-symmetry of S); returns C, which is
// also the first Gram-Schmidt pass for W.
Matrix BlockLanczos::append_pending_block(const Matrix& W) {
  ScopedTimer timer(&result_.seconds_orthogonalize);
  const int width = static_cast<int>(P_.cols());
  V_.middleCols(m_, width) = P_;
  MV_.middleCols(m_, width) = MP_;
  m_ += width;
  last_width_ = width;
  const Matrix C = MV_.leftCols(m_).transpose() * W;
  H_.block(0, m_ - width, m_, width) = C;
  H_.block(m_ - width, 0, width, m_) = C.transpose();
  const Matrix D = H_.block(m_ - width, m_ - width, width, width);
  H_.block(m_ - width, m_ - width, width, width) = 0.5 * (D + D.transpose());
  return C;
}

// The next block from W = S P: Gram-Schmidt against the basis (the first pass uses C, which
// append_pending_block computed for H anyway), SVQB, and fresh vectors for deflated columns.
void BlockLanczos::next_block(const Matrix& W_raw, const Matrix& C) {
  {
    ScopedTimer timer(&result_.seconds_orthogonalize);
    orthonormalize(W_raw - V_.leftCols(m_) * C, W_raw.colwise().norm().transpose());
  }
  for (int refill = 0; refill < kMaxRefills && P_.cols() < options_.block_size; ++refill) {
    const int missing = options_.block_size - static_cast<int>(P_.cols());
    result_.deflated += missing;
    const Matrix fresh = fresh_block(missing);
    ScopedTimer timer(&result_.seconds_orthogonalize);
    Matrix W(n_, options_.block_size);
    W << P_, fresh;
    const Vector reference = W.colwise().norm().transpose();
    project_out(&W);
    orthonormalize(std::move(W), reference);
  }
  ScopedTimer timer(&result_.seconds_orthogonalize);
  coupling_ = MP_.transpose() * W_raw;
}

// One classical Gram-Schmidt pass in the M-inner product against the basis.
void BlockLanczos::project_out(Matrix* W) const {
  if (m_ == 0) return;
  const Matrix C = MV_.leftCols(m_).transpose() * *W;
  W->noalias() -= V_.leftCols(m_) * C;
}

// Sets P to an M-orthonormal basis of the part of W (already projected once) that is
// M-orthogonal to the basis. Gram-Schmidt twice is enough for orthogonality to rounding
// (Giraud, Langou, Rozloznik & van den Eshof 2005); SVQB then orthonormalizes within the block
// and drops its numerically dependent directions.
void BlockLanczos::orthonormalize(Matrix W, Vector reference) {
  for (int round = 1;; ++round) {
    project_out(&W);
    std::vector<bool> keep(W.cols());
    for (int j = 0; j < W.cols(); ++j) keep[j] = W.col(j).norm() > kDeflation * reference[j];
    W = select_columns(W, keep);
    Matrix MW = symmetric_times(M_, W);
    const double mu = svqb(&W, &MW);
    if (W.cols() == 0 || mu >= kReorthogonalize || round == kMaxRounds) {
      P_ = std::move(W);
      MP_ = std::move(MW);
      return;
    }
    reference = W.colwise().norm().transpose();
    project_out(&W);
  }
}

// SVQB (Stathopoulos & Wu 2002): with G = W^T M W and D = diag(G)^{-1/2}, D G D = Z diag(mu) Z^T
// gives the M-orthonormal W D Z diag(mu)^{-1/2}; directions with mu below kDeflation^2 are
// dropped. Returns the smallest mu kept (1 for an empty block).
double BlockLanczos::svqb(Matrix* W, Matrix* MW) const {
  if (W->cols() == 0) return 1;
  Matrix G = W->transpose() * *MW;
  G = 0.5 * (G + G.transpose());
  const Vector d = G.diagonal().cwiseMax(std::numeric_limits<double>::min()).cwiseSqrt().cwiseInverse();
  Eigen::SelfAdjointEigenSolver<Matrix> es(d.asDiagonal() * G * d.asDiagonal());
  const Vector& mu = es.eigenvalues();  // ascending
  int first = 0;
  while (first < mu.size() && !(mu[first] > kDeflation * kDeflation)) ++first;
  const int kept = static_cast<int>(mu.size()) - first;
  const Matrix T = d.asDiagonal() * es.eigenvectors().rightCols(kept) *
                   mu.tail(kept).cwiseSqrt().cwiseInverse().asDiagonal();
  *W = *W * T;
  *MW = *MW * T;
  return kept > 0 ? mu[first] : 1;
}

// Ritz pairs of S on span(V): theta descending, so the lowest lambda = sigma + 1/theta come first.
void BlockLanczos::rayleigh_ritz() {
  ScopedTimer timer(&result_.seconds_rayleigh_ritz);
  Eigen::SelfAdjointEigenSolver<Matrix> es(H_.topLeftCorner(m_, m_));
  theta_ = es.eigenvalues().reverse();
  Y_ = es.eigenvectors().rowwise().reverse();
}

// Ritz vectors improved by one step of inverse iteration that costs no solve (Ericsson & Ruhe
// 1980, "The spectral transformation Lanczos method", sec. 4): for u = V y, the block Lanczos
// relation S V = V H + P B E^T (Grimes, Lewis & Simon 1994, sec. 2) gives
// S u = theta u + r with r = P B y_last, so u~ = S u / theta = u + r / theta, and
// (K - lambda M) u~ = -M r / theta^2 for lambda = sigma + 1/theta, whereas (K - lambda M) u =
// -A r / theta: A weights r by the higher eigenvalues that r is made of. u~ is in the range of
// S, hence free of null-space components of a singular M (Nour-Omid et al. 1987, "purification").
// ||r||_M / theta = ||B y_last|| / theta is the residual of the transformed problem (Spectra's test).
bool BlockLanczos::converged() {
  const int nev = options_.nev;
  const Matrix Z = coupling_ * Y_.block(m_ - last_width_, 0, last_width_, nev);  // r_i = P z_i
  for (int i = 0; i < nev; ++i)
    if (!(theta_[i] > 0) || Z.col(i).norm() > options_.tolerance * theta_[i]) return false;
  ScopedTimer timer(&result_.seconds_residual);
  ++result_.residual_checks;
  const Vector inverse_theta = theta_.head(nev).cwiseInverse();
  const Matrix ZT = Z * inverse_theta.asDiagonal();
  const Matrix U = V_.leftCols(m_) * Y_.leftCols(nev) + P_ * ZT;
  const Matrix MU = MV_.leftCols(m_) * Y_.leftCols(nev) + MP_ * ZT;
  const Matrix KU = symmetric_times(K_, U);
  const Vector lambda = (sigma_ + inverse_theta.array()).matrix();
  double worst = 0;  // largest residual over what the criterion allows
  for (int i = 0; i < nev; ++i) {
    const double residual = (KU.col(i) - lambda[i] * MU.col(i)).norm();
    const double rounding = std::numeric_limits<double>::epsilon() * norm_K_ * U.col(i).norm();
    const double allowed = std::abs(lambda[i]) > options_.rigid_threshold
                               ? options_.tolerance * std::abs(lambda[i]) * MU.col(i).norm() + rounding
                               : options_.tolerance * norm_K_ * U.col(i).norm();
    worst = std::max(worst, residual / allowed);
  }
  if (!(worst <= 1)) {
    stalls_ = worst > 0.5 * worst_failed_ ? stalls_ + 1 : 0;
    worst_failed_ = std::min(worst_failed_, worst);
    return false;
  }
  result_.eigenvalues = lambda;
  result_.vectors = U;
  return true;
}

// Thick restart (Wu & Simon 2000, "Thick-restart Lanczos method for large symmetric eigenvalue
// problems"): keep the best Ritz vectors, on which H is diagonal, and go on from the pending
// block, which is M-orthogonal to all of them.
void BlockLanczos::thick_restart() {
  rayleigh_ritz();
  ++result_.restarts;
  const int b = options_.block_size;
  const int keep = std::max(options_.nev, std::min(max_basis_ - 2 * b, (max_basis_ + options_.nev) / 2));
  V_.leftCols(keep) = V_.leftCols(m_) * Y_.leftCols(keep);
  MV_.leftCols(keep) = MV_.leftCols(m_) * Y_.leftCols(keep);
  H_.topLeftCorner(keep, keep) = theta_.head(keep).asDiagonal();
  m_ = keep;
}

BlockLanczosResult BlockLanczos::run() {
  const int b = options_.block_size;
  if (b < 1 || options_.nev < 1 || max_basis_ < options_.nev + 2 * b) return result_;
  V_.resize(n_, max_basis_);
  MV_.resize(n_, max_basis_);
  H_.resize(max_basis_, max_basis_);
  const Matrix start = fresh_block(b);
  {
    ScopedTimer timer(&result_.seconds_orthogonalize);
    orthonormalize(start, start.colwise().norm().transpose());
  }
  while (P_.cols() > 0) {
    if (m_ + P_.cols() > max_basis_) {
      if (result_.restarts == options_.max_restarts) break;
      thick_restart();
    }
    const Matrix W = apply(MP_);
    next_block(W, append_pending_block(W));
    if (m_ < options_.nev + b) continue;
    rayleigh_ritz();
    if (converged()) {
      result_.converged = true;
      break;
    }
    if (stalls_ >= kMaxStalls) break;
  }
  return result_;
}

}  // namespace

Matrix symmetric_times(const SparseMatrix& A, const Matrix& X) {
  const int b = static_cast<int>(X.cols());
  const RowMajorMatrix Xr = X;
  RowMajorMatrix Yr(A.rows(), b);
  int c = 0;
  for (; c + 8 <= b; c += 8) times_columns<8>(A, Xr.data() + c, Yr.data() + c, b);
  if (c + 4 <= b) times_columns<4>(A, Xr.data() + c, Yr.data() + c, b), c += 4;
  if (c + 2 <= b) times_columns<2>(A, Xr.data() + c, Yr.data() + c, b), c += 2;
  if (c < b) times_columns<1>(A, Xr.data() + c, Yr.data() + c, b);
  return Yr;
}

BlockLanczosResult block_lanczos(const CholmodFactor& factor, const SparseMatrix& K, const SparseMatrix& M,
                                 double sigma, const BlockLanczosOptions& options) {
  return BlockLanczos(factor, K, M, sigma, options).run();
}

}  // namespace modalcal::detail
