#include "eigen/cholmod_factor.hpp"

#include <chrono>
#include <cstring>
#include <stdexcept>

#if defined(MODALCAL_CHOLMOD_OPENMP) && __has_include(<omp.h>)
#include <omp.h>
#define MODALCAL_SERIAL_OPENMP_REGIONS 1
#endif

namespace modalcal::detail {

namespace {

/// CHOLMOD (SuiteSparse 5, as Debian 12 builds it) runs parts of its supernodal factorization in
/// OpenMP regions of a fixed four threads (CHOLMOD_OMP_NUM_THREADS, fixed when it was compiled; no
/// environment variable but OMP_THREAD_LIMIT changes it). Beside the threads the tool runs itself,
/// and on fewer cores than four, those regions cost more than they give: on two cores, the
/// forward solve at 6.6e4 DOFs took 3.06 s with them and 2.53 s without, at 3.1e5 DOFs 26.8 s
/// and 26.5 s, and an LFU diagnosis spent a tenth of its CPU time waking their threads
/// (docs/benchmarks.md, "CHOLMOD's OpenMP regions"). So a factorization runs them in the calling
/// thread: a maximum of 0 active levels makes every parallel region inactive. The setting is the
/// calling thread's own, and is restored afterwards, so a caller's own OpenMP code is left alone.
class SerialOpenMpRegions {
 public:
#ifdef MODALCAL_SERIAL_OPENMP_REGIONS
  SerialOpenMpRegions() : levels_(omp_get_max_active_levels()) { omp_set_max_active_levels(0); }
  ~SerialOpenMpRegions() { omp_set_max_active_levels(levels_); }

 private:
  int levels_;
#else
  SerialOpenMpRegions() {}  // no OpenMP runtime found: CHOLMOD has no regions to keep serial
#endif
};

double seconds_since(std::chrono::steady_clock::time_point t0) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
}

cholmod_dense dense_view(int rows, int cols, const double* data) {
  cholmod_dense d;
  std::memset(&d, 0, sizeof(d));
  d.nrow = rows;
  d.ncol = cols;
  d.nzmax = static_cast<size_t>(rows) * cols;
  d.d = rows;
  d.x = const_cast<double*>(data);
  d.xtype = CHOLMOD_REAL;
  d.dtype = CHOLMOD_DOUBLE;
  return d;
}
}  // namespace

CholmodFactor::CholmodFactor(const SparseMatrix& pattern) : n_(static_cast<int>(pattern.rows())), shifted_(pattern) {
  if (pattern.rows() != pattern.cols() || !pattern.isCompressed())
    throw std::invalid_argument("CholmodFactor: the pattern must be square and compressed");
  cholmod_start(&common_);
  common_.supernodal = CHOLMOD_SUPERNODAL;
  common_.print = 0;
  common_.error_handler = nullptr;
  const auto t0 = std::chrono::steady_clock::now();
  cholmod_sparse A = view();
  const SerialOpenMpRegions serial;
  factor_ = cholmod_analyze(&A, &common_);
  seconds_analyze_ = seconds_since(t0);
  if (!factor_) {
    cholmod_finish(&common_);
    throw std::runtime_error("CHOLMOD symbolic analysis failed (status " + std::to_string(common_.status) +
                             "): out of memory?");
  }
}

CholmodFactor::~CholmodFactor() {
  cholmod_free_factor(&factor_, &common_);
  cholmod_free_dense(&x_, &common_);
  cholmod_free_dense(&y_, &common_);
  cholmod_free_dense(&e_, &common_);
  cholmod_finish(&common_);
}

// CHOLMOD reads only the upper triangle (stype = 1) of our symmetric full storage.
cholmod_sparse CholmodFactor::view() {
  cholmod_sparse A;
  std::memset(&A, 0, sizeof(A));
  A.nrow = shifted_.rows();
  A.ncol = shifted_.cols();
  A.nzmax = shifted_.nonZeros();
  A.p = shifted_.outerIndexPtr();
  A.i = shifted_.innerIndexPtr();
  A.x = shifted_.valuePtr();
  A.stype = 1;
  A.itype = CHOLMOD_INT;
  A.xtype = CHOLMOD_REAL;
  A.dtype = CHOLMOD_DOUBLE;
  A.sorted = 1;
  A.packed = 1;
  return A;
}

bool CholmodFactor::factorize(const SparseMatrix& K, const SparseMatrix& M, double sigma, int* failed_column) {
  if (K.nonZeros() != shifted_.nonZeros() || M.nonZeros() != shifted_.nonZeros())
    throw std::invalid_argument("CholmodFactor: K and M must have the analysed pattern");
  const double* k = K.valuePtr();
  const double* m = M.valuePtr();
  double* a = shifted_.valuePtr();
  for (Eigen::Index i = 0; i < shifted_.nonZeros(); ++i) a[i] = k[i] - sigma * m[i];
  cholmod_sparse A = view();
  const SerialOpenMpRegions serial;
  cholmod_factorize(&A, factor_, &common_);
  const bool ok = common_.status == CHOLMOD_OK && factor_->minor == static_cast<size_t>(n_);
  if (failed_column) *failed_column = ok ? -1 : static_cast<int>(factor_->minor);
  return ok;
}

void CholmodFactor::solve(const double* b, double* x) const {
  cholmod_dense B = dense_view(n_, 1, b);
  cholmod_solve2(CHOLMOD_A, factor_, &B, nullptr, &x_, nullptr, &y_, &e_, &common_);
  std::memcpy(x, x_->x, sizeof(double) * n_);
}

Matrix CholmodFactor::solve(const Matrix& B) const {
  cholmod_dense view_b = dense_view(n_, static_cast<int>(B.cols()), B.data());
  cholmod_solve2(CHOLMOD_A, factor_, &view_b, nullptr, &x_, nullptr, &y_, &e_, &common_);
  return Eigen::Map<const Matrix>(static_cast<const double*>(x_->x), n_, B.cols());
}

double CholmodFactor::factor_nonzeros() const {
  if (!factor_->is_super) return static_cast<double>(factor_->nzmax);
  return static_cast<double>(factor_->xsize);
}

}  // namespace modalcal::detail
