#include "fullspace/block_kkt.hpp"

#include <stdexcept>

namespace modalcal::detail {

BlockKktSystem::BlockKktSystem(FullSpaceProblem& problem)
    : problem_(problem), n_(problem.num_dofs()), l_(problem.num_modes()), np_(problem.num_parameters()) {
  auto read = [](const SparseLayout& layout, std::vector<int>* rows, std::vector<int>* cols, std::vector<Slot>* slots) {
    rows->resize(layout.nonzeros());
    cols->resize(layout.nonzeros());
    layout.structure(rows->data(), cols->data());
    slots->resize(layout.nonzeros());
  };
  read(problem.jacobian_layout(), &jac_rows_, &jac_cols_, &jac_slots_);
  for (size_t k = 0; k < jac_slots_.size(); ++k) {
    Slot& s = jac_slots_[k];
    int row_mode, col_mode;
    problem.locate(jac_rows_[k], &row_mode, &s.row);
    problem.locate(jac_cols_[k], &col_mode, &s.col);
    s.mode = row_mode;
    if (col_mode == -1)
      s.kind = Slot::ParameterColumn;
    else if (col_mode != row_mode)
      throw std::logic_error("BlockKktSystem: the constraint Jacobian couples two modes");
  }
  read(problem.hessian_layout(), &hes_rows_, &hes_cols_, &hes_slots_);
  for (size_t k = 0; k < hes_slots_.size(); ++k) {
    Slot& s = hes_slots_[k];
    int row_mode, col_mode, row, col;
    problem.locate(hes_rows_[k], &row_mode, &row);
    problem.locate(hes_cols_[k], &col_mode, &col);
    if (row_mode == -1 && col_mode == -1) {
      s = {-1, row, col, Slot::ParameterPair};
    } else if (row_mode == -1 || col_mode == -1) {  // C_i(local unknown, parameter)
      s = {row_mode == -1 ? col_mode : row_mode, row_mode == -1 ? col : row, row_mode == -1 ? row : col,
           Slot::ParameterColumn};
    } else if (row_mode == col_mode) {
      s = {row_mode, row, col, Slot::ModeBlock};
    } else {
      throw std::logic_error("BlockKktSystem: the Lagrangian Hessian couples two modes");
    }
  }
  // Each mode's entries, so that build() holds one mode's blocks at a time.
  jac_entries_.resize(l_);
  hes_entries_.resize(l_);
  for (size_t k = 0; k < jac_slots_.size(); ++k) jac_entries_[jac_slots_[k].mode].push_back(static_cast<int>(k));
  for (size_t k = 0; k < hes_slots_.size(); ++k)
    (hes_slots_[k].kind == Slot::ParameterPair ? parameter_pairs_ : hes_entries_[hes_slots_[k].mode])
        .push_back(static_cast<int>(k));
  jac_values_.resize(jac_slots_.size());
  hes_values_.resize(hes_slots_.size());
  modes_.resize(l_);
  mode_index_.assign(l_, 0);
}

bool BlockKktSystem::build(const Vector& x, const Vector& y, std::string* error) {
  const int nv = problem_.num_variables();
  objective_gradient_.resize(nv);
  problem_.objective_gradient(x.data(), objective_gradient_.data());
  constraints_.resize(problem_.num_constraints());
  problem_.constraints(x.data(), constraints_.data());
  problem_.jacobian_values(x.data(), jac_values_.data());
  problem_.hessian_values(x.data(), 1.0, y.data(), hes_values_.data());
  lagrangian_gradient_ = objective_gradient_;
  for (size_t k = 0; k < jac_values_.size(); ++k) lagrangian_gradient_[jac_cols_[k]] += jac_values_[k] * y[jac_rows_[k]];

  reduced_hessian_ = Matrix::Zero(np_, np_);  // W_qq, then the Schur complement
  for (int k : parameter_pairs_) {
    const Slot& s = hes_slots_[k];
    reduced_hessian_(s.row, s.col) += hes_values_[k];
    if (s.row != s.col) reduced_hessian_(s.col, s.row) += hes_values_[k];
  }
  reduced_rhs_ = -lagrangian_gradient_.tail(np_);
  for (int i = 0; i < l_; ++i) {
    // Mode i's blocks: B_i = diag(s_i)^{-1} A_i (symmetric: its lower triangle suffices), P_i,
    // W_i (both triangles) and C_i.
    const Vector s = problem_.mode_row_scale(i);
    std::vector<Eigen::Triplet<double, int>> entries;
    Matrix P = Matrix::Zero(n_ + 1, np_), C = Matrix::Zero(n_ + 1, np_);
    for (int k : jac_entries_[i]) {
      const Slot& slot = jac_slots_[k];
      if (slot.kind == Slot::ParameterColumn)
        P(slot.row, slot.col) = jac_values_[k];
      else if (slot.row >= slot.col)
        entries.emplace_back(slot.row, slot.col, jac_values_[k] / s[slot.row]);
    }
    SparseMatrix B(n_ + 1, n_ + 1), W(n_ + 1, n_ + 1);
    B.setFromTriplets(entries.begin(), entries.end());
    entries.clear();
    for (int k : hes_entries_[i]) {
      const Slot& slot = hes_slots_[k];
      const double v = hes_values_[k];
      if (slot.kind == Slot::ParameterColumn) {
        C(slot.row, slot.col) += v;
      } else {
        entries.emplace_back(slot.row, slot.col, v);
        if (slot.row != slot.col) entries.emplace_back(slot.col, slot.row, v);
      }
    }
    W.setFromTriplets(entries.begin(), entries.end());
    entries = {};
    std::string why;
    if (!factor_.factor(B, &why)) {
      if (error)
        *error = "full-space mode " + std::to_string(i + 1) +
                 ": the bordered matrix [[K - lambda M, -M u], [-(M u)^T, 0]] could not be factored (" + why +
                 "): lambda_i is a repeated eigenvalue, or u_i is M-orthogonal to the eigenvector it should approach";
      return false;
    }
    mode_index_[i] = factor_.negative_pivots();
    Vector c_i(n_ + 1), g_i(n_ + 1);
    for (int a = 0; a <= n_; ++a) {
      c_i[a] = constraints_[problem_.mode_entry(i, a)];
      g_i[a] = lagrangian_gradient_[problem_.mode_entry(i, a)];
    }
    // A_i z = f  <=>  B_i z = f / s.
    Matrix& aS = modes_[i].a_S;
    aS.resize(n_ + 1, np_ + 1);
    aS.col(0) = -c_i;
    aS.rightCols(np_) = P;
    aS = s.cwiseInverse().asDiagonal() * aS;
    factor_.solve(&aS);
    // A_i^T w = f  <=>  B_i (s w) = f.
    const Matrix WaS = W * aS;
    Matrix& bT = modes_[i].b_T;
    bT.resize(n_ + 1, np_ + 1);
    bT.col(0) = -g_i - WaS.col(0);
    bT.rightCols(np_) = C - WaS.rightCols(np_);
    factor_.solve(&bT);
    bT = s.cwiseInverse().asDiagonal() * bT;

    const auto a = aS.col(0);
    const auto S = aS.rightCols(np_);
    const Matrix CtS = C.transpose() * S;
    reduced_hessian_ -= CtS + CtS.transpose() - S.transpose() * WaS.rightCols(np_);
    reduced_rhs_ -= C.transpose() * a + P.transpose() * bT.col(0);
  }
  reduced_hessian_ = 0.5 * (reduced_hessian_ + reduced_hessian_.transpose());
  return true;
}

void BlockKktSystem::step(const Vector& dq, Vector* dx, Vector* dy) const {
  dx->resize(problem_.num_variables());
  dy->resize(problem_.num_constraints());
  for (int i = 0; i < l_; ++i) {
    const Vector xi = modes_[i].a_S.col(0) - modes_[i].a_S.rightCols(np_) * dq;
    const Vector yi = modes_[i].b_T.col(0) - modes_[i].b_T.rightCols(np_) * dq;
    for (int a = 0; a <= n_; ++a) {
      (*dx)[problem_.mode_entry(i, a)] = xi[a];
      (*dy)[problem_.mode_entry(i, a)] = yi[a];
    }
  }
  dx->tail(np_) = dq;
}

}  // namespace modalcal::detail
