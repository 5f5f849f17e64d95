#pragma once
// Internal: sparse symmetric indefinite LDL^T factorization by MUMPS (sequential, the build Ipopt
// uses). CHOLMOD factors only definite matrices; the bordered eigen-blocks
// [[K - lambda M, -M u], [-(M u)^T, 0]] of the block Newton solver are indefinite and need
// threshold pivoting, which MUMPS does with BLAS-3 fronts.

#include <memory>
#include <string>

#include "modalcal/types.hpp"

namespace modalcal::detail {

class MumpsSymmetricFactor {
 public:
  MumpsSymmetricFactor();
  ~MumpsSymmetricFactor();
  MumpsSymmetricFactor(const MumpsSymmetricFactor&) = delete;
  MumpsSymmetricFactor& operator=(const MumpsSymmetricFactor&) = delete;

  /// Analyses and factors the symmetric matrix whose lower triangle (row >= column) is `lower`
  /// (entries above the diagonal are ignored). Returns false with `error` naming MUMPS's code and
  /// its likely cause (singular, out of memory).
  bool factor(const SparseMatrix& lower, std::string* error);
  /// MUMPS's relative pivot threshold CNTL(1) for later factorizations (default: MUMPS's, 0.01
  /// for symmetric matrices). Larger values count the inertia of saddle-point matrices more
  /// reliably at the price of more delayed pivots. Range: [0, 0.5].
  void set_pivot_threshold(double threshold);
  /// Number of negative pivots of the last factorization (the inertia, Sylvester).
  int negative_pivots() const;
  /// Entries of the factors of the last factorization (INFOG(29)), for memory reports.
  double factor_entries() const;
  /// Solves A X = B for every column of B, in place.
  void solve(Matrix* rhs);

 private:
  struct State;
  std::unique_ptr<State> state_;
};

}  // namespace modalcal::detail
