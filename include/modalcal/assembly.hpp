#pragma once
/// \file assembly.hpp
/// From a Model and a binding of calibration parameters to its properties, the parametric
/// system matrices K(p), M(p) on the free DOFs, and their exact first and second derivatives.
///
/// K and M are kept in an *affine-in-coefficients* form
/// \f[ K(p) = \sum_t c_t(\theta(p))\, K_t, \qquad M(p) = \sum_t d_t(\theta(p))\, M_t \f]
/// where each term matrix \f$K_t\f$ (a block's volumetric or deviatoric stiffness, one joint
/// component, ...) is assembled once, and the coefficient \f$c_t\f$ is a product of property
/// values or of the bulk/shear moduli computed from (E, ν). Properties \f$\theta\f$ equal their
/// nominal value unless a parameter targets them. Re-assembly for new p is then a scaled sum on a
/// fixed sparsity pattern, and \f$\partial K/\partial p_j = \sum_t \partial c_t/\partial p_j\, K_t\f$
/// exactly, second derivatives included.
///
/// Fixed DOFs and the coupled nodes of rigid couplings are eliminated:
/// \f$K = T^T K_{full} T\f$ with \f$u_{full} = T u\f$.

#include <memory>
#include <string>
#include <utility>
#include <vector>

#include "modalcal/export.hpp"
#include "modalcal/model.hpp"
#include "modalcal/types.hpp"

namespace modalcal {

/// Numbering of the model's DOFs and the elimination of fixed and rigidly coupled DOFs.
class MODALCAL_EXPORT DofMap {
 public:
  explicit DofMap(const Model& model);

  int num_full() const { return static_cast<int>(full_owner_.size()); }
  /// Number of independent (free) DOFs: the size of K and M.
  int num_free() const { return static_cast<int>(free_owner_.size()); }
  /// Full index of (node, component), -1 if the node has no such component.
  int full_index(int node, int component) const;
  /// Free index of (node, component), -1 if that DOF is fixed, coupled or absent.
  int free_index(int node, int component) const;
  /// (node, component) owning a free DOF.
  std::pair<int, int> free_owner(int free_dof) const { return free_owner_[free_dof]; }
  /// T (num_full x num_free): u_full = T u.
  const SparseMatrix& transformation() const { return transformation_; }
  using RowSparseMatrix = Eigen::SparseMatrix<double, Eigen::RowMajor, int>;
  /// T by rows: row f lists the free DOFs (and weights) full DOF f depends on.
  const RowSparseMatrix& transformation_rows() const { return rows_; }
  /// Number of full DOFs of a node (3 or 6).
  int node_dofs(int node) const { return node_offset_[node + 1] - node_offset_[node]; }
  /// Displacement of (node, component) for a free-DOF vector u (0 for fixed DOFs).
  double value(const Vector& u, int node, int component) const;
  /// Whether the two number the same DOFs alike and eliminate them alike (the same T): vectors
  /// on one are vectors on the other.
  bool operator==(const DofMap& other) const;

 private:
  std::vector<int> node_offset_;                 // first full DOF of each node
  std::vector<std::pair<int, int>> full_owner_;  // (node, component) of each full DOF
  std::vector<std::pair<int, int>> free_owner_;
  std::vector<int> full_to_free_;                // -1 if not independent
  SparseMatrix transformation_;
  RowSparseMatrix rows_;
};

/// A coefficient \f$c(\theta)\f$ of one term: a product of factors, each a property value or the
/// bulk/shear modulus from (E, ν). Exposed for testing.
struct MODALCAL_EXPORT Coefficient {
  enum class Kind { Property, BulkFromYoung, ShearFromYoung };
  struct Factor {
    Kind kind = Kind::Property;
    PropertyId a = kNoProperty;  ///< the property, or E
    PropertyId b = kNoProperty;  ///< ν for the (E, ν) kinds
  };
  std::vector<Factor> factors;
  /// Value, gradient and Hessian with respect to the properties it involves (`involved()`).
  double value(const Vector& theta) const;
  std::vector<PropertyId> involved() const;
  void derivatives(const Vector& theta, Vector* gradient, Matrix* hessian) const;
};

class MODALCAL_EXPORT ParametricSystem {
 public:
  /// `parameter_targets[j]` lists the properties parameter j sets. A property may be the target
  /// of at most one parameter.
  /// \throws std::invalid_argument for an invalid model or binding (names the entity).
  ParametricSystem(const Model& model, std::vector<std::vector<PropertyId>> parameter_targets);
  ~ParametricSystem();
  ParametricSystem(const ParametricSystem&) = delete;
  ParametricSystem& operator=(const ParametricSystem&) = delete;

  const Model& model() const { return model_; }
  const DofMap& dof_map() const { return *dofs_; }
  int num_dofs() const { return dofs_->num_free(); }
  int num_parameters() const { return static_cast<int>(targets_.size()); }
  /// Nominal property values with the parameters substituted.
  Vector property_values(const Vector& p) const;
  /// Why K(p) may look singular to an eigensolver though it is not, or "": a block so nearly
  /// incompressible (bulk modulus above 10^4 times the shear modulus, i.e. nu above 0.49995)
  /// that K is ill-conditioned. For failure messages, whose default suspects are the supports.
  std::string ill_conditioning(const Vector& p) const;
  /// A failed modal solve's message at p: the solver's, after ill_conditioning(p) when there is one.
  std::string failure_message(const Vector& p, const std::string& solver_message) const;
  /// The common sparsity pattern of K and M (full symmetric storage, values meaningless).
  const SparseMatrix& pattern() const { return pattern_; }

  /// K(p) and M(p) on pattern() (both triangles stored).
  void assemble(const Vector& p, SparseMatrix* K, SparseMatrix* M) const;
  /// The terms projected on a span V (num_dofs() x r): \f$V^T K_t V\f$ or \f$V^T M_t V\f$ for each
  /// term t, made once so that assemble_projected() gives \f$V^T K(p) V\f$ for any p from sums of
  /// r x r matrices (the many evaluations of a Rayleigh-Ritz model, Objective::set_span). Costs
  /// about one product of K with V plus, per term, a product over the DOFs it touches.
  /// \throws std::invalid_argument if V's rows are not the DOFs.
  std::vector<Matrix> project_terms(const Matrix& V) const;
  /// \f$V^T K(p) V\f$ and \f$V^T M(p) V\f$ (symmetric) from project_terms(V).
  /// \throws std::invalid_argument if `projected` is not one matrix per term.
  void assemble_projected(const Vector& p, const std::vector<Matrix>& projected, Matrix* Kr, Matrix* Mr) const;
  /// \f$\partial K/\partial p_j\f$, \f$\partial M/\partial p_j\f$ on pattern().
  void assemble_derivative(const Vector& p, int j, SparseMatrix* dK, SparseMatrix* dM) const;
  /// \f$\partial^2 K/\partial p_j \partial p_k\f$, \f$\partial^2 M/\partial p_j \partial p_k\f$.
  void assemble_second_derivative(const Vector& p, int j, int k, SparseMatrix* d2K,
                                  SparseMatrix* d2M) const;
  /// \f$ dK_j = \partial K/\partial p_j\,u \f$ and \f$ dM_j = \partial M/\partial p_j\,u \f$.
  void derivative_times(const Vector& p, int j, const Vector& u, Vector* dKu, Vector* dMu) const;
  /// \f$ a_j = v^T \partial K/\partial p_j\, u,\; b_j = v^T \partial M/\partial p_j\, u \f$ for all j.
  /// With v = u this is the eigenvalue sensitivity \f$\partial\lambda/\partial p_j = a_j - \lambda b_j\f$.
  void derivative_forms(const Vector& p, const Vector& v, const Vector& u, Vector* a, Vector* b) const;
  /// Blocked form of the above for m pairs of vectors at once: column c of A and B
  /// (num_parameters x m) holds \f$ V_c^T \partial K/\partial p_j\, U_c \f$ and
  /// \f$ V_c^T \partial M/\partial p_j\, U_c \f$ (V_c, U_c the c-th columns), each the same as the
  /// single-pair call. One pass over the assembly terms serves every column, so the
  /// sensitivities of all paired modes cost little more than those of one.
  /// \throws std::invalid_argument if V and U are not both num_dofs() x m.
  void derivative_forms(const Vector& p, const Matrix& V, const Matrix& U, Matrix* A, Matrix* B) const;
  /// Same with second derivatives: \f$ A_{jk} = v^T \partial^2 K/\partial p_j\partial p_k\, u\f$.
  void second_derivative_forms(const Vector& p, const Vector& v, const Vector& u, Matrix* A,
                               Matrix* B) const;
  /// True if K and M are affine in every parameter (all second derivatives vanish).
  bool is_affine() const;
  /// Total mass (rigid-body mass), for effective-mass fractions.
  double total_mass(const Vector& p) const;
  /// \f$T^T M_{full}\, r_d\f$ for the unit rigid translations \f$r_d\f$ (d = x, y, z) of every DOF,
  /// supported ones included (num_dofs x 3). Its product with a mode is the base-excitation
  /// participation factor \f$\Gamma_d = u^T (M_{ff} r_f + M_{fs} r_s)\f$, exact with consistent mass.
  Matrix rigid_body_inertia(const Vector& p) const;

 private:
  struct Term;
  class Builder;  // the constructor's steps (parametric_system.cpp)
  // Coefficient of a term (j < 0), its first (k < 0) or second derivative in the parameters.
  double term_scale(const Term& term, const Vector& theta, int j, int k) const;
  void check_parameter(int j) const;
  void accumulate(const Vector& p, int j, int k, SparseMatrix* K, SparseMatrix* M) const;
  Model model_;  // own copy: the system must not dangle when the caller's model goes away
  std::unique_ptr<DofMap> dofs_;
  std::vector<std::vector<PropertyId>> targets_;
  std::vector<int> property_parameter_;  // parameter index per property, -1 if none
  std::vector<Term> terms_;
  SparseMatrix pattern_;
  std::vector<int> columns_;            // column of each pattern position
  // Volume and density coefficient of each group of elements with the same multipliers, for the
  // total mass.
  std::vector<std::pair<double, Coefficient>> mass_groups_;
};

}  // namespace modalcal
