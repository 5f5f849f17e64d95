#include "objective/deflated_solve.hpp"

#include <cmath>

namespace modalcal::detail {

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
  for (int c = 0; c < m; ++c)
    for (int k = 0; k < U.cols(); ++k)
      if (k != own[c]) out.solution.col(c) += U.col(k) * (coefficients(k, c) / (basis.eigenvalues[k] - shift[c]));
  Matrix R = B - MU * coefficients;

  auto project = [&](Matrix& Z) { Z -= U * (MU.transpose() * Z); };  // Z <- (I - U U^T M) Z
  auto apply = [&](const Matrix& P) -> Matrix { return K * P - (M * P) * shift.asDiagonal(); };
  // Converged relative to the whole right-hand side: when the computed modes carry all of it, the
  // remainder is round-off and needs no iteration.
  Vector target(m);
  for (int c = 0; c < m; ++c) target[c] = tolerance * std::max(B.col(c).norm(), 1e-300);
  std::vector<bool> active(m);
  for (int c = 0; c < m; ++c) active[c] = R.col(c).norm() > target[c];

  Matrix Z = precondition(R);
  out.column_solves += m;
  project(Z);
  Matrix P = Z;
  Vector rz(m);
  for (int c = 0; c < m; ++c) rz[c] = R.col(c).dot(Z.col(c));
  Matrix Y = Matrix::Zero(n, m);
  for (out.iterations = 0; out.iterations < max_iterations; ++out.iterations) {
    bool any = false;
    for (int c = 0; c < m; ++c) any = any || active[c];
    if (!any) break;
    const Matrix Q = apply(P);
    for (int c = 0; c < m; ++c) {
      if (!active[c]) continue;
      const double curvature = P.col(c).dot(Q.col(c));
      if (!(curvature > 0)) {
        out.message = "K - lambda M is not positive definite on the deflated space (curvature " +
                      std::to_string(curvature) + "): an eigenvalue below lambda_" + std::to_string(own[c] + 1) +
                      " was not computed";
        return out;
      }
      const double alpha = rz[c] / curvature;
      Y.col(c) += alpha * P.col(c);
      R.col(c) -= alpha * Q.col(c);
    }
    // Keep the residual orthogonal to U despite rounding in the computed modes.
    R -= MU * (U.transpose() * R);
    for (int c = 0; c < m; ++c)
      if (active[c] && R.col(c).norm() <= target[c]) active[c] = false;
    std::vector<int> columns;
    for (int c = 0; c < m; ++c)
      if (active[c]) columns.push_back(c);
    if (columns.empty()) break;
    // Only the unconverged columns go through the (block) preconditioner.
    Matrix R_active(n, columns.size());
    for (size_t a = 0; a < columns.size(); ++a) R_active.col(a) = R.col(columns[a]);
    Matrix Z_active = precondition(R_active);
    out.column_solves += static_cast<int>(columns.size());
    project(Z_active);
    for (size_t a = 0; a < columns.size(); ++a) Z.col(columns[a]) = Z_active.col(a);
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
