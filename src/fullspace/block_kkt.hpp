#pragma once
// Internal: the Newton (KKT) system of a FullSpaceProblem solved by block elimination instead of
// one factorization of the whole matrix. The constraint Jacobian is block diagonal over the modes
// apart from the parameter columns, and so is the Lagrangian Hessian apart from the parameter
// rows (fullspace_problem.hpp). With, for mode i, A_i = dc_i/dx_i, P_i = dc_i/dq,
// W_i = d2L/dx_i^2, C_i = d2L/dx_i dq, the KKT system
//
//   W_i dx_i + C_i dq + A_i^T dy_i = -g_i,   sum_i (C_i^T dx_i + P_i^T dy_i) + W_qq dq = -g_q,
//   A_i dx_i + P_i dq = -c_i
//
// (g = gradient of the Lagrangian) gives dx_i = a_i - S_i dq, dy_i = b_i - T_i dq with
//   a_i = -A_i^{-1} c_i,  S_i = A_i^{-1} P_i,  b_i = -A_i^{-T} (g_i + W_i a_i),
//   T_i = A_i^{-T} (C_i - W_i S_i),
// and the m x m reduced (Schur) system H dq = h with
//   H = W_qq - sum_i (C_i^T S_i + S_i^T C_i - S_i^T W_i S_i),  h = -g_q - sum_i (C_i^T a_i + P_i^T b_i).
// H = Z^T W Z on the null space Z = [-S; I] of the constraint Jacobian: the KKT matrix has the
// inertia an interior-point or SQP method wants exactly when H is positive definite, so the
// inertia test is on an m x m matrix. Cost per mode: one sparse symmetric indefinite
// factorization of the bordered B_i (A_i = diag(s_i) B_i) and 2(m + 1) solves, against Ipopt's
// factorization of the whole 2 l (n + 1) + m KKT matrix (docs/benchmarks.md: where the time goes).

#include <string>
#include <vector>

#include "fullspace/fullspace_problem.hpp"
#include "fullspace/mumps_factor.hpp"

namespace modalcal::detail {

class BlockKktSystem {
 public:
  explicit BlockKktSystem(FullSpaceProblem& problem);

  /// Evaluates the derivatives at (x, y) and eliminates every mode. False (with `error` naming
  /// the mode and the likely cause) when a bordered block is singular.
  bool build(const Vector& x, const Vector& y, std::string* error);

  /// Gradient of the Lagrangian g + A^T y and constraint values at the last build.
  const Vector& lagrangian_gradient() const { return lagrangian_gradient_; }
  const Vector& constraints() const { return constraints_; }
  const Vector& objective_gradient() const { return objective_gradient_; }
  /// Reduced (Schur) Hessian H and right-hand side h in the parameters.
  const Matrix& reduced_hessian() const { return reduced_hessian_; }
  const Vector& reduced_rhs() const { return reduced_rhs_; }
  /// Negative pivots of B_i: the index (1-based) of the eigenpair u_i is near, by Sylvester's law
  /// (B_i's inertia is that of K - lambda M on the M-complement of u_i, plus one of each sign).
  int mode_index(int i) const { return mode_index_[i]; }

  /// The full step (dx, dy) for a parameter step dq.
  void step(const Vector& dq, Vector* dx, Vector* dy) const;

 private:
  struct ModeData {
    Matrix a_S;  // [a_i, S_i]
    Matrix b_T;  // [b_i, T_i]
  };
  FullSpaceProblem& problem_;
  int n_ = 0, l_ = 0, np_ = 0;
  // Structure, fixed: where every Jacobian and Hessian entry goes.
  struct Slot {
    int mode = -1;       // -1: both indices are parameters (Hessian q-q)
    int row = 0, col = 0;  // local indices (mode block: 0..n; parameter: 0..np-1)
    enum Kind { ModeBlock, ParameterColumn, ParameterPair } kind = ModeBlock;
  };
  std::vector<int> jac_rows_, jac_cols_, hes_rows_, hes_cols_;
  std::vector<Slot> jac_slots_, hes_slots_;
  std::vector<std::vector<int>> jac_entries_, hes_entries_;  // per mode: its entries' positions
  std::vector<int> parameter_pairs_;                          // Hessian q-q entries
  std::vector<double> jac_values_, hes_values_;
  MumpsSymmetricFactor factor_;
  std::vector<ModeData> modes_;
  std::vector<int> mode_index_;
  Vector lagrangian_gradient_, constraints_, objective_gradient_, reduced_rhs_;
  Matrix reduced_hessian_;
};

}  // namespace modalcal::detail
