#include "fullspace/mumps_factor.hpp"

#include <dmumps_c.h>

#include <cstdint>
#include <stdexcept>
#include <vector>

namespace modalcal::detail {

namespace {
constexpr MUMPS_INT kUseCommWorld = -987654;  // MUMPS's convention for the sequential library
// MUMPS's 1-based ICNTL/INFOG numbering, as its manual writes them.
MUMPS_INT& icntl(DMUMPS_STRUC_C& id, int k) { return id.icntl[k - 1]; }
MUMPS_INT infog(const DMUMPS_STRUC_C& id, int k) { return id.infog[k - 1]; }
}  // namespace

struct MumpsSymmetricFactor::State {
  DMUMPS_STRUC_C id{};
  bool initialized = false, analyzed = false, factored = false;
  // The matrix in MUMPS's coordinate form: read by the analysis and the factorization only (the
  // solves use the factors: no iterative refinement, ICNTL(10) = 0), so it is released once
  // factored, and the pattern is remembered by a fingerprint. A factorization kept per mode, as
  // Ipopt's structured KKT solver keeps them, would otherwise hold a second copy of its block.
  std::vector<MUMPS_INT> rows, cols;
  std::vector<double> values;
  std::uint64_t pattern = 0;
};

namespace {
/// FNV-1a over the coordinate pattern: equal patterns, equal fingerprints.
std::uint64_t fingerprint(MUMPS_INT n, const std::vector<MUMPS_INT>& rows, const std::vector<MUMPS_INT>& cols) {
  std::uint64_t h = 1469598103934665603ULL;
  auto mix = [&](std::uint64_t v) {
    h ^= v;
    h *= 1099511628211ULL;
  };
  mix(static_cast<std::uint64_t>(n));
  mix(rows.size());
  for (size_t k = 0; k < rows.size(); ++k) mix((static_cast<std::uint64_t>(rows[k]) << 32) ^ static_cast<std::uint32_t>(cols[k]));
  return h;
}
}  // namespace

MumpsSymmetricFactor::MumpsSymmetricFactor() : state_(std::make_unique<State>()) {
  DMUMPS_STRUC_C& id = state_->id;
  id.comm_fortran = kUseCommWorld;
  id.par = 1;
  id.sym = 2;  // general symmetric: LDL^T with 1x1 and 2x2 pivots
  id.job = -1;
  dmumps_c(&id);
  if (infog(id, 1) < 0) throw std::runtime_error("MUMPS initialization failed (INFOG(1) = " +
                                                 std::to_string(infog(id, 1)) + ")");
  state_->initialized = true;
  icntl(id, 1) = -1;  // errors, diagnostics, global information, print level: silent; the
  icntl(id, 2) = -1;  // caller reports failures with INFOG
  icntl(id, 3) = -1;
  icntl(id, 4) = 0;
}

MumpsSymmetricFactor::~MumpsSymmetricFactor() {
  if (!state_->initialized) return;
  state_->id.job = -2;
  dmumps_c(&state_->id);
}

bool MumpsSymmetricFactor::factor(const SparseMatrix& lower, std::string* error) {
  State& s = *state_;
  DMUMPS_STRUC_C& id = s.id;
  s.rows.clear();
  s.cols.clear();
  s.values.clear();
  for (int c = 0; c < lower.outerSize(); ++c)
    for (SparseMatrix::InnerIterator it(lower, c); it; ++it)
      if (it.row() >= c) {
        s.rows.push_back(static_cast<MUMPS_INT>(it.row() + 1));
        s.cols.push_back(static_cast<MUMPS_INT>(c + 1));
        s.values.push_back(it.value());
      }
  // The ordering and symbolic analysis depend on the pattern only: the modes' bordered blocks
  // share one, and so do the Newton iterations, so it is analysed once.
  const std::uint64_t pattern = fingerprint(static_cast<MUMPS_INT>(lower.rows()), s.rows, s.cols);
  const bool same_pattern = s.analyzed && id.n == static_cast<MUMPS_INT>(lower.rows()) && pattern == s.pattern;
  s.pattern = pattern;
  id.n = static_cast<MUMPS_INT>(lower.rows());
  id.nnz = static_cast<MUMPS_INT8>(s.values.size());
  id.irn = s.rows.data();
  id.jcn = s.cols.data();
  id.a = s.values.data();
  s.factored = false;
  // Working space: MUMPS estimates it in the analysis; delayed pivots can exceed the estimate
  // (INFOG(1) = -9 or -8), and the retry doubles the relaxation.
  if (!same_pattern) icntl(id, 14) = 30;
  for (int attempt = 0; attempt < 4; ++attempt) {
    id.job = same_pattern && attempt == 0 ? 2 : 4;  // factorization, or analysis and factorization
    dmumps_c(&id);
    const int code = infog(id, 1);
    s.analyzed = code >= 0 || id.job == 2;
    if (code >= 0) {
      s.factored = true;
      std::vector<MUMPS_INT>().swap(s.rows);  // the factors are all the solves need
      std::vector<MUMPS_INT>().swap(s.cols);
      std::vector<double>().swap(s.values);
      id.irn = id.jcn = nullptr;
      id.a = nullptr;
      return true;
    }
    if (code == -8 || code == -9 || code == -14 || code == -15 || code == -17 || code == -20) {
      icntl(id, 14) *= 2;
      continue;
    }
    if (error) {
      *error = "MUMPS factorization failed with INFOG(1) = " + std::to_string(code) +
               ", INFOG(2) = " + std::to_string(infog(id, 2));
      if (code == -10) *error += " (numerically singular matrix)";
      if (code == -13) *error += " (memory allocation failed: too little memory for the factors)";
    }
    return false;
  }
  if (error) *error = "MUMPS factorization ran out of working space after 4 attempts (INFOG(1) = " +
                      std::to_string(infog(id, 1)) + ")";
  return false;
}

void MumpsSymmetricFactor::set_pivot_threshold(double threshold) { state_->id.cntl[0] = threshold; }

int MumpsSymmetricFactor::negative_pivots() const { return infog(state_->id, 12); }

double MumpsSymmetricFactor::factor_entries() const {
  const MUMPS_INT entries = infog(state_->id, 29);
  return entries >= 0 ? entries : -1e6 * entries;  // negative: millions (MUMPS's convention)
}

void MumpsSymmetricFactor::solve(Matrix* rhs) {
  State& s = *state_;
  if (!s.factored) throw std::logic_error("MumpsSymmetricFactor::solve before a successful factor");
  DMUMPS_STRUC_C& id = s.id;
  if (rhs->rows() != id.n) throw std::invalid_argument("MumpsSymmetricFactor::solve: right-hand side size");
  if (rhs->cols() == 0) return;
  id.rhs = rhs->data();
  id.nrhs = static_cast<MUMPS_INT>(rhs->cols());
  id.lrhs = id.n;
  id.job = 3;
  dmumps_c(&id);
  if (infog(id, 1) < 0)
    throw std::runtime_error("MUMPS solve failed with INFOG(1) = " + std::to_string(infog(id, 1)));
}

}  // namespace modalcal::detail
