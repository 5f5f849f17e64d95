#pragma once
// Internal: a CHOLMOD supernodal Cholesky factorization of K - sigma M on a fixed pattern.
// The symbolic analysis is done once per pattern; each factorize() is numeric only.

#include <cholmod.h>

#include <string>

#include "modalcal/types.hpp"

namespace modalcal::detail {

class CholmodFactor {
 public:
  explicit CholmodFactor(const SparseMatrix& pattern);
  ~CholmodFactor();
  CholmodFactor(const CholmodFactor&) = delete;
  CholmodFactor& operator=(const CholmodFactor&) = delete;

  /// Numeric factorization of K - sigma M. Returns false (with the failing column in
  /// *failed_column) if the matrix is not positive definite.
  bool factorize(const SparseMatrix& K, const SparseMatrix& M, double sigma, int* failed_column);
  /// x = (K - sigma M)^{-1} b for one right-hand side.
  void solve(const double* b, double* x) const;
  /// X = (K - sigma M)^{-1} B for a block of right-hand sides (cheaper per column).
  Matrix solve(const Matrix& B) const;
  int rows() const { return n_; }
  double seconds_analyze() const { return seconds_analyze_; }
  /// Nonzeros of the factor L, for memory reports.
  double factor_nonzeros() const;

 private:
  cholmod_sparse view();
  int n_;
  SparseMatrix shifted_;  // K - sigma M on the common pattern
  mutable cholmod_common common_;
  cholmod_factor* factor_ = nullptr;
  mutable cholmod_dense* x_ = nullptr;   // reused solve workspaces
  mutable cholmod_dense* y_ = nullptr;
  mutable cholmod_dense* e_ = nullptr;
  double seconds_analyze_ = 0;
};

}  // namespace modalcal::detail
