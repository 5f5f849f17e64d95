#include "fullspace/block_kkt.hpp"

#include <stdexcept>

namespace modalcal::detail {

BlockKktSystem::BlockKktSystem(FullSpaceProblem& problem, bool shared_factorization)
    : problem_(problem),
      n_(problem.num_dofs()),
      l_(problem.num_modes()),
      np_(problem.num_parameters()),
      elimination_(problem.num_modes(), problem.num_parameters(), /*keep_factors=*/false),
      shared_factorization_(shared_factorization) {
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

  Matrix parameter_hessian = Matrix::Zero(np_, np_);
  for (int k : parameter_pairs_) {
    const Slot& s = hes_slots_[k];
    parameter_hessian(s.row, s.col) += hes_values_[k];
    if (s.row != s.col) parameter_hessian(s.col, s.row) += hes_values_[k];
  }
  const Vector parameter_rhs = -lagrangian_gradient_.tail(np_);
  SharedShiftSolver* shared = nullptr;
  if (shared_factorization_) {
    if (!shared_) shared_ = std::make_unique<SharedShiftSolver>();
    if (update_shared_shift_solver(problem_, x.data(), shared_.get(), nullptr))
      shared = shared_.get();
    else
      elimination_.count_shared_failures(l_);  // every mode factored
  }
  elimination_.begin(parameter_hessian, &parameter_rhs, shared);
  for (int i = 0; i < l_; ++i) {
    Vector f(n_ + 1), e(n_ + 1);  // the right-hand side: -g_i, -c_i
    for (int a = 0; a <= n_; ++a) {
      e[a] = -constraints_[problem_.mode_entry(i, a)];
      f[a] = -lagrangian_gradient_[problem_.mode_entry(i, a)];
    }
    std::string why;
    if (!elimination_.add_mode(i, mode_blocks(i), &f, &e, &why)) {
      if (error)
        *error = "full-space mode " + std::to_string(i + 1) +
                 ": the bordered matrix [[K - lambda M, -M u], [-(M u)^T, 0]] could not be factored (" + why +
                 "): lambda_i is a repeated eigenvalue, or u_i is M-orthogonal to the eigenvector it should approach";
      return false;
    }
    mode_index_[i] = elimination_.negative_pivots(i);
  }
  return true;
}

ModeKktBlocks BlockKktSystem::mode_blocks(int i) const {
  // B_i = diag(s_i)^{-1} A_i (symmetric: its lower triangle suffices), P_i, W_i (both triangles)
  // and C_i.
  ModeKktBlocks blocks;
  blocks.row_scale = problem_.mode_row_scale(i);
  std::vector<Eigen::Triplet<double, int>> entries;
  blocks.jacobian_parameters = Matrix::Zero(n_ + 1, np_);
  blocks.hessian_parameters = Matrix::Zero(n_ + 1, np_);
  for (int k : jac_entries_[i]) {
    const Slot& slot = jac_slots_[k];
    if (slot.kind == Slot::ParameterColumn)
      blocks.jacobian_parameters(slot.row, slot.col) = jac_values_[k];
    else if (slot.row >= slot.col)
      entries.emplace_back(slot.row, slot.col, jac_values_[k] / blocks.row_scale[slot.row]);
  }
  blocks.bordered.resize(n_ + 1, n_ + 1);
  blocks.bordered.setFromTriplets(entries.begin(), entries.end());
  entries.clear();
  for (int k : hes_entries_[i]) {
    const Slot& slot = hes_slots_[k];
    const double v = hes_values_[k];
    if (slot.kind == Slot::ParameterColumn) {
      blocks.hessian_parameters(slot.row, slot.col) += v;
    } else {
      entries.emplace_back(slot.row, slot.col, v);
      if (slot.row != slot.col) entries.emplace_back(slot.col, slot.row, v);
    }
  }
  blocks.hessian.resize(n_ + 1, n_ + 1);
  blocks.hessian.setFromTriplets(entries.begin(), entries.end());
  return blocks;
}

void BlockKktSystem::step(const Vector& dq, Vector* dx, Vector* dy) const {
  dx->resize(problem_.num_variables());
  dy->resize(problem_.num_constraints());
  Vector xi, yi;
  for (int i = 0; i < l_; ++i) {
    elimination_.expand(i, dq, &xi, &yi);
    for (int a = 0; a <= n_; ++a) {
      (*dx)[problem_.mode_entry(i, a)] = xi[a];
      (*dy)[problem_.mode_entry(i, a)] = yi[a];
    }
  }
  dx->tail(np_) = dq;
}

}  // namespace modalcal::detail
