#include <algorithm>
#include <cmath>
#include <cstdio>
#include <limits>
#include <map>
#include <stdexcept>

#include "modalcal/assembly.hpp"

namespace modalcal {

/// One affine term: coefficient(theta) * matrix, the matrix stored as values at positions of
/// the common pattern.
struct ParametricSystem::Term {
  Coefficient coefficient;
  bool mass = false;
  std::vector<int> positions;
  std::vector<double> values;
  std::vector<int> parameters;  // parameters the coefficient depends on
  // For a block's mass terms: T^T M_t,full r_d for the unit rigid translations r_d of *all* DOFs,
  // fixed ones included (num_free x 3); rigid_body_inertia() adds point masses itself. The mass
  // coupling to supported DOFs belongs in the participation factors of a supported model, and the
  // reduced M alone does not hold it.
  Matrix inertia;
};

namespace {

// Adds M_e r_d (local, 3 columns) through the rows of T: the rigid translation is applied to
// every local DOF, fixed or not.
void add_inertia(const DofMap& dofs, Matrix& inertia, const std::vector<int>& full, const Matrix& local_inertia) {
  const DofMap::RowSparseMatrix& T = dofs.transformation_rows();
  for (size_t a = 0; a < full.size(); ++a) {
    if (full[a] < 0) continue;
    for (DofMap::RowSparseMatrix::InnerIterator it(T, full[a]); it; ++it)
      inertia.row(it.col()) += it.value() * local_inertia.row(a);
  }
}

// Structured meshes repeat the same element shape many times; computing its matrices once
// makes setup of a 1e5-element model several times faster. Keyed on node coordinates relative
// to the first node, quantized far below any meaningful geometric difference.
class ElementMatrixCache {
 public:
  const SolidElementMatrices& get(SolidType type, const Eigen::Matrix3Xd& x) {
    const double scale = (x.colwise() - x.col(0)).cwiseAbs().maxCoeff();
    std::vector<long long> key;
    key.reserve(x.size() + 1);
    key.push_back(static_cast<long long>(type));
    for (int c = 0; c < x.cols(); ++c)
      for (int r = 0; r < 3; ++r)
        key.push_back(std::llround((x(r, c) - x(r, 0)) / (scale * 1e-10)));
    key.push_back(std::llround(std::log2(scale) * 1e6));
    auto it = cache_.find(key);
    if (it != cache_.end()) return it->second;
    if (cache_.size() >= kMaxEntries) {
      scratch_ = solid_element_matrices(type, x);
      return scratch_;
    }
    return cache_.emplace(key, solid_element_matrices(type, x)).first->second;
  }

 private:
  static constexpr size_t kMaxEntries = 2048;
  std::map<std::vector<long long>, SolidElementMatrices> cache_;
  SolidElementMatrices scratch_;
};

// Accumulates several term matrices over the common pattern at once, then hands each out in
// compressed (positions, values) form.
class TermAccumulator {
 public:
  TermAccumulator(int count, int nnz) : values_(count, std::vector<double>(nnz, 0.0)), touched_(nnz, 0) {}
  void add(int term, int position, double v) {
    values_[term][position] += v;
    if (!touched_[position]) {
      touched_[position] = 1;
      touched_list_.push_back(position);
      sorted_ = false;
    }
  }
  // Moves the accumulated values of `term` out; call for every term, then reset().
  void extract(int term, std::vector<int>* positions, std::vector<double>* values) {
    if (!sorted_) std::sort(touched_list_.begin(), touched_list_.end());  // once for the terms extracted together
    sorted_ = true;
    positions->clear();
    values->clear();
    for (int p : touched_list_) {
      if (values_[term][p] != 0.0) {
        positions->push_back(p);
        values->push_back(values_[term][p]);
      }
      values_[term][p] = 0.0;
    }
  }
  void reset() {
    for (int p : touched_list_) touched_[p] = 0;
    touched_list_.clear();
  }

 private:
  std::vector<std::vector<double>> values_;
  std::vector<char> touched_;
  std::vector<int> touched_list_;
  bool sorted_ = true;
};

/// The block's elements grouped by the regions they lie in (region indices, sorted): elements
/// of one group share their stiffness and mass multipliers.
std::map<std::vector<int>, std::vector<int>> elements_by_regions(const ElementBlock& block) {
  std::vector<std::vector<int>> regions_of(block.num_elements());
  for (size_t r = 0; r < block.regions.size(); ++r)
    for (int e : block.regions[r].elements) regions_of[e].push_back(static_cast<int>(r));
  std::map<std::vector<int>, std::vector<int>> groups;
  for (int e = 0; e < block.num_elements(); ++e) groups[regions_of[e]].push_back(e);
  return groups;
}

}  // namespace

ParametricSystem::~ParametricSystem() = default;

/// The constructor's steps: the parameters' properties, the sparsity pattern, the term matrices
/// of the blocks and of the discrete entities, and the check that every free DOF has a term.
class ParametricSystem::Builder {
 public:
  explicit Builder(ParametricSystem& system) : s_(system) {}
  void bind_parameters();
  void sparsity_pattern();
  void block_terms();
  void discrete_terms();
  void require_every_dof_touched() const;

 private:
  static Coefficient::Factor factor(PropertyId id) {
    return Coefficient::Factor{Coefficient::Kind::Property, id, kNoProperty};
  }
  int find_position(int row, int col) const;
  void scatter(const std::vector<int>& full, const std::vector<const Matrix*>& local);
  void finish(int index, Coefficient coefficient, bool mass, Matrix inertia = Matrix());
  void discrete_term(const std::vector<int>& full, const Matrix& local, PropertyId id, bool mass);
  void group_terms(const ElementBlock& b, const std::vector<int>& regions, const std::vector<int>& elements,
                   ElementMatrixCache* cache);

  ParametricSystem& s_;
  std::unique_ptr<TermAccumulator> acc_;
  std::vector<std::vector<std::pair<int, double>>> deps_;  // scatter's scratch
};

void ParametricSystem::Builder::bind_parameters() {
  s_.property_parameter_.assign(s_.model_.properties.size(), -1);
  for (int j = 0; j < s_.num_parameters(); ++j) {
    if (s_.targets_[j].empty()) throw std::invalid_argument("parameter " + std::to_string(j) + " targets no property");
    for (PropertyId id : s_.targets_[j]) {
      if (id < 0 || id >= static_cast<int>(s_.model_.properties.size()))
        throw std::invalid_argument("parameter " + std::to_string(j) + " targets an unknown property");
      if (s_.property_parameter_[id] >= 0)
        throw std::invalid_argument("property '" + s_.model_.properties[id].name + "' is the target of two parameters");
      s_.property_parameter_[id] = j;
    }
  }
}

// The sparsity pattern at node level: a coupled node acts through its reference node.
void ParametricSystem::Builder::sparsity_pattern() {
  const Model& model = s_.model_;
  const DofMap& dofs = *s_.dofs_;
  const int n = model.num_nodes();
  std::vector<int> representative(n);
  for (int v = 0; v < n; ++v) representative[v] = v;
  for (const RigidCoupling& r : model.rigid_couplings)
    for (int v : r.nodes) representative[v] = r.reference;
  std::vector<int> first_free(n, -1), free_count(n, 0);
  for (int f = 0; f < dofs.num_free(); ++f) {
    const int v = dofs.free_owner(f).first;
    if (first_free[v] < 0) first_free[v] = f;
    ++free_count[v];
  }
  std::vector<std::vector<int>> adjacency(n);
  auto connect = [&](const int* nodes, int count) {
    for (int a = 0; a < count; ++a)
      for (int b = 0; b < count; ++b) adjacency[representative[nodes[a]]].push_back(representative[nodes[b]]);
  };
  for (const ElementBlock& b : model.blocks) {
    const int npe = nodes_per_element(b.type);
    for (int e = 0; e < b.num_elements(); ++e) connect(&b.connectivity[e * npe], npe);
  }
  for (const Joint& j : model.joints) {
    const int pair[2] = {j.node_a, j.node_b};
    connect(pair, 2);
  }
  for (const GroundSpring& g : model.ground_springs)
    for (int v : g.nodes) connect(&v, 1);
  for (const PointMass& m : model.point_masses) connect(&m.node, 1);
  long long nnz = 0;
  for (int v = 0; v < n; ++v) {
    auto& a = adjacency[v];
    std::sort(a.begin(), a.end());
    a.erase(std::unique(a.begin(), a.end()), a.end());
    a.erase(std::remove_if(a.begin(), a.end(), [&](int u) { return free_count[u] == 0; }), a.end());
    for (int u : a) nnz += static_cast<long long>(free_count[u]) * free_count[v];
  }
  if (nnz > std::numeric_limits<int>::max())
    throw std::invalid_argument("model too large: K would have more than 2^31 nonzeros");
  SparseMatrix& pattern = s_.pattern_;
  pattern.resize(dofs.num_free(), dofs.num_free());
  pattern.resizeNonZeros(static_cast<int>(nnz));
  int* outer = pattern.outerIndexPtr();
  int* inner = pattern.innerIndexPtr();
  int position = 0;
  for (int f = 0; f < dofs.num_free(); ++f) {
    outer[f] = position;
    for (int u : adjacency[dofs.free_owner(f).first])
      for (int k = 0; k < free_count[u]; ++k) inner[position++] = first_free[u] + k;
  }
  outer[dofs.num_free()] = position;
  s_.columns_.resize(nnz);
  for (int f = 0; f < dofs.num_free(); ++f)
    std::fill(s_.columns_.begin() + outer[f], s_.columns_.begin() + outer[f + 1], f);
  std::fill(pattern.valuePtr(), pattern.valuePtr() + nnz, 0.0);
  acc_ = std::make_unique<TermAccumulator>(3, static_cast<int>(nnz));
}

int ParametricSystem::Builder::find_position(int row, int col) const {
  const int* outer = s_.pattern_.outerIndexPtr();
  const int* inner = s_.pattern_.innerIndexPtr();
  const int* begin = inner + outer[col];
  const int* end = inner + outer[col + 1];
  return static_cast<int>(std::lower_bound(begin, end, row) - inner);
}

// Adds the local matrices (one per accumulated term) for local full DOFs `full` (-1 = absent),
// through u_full = T u.
void ParametricSystem::Builder::scatter(const std::vector<int>& full, const std::vector<const Matrix*>& local) {
  const DofMap::RowSparseMatrix& T = s_.dofs_->transformation_rows();
  const int m = static_cast<int>(full.size());
  deps_.resize(m);
  for (int a = 0; a < m; ++a) {
    deps_[a].clear();
    if (full[a] < 0) continue;
    for (DofMap::RowSparseMatrix::InnerIterator it(T, full[a]); it; ++it)
      deps_[a].emplace_back(static_cast<int>(it.col()), it.value());
  }
  for (int b = 0; b < m; ++b)
    for (const auto& [j, wj] : deps_[b])
      for (int a = 0; a < m; ++a)
        for (const auto& [i, wi] : deps_[a]) {
          const int pos = find_position(i, j);
          for (size_t t = 0; t < local.size(); ++t) {
            const double v = (*local[t])(a, b);
            if (v != 0.0) acc_->add(static_cast<int>(t), pos, wi * wj * v);
          }
        }
}

// The accumulated term `index` as a Term with its coefficient (dropped when it touches nothing).
void ParametricSystem::Builder::finish(int index, Coefficient coefficient, bool mass, Matrix inertia) {
  Term term;
  term.inertia = std::move(inertia);
  term.coefficient = std::move(coefficient);
  term.mass = mass;
  acc_->extract(index, &term.positions, &term.values);
  for (PropertyId id : term.coefficient.involved())
    if (s_.property_parameter_[id] >= 0) term.parameters.push_back(s_.property_parameter_[id]);
  std::sort(term.parameters.begin(), term.parameters.end());
  term.parameters.erase(std::unique(term.parameters.begin(), term.parameters.end()), term.parameters.end());
  if (!term.positions.empty()) s_.terms_.push_back(std::move(term));
}


void ParametricSystem::Builder::block_terms() {
  ElementMatrixCache cache;
  s_.mass_groups_.clear();
  for (const ElementBlock& b : s_.model_.blocks)
    // One set of terms per group of elements in the same regions (most blocks: one group).
    for (const auto& [regions, elements] : elements_by_regions(b)) group_terms(b, regions, elements, &cache);
}

// The volumetric, deviatoric and mass terms of a block's elements that lie in `regions`, their
// coefficients the block's moduli and density times the block's and the regions' multipliers.
void ParametricSystem::Builder::group_terms(const ElementBlock& b, const std::vector<int>& regions,
                                            const std::vector<int>& elements, ElementMatrixCache* cache) {
  const DofMap& dofs = *s_.dofs_;
  const int npe = nodes_per_element(b.type);
  Matrix translations = Matrix::Zero(3 * npe, 3);
  for (int k = 0; k < npe; ++k) translations.block(3 * k, 0, 3, 3).setIdentity();
  std::vector<int> full(3 * npe);
  Eigen::Matrix3Xd x(3, npe);
  Matrix inertia = Matrix::Zero(dofs.num_free(), 3);
  double volume = 0;
  for (int e : elements) {
    for (int k = 0; k < npe; ++k) {
      const int v = b.connectivity[e * npe + k];
      x.col(k) = s_.model_.coordinates[v];
      for (int c = 0; c < 3; ++c) full[3 * k + c] = dofs.full_index(v, c);
    }
    const SolidElementMatrices* em;
    try {
      em = &cache->get(b.type, x);
    } catch (const std::invalid_argument& error) {
      throw std::invalid_argument("block '" + b.name + "', element " + std::to_string(e + 1) + ": " + error.what());
    }
    for (int k = 0; k < npe; ++k) volume += em->mass.row(3 * k).sum();
    scatter(full, {&em->volumetric, &em->deviatoric, &em->mass});
    add_inertia(dofs, inertia, full, em->mass * translations);
  }
  Coefficient bulk, shear, density;
  if (b.form == ElasticForm::BulkShear) {
    bulk.factors = {factor(b.modulus_a)};
    shear.factors = {factor(b.modulus_b)};
  } else {
    bulk.factors = {{Coefficient::Kind::BulkFromYoung, b.modulus_a, b.modulus_b}};
    shear.factors = {{Coefficient::Kind::ShearFromYoung, b.modulus_a, b.modulus_b}};
  }
  density.factors = {factor(b.density)};
  std::vector<PropertyId> stiffness_scales{b.stiffness_scale}, mass_scales{b.mass_scale};
  for (int r : regions) {
    stiffness_scales.push_back(b.regions[r].stiffness_scale);
    mass_scales.push_back(b.regions[r].mass_scale);
  }
  for (PropertyId id : stiffness_scales)
    if (id != kNoProperty) {
      bulk.factors.push_back(factor(id));
      shear.factors.push_back(factor(id));
    }
  for (PropertyId id : mass_scales)
    if (id != kNoProperty) density.factors.push_back(factor(id));
  s_.mass_groups_.push_back({volume, density});
  finish(0, bulk, false);
  finish(1, shear, false);
  finish(2, density, true, std::move(inertia));
  acc_->reset();
}

// A discrete entity's component as a term of its own (in the accumulator's first slot), so that
// each can be a parameter.
void ParametricSystem::Builder::discrete_term(const std::vector<int>& full, const Matrix& local, PropertyId id,
                                              bool mass) {
  scatter(full, {&local});
  finish(0, Coefficient{{factor(id)}}, mass);
  acc_->reset();
}

// Joints, springs to ground and point masses: one term per (entity, component).
void ParametricSystem::Builder::discrete_terms() {
  const DofMap& dofs = *s_.dofs_;
  for (const Joint& j : s_.model_.joints) {
    std::vector<int> full(12);
    for (int c = 0; c < 6; ++c) {
      full[c] = dofs.full_index(j.node_a, c);
      full[6 + c] = dofs.full_index(j.node_b, c);
    }
    for (int c = 0; c < 6; ++c)
      if (j.stiffness[c] != kNoProperty) discrete_term(full, joint_component_matrix(j.frame, c), j.stiffness[c], false);
  }
  const Matrix one = Matrix::Ones(1, 1);
  for (const GroundSpring& g : s_.model_.ground_springs)
    for (int c = 0; c < 6; ++c) {
      if (g.stiffness[c] == kNoProperty) continue;
      for (int v : g.nodes) scatter({dofs.full_index(v, c)}, {&one});
      finish(0, Coefficient{{factor(g.stiffness[c])}}, false);
      acc_->reset();
    }
  for (const PointMass& m : s_.model_.point_masses) {
    const Matrix identity = Matrix::Identity(3, 3);
    // Its rigid-translation inertia is added by rigid_body_inertia() itself: a dense num_free x 3
    // per point mass, in every system built, took most of a diagnosis's memory.
    if (m.mass != kNoProperty)
      discrete_term({dofs.full_index(m.node, 0), dofs.full_index(m.node, 1), dofs.full_index(m.node, 2)}, identity,
                    m.mass, true);
    for (int c = 0; c < 3; ++c)
      if (m.inertia[c] != kNoProperty) discrete_term({dofs.full_index(m.node, 3 + c)}, one, m.inertia[c], true);
  }
}

// A free DOF no term touches makes K and M singular together; name it instead of letting the
// factorization fail obscurely.
void ParametricSystem::Builder::require_every_dof_touched() const {
  const DofMap& dofs = *s_.dofs_;
  const int* inner = s_.pattern_.innerIndexPtr();
  std::vector<char> touched(dofs.num_free(), 0);
  for (const Term& t : s_.terms_)
    for (int pos : t.positions) touched[inner[pos]] = 1;
  for (int f = 0; f < dofs.num_free(); ++f)
    if (!touched[f]) {
      const auto [v, c] = dofs.free_owner(f);
      throw std::invalid_argument(
          "node " + std::to_string(s_.model_.node_ids[v]) + " DOF " + component_name(c) +
          " has neither stiffness nor mass: a reference node needs a rigid coupling, a joint or a "
          "point mass acting on every DOF it has (or fix the DOF)");
    }
}

ParametricSystem::ParametricSystem(const Model& model, std::vector<std::vector<PropertyId>> parameter_targets)
    : model_(model), targets_(std::move(parameter_targets)) {
  model_.validate();
  Builder build(*this);
  build.bind_parameters();
  dofs_ = std::make_unique<DofMap>(model_);
  if (dofs_->num_free() == 0) throw std::invalid_argument("model has no free degrees of freedom");
  build.sparsity_pattern();
  build.block_terms();
  build.discrete_terms();
  build.require_every_dof_touched();
}

Vector ParametricSystem::property_values(const Vector& p) const {
  if (p.size() != num_parameters())
    throw std::invalid_argument("expected " + std::to_string(num_parameters()) + " parameter values, got " +
                                std::to_string(p.size()));
  Vector theta(model_.properties.size());
  for (size_t i = 0; i < model_.properties.size(); ++i) theta[i] = model_.properties[i].value;
  for (int j = 0; j < num_parameters(); ++j)
    for (PropertyId id : targets_[j]) theta[id] = p[j];
  return theta;
}

std::string ParametricSystem::ill_conditioning(const Vector& p) const {
  const Vector theta = property_values(p);
  for (const ElementBlock& b : model_.blocks) {
    const double a = theta[b.modulus_a], m = theta[b.modulus_b];
    const bool young = b.form == ElasticForm::YoungPoisson;
    const double bulk_per_shear = young ? 2 * (1 + m) / (3 * (1 - 2 * m)) : a / m;
    if (!(bulk_per_shear > 1e4)) continue;
    char what[64], text[480];
    if (young)
      std::snprintf(what, sizeof what, "Poisson's ratio %.9g, so near 0.5,", m);
    else
      std::snprintf(what, sizeof what, "K = %.3g G", bulk_per_shear);
    std::snprintf(text, sizeof text,
                  "block '%.60s' has %s which makes the material nearly incompressible (bulk modulus %.2g times "
                  "the shear modulus) and K so ill-conditioned that the eigensolver sees zero-frequency modes; use %s",
                  b.name.c_str(), what, bulk_per_shear, young ? "nu <= 0.499" : "K <= 1000 G");
    return text;
  }
  return "";
}

std::string ParametricSystem::failure_message(const Vector& p, const std::string& solver_message) const {
  const std::string cause = ill_conditioning(p);
  return cause.empty() ? solver_message : cause + " (the solver: " + solver_message + ")";
}

namespace {
// d c / d p_j: sum over the properties parameter j sets.
double parameter_derivative(const Vector& gradient, const std::vector<PropertyId>& involved,
                            const std::vector<int>& property_parameter, int j) {
  double s = 0;
  for (size_t a = 0; a < involved.size(); ++a)
    if (property_parameter[involved[a]] == j) s += gradient[a];
  return s;
}
double parameter_second_derivative(const Matrix& hessian, const std::vector<PropertyId>& involved,
                                   const std::vector<int>& property_parameter, int j, int k) {
  double s = 0;
  for (size_t a = 0; a < involved.size(); ++a)
    for (size_t b = 0; b < involved.size(); ++b)
      if (property_parameter[involved[a]] == j && property_parameter[involved[b]] == k) s += hessian(a, b);
  return s;
}
}  // namespace

double ParametricSystem::term_scale(const Term& term, const Vector& theta, int j, int k) const {
  if (j < 0) return term.coefficient.value(theta);
  if (!std::binary_search(term.parameters.begin(), term.parameters.end(), j)) return 0.0;
  if (k >= 0 && !std::binary_search(term.parameters.begin(), term.parameters.end(), k)) return 0.0;
  Vector gradient;
  Matrix hessian;
  term.coefficient.derivatives(theta, &gradient, &hessian);
  const std::vector<PropertyId> involved = term.coefficient.involved();
  return k < 0 ? parameter_derivative(gradient, involved, property_parameter_, j)
               : parameter_second_derivative(hessian, involved, property_parameter_, j, k);
}

void ParametricSystem::accumulate(const Vector& p, int j, int k, SparseMatrix* K, SparseMatrix* M) const {
  for (SparseMatrix* A : {K, M}) {
    if (A->nonZeros() != pattern_.nonZeros() || A->rows() != pattern_.rows()) *A = pattern_;
    std::fill(A->valuePtr(), A->valuePtr() + A->nonZeros(), 0.0);
  }
  const Vector theta = property_values(p);
  for (const Term& t : terms_) {
    const double c = term_scale(t, theta, j, k);
    if (c == 0.0) continue;
    double* values = (t.mass ? M : K)->valuePtr();
    for (size_t i = 0; i < t.positions.size(); ++i) values[t.positions[i]] += c * t.values[i];
  }
}

void ParametricSystem::assemble(const Vector& p, SparseMatrix* K, SparseMatrix* M) const {
  accumulate(p, -1, -1, K, M);
}

std::vector<Matrix> ParametricSystem::project_terms(const Matrix& V) const {
  if (V.rows() != num_dofs())
    throw std::invalid_argument("ParametricSystem::project_terms: columns of length " + std::to_string(V.rows()) +
                                " for " + std::to_string(num_dofs()) + " DOFs");
  const Matrix Vt = V.transpose();  // row i of V is column i: contiguous
  const int* rows = pattern_.innerIndexPtr();
  std::vector<int> local(static_cast<size_t>(num_dofs()), -1);
  std::vector<Matrix> projected;
  projected.reserve(terms_.size());
  for (const Term& t : terms_) {
    // (K_t V)^T on the rows the term touches, then V^T K_t V from those rows alone.
    std::vector<int> touched;
    for (int position : t.positions)
      if (local[rows[position]] < 0) {
        local[rows[position]] = static_cast<int>(touched.size());
        touched.push_back(rows[position]);
      }
    Matrix W = Matrix::Zero(V.cols(), static_cast<Eigen::Index>(touched.size()));
    for (size_t i = 0; i < t.positions.size(); ++i)
      W.col(local[rows[t.positions[i]]]) += t.values[i] * Vt.col(columns_[t.positions[i]]);
    Matrix G(V.cols(), W.cols());
    for (size_t r = 0; r < touched.size(); ++r) {
      G.col(static_cast<Eigen::Index>(r)) = Vt.col(touched[r]);
      local[touched[r]] = -1;
    }
    Matrix P = G * W.transpose();
    projected.push_back(0.5 * (P + P.transpose()));
  }
  return projected;
}

void ParametricSystem::assemble_projected(const Vector& p, const std::vector<Matrix>& projected, Matrix* Kr,
                                          Matrix* Mr) const {
  if (projected.size() != terms_.size() || (!projected.empty() && projected.front().rows() != projected.front().cols()))
    throw std::invalid_argument("ParametricSystem::assemble_projected: " + std::to_string(projected.size()) +
                                " projected terms for " + std::to_string(terms_.size()) + " terms");
  const Eigen::Index r = projected.empty() ? 0 : projected.front().rows();
  Kr->setZero(r, r);
  Mr->setZero(r, r);
  const Vector theta = property_values(p);
  for (size_t t = 0; t < terms_.size(); ++t) {
    const double c = term_scale(terms_[t], theta, -1, -1);
    if (c != 0.0) (terms_[t].mass ? *Mr : *Kr) += c * projected[t];
  }
}

void ParametricSystem::assemble_derivative(const Vector& p, int j, SparseMatrix* dK, SparseMatrix* dM) const {
  check_parameter(j);
  accumulate(p, j, -1, dK, dM);
}

void ParametricSystem::assemble_second_derivative(const Vector& p, int j, int k, SparseMatrix* d2K,
                                                  SparseMatrix* d2M) const {
  check_parameter(j);
  check_parameter(k);
  accumulate(p, j, k, d2K, d2M);
}

void ParametricSystem::check_parameter(int j) const {
  if (j < 0 || j >= num_parameters())
    throw std::invalid_argument("parameter index " + std::to_string(j) + " out of range [0, " +
                                std::to_string(num_parameters()) + ")");
}

void ParametricSystem::derivative_times(const Vector& p, int j, const Vector& u, Vector* dKu, Vector* dMu) const {
  check_parameter(j);
  const Vector theta = property_values(p);
  dKu->setZero(num_dofs());
  dMu->setZero(num_dofs());
  const int* rows = pattern_.innerIndexPtr();
  for (const Term& t : terms_) {
    const double c = term_scale(t, theta, j, -1);
    if (c == 0.0) continue;
    Vector& y = t.mass ? *dMu : *dKu;
    for (size_t i = 0; i < t.positions.size(); ++i)
      y[rows[t.positions[i]]] += c * t.values[i] * u[columns_[t.positions[i]]];
  }
}

void ParametricSystem::derivative_forms(const Vector& p, const Vector& v, const Vector& u, Vector* a,
                                        Vector* b) const {
  const Vector theta = property_values(p);
  a->setZero(num_parameters());
  b->setZero(num_parameters());
  const int* rows = pattern_.innerIndexPtr();
  Vector gradient;
  Matrix hessian;
  for (const Term& t : terms_) {
    if (t.parameters.empty()) continue;
    double form = 0;
    for (size_t i = 0; i < t.positions.size(); ++i)
      form += v[rows[t.positions[i]]] * t.values[i] * u[columns_[t.positions[i]]];
    t.coefficient.derivatives(theta, &gradient, &hessian);
    const std::vector<PropertyId> involved = t.coefficient.involved();
    for (int j : t.parameters)
      (t.mass ? *b : *a)[j] += form * parameter_derivative(gradient, involved, property_parameter_, j);
  }
}

void ParametricSystem::derivative_forms(const Vector& p, const Matrix& V, const Matrix& U, Matrix* A,
                                        Matrix* B) const {
  if (V.rows() != num_dofs() || U.rows() != num_dofs() || V.cols() != U.cols())
    throw std::invalid_argument("derivative_forms: V is " + std::to_string(V.rows()) + " x " +
                                std::to_string(V.cols()) + " and U is " + std::to_string(U.rows()) + " x " +
                                std::to_string(U.cols()) + "; both must be " + std::to_string(num_dofs()) +
                                " x m");
  const Vector theta = property_values(p);
  const int m = static_cast<int>(U.cols());
  A->setZero(num_parameters(), m);
  B->setZero(num_parameters(), m);
  if (m == 0) return;
  // Row-major copies: the m entries a term position needs are contiguous, so the pass over the
  // terms streams positions and values once and the column loop vectorizes. Same products in
  // the same order per column as the single-pair version.
  using RowMajorMatrix = Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>;
  const RowMajorMatrix Ur = U;
  RowMajorMatrix Vr;
  const bool same = V.data() == U.data();
  if (!same) Vr = V;
  const double* u_rows = Ur.data();
  const double* v_rows = same ? Ur.data() : Vr.data();
  const int* rows = pattern_.innerIndexPtr();
  std::vector<double> form(m);
  Vector gradient;
  Matrix hessian;
  for (const Term& t : terms_) {
    if (t.parameters.empty()) continue;
    std::fill(form.begin(), form.end(), 0.0);
    double* f = form.data();
    for (size_t i = 0; i < t.positions.size(); ++i) {
      const int position = t.positions[i];
      const double* v = v_rows + static_cast<size_t>(rows[position]) * m;
      const double* u = u_rows + static_cast<size_t>(columns_[position]) * m;
      const double value = t.values[i];
      for (int c = 0; c < m; ++c) f[c] += v[c] * value * u[c];
    }
    t.coefficient.derivatives(theta, &gradient, &hessian);
    const std::vector<PropertyId> involved = t.coefficient.involved();
    Matrix& target = t.mass ? *B : *A;
    for (int j : t.parameters) {
      const double scale = parameter_derivative(gradient, involved, property_parameter_, j);
      for (int c = 0; c < m; ++c) target(j, c) += form[c] * scale;
    }
  }
}

void ParametricSystem::second_derivative_forms(const Vector& p, const Vector& v, const Vector& u, Matrix* A,
                                               Matrix* B) const {
  const Vector theta = property_values(p);
  A->setZero(num_parameters(), num_parameters());
  B->setZero(num_parameters(), num_parameters());
  const int* rows = pattern_.innerIndexPtr();
  Vector gradient;
  Matrix hessian;
  for (const Term& t : terms_) {
    if (t.parameters.empty()) continue;
    t.coefficient.derivatives(theta, &gradient, &hessian);
    if (hessian.isZero(0.0)) continue;
    double form = 0;
    for (size_t i = 0; i < t.positions.size(); ++i)
      form += v[rows[t.positions[i]]] * t.values[i] * u[columns_[t.positions[i]]];
    const std::vector<PropertyId> involved = t.coefficient.involved();
    for (int j : t.parameters)
      for (int k : t.parameters)
        (t.mass ? *B : *A)(j, k) += form * parameter_second_derivative(hessian, involved, property_parameter_, j, k);
  }
}

bool ParametricSystem::is_affine() const {
  const Vector theta = property_values(Vector::Ones(num_parameters()));
  Vector gradient;
  Matrix hessian;
  for (const Term& t : terms_) {
    if (t.parameters.empty()) continue;
    t.coefficient.derivatives(theta, &gradient, &hessian);
    const std::vector<PropertyId> involved = t.coefficient.involved();
    for (int j : t.parameters)
      for (int k : t.parameters)
        if (parameter_second_derivative(hessian, involved, property_parameter_, j, k) != 0.0) return false;
  }
  return true;
}

Matrix ParametricSystem::rigid_body_inertia(const Vector& p) const {
  const Vector theta = property_values(p);
  Matrix inertia = Matrix::Zero(num_dofs(), 3);
  for (const Term& t : terms_)
    if (t.inertia.size()) inertia += t.coefficient.value(theta) * t.inertia;
  // A point mass m at a node: m times the rows of T of the node's translations, which touch a few
  // free DOFs only (the terms keep no dense copy of them).
  for (const PointMass& m : model_.point_masses)
    if (m.mass != kNoProperty)
      add_inertia(*dofs_, inertia,
                  {dofs_->full_index(m.node, 0), dofs_->full_index(m.node, 1), dofs_->full_index(m.node, 2)},
                  theta[m.mass] * Matrix::Identity(3, 3));
  return inertia;
}

double ParametricSystem::total_mass(const Vector& p) const {
  const Vector theta = property_values(p);
  double mass = 0;
  for (const auto& [volume, density] : mass_groups_) mass += density.value(theta) * volume;
  for (const PointMass& m : model_.point_masses)
    if (m.mass != kNoProperty) mass += theta[m.mass];
  return mass;
}

}  // namespace modalcal
