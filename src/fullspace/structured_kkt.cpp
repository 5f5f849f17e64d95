#include "fullspace/structured_kkt.hpp"

#include <Eigen/Eigenvalues>

#include <algorithm>
#include <cmath>
#include <new>

#include "fullspace/block_elimination.hpp"
#include "fullspace/ipopt/pardiso_trampoline.h"
#include "fullspace/mumps_factor.hpp"
#include "fullspace/shared_shift_solve.hpp"

namespace modalcal::detail {

namespace {

struct Registration {
  FullSpaceProblem* problem = nullptr;
  KktFactorizationCounts* counts = nullptr;
  bool shared_factorization = false;
};
thread_local const Registration* current_registration = nullptr;

// What one stored KKT entry is in the registered layout (local indices as in ModeKktBlocks).
struct Place {
  enum Kind : unsigned char {
    ModeHessian,           // W_i(row, col)
    ModeParameterHessian,  // C_i(row, col = parameter)
    ParameterHessian,      // W_qq(row, col)
    ModeJacobian,          // A_i(row = constraint, col = unknown)
    ParameterJacobian,     // P_i(row = constraint, col = parameter)
    MultiplierDiagonal,    // -delta_c
  } kind;
  int mode, row, col;
};

// Ipopt's singular-matrix code (it then raises delta_c, and delta_w if need be).
constexpr int kSingular = -4;
constexpr int kInputError = -1;
constexpr int kOutOfMemory = -2;

// One Ipopt linear-solver instance (keyed by its PARDISO handle). It stores no copy of the
// matrix: every entry is placed again from its (row, column) when it is read (a few integer
// operations), since Ipopt passes its arrays with every call; only the factors, S_i, T_i, C_i and
// P_i are kept between the factorization and the solves.
class KktInstance {
 public:
  int analyse(const Registration* registration, int n, const int* ia, const int* ja) {
    registration_ = registration ? *registration : Registration{};
    n_ = n;
    structured_ = registration_.problem && classify(*registration_.problem, ia, ja);
    return 0;
  }

  int factor(const double* a, const int* ia, const int* ja, int* iparm) {
    double delta_c = 0;
    for (int k : multiplier_diagonal_) delta_c = std::max(delta_c, std::abs(a[k]));
    int negatives = 0;
    const bool blocks = structured_ && delta_c == 0;
    const int code = blocks ? factor_blocks(a, ia, ja, &negatives) : factor_whole(a, ia, ja, &negatives);
    whole_used_ = !blocks;
    if (registration_.counts) ++(blocks ? registration_.counts->structured : registration_.counts->mumps);
    iparm[6] = 0;   // iterative refinement steps
    iparm[13] = 0;  // perturbed pivots: none, so Ipopt never redoes the analysis
    iparm[21] = n_ - negatives;
    iparm[22] = negatives;
    return code;
  }

  int solve(const double* a, const int* ia, const int* ja, int nrhs, double* b) {
    if (nrhs <= 0) return 0;
    Eigen::Map<Matrix> rhs(b, n_, nrhs);
    if (whole_used_) {
      Matrix x = rhs;
      whole_->solve(&x);
      rhs = x;
      return 0;
    }
    const FullSpaceProblem& p = *registration_.problem;
    const int l = p.num_modes(), nd = p.num_dofs(), np = p.num_parameters(), nv = p.num_variables();
    std::vector<Matrix> f(l, Matrix(nd + 1, nrhs)), e(l, Matrix(nd + 1, nrhs));
    for (int i = 0; i < l; ++i)
      for (int k = 0; k <= nd; ++k) {
        f[i].row(k) = rhs.row(p.mode_entry(i, k));
        e[i].row(k) = rhs.row(nv + p.mode_entry(i, k));
      }
    Matrix fq = rhs.middleRows(p.parameter_offset(), np);
    auto hessian_product = [&](int i, const Matrix& v) {
      Matrix product = Matrix::Zero(v.rows(), v.cols());
      for_each_mode_hessian_entry(p, i, ia, ja, [&](int k, int row, int col) {
        product.row(row) += a[k] * v.row(col);
        if (row != col) product.row(col) += a[k] * v.row(row);
      });
      return product;
    };
    auto bordered_block = [&](int i) { return mode_blocks(p, i, a, ia, ja, Matrix::Zero(nd + 1, np)).bordered; };
    elimination_->solve(&f, &e, &fq, [this](Matrix* h) { *h = reduced_inverse_ * (*h); }, hessian_product,
                        bordered_block);
    report_shared_counts();
    for (int i = 0; i < l; ++i)
      for (int k = 0; k <= nd; ++k) {
        rhs.row(p.mode_entry(i, k)) = f[i].row(k);
        rhs.row(nv + p.mode_entry(i, k)) = e[i].row(k);
      }
    rhs.middleRows(p.parameter_offset(), np) = fq;
    return 0;
  }

 private:
  // True when every stored entry has a place in the [x | y_c] layout of the registered problem.
  bool classify(const FullSpaceProblem& p, const int* ia, const int* ja) {
    if (n_ != p.num_variables() + p.num_constraints()) return false;
    multiplier_diagonal_.clear();
    for (int r = 0; r < n_; ++r)
      for (int k = ia[r] - 1; k < ia[r + 1] - 1; ++k) {
        const int c = ja[k] - 1;
        Place place{};
        if (c < r || c >= n_ || !place_entry(p, r, c, &place)) return false;
        if (place.kind == Place::MultiplierDiagonal) multiplier_diagonal_.push_back(k);
      }
    elimination_ = std::make_unique<BlockElimination>(p.num_modes(), p.num_parameters(), /*keep_factors=*/true);
    reported_shared_ = reported_failures_ = 0;
    return true;
  }

  static bool place_entry(const FullSpaceProblem& p, int r, int c, Place* place) {
    const int nv = p.num_variables();
    int row_mode, row, col_mode, col;
    if (r >= nv) {  // (y, y): only -delta_c on the diagonal
      place->kind = Place::MultiplierDiagonal;
      return r == c;
    }
    p.locate(r, &row_mode, &row);
    p.locate(c < nv ? c : c - nv, &col_mode, &col);
    if (c >= nv) {  // J^T: unknown r, constraint c
      if (row_mode == -1) *place = {Place::ParameterJacobian, col_mode, col, row};
      else *place = {Place::ModeJacobian, col_mode, col, row};
      return row_mode == -1 || row_mode == col_mode;
    }
    if (row_mode == -1 && col_mode == -1) *place = {Place::ParameterHessian, -1, row, col};
    else if (row_mode == -1) *place = {Place::ModeParameterHessian, col_mode, col, row};
    else if (col_mode == -1) *place = {Place::ModeParameterHessian, row_mode, row, col};
    else *place = {Place::ModeHessian, row_mode, row, col};
    return row_mode == -1 || col_mode == -1 || row_mode == col_mode;
  }

  // The entries stored in the rows of `first .. first + count - 1`, placed.
  template <class Visit>
  static void for_each_in_rows(const FullSpaceProblem& p, int first, int count, const int* ia, const int* ja,
                               Visit&& visit) {
    for (int r = first; r < first + count; ++r)
      for (int k = ia[r] - 1; k < ia[r + 1] - 1; ++k) {
        Place place{};
        place_entry(p, r, ja[k] - 1, &place);
        visit(k, place);
      }
  }
  // Mode i's local index (0..n) of unknown or constraint `index`, or -1 when it is not mode i's:
  // a few comparisons, where locate() divides, for the entries read at every factorization.
  static int local_index(const FullSpaceProblem& p, int i, int index) {
    const int nd = p.num_dofs(), first = i * nd;
    if (index >= first && index < first + nd) return index - first;
    return index == p.mode_entry(i, nd) ? nd : -1;
  }

  // The entries of W_i (upper triangle: row <= col, local indices): in mode i's rows, those whose
  // column is one of mode i's unknowns.
  template <class Visit>
  static void for_each_mode_hessian_entry(const FullSpaceProblem& p, int i, const int* ia, const int* ja,
                                          Visit&& visit) {
    for (int row = 0; row <= p.num_dofs(); ++row) {
      const int r = p.mode_entry(i, row);
      for (int k = ia[r] - 1; k < ia[r + 1] - 1; ++k) {
        const int col = local_index(p, i, ja[k] - 1);
        if (col >= 0) visit(k, row, col);
      }
    }
  }

  ModeKktBlocks mode_blocks(const FullSpaceProblem& p, int i, const double* a, const int* ia, const int* ja,
                            Matrix jacobian_parameters) const {
    const int nd = p.num_dofs(), np = p.num_parameters();
    ModeKktBlocks blocks;
    blocks.row_scale = p.mode_row_scale(i);
    blocks.jacobian_parameters = std::move(jacobian_parameters);
    blocks.hessian_parameters = Matrix::Zero(nd + 1, np);
    std::vector<Eigen::Triplet<double, int>> bordered, hessian;
    // Mode i's rows hold W_i (in the columns of mode i's unknowns), C_i (the parameters' columns)
    // and A_i^T (mode i's constraints' columns) and nothing else, as classify() checked.
    const int nv = p.num_variables(), q0 = p.parameter_offset();
    for (int row = 0; row <= nd; ++row) {
      const int r = p.mode_entry(i, row);
      for (int k = ia[r] - 1; k < ia[r + 1] - 1; ++k) {
        const int c = ja[k] - 1;
        if (c >= nv) {  // A_i(constraint, row); B_i = diag(s_i)^{-1} A_i is symmetric: its lower triangle
          const int constraint = local_index(p, i, c - nv);
          if (constraint >= row) bordered.emplace_back(constraint, row, a[k] / blocks.row_scale[constraint]);
        } else if (c >= q0) {
          blocks.hessian_parameters(row, c - q0) += a[k];
        } else {
          const int col = local_index(p, i, c);
          hessian.emplace_back(row, col, a[k]);
          if (row != col) hessian.emplace_back(col, row, a[k]);
        }
      }
    }
    blocks.bordered.resize(nd + 1, nd + 1);
    blocks.bordered.setFromTriplets(bordered.begin(), bordered.end());
    blocks.hessian.resize(nd + 1, nd + 1);
    blocks.hessian.setFromTriplets(hessian.begin(), hessian.end());
    return blocks;
  }

  int factor_blocks(const double* a, const int* ia, const int* ja, int* negatives) {
    const FullSpaceProblem& p = *registration_.problem;
    const int np = p.num_parameters(), l = p.num_modes();
    // The parameter rows hold W_qq and every mode's P_i (as P_i^T).
    Matrix parameter_hessian = Matrix::Zero(np, np);
    std::vector<Matrix> jacobian_parameters(l, Matrix::Zero(p.num_dofs() + 1, np));
    for_each_in_rows(p, p.parameter_offset(), np, ia, ja, [&](int k, const Place& e) {
      if (e.kind == Place::ParameterJacobian) {
        jacobian_parameters[e.mode](e.row, e.col) += a[k];
      } else if (e.kind == Place::ParameterHessian) {
        parameter_hessian(e.row, e.col) += a[k];
        if (e.row != e.col) parameter_hessian(e.col, e.row) += a[k];
      }
    });
    // Ipopt's matrix is linearized where it last evaluated the Jacobian; add_mode() checks that
    // the shared solver's B_i agree with the matrix's.
    SharedShiftSolver* shared = nullptr;
    if (registration_.shared_factorization) {
      if (!shared_) shared_ = std::make_unique<SharedShiftSolver>();
      const Vector& point = registration_.problem->jacobian_point();
      if (update_shared_shift_solver(*registration_.problem, point.size() ? point.data() : nullptr, shared_.get(),
                                     nullptr))
        shared = shared_.get();
      else
        elimination_->count_shared_failures(l);  // every mode factored
    }
    elimination_->begin(parameter_hessian, nullptr, shared);
    for (int i = 0; i < l; ++i) {
      std::string why;
      const bool added = elimination_->add_mode(i, mode_blocks(p, i, a, ia, ja, std::move(jacobian_parameters[i])),
                                                nullptr, nullptr, &why);
      report_shared_counts();
      if (!added) return kSingular;
      elimination_->release_hessian(i);  // the solves read W_i from Ipopt's values
    }
    // Inertia from H's eigenvalues; a numerically zero one counts as negative, so that Ipopt
    // raises delta_w (which makes H definite) rather than delta_c (which would leave the layout).
    const Eigen::SelfAdjointEigenSolver<Matrix> eigen(elimination_->reduced_hessian());
    const Vector& values = eigen.eigenvalues();
    const double floor = 1e-13 * std::max(values.cwiseAbs().maxCoeff(), 1e-300);
    int negative = 0;
    Vector inverse(values.size());
    for (int j = 0; j < values.size(); ++j) {
      negative += values[j] <= floor;
      inverse[j] = std::abs(values[j]) > floor ? 1.0 / values[j] : 0.0;
    }
    reduced_inverse_ = eigen.eigenvectors() * inverse.asDiagonal() * eigen.eigenvectors().transpose();
    *negatives = p.num_constraints() + negative;
    return 0;
  }

  // The shared solver's eliminations and failures since the last report, into the counts.
  void report_shared_counts() {
    if (!registration_.counts) return;
    registration_.counts->shared_modes += elimination_->shared_eliminations() - reported_shared_;
    registration_.counts->shared_failures += elimination_->shared_failures() - reported_failures_;
    reported_shared_ = elimination_->shared_eliminations();
    reported_failures_ = elimination_->shared_failures();
  }

  int factor_whole(const double* a, const int* ia, const int* ja, int* negatives) {
    std::vector<Eigen::Triplet<double, int>> lower;  // the upper CSR, transposed
    for (int r = 0; r < n_; ++r)
      for (int k = ia[r] - 1; k < ia[r + 1] - 1; ++k) lower.emplace_back(ja[k] - 1, r, a[k]);
    SparseMatrix matrix(n_, n_);
    matrix.setFromTriplets(lower.begin(), lower.end());
    lower = {};
    if (!whole_) {
      whole_ = std::make_unique<MumpsSymmetricFactor>();
      whole_->set_pivot_threshold(0.1);  // as Ipopt's MUMPS path (ipopt_adapter.cpp says why)
    }
    std::string why;
    if (!whole_->factor(matrix, &why)) return kSingular;
    *negatives = whole_->negative_pivots();
    return 0;
  }

  Registration registration_;
  int n_ = 0;
  bool structured_ = false, whole_used_ = false;
  std::vector<int> multiplier_diagonal_;  // positions of the (y, y) diagonal: -delta_c
  std::unique_ptr<BlockElimination> elimination_;
  std::unique_ptr<SharedShiftSolver> shared_;  // with Registration::shared_factorization
  int reported_shared_ = 0, reported_failures_ = 0;
  Matrix reduced_inverse_;
  std::unique_ptr<MumpsSymmetricFactor> whole_;
};

extern "C" int structured_kkt_handler(void** handle, int phase, int n, const double* a, const int* ia, const int* ja,
                                      int nrhs, int* iparm, double* b) {
  KktInstance*& instance = *reinterpret_cast<KktInstance**>(handle);
  try {
    switch (phase) {
      case -1:
        delete instance;
        instance = nullptr;
        return 0;
      case 11:
        if (!instance) instance = new KktInstance;
        return instance->analyse(current_registration, n, ia, ja);
      case 22: return instance ? instance->factor(a, ia, ja, iparm) : kInputError;
      case 33: return instance ? instance->solve(a, ia, ja, nrhs, b) : kInputError;
      default: return kInputError;
    }
  } catch (const std::bad_alloc&) {
    return kOutOfMemory;
  } catch (...) {
    return kInputError;
  }
}

}  // namespace

StructuredKktScope::StructuredKktScope(FullSpaceProblem& problem, KktFactorizationCounts* counts,
                                       bool shared_factorization)
    : previous_(current_registration) {
  modalcal_set_kkt_handler(&structured_kkt_handler);
  current_registration = new Registration{&problem, counts, shared_factorization};
}

StructuredKktScope::~StructuredKktScope() {
  delete current_registration;
  current_registration = static_cast<const Registration*>(previous_);
}

}  // namespace modalcal::detail
