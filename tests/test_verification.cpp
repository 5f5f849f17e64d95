// Verification of the whole forward pipeline (problem file -> box mesher -> parametric assembly
// -> modal solve -> mode description) against closed-form solutions:
//   - axial modes of a fixed-free rod, with the observed h-convergence order of hex8, tet4, tet10;
//   - the first bending modes of a solid cantilever against Euler-Bernoulli (tet10), and the
//     shear-locking convergence from above of fully integrated hex8;
//   - the sparse (CHOLMOD + Lanczos) path against a dense generalized eigensolve;
//   - rigid-body modes of a free-free solid;
//   - rigid couplings + a Joint2G between two stiff cubes (a one-DOF oscillator);
//   - a point mass with rotary inertia on a six-component joint;
//   - effective-mass fractions of the rod.
// The spring-mass chain is verified in test_eigen.cpp and not repeated here.

#include <Eigen/Eigenvalues>

#include <array>
#include <cmath>
#include <cstdio>
#include <memory>
#include <sstream>
#include <string>
#include <vector>

#include "modalcal/assembly.hpp"
#include "modalcal/eigen.hpp"
#include "modalcal/mode_description.hpp"
#include "modalcal/problem.hpp"
#include "modalcal/problem_file.hpp"
#include "test_util.hpp"

namespace modalcal {
namespace {

using testing::LoadProblem;
using testing::WriteTempFile;

constexpr double kPi = 3.14159265358979323846;

// A problem loaded from YAML, its assembled K and M at the initial parameters, and the modal
// solution with the problem's options (num_modes, max_rigid_modes, tolerance).
struct Solution {
  Problem problem;
  std::unique_ptr<ParametricSystem> system;
  Vector p;
  SparseMatrix K, M;
  ModalResult result;
};

Solution Solve(const std::string& file, const std::string& yaml) {
  Solution s;
  s.problem = LoadProblem(WriteTempFile(file, yaml));
  s.system = std::make_unique<ParametricSystem>(s.problem.model, s.problem.parameter_targets());
  s.p = s.problem.initial_values();
  s.system->assemble(s.p, &s.K, &s.M);
  ModalOptions options;
  options.num_modes = s.problem.options.num_modes;
  options.max_rigid_modes = s.problem.expected_rigid_modes();
  options.tolerance = s.problem.options.tolerance;
  ModalSolver solver(s.system->pattern(), options);
  s.result = solver.solve(s.K, s.M);
  return s;
}

std::string Num(double x) {
  std::ostringstream s;
  s.precision(17);
  s << x;
  return s.str();
}

// ------------------------------------------------------------------------------ axial rod

// Bar along x, length 10, section 0.5 x 0.5, E = 1000, nu = 0, rho = 1. u_x = 0 on the x = 0
// face and u_y = u_z = 0 at *every* node: only u_x(x, y, z) remains, and with nu = 0 the
// section-uniform fields u_x(x) carry exactly the 1-D rod energy (E A/2) int u'^2 and kinetic
// energy (rho A/2) int u^2, so the continuum problem is exactly the fixed-free rod
//   omega_n = (2n - 1) pi / (2 L) sqrt(E / rho),   f_n = (2n - 1) / (4 L) sqrt(E / rho).
// Modes varying over the section (shear of u_x) start near G (pi / 0.5)^2 / rho ~ 2e4, far
// above the third axial mode (omega_3^2 ~ 617).
constexpr double kBarL = 10, kBarE = 1000, kBarRho = 1;

std::string BarYaml(const std::string& element, int nx, int num_modes) {
  return R"(
mesh:
  element: )" + element + R"(
  element_size: )" + Num(kBarL / nx) + R"(
  boxes:
    - {block: bar, min: [0, 0, 0], max: [10, 0.5, 0.5]}
blocks:
  bar: {E: 1000, nu: 0, density: 1}
node_sets:
  root: {box: {min: [0, 0, 0], max: [0, 0.5, 0.5]}}
  all: {box: {min: [0, 0, 0], max: [10, 0.5, 0.5]}}
fixed:
  - {node_set: root, dofs: [x]}
  - {node_set: all, dofs: [y, z]}
options: {num_modes: )" + std::to_string(num_modes) + R"(}
)";
}

double RodOmega2(int n) {
  const double omega = (2 * n - 1) * kPi / (2 * kBarL) * std::sqrt(kBarE / kBarRho);
  return omega * omega;
}

struct BarCase {
  const char* element;
  std::array<int, 3> nx;    // elements along the bar, each mesh halving h
  int modes;                // modes whose convergence order is checked
  double min_order, max_order;
  double finest_error;      // bound on the relative eigenvalue error on the finest mesh
};

void PrintTo(const BarCase& c, std::ostream* os) {
  *os << c.element << " nx = " << c.nx[0] << ", " << c.nx[1] << ", " << c.nx[2];
}

class AxialBar : public ::testing::TestWithParam<BarCase> {};

// Consistent mass and conforming elements make the discrete problem a Rayleigh-Ritz
// approximation: every eigenvalue converges from above, lambda_h >= lambda. For elements of
// degree p the eigenvalue error is O(h^{2p}) (Strang & Fix, "An Analysis of the Finite Element
// Method", ch. 6): order 2 for hex8 and tet4, 4 for tet10. For linear elements on the 1-D rod
// it is exactly lambda_h = (6 / h^2) (1 - cos kh) / (2 + cos kh) E/rho = lambda (1 + (kh)^2/12
// + ...). The observed order log2(err(h) / err(h/2)) must match.
// hex8 reproduces the 1-D rod exactly (tested below); the tet split is not symmetric across
// the section, so tet4 only contains the 1-D rod space (its eigenvalues are a little lower
// than the rod's, still above the exact ones) and tet10 contains the quadratic rod space.
TEST_P(AxialBar, ConvergesToRodFrequenciesAtTheTheoreticalOrder) {
  const BarCase c = GetParam();
  std::array<std::array<double, 3>, 3> error{};  // [mode][level], relative eigenvalue error
  for (int level = 0; level < 3; ++level) {
    const int nx = c.nx[level];
    SCOPED_TRACE(std::string(c.element) + ", nx = " + std::to_string(nx));
    const Solution s = Solve("bar.yaml", BarYaml(c.element, nx, 3));
    ASSERT_EQ(s.result.status, EigenStatus::Successful) << s.result.message;
    ASSERT_EQ(s.result.eigenvalues.size(), 3);
    for (int m = 0; m < 3; ++m) {
      const double exact = RodOmega2(m + 1);
      error[m][level] = (s.result.eigenvalues[m] - exact) / exact;
      EXPECT_GT(error[m][level], 0.0) << "mode " << m + 1 << ": Rayleigh-Ritz upper bound violated";
    }
  }
  for (int m = 0; m < 3; ++m) {
    SCOPED_TRACE(std::string(c.element) + ", mode " + std::to_string(m + 1));
    EXPECT_LT(error[m][1], error[m][0]);
    EXPECT_LT(error[m][2], error[m][1]);
    EXPECT_LT(error[m][2], c.finest_error);
    const double order01 = std::log2(error[m][0] / error[m][1]);
    const double order12 = std::log2(error[m][1] / error[m][2]);
    std::printf("[ verify   ] %s axial mode %d: rel. eigenvalue error %.3e %.3e %.3e (nx = %d %d %d), "
                "observed order %.3f %.3f\n",
                c.element, m + 1, error[m][0], error[m][1], error[m][2], c.nx[0], c.nx[1], c.nx[2],
                order01, order12);
    if (m >= c.modes) continue;
    EXPECT_GE(order01, c.min_order);
    EXPECT_LE(order01, c.max_order);
    EXPECT_GE(order12, c.min_order);
    EXPECT_LE(order12, c.max_order);
  }
}

INSTANTIATE_TEST_SUITE_P(
    Elements, AxialBar,
    ::testing::Values(BarCase{"hex8", {8, 16, 32}, 3, 1.8, 2.2, 1e-2},
                      BarCase{"tet4", {8, 16, 32}, 3, 1.8, 2.2, 1e-2},
                      BarCase{"tet10", {2, 4, 8}, 3, 3.5, 4.5, 2e-3}),
    [](const ::testing::TestParamInfo<BarCase>& test) { return std::string(test.param.element); });

// Tensor-product hex8 with u_y = u_z = 0 and nu = 0 is exactly the 1-D rod of linear elements
// with consistent mass, whose eigenvalues are known in closed form (the mode shapes
// sin(j theta) at the nodes satisfy the interior difference equations for any theta, and the
// free end selects cos(N theta) = 0):
//   lambda_n = (E / rho) (6 / h^2) (1 - cos theta) / (2 + cos theta),  theta = (2n - 1) pi / (2N).
// All four section nodes move together: the section-varying modes are far higher.
TEST(AxialRod, Hex8ReproducesTheDiscreteRodEigenvaluesExactly) {
  const int nx = 32;
  const Solution s = Solve("bar.yaml", BarYaml("hex8", nx, 3));
  ASSERT_EQ(s.result.status, EigenStatus::Successful) << s.result.message;
  const double h = kBarL / nx;
  for (int n = 1; n <= 3; ++n) {
    const double theta = (2 * n - 1) * kPi / (2 * nx);
    const double discrete =
        kBarE / kBarRho * 6 / (h * h) * (1 - std::cos(theta)) / (2 + std::cos(theta));
    EXPECT_CLOSE(s.result.eigenvalues[n - 1], discrete, 1e-10) << "mode " << n;
  }
}

// Fixed-free rod: the effective mass of mode n along the rod is 8 / ((2n - 1)^2 pi^2) of the
// total mass (Gamma_n = int rho A phi_n dx with phi_n = sqrt(2/(rho A L)) sin((2n-1) pi x/(2L))),
// 0.8106 for the first mode; the fractions sum to 1 over all modes.
double RodEffectiveMassFraction(int n) { return 8 / ((2 * n - 1) * (2 * n - 1) * kPi * kPi); }

TEST(EffectiveMass, FixedFreeRodFirstModeCarriesEightOverPiSquared) {
  const Solution s = Solve("bar.yaml", BarYaml("hex8", 40, 3));
  ASSERT_EQ(s.result.status, EigenStatus::Successful) << s.result.message;
  EXPECT_CLOSE(s.system->total_mass(s.p), kBarRho * kBarL * 0.25, 1e-12);
  const std::vector<ModeDescription> d = describe_modes(*s.system, s.p, s.M, s.result);
  ASSERT_EQ(d.size(), 3u);
  EXPECT_CLOSE(d[0].effective_mass_fraction[0], RodEffectiveMassFraction(1), 1e-2);
  for (const ModeDescription& m : d) {
    EXPECT_NEAR(m.effective_mass_fraction[1], 0.0, 1e-14);
    EXPECT_NEAR(m.effective_mass_fraction[2], 0.0, 1e-14);
    EXPECT_EQ(m.dominant_direction, 0);
    EXPECT_NEAR(m.energy_fraction[0], 1.0, 1e-12);
  }
}

// Over *all* modes of a model the fractions sum to r^T M r / m_total (the modes are complete);
// this tends to 1 as the mesh is refined (only the mass next to the support is lost, O(h / L)).
// nx = 20 with one element across the section: 80 free DOFs, all computed (dense path).
TEST(EffectiveMass, FixedFreeRodFractionsOverAllModesSumTowardOne) {
  const int nx = 20;
  const Solution s = Solve("bar.yaml", BarYaml("hex8", nx, 80));
  ASSERT_EQ(s.system->num_dofs(), 80);
  ASSERT_EQ(s.result.status, EigenStatus::Successful) << s.result.message;
  const std::vector<ModeDescription> d = describe_modes(*s.system, s.p, s.M, s.result);
  double sum = 0;
  for (const ModeDescription& m : d) sum += m.effective_mass_fraction[0];
  const double h = kBarL / nx;
  std::printf("[ verify   ] rod (nx = %d): effective mass fractions over all %zu modes sum to %.6f\n",
              nx, d.size(), sum);
  EXPECT_LE(sum, 1.0 + 1e-12);
  EXPECT_GE(sum, 1.0 - h / kBarL);
}

// The next modes too: 8 / ((2n - 1)^2 pi^2) = 0.0901, 0.0324, 0.0165, 0.0100 for n = 2..5.
// The discrete model reproduces them closely: with the standard base-excitation participation
// factor Gamma = phi^T M_full r_full (r = 1 on *every* x DOF, the supported ones included,
// since the base moves them), the consistent-mass rod at nx = 40 is within 2e-4 of the closed
// form for n <= 5 (checked below on a companion model whose root x DOFs are kept). The test
// asks 1e-3 of describe_modes.
//
// KNOWN FAILURE (library): describe_modes uses Gamma = r_f^T M_ff phi over the free DOFs only,
// which drops the inertial coupling M_fs between the support and the free DOFs of the consistent
// mass matrix. For the rod this loses rho A h/6 sin(kh) of Gamma, a relative error of about
// -(kh)^2/3 in the fraction: -0.05 %, -0.46 %, -1.3 %, -2.5 %, -4.1 % for n = 1..5 at nx = 40
// (and the all-mode sum is r_f^T M_ff r_f / m = 1 - 2h/(3L)). The formula is exact only for a
// lumped mass matrix (M_fs = 0); this library's mass matrices are consistent.
TEST(EffectiveMass, FixedFreeRodHigherModeFractionsMatchClosedForm) {
  const Solution s = Solve("bar.yaml", BarYaml("hex8", 40, 5));
  ASSERT_EQ(s.result.status, EigenStatus::Successful) << s.result.message;
  const std::vector<ModeDescription> d = describe_modes(*s.system, s.p, s.M, s.result);
  ASSERT_EQ(d.size(), 5u);
  // Companion model: the same mesh with the root's x DOFs free, to get the full mass matrix on
  // the x DOFs (node indices are the same in both models).
  std::string yaml = BarYaml("hex8", 40, 5);
  const std::string root_fix = "  - {node_set: root, dofs: [x]}\n";
  yaml.erase(yaml.find(root_fix), root_fix.size());
  const Problem full_problem = LoadProblem(WriteTempFile("bar_full.yaml", yaml));
  ParametricSystem full(full_problem.model, {});
  SparseMatrix K_full, M_full;
  full.assemble(Vector(), &K_full, &M_full);
  const int root_nodes = static_cast<int>(full_problem.model.find_node_set("root")->nodes.size());
  ASSERT_EQ(full.num_dofs(), s.system->num_dofs() + root_nodes);  // the root nodes' x DOFs
  Vector r_full = Vector::Ones(full.num_dofs());            // every DOF is an x DOF
  const double m_total = s.system->total_mass(s.p);
  for (int n = 1; n <= 5; ++n) {
    SCOPED_TRACE("mode " + std::to_string(n));
    Vector phi = Vector::Zero(full.num_dofs());
    for (int f = 0; f < s.system->num_dofs(); ++f) {
      const auto [node, comp] = s.system->dof_map().free_owner(f);
      phi[full.dof_map().free_index(node, comp)] = s.result.modes(f, n - 1);
    }
    const double gamma = r_full.dot(M_full * phi);
    EXPECT_CLOSE(gamma * gamma / m_total, RodEffectiveMassFraction(n), 2e-4);  // the model is right
    EXPECT_CLOSE(d[n - 1].effective_mass_fraction[0], RodEffectiveMassFraction(n), 1e-3);
  }
}

// ------------------------------------------------------------------------------ cantilever

// Cantilever along x: L = 10, section h_y = 1 by h_z = 1.1, E = 1e4, nu = 0, rho = 1, clamped
// (u = 0) on the x = 0 face. nu = 0 makes the clamp exact for beam theory (no Poisson
// constraint at the root) and removes Poisson stiffening.
//
// The section is deliberately not square. For a square section the y and z bending modes are
// degenerate in the continuum, and any combination of them is an eigenvector; the tet split of
// the mesher (all six tets of a hex around its 0-6 diagonal) is symmetric under y <-> z but
// not under a 90 degree rotation about x, so it would split the pair into *diagonal* bending
// modes (along y + z and y - z), whose dominant direction is meaningless. With h_z = 1.1 h_y
// the pair is 10 % apart and each mode bends along one axis.
//
// Euler-Bernoulli: omega_1 = (beta_1 L)^2 / L^2 sqrt(E I / (rho A)), beta_1 L = 1.8751041,
// and I / A = h^2 / 12 with h the thickness in the bending direction: h_y for bending along y
// (first mode), h_z for bending along z (second).
constexpr double kBeamL = 10, kBeamE = 1e4, kBeamRho = 1, kBeamHy = 1.0, kBeamHz = 1.1;

std::string BeamYaml(const std::string& element, double element_size) {
  return R"(
mesh:
  element: )" + element + R"(
  element_size: )" + Num(element_size) + R"(
  boxes:
    - {block: beam, min: [0, 0, 0], max: [10, 1, 1.1]}
blocks:
  beam: {E: 1.0e4, nu: 0, density: 1}
node_sets:
  root: {box: {min: [0, 0, 0], max: [0, 1, 1.1]}}
fixed:
  - {node_set: root, dofs: [x, y, z]}
options: {num_modes: 2}
)";
}

double EulerBernoulliHz(double h) {
  const double beta_l = 1.87510407;
  return beta_l * beta_l / (2 * kPi * kBeamL * kBeamL) * std::sqrt(kBeamE * h * h / 12 / kBeamRho);
}

// tet10 has no shear locking. At L/h = 10, shear deformation and rotary inertia (Timoshenko)
// lower the first frequency below Euler-Bernoulli by under 1 % (0.65 % measured), the
// discretization raises it slightly: 2 % bounds both.
TEST(Cantilever, Tet10FirstBendingPairMatchesEulerBernoulli) {
  const Solution s = Solve("beam.yaml", BeamYaml("tet10", 0.5));
  ASSERT_EQ(s.result.status, EigenStatus::Successful) << s.result.message;
  const std::vector<ModeDescription> d = describe_modes(*s.system, s.p, s.M, s.result);
  ASSERT_EQ(d.size(), 2u);
  const double fy = EulerBernoulliHz(kBeamHy), fz = EulerBernoulliHz(kBeamHz);
  std::printf("[ verify   ] tet10 cantilever: f1 = %.6f Hz (EB %.6f, ratio %.5f), f2 = %.6f Hz "
              "(EB %.6f, ratio %.5f)\n",
              d[0].frequency_hz, fy, d[0].frequency_hz / fy, d[1].frequency_hz, fz,
              d[1].frequency_hz / fz);
  EXPECT_CLOSE(d[0].frequency_hz, fy, 0.02);
  EXPECT_CLOSE(d[1].frequency_hz, fz, 0.02);
  // Shear deformation and rotary inertia can only lower the frequency below Euler-Bernoulli;
  // the tet10 discretization error at this size (0.011 %: 0.160511 Hz here, 0.160493 Hz at
  // element size 0.25) is far smaller than that drop (0.65 %).
  EXPECT_LT(d[0].frequency_hz, fy);
  EXPECT_LT(d[1].frequency_hz, fz);
  // The pair: bending along y first (thinner), then along z, 1.1 x apart as h_z / h_y.
  EXPECT_CLOSE(d[1].frequency_hz / d[0].frequency_hz, kBeamHz / kBeamHy, 0.01);
  EXPECT_EQ(d[0].dominant_direction, 1);
  EXPECT_EQ(d[1].dominant_direction, 2);
  // Bending: kinetic energy is mostly transverse (the axial share comes from section rotation,
  // ~ (h / L)^2), and a clamped cantilever's first mode has effective mass 0.613 of the total
  // (Euler-Bernoulli) in its bending direction.
  EXPECT_GT(d[0].energy_fraction[1], 0.95);
  EXPECT_GT(d[1].energy_fraction[2], 0.95);
  EXPECT_NEAR(d[0].effective_mass_fraction[1], 0.613, 0.02);
  EXPECT_NEAR(d[1].effective_mass_fraction[2], 0.613, 0.02);
}

// Fully integrated (2x2x2 Gauss) hex8 elements shear-lock in bending: the trilinear element's
// edges stay straight, so it cannot bend without a parasitic shear strain
// gamma ~ curvature * (element length). The spurious shear energy, relative to the bending
// energy ~ (G / E) (L_e / h)^2 with L_e the element length and h the beam depth, makes coarse
// meshes far too stiff and vanishes only as L_e -> 0. The frequency therefore lies above the
// converged value (tet10, which does not lock) and decreases monotonically towards it with
// refinement.
TEST(Cantilever, Hex8LocksAndConvergesFromAbove) {
  const Solution ref = Solve("beam_tet10.yaml", BeamYaml("tet10", 0.5));
  ASSERT_EQ(ref.result.status, EigenStatus::Successful) << ref.result.message;
  const double f_ref = frequency_hz(ref.result.eigenvalues[0]);
  std::vector<double> f;
  for (double size : {1.0, 0.5, 0.25}) {
    const Solution s = Solve("beam_hex8.yaml", BeamYaml("hex8", size));
    ASSERT_EQ(s.result.status, EigenStatus::Successful) << s.result.message;
    f.push_back(frequency_hz(s.result.eigenvalues[0]));
  }
  std::printf("[ verify   ] hex8 cantilever f1: %.6f %.6f %.6f Hz (element size 1, 0.5, 0.25); "
              "tet10 %.6f Hz\n", f[0], f[1], f[2], f_ref);
  EXPECT_GT(f[0], f[1]);
  EXPECT_GT(f[1], f[2]);
  EXPECT_GT(f[2], f_ref);
  // Locking is real, not a 0.1 % effect: the coarsest mesh is clearly too stiff.
  EXPECT_GT(f[0] / f_ref, 1.05);
  // ... and the error shrinks with refinement (by at least a third per halving).
  EXPECT_LT(f[2] - f_ref, (2.0 / 3.0) * (f[1] - f_ref));
  EXPECT_LT(f[1] - f_ref, (2.0 / 3.0) * (f[0] - f_ref));
}

// --------------------------------------------------------------------- sparse against dense

// An L-shaped hex8 part clamped at x = 0, with > 300 free DOFs, so ModalSolver takes its
// Lanczos/CHOLMOD path (dense only up to 300 DOFs). No symmetry, so no repeated eigenvalues.
TEST(SparseVsDense, LShapedSolidMatchesDenseGeneralizedSolve) {
  const Solution s = Solve("lshape.yaml", R"(
mesh:
  element: hex8
  element_size: 0.25
  boxes:
    - {block: a, min: [0, 0, 0], max: [2, 1, 0.6]}
    - {block: a, min: [0, 1, 0], max: [0.7, 1.9, 0.6]}
blocks:
  a: {E: 7.0e4, nu: 0.3, density: 2.7e-3}
node_sets:
  root: {box: {min: [0, 0, 0], max: [0, 1.9, 0.6]}}
fixed:
  - {node_set: root, dofs: [x, y, z]}
options: {num_modes: 8}
)");
  ASSERT_GT(s.system->num_dofs(), 300);
  ASSERT_EQ(s.result.status, EigenStatus::Successful) << s.result.message;
  ASSERT_EQ(s.result.eigenvalues.size(), 8);
  EXPECT_EQ(s.result.rigid_eigenvalues.size(), 0);
  EXPECT_GT(s.result.operator_solves, 0);  // the Lanczos path ran
  Eigen::GeneralizedSelfAdjointEigenSolver<Matrix> dense(Matrix(s.K), Matrix(s.M));
  ASSERT_EQ(dense.info(), Eigen::Success);
  const Vector& ld = dense.eigenvalues();
  for (int j = 0; j < 8; ++j) {
    SCOPED_TRACE("mode " + std::to_string(j + 1));
    EXPECT_CLOSE(s.result.eigenvalues[j], ld[j], 1e-9);
    EXPECT_LT(s.result.residuals[j], 1e-8);
    const Vector us = s.result.modes.col(j);
    EXPECT_NEAR(us.dot(s.M * us), 1.0, 1e-12);
    // A shape is defined (up to sign) only for a simple eigenvalue.
    const double gap = std::min(j > 0 ? ld[j] - ld[j - 1] : INFINITY, ld[j + 1] - ld[j]);
    ASSERT_GT(gap, 1e-6 * ld[j]) << "near-repeated eigenvalue: the geometry was meant to avoid it";
    EXPECT_NEAR(std::abs(dense.eigenvectors().col(j).dot(s.M * us)), 1.0, 1e-8);
  }
}

// ------------------------------------------------------------------------------- free-free

// Analytic rigid-body motions on the free DOFs: translations along x, y, z and rotations
// theta x (x - c) about x, y, z.
Matrix RigidMotions(const ParametricSystem& system, const Vec3& c) {
  const DofMap& dofs = system.dof_map();
  Matrix r = Matrix::Zero(system.num_dofs(), 6);
  for (int f = 0; f < system.num_dofs(); ++f) {
    const auto [node, comp] = dofs.free_owner(f);
    if (comp >= 3) continue;  // solid nodes only here
    const Vec3 x = system.model().coordinates[node] - c;
    r(f, comp) = 1;
    for (int a = 0; a < 3; ++a) r(f, 3 + a) = Vec3::Unit(a).cross(x)[comp];
  }
  return r;
}

// A free brick with unequal sides (648 DOFs: Lanczos path): exactly 6 rigid-body modes,
// reported separately; they carry no strain energy and span the six rigid motions; the first
// elastic mode agrees with a dense solve.
TEST(FreeFree, SixRigidModesSpanRigidMotionsAndElasticModesMatchDense) {
  const Solution s = Solve("brick.yaml", R"(
mesh:
  element: hex8
  element_size: 0.25
  boxes:
    - {block: brick, min: [0, 0, 0], max: [2, 1.25, 0.75]}
blocks:
  brick: {E: 2.0e5, nu: 0.29, density: 7.8e-3}
options: {num_modes: 4, max_rigid_modes: 6}
)");
  ASSERT_GT(s.system->num_dofs(), 300);
  ASSERT_EQ(s.result.status, EigenStatus::Successful) << s.result.message;
  ASSERT_EQ(s.result.rigid_eigenvalues.size(), 6);
  ASSERT_EQ(s.result.eigenvalues.size(), 4);
  const double lambda1 = s.result.eigenvalues[0];
  const Matrix& Q = s.result.rigid_modes;
  for (int k = 0; k < 6; ++k) {
    SCOPED_TRACE("rigid mode " + std::to_string(k + 1));
    const Vector u = Q.col(k);
    EXPECT_LT(std::abs(s.result.rigid_eigenvalues[k]), 1e-8 * lambda1);
    // Strain energy relative to that of the first elastic mode with the same kinetic norm.
    EXPECT_LT(std::abs(u.dot(s.K * u)) / (lambda1 * u.dot(s.M * u)), 1e-8);
    // M-orthogonal to the elastic modes.
    for (int j = 0; j < 4; ++j) EXPECT_NEAR(u.dot(s.M * s.result.modes.col(j)), 0.0, 1e-8);
  }
  // Each analytic rigid motion lies in the span of the computed rigid modes: the M-orthogonal
  // projection residual vanishes.
  const Matrix R = RigidMotions(*s.system, Vec3(1.0, 0.625, 0.375));
  const Matrix G = Q.transpose() * (s.M * Q);
  for (int a = 0; a < 6; ++a) {
    SCOPED_TRACE("rigid motion " + std::to_string(a));
    const Vector r = R.col(a);
    const Vector res = r - Q * G.ldlt().solve(Q.transpose() * (s.M * r));
    EXPECT_LT(std::sqrt(res.dot(s.M * res) / r.dot(s.M * r)), 1e-6);
  }
  Eigen::GeneralizedSelfAdjointEigenSolver<Matrix> dense(Matrix(s.K), Matrix(s.M));
  ASSERT_EQ(dense.info(), Eigen::Success);
  // The dense solve's six lowest are the (numerically zero) rigid modes.
  EXPECT_LT(std::abs(dense.eigenvalues()[5]), 1e-8 * dense.eigenvalues()[6]);
  for (int j = 0; j < 4; ++j) EXPECT_CLOSE(s.result.eigenvalues[j], dense.eigenvalues()[6 + j], 1e-8);
}

// ------------------------------------------------------------------------- coupling + joint

// Two unit cubes, [0,1]^3 clamped on its x = 0 face and [2,3]^3 free, each face-coupled
// (RBE2) to a reference node at (1.5, 0.5, 0.5): cube 1's x = 1 face to r1, cube 2's x = 2
// face to r2. A zero-length Joint2G joins r1 and r2: soft axially (kx = 1e3), stiff otherwise
// (1e7). The cubes are nearly rigid (E = 1e9): their axial stiffness E A / L = 1e9 is 1e6 times
// kx. So the lowest mode is cube 2 translating along x on the spring, omega^2 = kx / m2 with
// m2 = rho V = 1, to a relative error ~ kx / (E A / L) = 1e-6; the next modes (cube 2 swaying
// and rocking on the stiff components) are above 1e5.
TEST(RigidCouplingAndJoint, StiffCubesOnAxialJointAreAOneDofOscillator) {
  const Solution s = Solve("cubes.yaml", R"(
mesh:
  element: hex8
  element_size: 0.5
  boxes:
    - {block: c1, min: [0, 0, 0], max: [1, 1, 1]}
    - {block: c2, min: [2, 0, 0], max: [3, 1, 1]}
blocks:
  c1: {E: 1.0e9, nu: 0.3, density: 1}
  c2: {E: 1.0e9, nu: 0.3, density: 1}
node_sets:
  clamp: {box: {min: [0, 0, 0], max: [0, 1, 1]}}
  face1: {box: {min: [1, 0, 0], max: [1, 1, 1]}}
  face2: {box: {min: [2, 0, 0], max: [2, 1, 1]}}
reference_nodes:
  r1: [1.5, 0.5, 0.5]
  r2: [1.5, 0.5, 0.5]
rigid_couplings:
  - {reference: r1, node_set: face1}
  - {reference: r2, node_set: face2}
joints:
  j: {nodes: [r1, r2], kx: 1.0e3, ky: 1.0e7, kz: 1.0e7, krx: 1.0e7, kry: 1.0e7, krz: 1.0e7}
fixed:
  - {node_set: clamp, dofs: [x, y, z]}
options: {num_modes: 3}
)");
  ASSERT_EQ(s.result.status, EigenStatus::Successful) << s.result.message;
  const double kx = 1e3, m2 = 1.0;
  std::printf("[ verify   ] stiff cubes on joint: omega^2 = %.10g (kx / m2 = %g), next %.4g\n",
              s.result.eigenvalues[0], kx / m2, s.result.eigenvalues[1]);
  EXPECT_CLOSE(s.result.eigenvalues[0], kx / m2, 1e-5);
  EXPECT_LT(s.result.eigenvalues[0], kx / m2);  // the cubes' compliance acts in series
  EXPECT_GT(s.result.eigenvalues[1], 1e5);
  const std::vector<ModeDescription> d = describe_modes(*s.system, s.p, s.M, s.result);
  EXPECT_EQ(d[0].dominant_direction, 0);
  EXPECT_GT(d[0].energy_fraction[0], 0.999);
  // Cube 2 moving as a rigid body along x carries its whole mass, half the model's.
  EXPECT_CLOSE(d[0].effective_mass_fraction[0], m2 / (2 * m2), 1e-4);
}

// ------------------------------------------------------------------------- point mass

// A point mass m with rotary inertia (Ixx, Iyy, Izz) on reference node a, tied by a zero-length
// six-component joint to reference node g, which is fixed in all six DOFs (a one-element cube
// fixed everywhere is there because a problem needs a mesh; it adds no free DOF). The six free
// DOFs decouple: omega^2 = kx/m, ky/m, kz/m, krx/Ixx, kry/Iyy, krz/Izz, exactly.
TEST(PointMass, MassAndRotaryInertiaOnJointGiveExactFrequencies) {
  // One hex8 element: mesh nodes have ids 1..8, reference nodes follow (a = 9, g = 10).
  const Solution s = Solve("point_mass.yaml", R"(
mesh:
  element: hex8
  element_size: 1
  boxes:
    - {block: cube, min: [0, 0, 0], max: [1, 1, 1]}
blocks:
  cube: {E: 1.0, nu: 0.3, density: 1.0}
node_sets:
  cube: {box: {min: [0, 0, 0], max: [1, 1, 1]}}
  ground: {nodes: [10]}
reference_nodes:
  a: [0.5, 0.5, 3]
  g: [0.5, 0.5, 3]
joints:
  j: {nodes: [a, g], kx: 400, ky: 900, kz: 1600, krx: 3, kry: 5, krz: 7}
point_masses:
  pm: {node: a, mass: 4, inertia: [0.1, 0.2, 0.3]}
fixed:
  - {node_set: cube, dofs: [x, y, z]}
  - {node_set: ground, dofs: [x, y, z, rx, ry, rz]}
options: {num_modes: 6}
)");
  const Model& model = s.problem.model;
  ASSERT_EQ(model.num_nodes(), 10);
  ASSERT_TRUE(model.has_rotations[model.find_node(10)]);
  ASSERT_EQ(s.system->num_dofs(), 6);
  ASSERT_EQ(s.result.status, EigenStatus::Successful) << s.result.message;
  // Ascending: krz/Izz = 23.3, kry/Iyy = 25, krx/Ixx = 30, kx/m = 100, ky/m = 225, kz/m = 400.
  const std::array<double, 6> expected{7 / 0.3, 5 / 0.2, 3 / 0.1, 400 / 4.0, 900 / 4.0, 1600 / 4.0};
  const std::array<int, 6> component{5, 4, 3, 0, 1, 2};
  const int a = model.find_node(9);
  for (int k = 0; k < 6; ++k) {
    SCOPED_TRACE("mode " + std::to_string(k + 1));
    EXPECT_CLOSE(s.result.eigenvalues[k], expected[k], 1e-10);
    // Each mode moves node a in exactly one component; mass-normalized, that entry is
    // 1/sqrt(m) or 1/sqrt(I).
    const Vector u = s.result.modes.col(k);
    const int f = s.system->dof_map().free_index(a, component[k]);
    ASSERT_GE(f, 0);
    const double inertia = component[k] < 3 ? 4.0 : std::array<double, 3>{0.1, 0.2, 0.3}[component[k] - 3];
    EXPECT_CLOSE(u[f], 1 / std::sqrt(inertia), 1e-10);
    EXPECT_NEAR(u.norm(), std::abs(u[f]), 1e-10 * std::abs(u[f]));
  }
}

}  // namespace
}  // namespace modalcal
