#include "fullspace/block_elimination.hpp"

#include <stdexcept>

#include "eigen/block_lanczos.hpp"  // symmetric_times: W_i is stored in full
#include "fullspace/shared_shift_solve.hpp"

namespace modalcal::detail {

BlockElimination::BlockElimination(int num_modes, int num_parameters, bool keep_factors)
    : np_(num_parameters), keep_factors_(keep_factors), modes_(num_modes), negative_pivots_(num_modes, 0) {
  if (!keep_factors_) one_factor_ = std::make_unique<MumpsSymmetricFactor>();
}

BlockElimination::~BlockElimination() = default;

void BlockElimination::begin(const Matrix& parameter_hessian, const Vector* parameter_rhs, SharedShiftSolver* shared) {
  shared_ = shared;
  reduced_hessian_ = parameter_hessian;
  added_ = 0;
  has_rhs_ = parameter_rhs != nullptr;
  reduced_rhs_ = has_rhs_ ? *parameter_rhs : Vector();
}

bool BlockElimination::eliminate(const ModeKktBlocks& blocks, const BorderedSolve& solve_bordered, Matrix* right,
                                 Matrix* left, const std::function<Matrix(const Matrix&)>& hessian_product,
                                 Matrix* reduction) {
  // A z = e <=> B z = e / s;  A^T w = g <=> B (s w) = g.
  const Vector inverse_scale = blocks.row_scale.cwiseInverse();
  *right = inverse_scale.asDiagonal() * (*right);
  if (!solve_bordered(right)) return false;
  *left -= hessian_product ? hessian_product(*right) : symmetric_times(blocks.hessian, *right);
  if (!solve_bordered(left)) return false;
  *left = inverse_scale.asDiagonal() * (*left);
  // With right = [a, S] and left = [b, T]: C^T S + P^T T = C^T S + S^T (C - W S) (as T = A^{-T}
  // (C - W S) and P = A S), the mode's part of H; C^T a + P^T b its part of h.
  *reduction = blocks.hessian_parameters.transpose() * (*right) + blocks.jacobian_parameters.transpose() * (*left);
  return true;
}

BlockElimination::BorderedSolve BlockElimination::bordered_solve(int i) {
  Mode& mode = modes_[i];
  if (mode.shared) return [this, i](Matrix* x) { return shared_->solve(i, x, nullptr); };
  MumpsSymmetricFactor* factor = keep_factors_ ? mode.factor.get() : one_factor_.get();
  return [factor](Matrix* x) {
    factor->solve(x);
    return true;
  };
}

bool BlockElimination::add_mode(int i, ModeKktBlocks blocks, const Vector* f, const Vector* e, std::string* error) {
  Mode& mode = modes_[i];
  const int n1 = static_cast<int>(blocks.row_scale.size());
  const int rhs = has_rhs_ && f && e ? 1 : 0;
  Matrix right(n1, rhs + np_), left(n1, rhs + np_), reduction;
  auto fill = [&] {
    if (rhs) {
      right.col(0) = *e;
      left.col(0) = *f;
    }
    right.rightCols(np_) = blocks.jacobian_parameters;
    left.rightCols(np_) = blocks.hessian_parameters;
  };
  fill();
  mode.shared = shared_ && shared_->agrees_with(i, blocks.bordered);
  if (mode.shared && eliminate(blocks, bordered_solve(i), &right, &left, {}, &reduction)) {
    ++shared_eliminations_;
    negative_pivots_[i] = shared_->negative_eigenvalues(i);
    mode.factor.reset();
  } else {
    if (mode.shared) ++shared_failures_;
    if (!factor_bordered(i, blocks.bordered, error)) return false;
    fill();
    eliminate(blocks, bordered_solve(i), &right, &left, {}, &reduction);
  }
  reduced_hessian_ -= reduction.rightCols(np_);
  mode.S = right.rightCols(np_);
  mode.T = left.rightCols(np_);
  if (rhs) {
    reduced_rhs_ -= reduction.col(0);
    mode.a = right.col(0);
    mode.b = left.col(0);
  }
  if (++added_ == static_cast<int>(modes_.size())) reduced_hessian_ = 0.5 * (reduced_hessian_ + reduced_hessian_.transpose());
  if (keep_factors_) {
    release(&blocks.bordered);  // in the factor now, or not needed
    mode.blocks = std::move(blocks);  // a swap: the previous blocks leave with the argument
  }
  return true;
}

void BlockElimination::expand(int i, const Vector& dq, Vector* dx, Vector* dy) const {
  const Mode& mode = modes_[i];
  *dx = mode.a - mode.S * dq;
  *dy = mode.b - mode.T * dq;
}

void BlockElimination::solve(std::vector<Matrix>* f, std::vector<Matrix>* e, Matrix* fq,
                             const std::function<void(Matrix*)>& solve_reduced,
                             const std::function<Matrix(int, const Matrix&)>& hessian_product,
                             const std::function<SparseMatrix(int)>& bordered_block) {
  if (!keep_factors_) throw std::logic_error("BlockElimination::solve without kept factors");
  for (size_t i = 0; i < modes_.size(); ++i) {
    const int mode = static_cast<int>(i);
    std::function<Matrix(const Matrix&)> product;
    if (modes_[i].blocks.hessian.size() == 0) {
      if (!hessian_product) throw std::logic_error("BlockElimination::solve: W_i released and no product given");
      product = [&, mode](const Matrix& v) { return hessian_product(mode, v); };
    }
    Matrix reduction;  // e_i -> a_i, f_i -> b_i
    const Matrix e_given = modes_[i].shared ? (*e)[i] : Matrix(), f_given = modes_[i].shared ? (*f)[i] : Matrix();
    if (!eliminate(modes_[i].blocks, bordered_solve(mode), &(*e)[i], &(*f)[i], product, &reduction)) {
      // The shared solves fell short on these right-hand sides: factor B_i after all.
      ++shared_failures_;
      std::string why;
      if (!bordered_block || !factor_bordered(mode, bordered_block(mode), &why))
        throw std::runtime_error("full-space mode " + std::to_string(mode + 1) + ": " + why);
      (*e)[i] = e_given;
      (*f)[i] = f_given;
      eliminate(modes_[i].blocks, bordered_solve(mode), &(*e)[i], &(*f)[i], product, &reduction);
    }
    *fq -= reduction;
  }
  solve_reduced(fq);
  for (size_t i = 0; i < modes_.size(); ++i) {
    Matrix& a = (*e)[i];
    Matrix& b = (*f)[i];
    a -= modes_[i].S * (*fq);  // dx_i
    b -= modes_[i].T * (*fq);  // dy_i
    a.swap(b);                 // f_i <- dx_i, e_i <- dy_i
  }
}

bool BlockElimination::factor_bordered(int i, const SparseMatrix& bordered, std::string* error) {
  Mode& mode = modes_[i];
  mode.shared = false;
  if (keep_factors_ && !mode.factor) mode.factor = std::make_unique<MumpsSymmetricFactor>();
  MumpsSymmetricFactor& factor = keep_factors_ ? *mode.factor : *one_factor_;
  if (!factor.factor(bordered, error)) return false;
  negative_pivots_[i] = factor.negative_pivots();
  return true;
}

}  // namespace modalcal::detail
