#pragma once
// Internal: the full-space calibration problem, independent of any optimizer. Unknowns
// x = (u~_1 .. u~_l, t_1 .. t_l, q), constraints c = (r_1 .. r_l, n_1 .. n_l), nondimensionalized
// as documented in include/modalcal/fullspace.hpp. The Ipopt adapter only maps this class.

#include <memory>
#include <vector>

#include "fullspace/sparse_layout.hpp"
#include "modalcal/objective.hpp"
#include "objective/shape_misfit.hpp"

namespace modalcal::detail {

class FullSpaceProblem {
 public:
  /// One full-space mode per measured mode with a nonzero weight. `p_scale` fixes the
  /// nondimensionalization (s_u^2 = tr M(p_scale)).
  FullSpaceProblem(Objective& objective, const ParameterScaling& scaling, const Vector& p_scale);

  int num_modes() const { return static_cast<int>(measured_.size()); }
  int num_dofs() const { return n_; }
  int num_parameters() const { return np_; }
  int num_variables() const { return num_modes() * (n_ + 1) + np_; }
  int num_constraints() const { return num_modes() * (n_ + 1); }
  /// Measured mode (index into Problem::measured) of full-space mode i.
  int measured_of(int i) const { return measured_[i]; }
  const std::vector<int>& measured_modes() const { return measured_; }

  /// x from physical modes (columns, mass-normalized), eigenvalues and parameters.
  Vector pack(const Matrix& modes, const Vector& eigenvalues, const Vector& p) const;
  /// Physical modes, eigenvalues and parameters of x.
  void unpack(const double* x, Matrix* modes, Vector* eigenvalues, Vector* p) const;
  /// Physical parameters of x.
  Vector parameters(const double* x) const { return scaling_.to_physical(scaled_parameters(x)); }
  /// Constraint multipliers from the physical ones (w_i of (K - lambda_i M) u_i = 0 and eta_i of
  /// u_i^T M u_i - 1 = 0), and back.
  Vector pack_multipliers(const Matrix& w, const Vector& eta) const;
  void unpack_multipliers(const double* y, Matrix* w, Vector* eta) const;
  /// Bounds of the unknowns (only q is bounded; +-1e20 stands for none, as in Ipopt).
  void bounds(double* lower, double* upper) const;

  double objective(const double* x);
  void objective_gradient(const double* x, double* gradient);
  void constraints(const double* x, double* c);
  const SparseLayout& jacobian_layout() const { return jacobian_; }
  void jacobian_values(const double* x, double* values);
  const SparseLayout& hessian_layout() const { return hessian_; }
  /// Lower triangle of sigma * Hessian(objective) + sum_k y_k Hessian(c_k).
  void hessian_values(const double* x, double sigma, const double* y, double* values);

  /// Unknowns and constraint rows share one layout: l blocks of n (u~_i; r_i), then l scalars
  /// (t_i; n_i), then (unknowns only) q. mode_entry(i, a) is the index of mode i's local entry a
  /// in 0..n (a = n: its scalar); locate() is the inverse, with mode -1 and the parameter's index
  /// for q.
  int mode_entry(int i, int a) const { return a < n_ ? i * n_ + a : num_modes() * n_ + i; }
  void locate(int index, int* mode, int* local) const;
  int parameter_offset() const { return num_modes() * (n_ + 1); }
  /// s_i with: the Jacobian block of mode i (rows r_i, n_i; columns u~_i, t_i) equals diag(s_i) B_i,
  /// B_i = [[K / lambda_ref,i - t_i M, -M u~_i], [-(M u~_i)^T, 0]] symmetric (the bordered
  /// eigen-matrix), so that one symmetric factorization serves A_i and A_i^T.
  Vector mode_row_scale(int i) const;

  /// Sign (+1 or -1) that aligns a physical mode with the measured shape of full-space mode i at
  /// the sensors (+1 without a shape).
  double shape_sign(int i, const Vector& u) const;
  /// M(p(x)), for mass-weighted MAC checks; K(p(x)). Both in full, on one pattern.
  const SparseMatrix& mass_matrix(const double* x);
  const SparseMatrix& stiffness_matrix(const double* x);
  /// Mode i's scaled eigenvector u~_i, eigenvalue ratio t_i = lambda_i / lambda_ref,i and
  /// reference eigenvalue lambda_ref,i (the measured one): B_i's ingredients.
  Eigen::Map<const Vector> mode_vector(const double* x, int i) const { return mode(x, i); }
  double eigenvalue_ratio(const double* x, int i) const { return x[num_modes() * n_ + i]; }
  double reference_eigenvalue(int i) const { return lambda_ref_[i]; }
  /// Approximate eigenvectors of (K, M) near the current parameters - the last forward solve's,
  /// rigid-body and unmeasured modes included - that deflate the shared-factorization solves
  /// of the bordered blocks (shared_shift_solve.hpp). Empty until set.
  void set_deflation_basis(const Matrix& modes);
  const Matrix& deflation_basis() const { return deflation_basis_; }
  /// Counts set_deflation_basis() calls: a solver built on the basis knows when it changed.
  long deflation_basis_version() const { return deflation_basis_version_; }
  /// x of the last jacobian_values() call: where an optimizer's next KKT matrix is linearized
  /// (empty before the first).
  const Vector& jacobian_point() const { return jacobian_point_; }
  const ParameterScaling& scaling() const { return scaling_; }

 private:
  struct ModeBlocks {  // where each block of mode i lives in the value arrays
    SparseLayout::Block r_u, r_t, n_u, n_q;
    std::vector<SparseLayout::Block> r_q;
    SparseLayout::Block h_uu, h_tu, h_tt, h_qt;
    std::vector<SparseLayout::Block> h_qu;
  };
  // The constructor's steps, in order.
  void select_measured_modes();
  void set_scales(const Vector& p_scale);
  void find_parameter_rows(const Vector& p_scale);
  void build_uu_pattern();
  void register_layouts();
  void update(const double* x);  // K, M and their parameter derivatives at p(q)
  Eigen::Map<const Vector> mode(const double* x, int i) const { return Eigen::Map<const Vector>(x + i * n_, n_); }
  Eigen::Map<const Vector> scaled_parameters(const double* x) const {
    return Eigen::Map<const Vector>(x + num_modes() * (n_ + 1), np_);
  }
  void regularization(const Vector& q, double* value, Vector* gradient, Vector* hessian) const;

  Objective& objective_;
  const Problem& problem_;
  const ParametricSystem& system_;
  ParameterScaling scaling_;
  int n_ = 0, np_ = 0;
  std::vector<int> measured_;          // measured mode of each full-space mode
  Vector lambda_ref_;                  // measured eigenvalue of each full-space mode
  std::vector<std::unique_ptr<ShapeMisfit>> shape_;  // null without a measured shape
  double mass_scale_ = 1, mode_scale_ = 1;  // m_bar and s_u
  // n_s: the normalization row times the number of DOFs has entries of the size of the r rows.
  double normalization_scale_ = 1;
  std::vector<Vector> row_scale_;       // D_i: per mode, per row of r_i
  SparseMatrix sensors_;
  std::vector<int> sensor_dofs_;       // free DOFs the sensors read
  std::vector<std::vector<int>> parameter_rows_;  // DOFs K_j, M_j touch, per parameter
  SparseMatrix uu_pattern_;            // lower triangle of pattern(K) + sensor block
  std::vector<int> uu_from_pattern_;   // per entry of pattern(K): position in uu_pattern_, or -1
  Matrix uu_sensor_positions_;         // position of (sensor dof a, sensor dof b), a >= b
  SparseLayout jacobian_, hessian_;
  std::vector<ModeBlocks> blocks_;
  SparseLayout::Block h_qq_;
  // Cached at p(q) of the last update.
  Vector cached_q_;
  Vector p_, dp_, d2p_;
  // K and M only: the derivatives dK_j, dM_j enter as products (ParametricSystem::derivative_times),
  // which touch only parameter j's terms; formed, each would hold pattern(K)'s size.
  SparseMatrix K_, M_;
  Matrix deflation_basis_;
  long deflation_basis_version_ = 0;
  Vector jacobian_point_;
};

}  // namespace modalcal::detail
