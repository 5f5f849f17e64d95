#include "objective/deflated_solve.hpp"

#include <algorithm>
#include <cmath>
#include <utility>

#include <Eigen/Cholesky>
#include <Eigen/Eigenvalues>

#include "eigen/block_lanczos.hpp"  // symmetric_times

namespace modalcal::detail {

namespace {

/// The solution's part in the computed modes other than each column's own: sum over k != own of
/// u_k (u_k^T b) / (lambda_k - shift).
Matrix modal_part(const DeflationBasis& basis, const std::vector<int>& own, const Vector& shift,
                  const Matrix& coefficients) {
  const Matrix& U = basis.modes;
  Matrix part = Matrix::Zero(U.rows(), coefficients.cols());
  for (int c = 0; c < coefficients.cols(); ++c)
    for (int k = 0; k < U.cols(); ++k)
      if (k != own[c]) part.col(c) += U.col(k) * (coefficients(k, c) / (basis.eigenvalues[k] - shift[c]));
  return part;
}

/// The indices of the columns still iterating.
std::vector<int> active_columns(const std::vector<bool>& active) {
  std::vector<int> columns;
  for (int c = 0; c < static_cast<int>(active.size()); ++c)
    if (active[c]) columns.push_back(c);
  return columns;
}

/// The listed columns of X, in that order.
Matrix gather(const Matrix& X, const std::vector<int>& columns) {
  Matrix part(X.rows(), static_cast<Eigen::Index>(columns.size()));
  for (size_t a = 0; a < columns.size(); ++a) part.col(static_cast<Eigen::Index>(a)) = X.col(columns[a]);
  return part;
}

/// Z's active columns <- the preconditioned residual, projected onto the complement of the modes.
/// Only the unconverged columns go through the (block) preconditioner.
void precondition_active(const Matrix& R, const std::vector<bool>& active, const DeflationBasis& basis,
                         const std::function<Matrix(const Matrix&)>& precondition, Matrix* Z, int* column_solves) {
  const std::vector<int> columns = active_columns(active);
  Matrix Z_active = precondition(gather(R, columns));
  *column_solves += static_cast<int>(columns.size());
  Z_active -= basis.modes * (basis.mass_modes.transpose() * Z_active);  // (I - U U^T M) Z
  for (size_t a = 0; a < columns.size(); ++a) Z->col(columns[a]) = Z_active.col(static_cast<Eigen::Index>(a));
}

/// (K - shift_c M) p_c for the listed columns c of P, in that order. K and M are stored in full:
/// the row-wise product reads them once for all columns, where Eigen's column-major sparse x
/// dense product is several times slower per column. Columns converge at different rates, so
/// only the active ones are multiplied (a converged column's residual is not used again).
Matrix shifted_times(const SparseMatrix& K, const SparseMatrix& M, const Vector& shift, const Matrix& P,
                     const std::vector<int>& columns) {
  const Matrix P_active = gather(P, columns);
  Vector shifts(static_cast<Eigen::Index>(columns.size()));
  for (size_t a = 0; a < columns.size(); ++a) shifts[static_cast<Eigen::Index>(a)] = shift[columns[a]];
  return symmetric_times(K, P_active) - symmetric_times(M, P_active) * shifts.asDiagonal();
}

/// The listed columns of R <- (I - M U U^T) R: orthogonal to the modes again.
void project_out_modes(const DeflationBasis& basis, const std::vector<int>& columns, Matrix* R) {
  const Matrix drift = basis.mass_modes * (basis.modes.transpose() * gather(*R, columns));
  for (size_t a = 0; a < columns.size(); ++a) R->col(columns[a]) -= drift.col(static_cast<Eigen::Index>(a));
}

bool any_of(const std::vector<bool>& flags) { return std::find(flags.begin(), flags.end(), true) != flags.end(); }

/// The Krylov space the shifts share (solve_deflated_shared): Q M-orthonormal and M-orthogonal to
/// the modes, with M Q, K Q and G = Q^T K Q.
struct SharedSpace {
  Matrix Q, MQ, KQ, G;
};

/// X <- X M-orthogonal to the modes and to the space, twice (one pass of classical Gram-Schmidt
/// leaves what rounding put back), the given M X updated to match.
void project_out(const DeflationBasis& basis, const SharedSpace& space, Matrix* X, Matrix* MX) {
  for (int pass = 0; pass < 2; ++pass) {
    const Matrix on_modes = basis.mass_modes.transpose() * *X;
    *X -= basis.modes * on_modes;
    *MX -= basis.mass_modes * on_modes;
    if (space.Q.cols() == 0) continue;
    const Matrix on_space = space.MQ.transpose() * *X;
    *X -= space.Q * on_space;
    *MX -= space.MQ * on_space;
  }
}

/// X's new directions, M-orthonormal: those whose share of X's M-norm survives the projection by
/// more than 1e-6 (the rest lie in the space already, to rounding). Empty when none does.
Matrix new_directions(const SparseMatrix& M, const DeflationBasis& basis, const SharedSpace& space, Matrix X,
                      Matrix* MX) {
  *MX = symmetric_times(M, X);
  const double before = (X.transpose() * *MX).diagonal().maxCoeff();
  for (int round = 0; round < 2; ++round) {  // the second round repairs what dividing by small norms lost
    project_out(basis, space, &X, MX);
    Eigen::SelfAdjointEigenSolver<Matrix> gram(X.transpose() * *MX);
    std::vector<Eigen::Index> kept;
    for (Eigen::Index k = 0; k < gram.eigenvalues().size(); ++k)
      if (gram.eigenvalues()[k] > 1e-12 * before) kept.push_back(k);
    Matrix scale(X.cols(), static_cast<Eigen::Index>(kept.size()));
    for (size_t a = 0; a < kept.size(); ++a)
      scale.col(static_cast<Eigen::Index>(a)) = gram.eigenvectors().col(kept[a]) / std::sqrt(gram.eigenvalues()[kept[a]]);
    X = X * scale;
    *MX = *MX * scale;
    if (X.cols() == 0) break;
  }
  return X;
}

/// Adds Z's new directions to the space and K times them to K Q and G. False when there are none:
/// the space holds every solution it can give.
bool extend_space(const SparseMatrix& K, const SparseMatrix& M, const DeflationBasis& basis, const Matrix& Z,
                  SharedSpace* space, Matrix* MZ) {
  const Matrix X = new_directions(M, basis, *space, Z, MZ);
  if (X.cols() == 0) return false;
  const Matrix KX = symmetric_times(K, X);
  const Eigen::Index q = space->Q.cols(), b = X.cols();
  Matrix G(q + b, q + b);
  G.topLeftCorner(q, q) = space->G;
  G.topRightCorner(q, b) = space->Q.transpose() * KX;
  G.bottomLeftCorner(b, q) = G.topRightCorner(q, b).transpose();
  G.bottomRightCorner(b, b) = 0.5 * (X.transpose() * KX + KX.transpose() * X);
  space->G = std::move(G);
  auto append = [&](Matrix* to, const Matrix& columns) {
    to->conservativeResize(X.rows(), q + b);
    to->rightCols(b) = columns;
  };
  append(&space->Q, X);
  append(&space->MQ, *MZ);
  append(&space->KQ, KX);
  return true;
}

/// Each shift's Galerkin solution on the space, (G - shift I) Y = Q^T R, in `Y`; true when every
/// residual R - (K - shift M) Q Y is within `target`. The highest shift, the slowest to converge,
/// goes first, and the first that falls short ends the round (its solutions are not used then).
/// A shift at which G - shift I is not positive definite (a mode in the space that should have
/// been computed) gives `message`.
bool galerkin_solutions(const SharedSpace& space, const Matrix& R, const Vector& shifts, const Vector& target,
                        std::vector<Matrix>* Y, std::string* message) {
  const Matrix QR = space.Q.transpose() * R;
  std::vector<Eigen::Index> order(static_cast<size_t>(shifts.size()));
  for (size_t k = 0; k < order.size(); ++k) order[k] = static_cast<Eigen::Index>(k);
  std::sort(order.begin(), order.end(), [&](Eigen::Index a, Eigen::Index b) { return shifts[a] > shifts[b]; });
  Y->resize(order.size());
  for (Eigen::Index k : order) {
    Eigen::LLT<Matrix> shifted(space.G - shifts[k] * Matrix::Identity(space.G.rows(), space.G.cols()));
    if (shifted.info() != Eigen::Success) {
      *message = "K - lambda M is not positive definite on the deflated space: an eigenvalue below lambda = " +
                 std::to_string(shifts[k]) + " was not computed";
      return false;
    }
    Matrix& y = (*Y)[static_cast<size_t>(k)];
    y = shifted.solve(QR);
    const Matrix residual = R - space.KQ * y + shifts[k] * (space.MQ * y);
    for (Eigen::Index c = 0; c < R.cols(); ++c)
      if (!(residual.col(c).norm() <= target[c])) return false;
  }
  return true;
}

}  // namespace

Matrix solve_in_basis(const DeflationBasis& basis, const std::vector<int>& own, const Matrix& B) {
  Matrix weights = basis.modes.transpose() * B;  // u_k^T b, then divided by lambda_k - lambda_own
  for (Eigen::Index c = 0; c < B.cols(); ++c) {
    const int own_mode = own[static_cast<size_t>(c)];
    weights.col(c).array() /= basis.eigenvalues.array() - basis.eigenvalues[own_mode];
    weights(own_mode, c) = 0;
  }
  return basis.modes * weights;
}

DeflatedSolveResult solve_deflated(const SparseMatrix& K, const SparseMatrix& M, const DeflationBasis& basis,
                                   const std::vector<int>& own, const Matrix& B,
                                   const std::function<Matrix(const Matrix&)>& precondition, double tolerance,
                                   int max_iterations) {
  const int n = static_cast<int>(B.rows()), m = static_cast<int>(B.cols());
  const Matrix& U = basis.modes;
  const Matrix& MU = basis.mass_modes;
  DeflatedSolveResult out;
  out.solution = Matrix::Zero(n, m);
  if (m == 0) {
    out.converged = true;
    return out;
  }
  Vector shift(m);
  for (int c = 0; c < m; ++c) shift[c] = basis.eigenvalues[own[c]];

  // Modal part, and the right-hand side left for the complement.
  const Matrix coefficients = U.transpose() * B;  // u_k^T b
  out.solution = modal_part(basis, own, shift, coefficients);
  Matrix R = B - MU * coefficients;

  // Converged relative to the whole right-hand side: when the computed modes carry all of it, the
  // remainder is round-off and needs no iteration.
  Vector target(m);
  for (int c = 0; c < m; ++c) target[c] = tolerance * std::max(B.col(c).norm(), 1e-300);
  std::vector<bool> active(m);
  for (int c = 0; c < m; ++c) active[c] = R.col(c).norm() > target[c];

  Matrix Z = Matrix::Zero(n, m);
  precondition_active(R, std::vector<bool>(m, true), basis, precondition, &Z, &out.column_solves);
  Matrix P = Z;
  Vector rz(m);
  for (int c = 0; c < m; ++c) rz[c] = R.col(c).dot(Z.col(c));
  Matrix Y = Matrix::Zero(n, m);
  for (out.iterations = 0; out.iterations < max_iterations && any_of(active); ++out.iterations) {
    const std::vector<int> columns = active_columns(active);
    const Matrix Q = shifted_times(K, M, shift, P, columns);
    for (size_t a = 0; a < columns.size(); ++a) {
      const int c = columns[a];
      const auto q = Q.col(static_cast<Eigen::Index>(a));
      const double curvature = P.col(c).dot(q);
      if (!(curvature > 0)) {
        out.message = "K - lambda M is not positive definite on the deflated space (curvature " +
                      std::to_string(curvature) + "): an eigenvalue below lambda_" + std::to_string(own[c] + 1) +
                      " was not computed";
        return out;
      }
      const double alpha = rz[c] / curvature;
      Y.col(c) += alpha * P.col(c);
      R.col(c) -= alpha * q;
    }
    project_out_modes(basis, columns, &R);  // rounding in the computed modes lets R drift into them
    for (int c = 0; c < m; ++c)
      if (active[c] && R.col(c).norm() <= target[c]) active[c] = false;
    if (!any_of(active)) break;
    precondition_active(R, active, basis, precondition, &Z, &out.column_solves);
    for (int c = 0; c < m; ++c) {
      if (!active[c]) continue;
      const double rz_new = R.col(c).dot(Z.col(c));
      P.col(c) = Z.col(c) + (rz_new / rz[c]) * P.col(c);
      rz[c] = rz_new;
    }
  }
  out.solution += Y;
  out.converged = true;
  for (int c = 0; c < m; ++c) out.converged = out.converged && !active[c];
  if (!out.converged)
    out.message = "deflated conjugate gradients did not reach the tolerance in " + std::to_string(max_iterations) +
                  " iterations; compute more extra modes (objective option extra_modes)";
  return out;
}

DeflatedSolveResult solve_deflated_shared(const SparseMatrix& K, const SparseMatrix& M, const DeflationBasis& basis,
                                          const std::vector<int>& own, const Matrix& B,
                                          const std::function<Matrix(const Matrix&)>& precondition,
                                          double tolerance, int max_iterations, Eigen::Index max_columns) {
  const Eigen::Index s = B.cols(), m = static_cast<Eigen::Index>(own.size());
  std::vector<int> own_of_column;  // the layout of the result, B once per own[k]
  for (int mode : own) own_of_column.insert(own_of_column.end(), static_cast<size_t>(s), mode);
  Vector shifts(m), shift_of_column(s * m);
  for (Eigen::Index k = 0; k < m; ++k) shifts[k] = basis.eigenvalues[own[static_cast<size_t>(k)]];
  for (Eigen::Index c = 0; c < s * m; ++c) shift_of_column[c] = basis.eigenvalues[own_of_column[static_cast<size_t>(c)]];

  const Matrix coefficients = basis.modes.transpose() * B;
  DeflatedSolveResult out;
  out.solution = modal_part(basis, own_of_column, shift_of_column, coefficients.replicate(1, m));
  const Matrix R = B - basis.mass_modes * coefficients;
  Vector target(s);
  for (Eigen::Index c = 0; c < s; ++c) target[c] = tolerance * std::max(B.col(c).norm(), 1e-300);
  bool done = true;
  for (Eigen::Index c = 0; c < s; ++c) done = done && R.col(c).norm() <= target[c];

  SharedSpace space{Matrix(B.rows(), 0), Matrix(B.rows(), 0), Matrix(B.rows(), 0), Matrix(0, 0)};
  std::vector<Matrix> Y(static_cast<size_t>(m), Matrix::Zero(0, s));
  Matrix MZ = R;  // what the next block's preconditioner is applied to: R, then M times the last block
  while (!done && out.iterations < max_iterations && space.Q.cols() + s <= max_columns && s * m > 0) {
    const Matrix Z = precondition(MZ);
    out.column_solves += static_cast<int>(Z.cols());
    ++out.iterations;
    if (!extend_space(K, M, basis, Z, &space, &MZ)) break;
    done = galerkin_solutions(space, R, shifts, target, &Y, &out.message);
    if (!out.message.empty()) return out;
  }
  if (!done) {  // the space may not grow further (max_columns, max_iterations) or cannot: each shift on its own
    DeflatedSolveResult alone = solve_deflated(K, M, basis, own_of_column, B.replicate(1, m), precondition,
                                               tolerance, max_iterations);
    alone.column_solves += out.column_solves;
    return alone;
  }
  for (Eigen::Index k = 0; k < m && space.Q.cols() > 0; ++k)
    out.solution.middleCols(k * s, s) += space.Q * Y[static_cast<size_t>(k)];
  out.converged = true;
  return out;
}

}  // namespace modalcal::detail
