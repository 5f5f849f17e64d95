#include "objective/deflated_solve.hpp"

#include <algorithm>
#include <cmath>

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

}  // namespace modalcal::detail
