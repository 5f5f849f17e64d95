#include "fullspace/fullspace_problem.hpp"

#include <algorithm>
#include <cmath>
#include <numeric>
#include <stdexcept>

namespace modalcal::detail {

namespace {

constexpr double kNoBound = 1e20;  // Ipopt's default nlp_upper_bound_inf

std::vector<int> range(int begin, int count) {
  std::vector<int> v(count);
  std::iota(v.begin(), v.end(), begin);
  return v;
}

// Storage position of (row, col) in a compressed column-major matrix; -1 if not stored.
int position(const SparseMatrix& A, int row, int col) {
  const int* begin = A.innerIndexPtr() + A.outerIndexPtr()[col];
  const int* end = A.innerIndexPtr() + A.outerIndexPtr()[col + 1];
  const int* it = std::lower_bound(begin, end, row);
  return (it != end && *it == row) ? static_cast<int>(it - A.innerIndexPtr()) : -1;
}

}  // namespace

FullSpaceProblem::FullSpaceProblem(Objective& objective, const ParameterScaling& scaling, const Vector& p_scale)
    : objective_(objective),
      problem_(objective.problem()),
      system_(objective.system()),
      scaling_(scaling),
      n_(objective.system().num_dofs()),
      np_(objective.num_parameters()) {
  select_measured_modes();
  set_scales(p_scale);
  find_parameter_rows(p_scale);
  build_uu_pattern();
  register_layouts();
}

/// The measured modes that are unknowns (those with a weight or a shape term), their shape
/// misfits and reference eigenvalues.
void FullSpaceProblem::select_measured_modes() {
  for (size_t m = 0; m < problem_.measured.size(); ++m) {
    const MeasuredMode& mode = problem_.measured[m];
    const bool shape = mode.has_shape_term();
    if (mode.weight <= 0 && !shape) continue;  // switched off: not an unknown at all
    measured_.push_back(static_cast<int>(m));
    shape_.push_back(shape ? std::make_unique<ShapeMisfit>(mode.shape, mode.shape_weight) : nullptr);
  }
  if (measured_.empty()) throw std::invalid_argument(problem_.path + ": every measured mode has zero weight");
  lambda_ref_.resize(num_modes());
  for (int i = 0; i < num_modes(); ++i) lambda_ref_[i] = eigenvalue_of_hz(problem_.measured[measured_[i]].frequency_hz);
}

/// K and M at the scale point, the scales of modes, masses and normalization, and the rows'
/// scaling; the sensor DOFs.
void FullSpaceProblem::set_scales(const Vector& p_scale) {
  system_.assemble(p_scale, &K_, &M_);
  const double trace = M_.diagonal().sum();
  if (!(trace > 0)) throw std::invalid_argument(problem_.path + ": the mass matrix has no positive diagonal");
  mode_scale_ = std::sqrt(trace);
  mass_scale_ = trace / n_;
  normalization_scale_ = n_;

  // Row scaling of the eigen-residuals: row a of mode i divided by (K_aa / lambda_ref,i + M_aa)
  // / m_bar, so that the diagonal of the scaled K / lambda - t M lies in (-1, 1]. Without it,
  // rows of stiff regions are 1e4-1e6 times larger than the rest: their rounding error alone
  // holds the constraint violation at 1e-8, and MUMPS miscounts the inertia.
  row_scale_.resize(num_modes());
  for (int i = 0; i < num_modes(); ++i)
    row_scale_[i] = (mass_scale_ / (K_.diagonal().array() / lambda_ref_[i] + M_.diagonal().array()).max(1e-300)).matrix();

  sensors_ = sensor_matrix(problem_, system_.dof_map());
  for (int c = 0; c < sensors_.outerSize(); ++c)
    if (sensors_.outerIndexPtr()[c + 1] > sensors_.outerIndexPtr()[c]) sensor_dofs_.push_back(c);
}

/// Structural rows of K_j, M_j: where any term depending on p_j has an entry.
void FullSpaceProblem::find_parameter_rows(const Vector& p_scale) {
  parameter_rows_.resize(np_);
  for (int j = 0; j < np_; ++j) {
    SparseMatrix dK, dM;
    system_.assemble_derivative(p_scale, j, &dK, &dM);
    std::vector<char> touched(n_, 0);
    for (const SparseMatrix* A : {&dK, &dM})
      for (int k = 0; k < A->nonZeros(); ++k)
        if (A->valuePtr()[k] != 0.0) touched[A->innerIndexPtr()[k]] = 1;
    for (int r = 0; r < n_; ++r)
      if (touched[r]) parameter_rows_[j].push_back(r);
  }
}

/// Pattern of the u~_i u~_i Hessian block: z_i M (lower) plus the dense sensor block.
void FullSpaceProblem::build_uu_pattern() {
  const SparseMatrix& pattern = system_.pattern();
  std::vector<Eigen::Triplet<double, int>> entries;
  for (int c = 0; c < pattern.outerSize(); ++c)
    for (SparseMatrix::InnerIterator it(pattern, c); it; ++it)
      if (it.row() >= c) entries.emplace_back(static_cast<int>(it.row()), c, 1.0);
  for (size_t a = 0; a < sensor_dofs_.size(); ++a)
    for (size_t b = 0; b <= a; ++b) entries.emplace_back(sensor_dofs_[a], sensor_dofs_[b], 1.0);
  uu_pattern_.resize(n_, n_);
  uu_pattern_.setFromTriplets(entries.begin(), entries.end());
  uu_pattern_.makeCompressed();
  uu_from_pattern_.assign(pattern.nonZeros(), -1);
  for (int c = 0; c < pattern.outerSize(); ++c)
    for (int k = pattern.outerIndexPtr()[c]; k < pattern.outerIndexPtr()[c + 1]; ++k)
      if (pattern.innerIndexPtr()[k] >= c) uu_from_pattern_[k] = position(uu_pattern_, pattern.innerIndexPtr()[k], c);
  uu_sensor_positions_ = Matrix::Constant(sensor_dofs_.size(), sensor_dofs_.size(), -1);
  for (size_t a = 0; a < sensor_dofs_.size(); ++a)
    for (size_t b = 0; b <= a; ++b) uu_sensor_positions_(a, b) = position(uu_pattern_, sensor_dofs_[a], sensor_dofs_[b]);
}

/// The layouts of the Jacobian and Hessian values: every block registered once, in this order.
void FullSpaceProblem::register_layouts() {
  const SparseMatrix& pattern = system_.pattern();
  const int l = num_modes(), t0 = l * n_, q0 = l * (n_ + 1);
  const std::vector<int> q_columns = range(q0, np_);
  blocks_.resize(l);
  for (int i = 0; i < l; ++i) {
    ModeBlocks& b = blocks_[i];
    b.r_u = jacobian_.add_matrix(pattern, i * n_, i * n_, SparseLayout::Triangle::All);
    b.r_t = jacobian_.add_column(range(i * n_, n_), t0 + i);
    for (int j = 0; j < np_; ++j) b.r_q.push_back(jacobian_.add_column(parameter_rows_[j], i * n_, q0 + j));
    b.n_u = jacobian_.add_row(t0 + i, range(i * n_, n_));
    b.n_q = jacobian_.add_row(t0 + i, q_columns);

    b.h_uu = hessian_.add_matrix(uu_pattern_, i * n_, i * n_, SparseLayout::Triangle::All);
    b.h_tu = hessian_.add_row(t0 + i, range(i * n_, n_));
    b.h_tt = hessian_.add_row(t0 + i, {t0 + i});
    for (int j = 0; j < np_; ++j) {
      std::vector<int> cols = parameter_rows_[j];
      for (int& c : cols) c += i * n_;
      b.h_qu.push_back(hessian_.add_row(q0 + j, std::move(cols)));
    }
    b.h_qt = hessian_.add_column(q_columns, t0 + i);
  }
  h_qq_.offset = hessian_.nonzeros();
  for (int j = 0; j < np_; ++j) h_qq_.size += hessian_.add_row(q0 + j, range(q0, j + 1)).size;}

void FullSpaceProblem::update(const double* x) {
  const Vector q = scaled_parameters(x);
  if (cached_q_.size() == q.size() && cached_q_ == q) return;
  p_ = scaling_.to_physical(q);
  dp_ = scaling_.first_derivative(q);
  d2p_ = scaling_.second_derivative(q);
  system_.assemble(p_, &K_, &M_);
  cached_q_ = q;
}

double FullSpaceProblem::shape_sign(int i, const Vector& u) const {
  const MeasuredMode& m = problem_.measured[measured_[i]];
  if (m.shape.size() == 0) return 1.0;
  return m.shape.dot(sensors_ * u) < 0 ? -1.0 : 1.0;
}

const SparseMatrix& FullSpaceProblem::mass_matrix(const double* x) {
  update(x);
  return M_;
}

const SparseMatrix& FullSpaceProblem::stiffness_matrix(const double* x) {
  update(x);
  return K_;
}

void FullSpaceProblem::set_deflation_basis(const Matrix& modes) {
  deflation_basis_ = modes;
  ++deflation_basis_version_;
}

Vector FullSpaceProblem::pack(const Matrix& modes, const Vector& eigenvalues, const Vector& p) const {
  Vector x(num_variables());
  for (int i = 0; i < num_modes(); ++i) {
    x.segment(i * n_, n_) = mode_scale_ * modes.col(i);
    x[num_modes() * n_ + i] = eigenvalues[i] / lambda_ref_[i];
  }
  x.tail(np_) = scaling_.to_scaled(p);
  return x;
}

void FullSpaceProblem::unpack(const double* x, Matrix* modes, Vector* eigenvalues, Vector* p) const {
  modes->resize(n_, num_modes());
  eigenvalues->resize(num_modes());
  for (int i = 0; i < num_modes(); ++i) {
    modes->col(i) = mode(x, i) / mode_scale_;
    (*eigenvalues)[i] = eigenvalue_ratio(x, i) * lambda_ref_[i];
  }
  *p = scaling_.to_physical(scaled_parameters(x));
}

// w^T (K - lambda M) u = y^T r with r = D s_u / (lambda_ref m_bar) (K - lambda M) u, and
// eta (u^T M u - 1) = z n with n = (u^T M u - 1) n_s / 2.
Vector FullSpaceProblem::pack_multipliers(const Matrix& w, const Vector& eta) const {
  Vector y(num_constraints());
  for (int i = 0; i < num_modes(); ++i) {
    y.segment(i * n_, n_) = w.col(i).cwiseQuotient(row_scale_[i]) * (lambda_ref_[i] * mass_scale_ / mode_scale_);
    y[num_modes() * n_ + i] = 2 * eta[i] / normalization_scale_;
  }
  return y;
}

void FullSpaceProblem::unpack_multipliers(const double* y, Matrix* w, Vector* eta) const {
  w->resize(n_, num_modes());
  eta->resize(num_modes());
  for (int i = 0; i < num_modes(); ++i) {
    w->col(i) = Eigen::Map<const Vector>(y + i * n_, n_).cwiseProduct(row_scale_[i]) *
                (mode_scale_ / (lambda_ref_[i] * mass_scale_));
    (*eta)[i] = 0.5 * y[num_modes() * n_ + i] * normalization_scale_;
  }
}

void FullSpaceProblem::locate(int index, int* mode, int* local) const {
  if (index >= parameter_offset()) {
    *mode = -1;
    *local = index - parameter_offset();
  } else if (index < num_modes() * n_) {
    *mode = index / n_;
    *local = index % n_;
  } else {
    *mode = index - num_modes() * n_;
    *local = n_;
  }
}

Vector FullSpaceProblem::mode_row_scale(int i) const {
  Vector s(n_ + 1);
  s.head(n_) = row_scale_[i] / mass_scale_;  // r_i = D (K / lambda_ref - t M) u~ / m_bar
  s[n_] = -normalization_scale_ / (mode_scale_ * mode_scale_);  // dn_i/du~ = n_s M u~ / s_u^2
  return s;
}

void FullSpaceProblem::bounds(double* lower, double* upper) const {
  const int q0 = num_modes() * (n_ + 1);
  std::fill(lower, lower + q0, -kNoBound);
  std::fill(upper, upper + q0, kNoBound);
  Vector pl(np_), pu(np_);
  for (int j = 0; j < np_; ++j) {
    pl[j] = problem_.parameters[j].lower;
    pu[j] = problem_.parameters[j].upper;
  }
  const Vector ql = scaling_.to_scaled(pl), qu = scaling_.to_scaled(pu);
  for (int j = 0; j < np_; ++j) {
    lower[q0 + j] = ql[j];
    upper[q0 + j] = qu[j];
  }
}

// R = alpha/2 |s(p(q)) - s0|^2 in the regularization variables s (the problem file's scaling):
// with phi(q) = s(p(q)), phi' = s'(p) p'(q), phi'' = s''(p) p'^2 + s'(p) p'', where
// s' = 1 / (dp/ds) and s'' = -(d2p/ds2) / (dp/ds)^3.
void FullSpaceProblem::regularization(const Vector& q, double* value, Vector* gradient, Vector* hessian) const {
  const double alpha = objective_.options().regularization;
  const ParameterScaling& reg = objective_.regularization_scaling();
  const Vector p = scaling_.to_physical(q), dp = scaling_.first_derivative(q), d2p = scaling_.second_derivative(q);
  const Vector s = reg.to_scaled(p), s0 = reg.to_scaled(problem_.initial_values());
  const Vector ds = reg.first_derivative(s), d2s = reg.second_derivative(s);
  *value = 0.5 * alpha * (s - s0).squaredNorm();
  if (gradient) gradient->resize(np_);
  if (hessian) hessian->resize(np_);
  for (int j = 0; j < np_; ++j) {
    const double s1 = 1 / ds[j], s2 = -d2s[j] / (ds[j] * ds[j] * ds[j]);
    const double phi1 = s1 * dp[j], phi2 = s2 * dp[j] * dp[j] + s1 * d2p[j];
    if (gradient) (*gradient)[j] = alpha * (s[j] - s0[j]) * phi1;
    if (hessian) (*hessian)[j] = alpha * (phi1 * phi1 + (s[j] - s0[j]) * phi2);
  }
}

double FullSpaceProblem::objective(const double* x) {
  double value = 0;
  regularization(scaled_parameters(x), &value, nullptr, nullptr);
  for (int i = 0; i < num_modes(); ++i) {
    const MeasuredMode& m = problem_.measured[measured_[i]];
    const double r = eigenvalue_ratio(x, i) - 1;  // (lambda - lambda_m) / lambda_m
    value += 0.5 * m.weight * r * r;
    if (shape_[i]) value += shape_[i]->value(sensors_ * mode(x, i));
  }
  return value;
}

void FullSpaceProblem::objective_gradient(const double* x, double* gradient) {
  Eigen::Map<Vector> g(gradient, num_variables());
  g.setZero();
  for (int i = 0; i < num_modes(); ++i) {
    const MeasuredMode& m = problem_.measured[measured_[i]];
    g[num_modes() * n_ + i] = m.weight * (eigenvalue_ratio(x, i) - 1);
    if (shape_[i]) g.segment(i * n_, n_) = sensors_.transpose() * shape_[i]->gradient(sensors_ * mode(x, i));
  }
  double value;
  Vector reg;
  regularization(scaled_parameters(x), &value, &reg, nullptr);
  g.tail(np_) = reg;
}

void FullSpaceProblem::constraints(const double* x, double* c) {
  update(x);
  for (int i = 0; i < num_modes(); ++i) {
    const auto u = mode(x, i);
    const Vector Mu = M_ * u;
    Eigen::Map<Vector>(c + i * n_, n_) =
        row_scale_[i].cwiseProduct(K_ * u / lambda_ref_[i] - eigenvalue_ratio(x, i) * Mu) / mass_scale_;
    c[num_modes() * n_ + i] = 0.5 * (u.dot(Mu) / (mode_scale_ * mode_scale_) - 1) * normalization_scale_;
  }
}

void FullSpaceProblem::jacobian_values(const double* x, double* values) {
  update(x);
  jacobian_point_ = Eigen::Map<const Vector>(x, num_variables());
  const double s2 = mode_scale_ * mode_scale_;
  for (int i = 0; i < num_modes(); ++i) {
    const ModeBlocks& b = blocks_[i];
    const auto u = mode(x, i);
    const double t = eigenvalue_ratio(x, i), lambda = lambda_ref_[i];
    const Vector& D = row_scale_[i];
    // K and M share pattern(): their value arrays are aligned with the r_u block.
    for (int k = 0; k < b.r_u.size; ++k)
      values[b.r_u.offset + k] =
          D[K_.innerIndexPtr()[k]] * (K_.valuePtr()[k] / lambda - t * M_.valuePtr()[k]) / mass_scale_;
    const Vector Mu = M_ * u;
    Eigen::Map<Vector>(values + b.r_t.offset, n_) = -D.cwiseProduct(Mu) / mass_scale_;
    Eigen::Map<Vector>(values + b.n_u.offset, n_) = Mu / s2 * normalization_scale_;
    for (int j = 0; j < np_; ++j) {
      Vector dKu, dMu;
      system_.derivative_times(p_, j, u, &dKu, &dMu);
      const Vector column = D.cwiseProduct(dKu / lambda - t * dMu) * (dp_[j] / mass_scale_);
      const std::vector<int>& rows = parameter_rows_[j];
      for (size_t k = 0; k < rows.size(); ++k) values[b.r_q[j].offset + k] = column[rows[k]];
      values[b.n_q.offset + j] = 0.5 * u.dot(dMu) / s2 * dp_[j] * normalization_scale_;
    }
  }
}

void FullSpaceProblem::hessian_values(const double* x, double sigma, const double* y, double* values) {
  update(x);
  const double s2 = mode_scale_ * mode_scale_;
  const bool affine = system_.is_affine();
  Matrix Hqq = Matrix::Zero(np_, np_);
  for (int i = 0; i < num_modes(); ++i) {
    const ModeBlocks& b = blocks_[i];
    const MeasuredMode& m = problem_.measured[measured_[i]];
    const auto u = mode(x, i);
    const Vector yr = row_scale_[i].cwiseProduct(Eigen::Map<const Vector>(y + i * n_, n_));  // D y
    const double z = y[num_modes() * n_ + i] * normalization_scale_;  // multiplier of (u^T M u / s^2 - 1) / 2
    const double t = eigenvalue_ratio(x, i), lambda = lambda_ref_[i];

    double* uu = values + b.h_uu.offset;
    std::fill(uu, uu + b.h_uu.size, 0.0);
    for (size_t k = 0; k < uu_from_pattern_.size(); ++k)
      if (uu_from_pattern_[k] >= 0) uu[uu_from_pattern_[k]] += z / s2 * M_.valuePtr()[k];
    if (shape_[i] && sigma != 0) {
      // P^T H_y P restricted to the sensor DOFs (dense, small).
      const Matrix Hy = sigma * shape_[i]->hessian(sensors_ * u);
      Matrix P(sensors_.rows(), sensor_dofs_.size());
      for (size_t a = 0; a < sensor_dofs_.size(); ++a) P.col(a) = sensors_.col(sensor_dofs_[a]);
      const Matrix H = P.transpose() * Hy * P;
      for (int a = 0; a < H.rows(); ++a)
        for (int c = 0; c <= a; ++c) uu[static_cast<int>(uu_sensor_positions_(a, c))] += H(a, c);
    }
    Eigen::Map<Vector>(values + b.h_tu.offset, n_) = -(M_ * yr) / mass_scale_;
    values[b.h_tt.offset] = sigma * m.weight;
    for (int j = 0; j < np_; ++j) {
      Vector dKu, dMu, dKy, dMy;
      system_.derivative_times(p_, j, u, &dKu, &dMu);
      system_.derivative_times(p_, j, yr, &dKy, &dMy);
      const Vector row = (dKy / lambda - t * dMy) * (dp_[j] / mass_scale_) + z / s2 * dp_[j] * dMu;
      const std::vector<int>& rows = parameter_rows_[j];
      for (size_t k = 0; k < rows.size(); ++k) values[b.h_qu[j].offset + k] = row[rows[k]];
      values[b.h_qt.offset + j] = -yr.dot(dMu) / mass_scale_ * dp_[j];
    }
    // q-q: second derivatives of the constraint terms in p, then the chain rule through p(q).
    Vector a, bm, au, bu;
    system_.derivative_forms(p_, yr, u, &a, &bm);
    system_.derivative_forms(p_, u, u, &au, &bu);
    const Vector first = (a / lambda - t * bm) / mass_scale_ + 0.5 * z / s2 * bu;
    for (int j = 0; j < np_; ++j) Hqq(j, j) += first[j] * d2p_[j];
    if (!affine) {
      Matrix A, B, Au, Bu;
      system_.second_derivative_forms(p_, yr, u, &A, &B);
      system_.second_derivative_forms(p_, u, u, &Au, &Bu);
      const Matrix second = (A / lambda - t * B) / mass_scale_ + 0.5 * z / s2 * Bu;
      Hqq += dp_.asDiagonal() * second * dp_.asDiagonal();
    }
  }
  double value;
  Vector reg_hessian;
  regularization(scaled_parameters(x), &value, nullptr, &reg_hessian);
  Hqq.diagonal() += sigma * reg_hessian;
  int k = h_qq_.offset;
  for (int j = 0; j < np_; ++j)
    for (int c = 0; c <= j; ++c) values[k++] = Hqq(j, c);
}

}  // namespace modalcal::detail
