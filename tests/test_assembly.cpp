// Parametric assembly: exact first and second derivatives of K(p), M(p) against finite
// differences for every kind of parameter (Taylor remainder shrinking at second order), the
// product/derivative shortcuts against the assembled derivatives, and the rigid-coupling
// elimination.

#include <Eigen/Geometry>

#include <cmath>

#include "modalcal/assembly.hpp"
#include "modalcal/problem.hpp"
#include "modalcal/problem_file.hpp"
#include "test_util.hpp"

namespace modalcal {
namespace {

using testing::LoadProblem;
using testing::WriteTempFile;

// Two blocks (E/nu and K/G forms, with stiffness and mass scales), a rigid coupling, a joint
// with all six components in a rotated frame, springs to ground and a point mass with inertia:
// one parameter of every kind.
const char* kEveryKind = R"(
mesh:
  element: hex8
  element_size: 1.0
  boxes:
    - {block: a, min: [0, 0, 0], max: [2, 1, 1]}
    - {block: b, min: [2, 0, 0], max: [3, 1, 1]}
blocks:
  a: {E: 2.0e3, nu: 0.3, density: 1.0, stiffness_scale: 1.0, mass_scale: 1.0}
  b: {K: 1.5e3, G: 0.8e3, density: 2.0}
node_sets:
  left: {box: {min: [0, 0, 0], max: [0, 1, 1]}}
  right: {box: {min: [3, 0, 0], max: [3, 1, 1]}}
reference_nodes:
  r: [3.5, 0.5, 0.5]
  g: [3.5, 0.5, 0.5]
rigid_couplings:
  - {reference: r, node_set: right}
joints:
  j: {nodes: [r, g], frame: {x: [0.6, 0.8, 0], y: [-0.8, 0.6, 0]}, kx: 100, ky: 200, kz: 300, krx: 10, kry: 20, krz: 30}
springs:
  s: {node_set: left, kx: 50, ky: 60, kz: 70}
point_masses:
  pm: {node: g, mass: 0.5, inertia: [0.01, 0.02, 0.03]}
parameters:
  E: {targets: [a.E], initial: 2.0e3, lower: 1, upper: 1e5}
  nu: {targets: [a.nu], initial: 0.3, lower: 0.0, upper: 0.45}
  K: {targets: [b.K], initial: 1.5e3, lower: 1, upper: 1e5}
  G: {targets: [b.G], initial: 0.8e3, lower: 1, upper: 1e5}
  rho: {targets: [a.density, b.density], initial: 1.5, lower: 0.1, upper: 10}
  kscale: {targets: [a.stiffness_scale], initial: 1.2, lower: 0.1, upper: 10}
  mscale: {targets: [a.mass_scale], initial: 0.9, lower: 0.1, upper: 10}
  kx: {targets: [j.kx], initial: 100, lower: 1, upper: 1e4}
  krz: {targets: [j.krz], initial: 30, lower: 1, upper: 1e4}
  spring: {targets: [s.ky], initial: 60, lower: 1, upper: 1e4}
  mass: {targets: [pm.mass], initial: 0.5, lower: 0.01, upper: 10}
  inertia: {targets: [pm.Ixx], initial: 0.01, lower: 0.001, upper: 1}
)";

struct Fixture {
  Problem problem;
  std::unique_ptr<ParametricSystem> system;
  Vector p0;
};

Fixture Load() {
  Fixture f;
  f.problem = LoadProblem(WriteTempFile("every_kind.yaml", kEveryKind));
  f.system = std::make_unique<ParametricSystem>(f.problem.model, f.problem.parameter_targets());
  f.p0 = f.problem.initial_values();
  return f;
}

Matrix Dense(const SparseMatrix& A) { return Matrix(A); }

TEST(ParametricSystem, FirstDerivativesMatchFiniteDifferencesWithSecondOrderRemainder) {
  Fixture f = Load();
  SparseMatrix K0, M0, dK, dM, Kh, Mh;
  f.system->assemble(f.p0, &K0, &M0);
  ASSERT_FALSE(f.system->is_affine());  // (E, nu) and the scale products are not affine
  for (int j = 0; j < f.system->num_parameters(); ++j) {
    SCOPED_TRACE(f.problem.parameters[j].name);
    f.system->assemble_derivative(f.p0, j, &dK, &dM);
    const double scale = Dense(dK).norm() + Dense(dM).norm();
    ASSERT_GT(scale, 0.0) << "derivative vanishes: the parameter does not act";
    // Taylor remainder r(h) = |A(p + h e_j) - A(p) - h dA| must fall ~4x when h halves.
    double previous = 0;
    for (int level = 0; level < 3; ++level) {
      const double h = 1e-2 * std::abs(f.p0[j]) / std::pow(2.0, level);
      Vector p = f.p0;
      p[j] += h;
      f.system->assemble(p, &Kh, &Mh);
      const double remainder = (Dense(Kh) - Dense(K0) - h * Dense(dK)).norm() +
                               (Dense(Mh) - Dense(M0) - h * Dense(dM)).norm();
      if (level > 0 && remainder > 1e-9 * scale * h) {
        EXPECT_NEAR(previous / remainder, 4.0, 0.4) << "h = " << h;
      }
      previous = remainder;
    }
  }
}

TEST(ParametricSystem, SecondDerivativesMatchFiniteDifferencesOfFirst) {
  Fixture f = Load();
  SparseMatrix dKp, dMp, dKm, dMm, d2K, d2M;
  const int n = f.system->num_parameters();
  for (int j = 0; j < n; ++j)
    for (int k = 0; k < n; ++k) {
      const double h = 1e-5 * std::abs(f.p0[k]);
      Vector pp = f.p0, pm = f.p0;
      pp[k] += h;
      pm[k] -= h;
      f.system->assemble_derivative(pp, j, &dKp, &dMp);
      f.system->assemble_derivative(pm, j, &dKm, &dMm);
      f.system->assemble_second_derivative(f.p0, j, k, &d2K, &d2M);
      const Matrix fdK = (Dense(dKp) - Dense(dKm)) / (2 * h);
      const Matrix fdM = (Dense(dMp) - Dense(dMm)) / (2 * h);
      const double scale = fdK.norm() + fdM.norm() + Dense(d2K).norm() + Dense(d2M).norm();
      if (scale == 0) continue;
      EXPECT_LT(((fdK - Dense(d2K)).norm() + (fdM - Dense(d2M)).norm()) / scale, 1e-6)
          << f.problem.parameters[j].name << " x " << f.problem.parameters[k].name;
    }
}

TEST(ParametricSystem, ProductsAndFormsAgreeWithAssembledDerivatives) {
  Fixture f = Load();
  const int n = f.system->num_dofs();
  const Vector u = Vector::LinSpaced(n, -1.0, 2.0).array().sin();
  const Vector v = Vector::LinSpaced(n, 0.5, 3.0).array().cos();
  Vector a, b, dKu, dMu;
  Matrix A, B;
  f.system->derivative_forms(f.p0, v, u, &a, &b);
  f.system->second_derivative_forms(f.p0, v, u, &A, &B);
  SparseMatrix dK, dM;
  for (int j = 0; j < f.system->num_parameters(); ++j) {
    f.system->assemble_derivative(f.p0, j, &dK, &dM);
    f.system->derivative_times(f.p0, j, u, &dKu, &dMu);
    EXPECT_LT((dKu - dK * u).norm(), 1e-12 * (1 + (dK * u).norm()));
    EXPECT_LT((dMu - dM * u).norm(), 1e-12 * (1 + (dM * u).norm()));
    EXPECT_NEAR(a[j], v.dot(dK * u), 1e-10 * (1 + std::abs(a[j])));
    EXPECT_NEAR(b[j], v.dot(dM * u), 1e-10 * (1 + std::abs(b[j])));
    for (int k = 0; k < f.system->num_parameters(); ++k) {
      SparseMatrix d2K, d2M;
      f.system->assemble_second_derivative(f.p0, j, k, &d2K, &d2M);
      EXPECT_NEAR(A(j, k), v.dot(d2K * u), 1e-10 * (1 + std::abs(A(j, k))));
      EXPECT_NEAR(B(j, k), v.dot(d2M * u), 1e-10 * (1 + std::abs(B(j, k))));
    }
  }
}

// The objective takes the eigenvalue sensitivities of all paired modes (and the adjoint forms of
// all shapes) in one blocked call: it must give exactly what one call per column gives, also
// when V and U are the same matrix (its shortcut) and for terms no parameter touches.
TEST(ParametricSystem, BlockedFormsEqualPerColumnForms) {
  Fixture f = Load();
  const int n = f.system->num_dofs(), np = f.system->num_parameters(), m = 5;
  Matrix U(n, m), V(n, m);
  for (int c = 0; c < m; ++c) {
    U.col(c) = Vector::LinSpaced(n, -1.0 - c, 2.0 + 0.5 * c).array().sin();
    V.col(c) = Vector::LinSpaced(n, 0.5 * c, 3.0 + c).array().cos();
  }
  Matrix A, B, Auu, Buu;
  f.system->derivative_forms(f.p0, V, U, &A, &B);
  f.system->derivative_forms(f.p0, U, U, &Auu, &Buu);
  ASSERT_EQ(A.rows(), np);
  ASSERT_EQ(A.cols(), m);
  ASSERT_EQ(Buu.rows(), np);
  ASSERT_EQ(Buu.cols(), m);
  for (int c = 0; c < m; ++c) {
    Vector a, b, auu, buu;
    f.system->derivative_forms(f.p0, Vector(V.col(c)), Vector(U.col(c)), &a, &b);
    f.system->derivative_forms(f.p0, Vector(U.col(c)), Vector(U.col(c)), &auu, &buu);
    for (int j = 0; j < np; ++j) {
      EXPECT_NEAR(A(j, c), a[j], 1e-14 * (1 + std::abs(a[j]))) << f.problem.parameters[j].name << ", column " << c;
      EXPECT_NEAR(B(j, c), b[j], 1e-14 * (1 + std::abs(b[j]))) << f.problem.parameters[j].name << ", column " << c;
      EXPECT_NEAR(Auu(j, c), auu[j], 1e-14 * (1 + std::abs(auu[j]))) << f.problem.parameters[j].name;
      EXPECT_NEAR(Buu(j, c), buu[j], 1e-14 * (1 + std::abs(buu[j]))) << f.problem.parameters[j].name;
    }
  }
  // No columns: empty results; mismatched blocks are refused.
  f.system->derivative_forms(f.p0, Matrix(n, 0), Matrix(n, 0), &A, &B);
  EXPECT_EQ(A.rows(), np);
  EXPECT_EQ(A.cols(), 0);
  EXPECT_THROW(f.system->derivative_forms(f.p0, V, Matrix(U.leftCols(m - 1)), &A, &B), std::invalid_argument);
  EXPECT_THROW(f.system->derivative_forms(f.p0, Matrix(V.topRows(n - 1)), Matrix(U.topRows(n - 1)), &A, &B),
               std::invalid_argument);
}

// The terms projected on a span once give V^T K(p) V and V^T M(p) V at any p, the nominal and
// a point where every parameter has moved (Young/Poisson coefficients included), to rounding.
TEST(ParametricSystem, ProjectedTermsGiveTheProjectedMatricesAtEveryPoint) {
  Fixture f = Load();
  const int n = f.system->num_dofs(), r = 7;
  Matrix V(n, r);
  for (int c = 0; c < r; ++c) V.col(c) = Vector::LinSpaced(n, -1.0 - c, 2.0 + 0.7 * c).array().sin();
  const std::vector<Matrix> projected = f.system->project_terms(V);
  for (const Vector& p : {f.p0, Vector(f.p0 * 1.2)}) {
    SparseMatrix K, M;
    f.system->assemble(p, &K, &M);
    Matrix Kr, Mr;
    f.system->assemble_projected(p, projected, &Kr, &Mr);
    const Matrix expected_K = V.transpose() * K * V, expected_M = V.transpose() * M * V;
    EXPECT_LT((Kr - expected_K).norm(), 1e-12 * expected_K.norm());
    EXPECT_LT((Mr - expected_M).norm(), 1e-12 * expected_M.norm());
    EXPECT_LE((Kr - Kr.transpose()).norm(), 1e-14 * Kr.norm());
  }
  EXPECT_THROW(f.system->project_terms(Matrix(V.topRows(n - 1))), std::invalid_argument);
  Matrix Kr, Mr;
  EXPECT_THROW(f.system->assemble_projected(f.p0, std::vector<Matrix>(1, Matrix::Identity(r, r)), &Kr, &Mr),
               std::invalid_argument);
}

TEST(ParametricSystem, MatricesAreSymmetricAndTotalMassIsExact) {
  Fixture f = Load();
  SparseMatrix K, M;
  f.system->assemble(f.p0, &K, &M);
  EXPECT_LT((Dense(K) - Dense(K).transpose()).norm(), 1e-12 * Dense(K).norm());
  EXPECT_LT((Dense(M) - Dense(M).transpose()).norm(), 1e-12 * Dense(M).norm());
  // rho = 1.5 on both blocks (volumes 2 and 1), block a's mass scale 0.9, point mass 0.5.
  EXPECT_CLOSE(f.system->total_mass(f.p0), 1.5 * 0.9 * 2.0 + 1.5 * 1.0 + 0.5, 1e-12);
}

// With no DOF fixed (the model is free-free), the rigid-translation inertia is M r_d, r_d the unit
// translation along d of every node (through the rigid coupling, of its reference node), and
// r_d^T M r_d is the total mass: blocks and the point mass alike.
TEST(ParametricSystem, RigidBodyInertiaIsTheMassTimesTheRigidTranslations) {
  Fixture f = Load();
  SparseMatrix K, M;
  f.system->assemble(f.p0, &K, &M);
  const Matrix inertia = f.system->rigid_body_inertia(f.p0);
  const DofMap& dofs = f.system->dof_map();
  ASSERT_EQ(inertia.rows(), dofs.num_free());
  for (int d = 0; d < 3; ++d) {
    Vector r = Vector::Zero(dofs.num_free());
    for (int i = 0; i < dofs.num_free(); ++i) r[i] = dofs.free_owner(i).second == d ? 1.0 : 0.0;
    const Vector Mr = M * r;
    EXPECT_LT((inertia.col(d) - Mr).norm(), 1e-12 * Mr.norm()) << "direction " << d;
    EXPECT_CLOSE(r.dot(inertia.col(d)), f.system->total_mass(f.p0), 1e-12);
  }
}

TEST(DofMap, RigidCouplingMovesCoupledNodesRigidly) {
  Fixture f = Load();
  const DofMap& dofs = f.system->dof_map();
  const Model& model = f.problem.model;
  const RigidCoupling& coupling = model.rigid_couplings.at(0);
  const int r = coupling.reference;
  Vector u = Vector::Zero(dofs.num_free());
  const Vec3 t(0.1, -0.2, 0.3), theta(0.01, 0.02, -0.03);
  for (int c = 0; c < 3; ++c) {
    u[dofs.free_index(r, c)] = t[c];
    u[dofs.free_index(r, 3 + c)] = theta[c];
  }
  for (int s : coupling.nodes) {
    EXPECT_EQ(dofs.free_index(s, 0), -1) << "coupled DOFs must be eliminated";
    const Vec3 expected = t + theta.cross(model.coordinates[s] - model.coordinates[r]);
    for (int c = 0; c < 3; ++c) EXPECT_NEAR(dofs.value(u, s, c), expected[c], 1e-14);
  }
}

TEST(Coefficient, YoungPoissonDerivativesMatchFiniteDifferences) {
  Vector theta(3);
  theta << 2.0e3, 0.3, 1.7;
  for (auto kind : {Coefficient::Kind::BulkFromYoung, Coefficient::Kind::ShearFromYoung}) {
    Coefficient c;
    c.factors = {{kind, 0, 1}, {Coefficient::Kind::Property, 2, kNoProperty}};
    Vector g;
    Matrix h;
    c.derivatives(theta, &g, &h);
    for (int i = 0; i < 3; ++i) {
      const double step = 1e-6 * std::abs(theta[i]);
      Vector tp = theta, tm = theta;
      tp[i] += step;
      tm[i] -= step;
      EXPECT_CLOSE(g[i], (c.value(tp) - c.value(tm)) / (2 * step), 1e-7);
      Vector gp, gm;
      Matrix unused;
      c.derivatives(tp, &gp, &unused);
      c.derivatives(tm, &gm, &unused);
      for (int k = 0; k < 3; ++k)
        EXPECT_NEAR(h(k, i), (gp[k] - gm[k]) / (2 * step), 1e-6 * (1 + std::abs(h(k, i))));
    }
  }
}

TEST(ParametricSystem, UnactedDofIsNamed) {
  Model model = testing::MakeChain(3, 1.0, 10.0, true);
  model.add_node(99, Vec3(10, 0, 0), true);  // a reference node nothing acts on
  try {
    ParametricSystem system(model, {});
    FAIL() << "expected an error";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("node 99"), std::string::npos) << e.what();
  }
}

}  // namespace
}  // namespace modalcal
