// Element matrices: rigid-body modes, patch tests, mass totals, hand-computed entries, input
// validation, joint springs and exactness of the tet10 mass quadrature. References are computed
// here independently of src/model/elements.cpp (own shape functions, own quadrature).

#include "modalcal/elements.hpp"

#include <algorithm>
#include <cmath>
#include <stdexcept>
#include <string>
#include <vector>

#include <Eigen/Dense>
#include <Eigen/Eigenvalues>
#include <gtest/gtest.h>

#include "support/random_draws.hpp"

namespace modalcal {
namespace {

constexpr SolidType kAllTypes[] = {SolidType::Hex8, SolidType::Tet4, SolidType::Tet10};
constexpr double kBulk = 1.7;
constexpr double kShear = 0.8;

// Exodus TETRA10 mid-edge order, as documented in elements.hpp.
constexpr int kTetEdges[6][2] = {{0, 1}, {1, 2}, {2, 0}, {0, 3}, {1, 3}, {2, 3}};

double MaxAbs(const Matrix& a) { return a.cwiseAbs().maxCoeff(); }

Eigen::Matrix3Xd UnitCubeHex() {
  Eigen::Matrix3Xd x(3, 8);
  x << 0, 1, 1, 0, 0, 1, 1, 0,  //
      0, 0, 1, 1, 0, 0, 1, 1,   //
      0, 0, 0, 0, 1, 1, 1, 1;
  return x;
}

Eigen::Matrix3Xd UnitTet4() {
  Eigen::Matrix3Xd x(3, 4);
  x << 0, 1, 0, 0,  //
      0, 0, 1, 0,   //
      0, 0, 0, 1;
  return x;
}

/// Straight-sided tet10: corners plus exact edge midpoints.
Eigen::Matrix3Xd WithMidNodes(const Eigen::Matrix3Xd& corners) {
  Eigen::Matrix3Xd x(3, 10);
  x.leftCols<4>() = corners;
  for (int e = 0; e < 6; ++e)
    x.col(4 + e) = 0.5 * (corners.col(kTetEdges[e][0]) + corners.col(kTetEdges[e][1]));
  return x;
}

/// Random affine map x -> A x + t with det A > 0, then random nodal perturbations of size
/// `jitter`: a genuinely distorted (non-affine for hex8) but valid element.
Eigen::Matrix3Xd Distort(const Eigen::Matrix3Xd& x, double jitter, unsigned seed) {
  detail::Uniform rng_draws(seed);
  auto u = [&] { return rng_draws(-1.0, 1.0); };
  Mat3 A;
  for (int i = 0; i < 9; ++i) A(i) = (i % 4 == 0 ? 1.0 : 0.0) + 0.3 * u();
  EXPECT_GT(A.determinant(), 0.0);
  const Vec3 t(u(), u(), u());
  Eigen::Matrix3Xd y = A * x;
  y.colwise() += t;
  for (int i = 0; i < y.size(); ++i) y(i) += jitter * u();
  return y;
}

enum class Shape { Straight, Curved };

/// A valid, distorted element of `type`. Tet10 is straight-sided unless `shape` is Curved, in
/// which case its mid-nodes are moved off the edges too.
Eigen::Matrix3Xd DistortedElement(SolidType type, unsigned seed, Shape shape = Shape::Straight) {
  switch (type) {
    case SolidType::Hex8:
      return Distort(UnitCubeHex(), 0.15, seed);
    case SolidType::Tet4:
      return Distort(UnitTet4(), 0.15, seed);
    case SolidType::Tet10: {
      Eigen::Matrix3Xd x = WithMidNodes(Distort(UnitTet4(), 0.15, seed));
      if (shape == Shape::Curved) {
        detail::Uniform rng_draws(seed + 1000);
        auto u = [&] { return rng_draws(-0.04, 0.04); };
        for (int j = 4; j < 10; ++j)
          for (int i = 0; i < 3; ++i) x(i, j) += u();
      }
      return x;
    }
  }
  return {};
}

Matrix Stiffness(const SolidElementMatrices& m) {
  return kBulk * m.volumetric + kShear * m.deviatoric;
}

/// Constitutive matrix of the header: D = K m m^T + 2G (I0 - m m^T / 3).
Eigen::Matrix<double, 6, 6> Elasticity(double bulk, double shear) {
  Eigen::Matrix<double, 6, 1> m;
  m << 1, 1, 1, 0, 0, 0;
  Eigen::Matrix<double, 6, 1> i0;
  i0 << 1, 1, 1, 0.5, 0.5, 0.5;
  Eigen::Matrix<double, 6, 6> D = bulk * m * m.transpose();
  D += 2.0 * shear * (Eigen::Matrix<double, 6, 6>(i0.asDiagonal()) - m * m.transpose() / 3.0);
  return D;
}

/// Nodal values of u = A x + b, node-major.
Vector LinearField(const Eigen::Matrix3Xd& x, const Mat3& A, const Vec3& b) {
  Vector u(3 * x.cols());
  for (int i = 0; i < x.cols(); ++i) u.segment<3>(3 * i) = A * x.col(i) + b;
  return u;
}

/// Engineering Voigt strain of the gradient A: (xx, yy, zz, xy, yz, zx).
Eigen::Matrix<double, 6, 1> VoigtStrain(const Mat3& A) {
  Eigen::Matrix<double, 6, 1> e;
  e << A(0, 0), A(1, 1), A(2, 2), A(0, 1) + A(1, 0), A(1, 2) + A(2, 1), A(2, 0) + A(0, 2);
  return e;
}

/// Columns: translations along x, y, z, then infinitesimal rotations w x X about x, y, z.
Matrix RigidBodyModes(const Eigen::Matrix3Xd& x) {
  Matrix R = Matrix::Zero(3 * x.cols(), 6);
  for (int i = 0; i < x.cols(); ++i)
    for (int c = 0; c < 3; ++c) {
      R.block<3, 1>(3 * i, c) = Vec3::Unit(c);
      R.block<3, 1>(3 * i, 3 + c) = Vec3::Unit(c).cross(Vec3(x.col(i)));
    }
  return R;
}

// --- Independent reference quadrature -----------------------------------------------------

struct Gauss1D {
  std::vector<double> x, w;  // on [0, 1]
};

/// Gauss-Legendre on [0, 1] by Golub-Welsch (eigen-decomposition of the Jacobi matrix).
Gauss1D GaussLegendre(int n) {
  Matrix J = Matrix::Zero(n, n);
  for (int k = 1; k < n; ++k) J(k, k - 1) = J(k - 1, k) = k / std::sqrt(4.0 * k * k - 1.0);
  Eigen::SelfAdjointEigenSolver<Matrix> es(J);
  Gauss1D g;
  for (int i = 0; i < n; ++i) {
    g.x.push_back(0.5 * (es.eigenvalues()(i) + 1.0));
    g.w.push_back(es.eigenvectors()(0, i) * es.eigenvectors()(0, i));  // 2 v0^2 / 2
  }
  return g;
}

/// Integrates f(xi, eta, zeta) over the reference tet by the Stroud conical product (collapsed
/// cube): xi = u, eta = (1-u) v, zeta = (1-u)(1-v) w, dV = (1-u)^2 (1-v) du dv dw.
template <class F>
void ConicalProduct(int n, F&& f) {
  const Gauss1D g = GaussLegendre(n);
  for (int a = 0; a < n; ++a)
    for (int b = 0; b < n; ++b)
      for (int c = 0; c < n; ++c) {
        const double u = g.x[a], v = g.x[b], w = g.x[c];
        const double weight = g.w[a] * g.w[b] * g.w[c] * (1 - u) * (1 - u) * (1 - v);
        f(Vec3(u, (1 - u) * v, (1 - u) * (1 - v) * w), weight);
      }
}

/// Tet10 shape functions in barycentric form, with natural-coordinate gradients (rows).
void Tet10Shape(const Vec3& xi, Eigen::Matrix<double, 10, 1>& N, Eigen::Matrix<double, 10, 3>& dN) {
  const double L[4] = {1 - xi.sum(), xi(0), xi(1), xi(2)};
  const Vec3 dL[4] = {Vec3(-1, -1, -1), Vec3::UnitX(), Vec3::UnitY(), Vec3::UnitZ()};
  for (int i = 0; i < 4; ++i) {
    N(i) = 2 * L[i] * L[i] - L[i];
    dN.row(i) = (4 * L[i] - 1) * dL[i].transpose();
  }
  for (int e = 0; e < 6; ++e) {
    const int a = kTetEdges[e][0], b = kTetEdges[e][1];
    N(4 + e) = 4 * L[a] * L[b];
    dN.row(4 + e) = 4 * (L[a] * dL[b] + L[b] * dL[a]).transpose();
  }
}

/// Exact volume of any tet10 (det J is cubic; 6-point conical product is exact to degree 9).
double Tet10Volume(const Eigen::Matrix3Xd& x) {
  double v = 0;
  ConicalProduct(6, [&](const Vec3& xi, double w) {
    Eigen::Matrix<double, 10, 1> N;
    Eigen::Matrix<double, 10, 3> dN;
    Tet10Shape(xi, N, dN);
    v += w * (x * dN).determinant();
  });
  return v;
}

double TetVolume(const Eigen::Matrix3Xd& x) {
  return (x.col(1) - x.col(0)).cross(x.col(2) - x.col(0)).dot(x.col(3) - x.col(0)) / 6.0;
}

/// Exact volume of a trilinear hex: det J has degree <= 2 in each natural coordinate, and a
/// 3-point Gauss rule per direction integrates degree 5.
double HexVolume(const Eigen::Matrix3Xd& x) {
  const Gauss1D g = GaussLegendre(3);
  const Eigen::Matrix3Xd ref = 2.0 * UnitCubeHex().array() - 1.0;  // natural corner coordinates
  double v = 0;
  for (int a = 0; a < 3; ++a)
    for (int b = 0; b < 3; ++b)
      for (int c = 0; c < 3; ++c) {
        const Vec3 xi(2 * g.x[a] - 1, 2 * g.x[b] - 1, 2 * g.x[c] - 1);
        Mat3 J = Mat3::Zero();
        for (int i = 0; i < 8; ++i) {
          const Vec3 s = ref.col(i);
          const Vec3 f = Vec3::Ones() + s.cwiseProduct(xi);
          const Vec3 dN(s(0) * f(1) * f(2), f(0) * s(1) * f(2), f(0) * f(1) * s(2));
          J += x.col(i) * dN.transpose() / 8.0;
        }
        v += 8.0 * g.w[a] * g.w[b] * g.w[c] * J.determinant();
      }
  return v;
}

double Volume(SolidType type, const Eigen::Matrix3Xd& x) {
  switch (type) {
    case SolidType::Hex8:
      return HexVolume(x);
    case SolidType::Tet4:
      return TetVolume(x);
    case SolidType::Tet10:
      return Tet10Volume(x);
  }
  return 0;
}

double Factorial(int n) { return n <= 1 ? 1.0 : n * Factorial(n - 1); }

// --- Tests ----------------------------------------------------------------------------------

TEST(SolidElements, TypeNamesAndNodeCounts) {
  EXPECT_EQ(nodes_per_element(SolidType::Hex8), 8);
  EXPECT_EQ(nodes_per_element(SolidType::Tet4), 4);
  EXPECT_EQ(nodes_per_element(SolidType::Tet10), 10);
  EXPECT_EQ(solid_type_name(SolidType::Hex8), "hex8");
  EXPECT_EQ(solid_type_name(SolidType::Tet4), "tet4");
  EXPECT_EQ(solid_type_name(SolidType::Tet10), "tet10");
}

TEST(SolidElements, MatricesAreExactlySymmetricAndSized) {
  for (SolidType type : kAllTypes) {
    SCOPED_TRACE(solid_type_name(type));
    const SolidElementMatrices m = solid_element_matrices(type, DistortedElement(type, 3));
    const int ndof = 3 * nodes_per_element(type);
    for (const Matrix* a : {&m.volumetric, &m.deviatoric, &m.mass}) {
      ASSERT_EQ(a->rows(), ndof);
      ASSERT_EQ(a->cols(), ndof);
      EXPECT_EQ(MaxAbs(*a - a->transpose()), 0.0);
    }
  }
}

TEST(SolidElements, RigidBodyModesAreExactlyTheNullSpace) {
  for (SolidType type : kAllTypes) {
    SCOPED_TRACE(solid_type_name(type));
    const Eigen::Matrix3Xd x = DistortedElement(type, 7, Shape::Curved);
    const SolidElementMatrices m = solid_element_matrices(type, x);
    const Matrix R = RigidBodyModes(x);
    const Matrix K = Stiffness(m);
    const double scale = MaxAbs(K) * MaxAbs(R);
    EXPECT_LT(MaxAbs(m.volumetric * R), 1e-13 * scale);
    EXPECT_LT(MaxAbs(m.deviatoric * R), 1e-13 * scale);
    EXPECT_LT(MaxAbs(K * R), 1e-13 * scale);

    // Full rank apart from the 6 rigid-body modes: no spurious zero-energy (hourglass) modes.
    const Vector lambda = Eigen::SelfAdjointEigenSolver<Matrix>(K).eigenvalues();
    const double lmax = lambda.maxCoeff();
    int zeros = 0;
    for (double l : lambda) {
      EXPECT_GT(l, -1e-12 * lmax);
      if (l < 1e-10 * lmax) ++zeros;
    }
    EXPECT_EQ(zeros, 6);
    EXPECT_GT(lambda(6), 1e-4 * lmax);
  }
}

// Linear fields are reproduced exactly, so 1/2 u^T K u must equal V 1/2 eps^T D eps. The tet10
// is straight-sided: its 4-point rule integrates det J exactly only for affine geometry.
TEST(SolidElements, SingleElementPatchTestEnergy) {
  detail::Uniform rng_draws(11);
  auto u = [&] { return rng_draws(-1.0, 1.0); };
  const Eigen::Matrix<double, 6, 6> D = Elasticity(kBulk, kShear);
  for (SolidType type : kAllTypes) {
    SCOPED_TRACE(solid_type_name(type));
    const Eigen::Matrix3Xd x = DistortedElement(type, 21);
    const Matrix K = Stiffness(solid_element_matrices(type, x));
    for (int trial = 0; trial < 3; ++trial) {
      Mat3 A;
      for (int i = 0; i < 9; ++i) A(i) = u();
      const Vec3 b(u(), u(), u());
      const Vector d = LinearField(x, A, b);
      const Eigen::Matrix<double, 6, 1> eps = VoigtStrain(A);
      const double exact = Volume(type, x) * 0.5 * eps.dot(D * eps);
      EXPECT_NEAR(0.5 * d.dot(K * d), exact, 1e-12 * std::abs(exact));
    }
  }
}

TEST(SolidElements, Hex8MultiElementPatchRecoversLinearField) {
  // 3 x 3 x 3 distorted hexes; the 8 interior nodes are free, the boundary follows u = A x + b.
  constexpr int kN = 4;
  const auto id = [](int i, int j, int k) { return i + kN * j + kN * kN * k; };
  detail::Uniform rng_draws(5);
  auto u = [&] { return rng_draws(-1.0, 1.0); };
  Eigen::Matrix3Xd nodes(3, kN * kN * kN);
  for (int k = 0; k < kN; ++k)
    for (int j = 0; j < kN; ++j)
      for (int i = 0; i < kN; ++i)
        nodes.col(id(i, j, k)) = Vec3(i, j, k) + 0.25 * Vec3(u(), u(), u());

  const int ndof = 3 * nodes.cols();
  Matrix K = Matrix::Zero(ndof, ndof);
  for (int k = 0; k + 1 < kN; ++k)
    for (int j = 0; j + 1 < kN; ++j)
      for (int i = 0; i + 1 < kN; ++i) {
        const int conn[8] = {
            id(i, j, k),     id(i + 1, j, k),     id(i + 1, j + 1, k),     id(i, j + 1, k),
            id(i, j, k + 1), id(i + 1, j, k + 1), id(i + 1, j + 1, k + 1), id(i, j + 1, k + 1)};
        Eigen::Matrix3Xd xe(3, 8);
        for (int a = 0; a < 8; ++a) xe.col(a) = nodes.col(conn[a]);
        const Matrix Ke = Stiffness(solid_element_matrices(SolidType::Hex8, xe));
        for (int a = 0; a < 8; ++a)
          for (int b = 0; b < 8; ++b)
            K.block<3, 3>(3 * conn[a], 3 * conn[b]) += Ke.block<3, 3>(3 * a, 3 * b);
      }

  std::vector<int> free, fixed;
  for (int k = 0; k < kN; ++k)
    for (int j = 0; j < kN; ++j)
      for (int i = 0; i < kN; ++i) {
        const bool interior = i > 0 && i < kN - 1 && j > 0 && j < kN - 1 && k > 0 && k < kN - 1;
        for (int c = 0; c < 3; ++c) (interior ? free : fixed).push_back(3 * id(i, j, k) + c);
      }
  ASSERT_EQ(free.size(), 24u);

  Mat3 A;
  A << 0.3, -0.2, 0.1, 0.05, -0.4, 0.25, 0.15, 0.35, 0.2;
  const Vector exact = LinearField(nodes, A, Vec3(0.1, -0.3, 0.7));
  const Eigen::Index nf = static_cast<Eigen::Index>(free.size());
  Matrix Kff(nf, nf);
  Vector rhs = Vector::Zero(nf);
  for (Eigen::Index a = 0; a < nf; ++a) {
    for (Eigen::Index b = 0; b < nf; ++b) Kff(a, b) = K(free[a], free[b]);
    for (int c : fixed) rhs(a) -= K(free[a], c) * exact(c);
  }
  const Vector solved = Kff.ldlt().solve(rhs);
  for (Eigen::Index a = 0; a < nf; ++a) EXPECT_NEAR(solved(a), exact(free[a]), 1e-11);
}

TEST(SolidElements, MassOfUnitTranslationIsVolume) {
  for (SolidType type : kAllTypes) {
    for (Shape shape : {Shape::Straight, Shape::Curved}) {
      SCOPED_TRACE(solid_type_name(type) + (shape == Shape::Curved ? " curved" : ""));
      const Eigen::Matrix3Xd x = DistortedElement(type, 31, shape);
      const Matrix M = solid_element_matrices(type, x).mass;
      const double volume = Volume(type, x);
      for (int c = 0; c < 3; ++c) {
        Vector r = Vector::Zero(M.rows());
        for (int i = 0; i < x.cols(); ++i) r(3 * i + c) = 1.0;
        EXPECT_NEAR(r.dot(M * r), volume, 1e-13 * volume);
      }
      // Directions do not couple.
      for (int i = 0; i < M.rows(); ++i)
        for (int j = 0; j < M.cols(); ++j)
          if (i % 3 != j % 3) {
            EXPECT_EQ(M(i, j), 0.0);
          }
    }
  }
}

TEST(SolidElements, Tet10MassMatchesConicalProductAndClosedForm) {
  const Eigen::Matrix3Xd x = DistortedElement(SolidType::Tet10, 41);
  const Matrix M = solid_element_matrices(SolidType::Tet10, x).mass;
  const double detJ = 6.0 * TetVolume(x);

  Eigen::Matrix<double, 10, 10> reference = Eigen::Matrix<double, 10, 10>::Zero();
  ConicalProduct(6, [&](const Vec3& xi, double w) {
    Eigen::Matrix<double, 10, 1> N;
    Eigen::Matrix<double, 10, 3> dN;
    Tet10Shape(xi, N, dN);
    reference += w * detJ * N * N.transpose();
  });

  // Closed form (e.g. Zienkiewicz & Taylor): V/420 times 6 (corner diagonal), 1 (two corners),
  // -4 (corner on the edge of the mid-node), -6 (corner off that edge), 32 (mid-node diagonal),
  // 16 (edges sharing a corner), 8 (opposite edges).
  const double v420 = TetVolume(x) / 420.0;
  const auto on_edge = [](int corner, int e) {
    return kTetEdges[e][0] == corner || kTetEdges[e][1] == corner;
  };
  for (int i = 0; i < 10; ++i)
    for (int j = 0; j < 10; ++j) {
      double closed;
      if (i < 4 && j < 4) {
        closed = i == j ? 6 : 1;
      } else if (i < 4 || j < 4) {
        const int corner = std::min(i, j), e = std::max(i, j) - 4;
        closed = on_edge(corner, e) ? -4 : -6;
      } else if (i == j) {
        closed = 32;
      } else {
        const bool share =
            on_edge(kTetEdges[i - 4][0], j - 4) || on_edge(kTetEdges[i - 4][1], j - 4);
        closed = share ? 16 : 8;
      }
      SCOPED_TRACE("entry (" + std::to_string(i) + ", " + std::to_string(j) + ")");
      EXPECT_NEAR(reference(i, j), closed * v420, 1e-14);
      for (int c = 0; c < 3; ++c) EXPECT_NEAR(M(3 * i + c, 3 * j + c), closed * v420, 1e-14);
    }
}

TEST(SolidElements, Tet10MassRuleIntegratesQuarticsExactly) {
  // Products of two quadratics span the quartics, and a quadratic p is interpolated exactly by
  // its nodal values, so p^T M_scalar q = \int p q dV tests the mass rule on every monomial
  // x^a y^b z^c with a+b+c <= 4 over the reference tet, where the integral is
  // a! b! c! / (a+b+c+3)!.
  const Eigen::Matrix3Xd x = WithMidNodes(UnitTet4());
  const Matrix M = solid_element_matrices(SolidType::Tet10, x).mass;
  Matrix Ms(10, 10);
  for (int i = 0; i < 10; ++i)
    for (int j = 0; j < 10; ++j) Ms(i, j) = M(3 * i, 3 * j);

  int checked = 0;
  for (int a = 0; a <= 4; ++a)
    for (int b = 0; a + b <= 4; ++b)
      for (int c = 0; a + b + c <= 4; ++c) {
        // Split the exponents so that each factor has degree <= 2.
        int e[3] = {a, b, c}, p[3] = {0, 0, 0};
        for (int k = 0, budget = 2; k < 3; ++k) {
          p[k] = std::min(e[k], budget);
          budget -= p[k];
        }
        Vector pv(10), qv(10);
        for (int i = 0; i < 10; ++i) {
          pv(i) = qv(i) = 1.0;
          for (int k = 0; k < 3; ++k) {
            pv(i) *= std::pow(x(k, i), p[k]);
            qv(i) *= std::pow(x(k, i), e[k] - p[k]);
          }
        }
        const double exact = Factorial(a) * Factorial(b) * Factorial(c) / Factorial(a + b + c + 3);
        SCOPED_TRACE("x^" + std::to_string(a) + " y^" + std::to_string(b) + " z^" +
                     std::to_string(c));
        EXPECT_NEAR(pv.dot(Ms * qv), exact, 1e-15 + 1e-13 * exact);
        ++checked;
      }
  EXPECT_EQ(checked, 35);
}

TEST(SolidElements, Tet4UnitTetHandComputedEntries) {
  // Gradients: g0 = (-1,-1,-1), g1 = e_x, g2 = e_y, g3 = e_z; V = 1/6. With d = B^T m the
  // stacked gradients, node blocks (k, l components) are
  //   vol_ij = V g_i g_j^T,
  //   dev_ij = V [ (g_i . g_j) I + g_j g_i^T - 2/3 g_i g_j^T ]   (from 2 eps:eps - 2/3 (div u)^2).
  // Hence: vol(0,0) = 1/6, vol(0,1) = 1/6, vol(0,3) = -1/6, vol(3,7) = 1/6, vol(3,4) = 0;
  //   dev(0,0) = (3 + 1 - 2/3)/6 = 5/9, dev(0,1) = (1 - 2/3)/6 = 1/18,
  //   dev(3,3) = (1 + 1 - 2/3)/6 = 2/9, dev(4,4) = 1/6,
  //   dev(3,7) (u1x-u2y) = -2/3 / 6 = -1/9, dev(4,6) (u1y-u2x) = 1/6.
  // Check against Lame form: K(3,7) = V lambda with kappa - 2/3 G = lambda.
  // Mass: V/20 (1 + delta_ij) = 1/60 diagonal, 1/120 off-diagonal.
  const SolidElementMatrices m = solid_element_matrices(SolidType::Tet4, UnitTet4());
  const double t = 1e-15;
  EXPECT_NEAR(m.volumetric(0, 0), 1.0 / 6, t);
  EXPECT_NEAR(m.volumetric(0, 1), 1.0 / 6, t);
  EXPECT_NEAR(m.volumetric(0, 3), -1.0 / 6, t);
  EXPECT_NEAR(m.volumetric(3, 7), 1.0 / 6, t);
  EXPECT_NEAR(m.volumetric(3, 4), 0.0, t);
  EXPECT_NEAR(m.deviatoric(0, 0), 5.0 / 9, t);
  EXPECT_NEAR(m.deviatoric(0, 1), 1.0 / 18, t);
  EXPECT_NEAR(m.deviatoric(3, 3), 2.0 / 9, t);
  EXPECT_NEAR(m.deviatoric(4, 4), 1.0 / 6, t);
  EXPECT_NEAR(m.deviatoric(3, 7), -1.0 / 9, t);
  EXPECT_NEAR(m.deviatoric(4, 6), 1.0 / 6, t);
  EXPECT_NEAR(m.mass(0, 0), 1.0 / 60, t);
  EXPECT_NEAR(m.mass(0, 3), 1.0 / 120, t);
  EXPECT_NEAR(m.mass(0, 1), 0.0, t);

  const double E = 1.0, nu = 0.3;
  const double lambda = E * nu / ((1 + nu) * (1 - 2 * nu)), mu = E / (2 * (1 + nu));
  const Matrix K = (lambda + 2.0 * mu / 3.0) * m.volumetric + mu * m.deviatoric;
  EXPECT_NEAR(K(3, 7), lambda / 6, t);
  EXPECT_NEAR(K(4, 6), mu / 6, t);
  EXPECT_NEAR(K(3, 3), (lambda + 2 * mu) / 6, t);
}

TEST(SolidElements, Hex8UnitCubeClosedForm) {
  // Unit cube, N_0 = (1-x)(1-y)(1-z). 2x2x2 Gauss is exact here (integrands of degree <= 2 per
  // variable). In Lame form K_ij^kl = \int lambda g_ik g_jl + mu (g_il g_jk + delta_kl g_i.g_j):
  //   diagonal  K(0,0) = (lambda + 2mu) \int g_0x^2 + mu \int (g_0y^2 + g_0z^2)
  //                    = (lambda + 4 mu)/9 = E (2 - 3 nu) / (9 (1 + nu)(1 - 2 nu)),
  //   since \int (1-y)^2 (1-z)^2 = 1/9; every diagonal entry equals this by symmetry;
  //   K(0,1) (u0x-u0y) = (lambda + mu) \int g_0x g_0y = (lambda + mu)/12;
  //   K(0,18) (u0x-u6x, opposite corner N_6 = xyz) = -(lambda + 4 mu)/36.
  // Per unit moduli: vol(0,0) = 1/9, dev(0,0) = \int |g|^2 + g_x^2/3 = 1/3 + 1/27 = 10/27.
  // Mass: \int N_i N_j = product of 1D factors 1/3 (same end) or 1/6 (other end):
  //   diagonal 1/27 = 8/216, edge neighbour 4/216, face diagonal 2/216, opposite corner 1/216.
  const SolidElementMatrices m = solid_element_matrices(SolidType::Hex8, UnitCubeHex());
  const double t = 1e-15;
  const double E = 1.0, nu = 0.3;
  const double lambda = E * nu / ((1 + nu) * (1 - 2 * nu)), mu = E / (2 * (1 + nu));
  const Matrix K = (lambda + 2.0 * mu / 3.0) * m.volumetric + mu * m.deviatoric;
  const double k11 = E * (2 - 3 * nu) / (9 * (1 + nu) * (1 - 2 * nu));
  for (int i = 0; i < 24; ++i) {
    EXPECT_NEAR(K(i, i), k11, t);
    EXPECT_NEAR(m.volumetric(i, i), 1.0 / 9, t);
    EXPECT_NEAR(m.deviatoric(i, i), 10.0 / 27, t);
    EXPECT_NEAR(m.mass(i, i), 1.0 / 27, t);
  }
  EXPECT_EQ(MaxAbs(K - K.transpose()), 0.0);
  EXPECT_NEAR(K(0, 1), (lambda + mu) / 12, t);
  EXPECT_NEAR(K(0, 18), -(lambda + 4 * mu) / 36, t);
  EXPECT_NEAR(m.mass(0, 3), 4.0 / 216, t);   // node 1: edge neighbour
  EXPECT_NEAR(m.mass(0, 6), 2.0 / 216, t);   // node 2: face diagonal
  EXPECT_NEAR(m.mass(0, 18), 1.0 / 216, t);  // node 6: opposite corner
}

void ExpectInvalid(SolidType type, const Eigen::Matrix3Xd& x,
                   const std::vector<std::string>& fragments) {
  try {
    solid_element_matrices(type, x);
    ADD_FAILURE() << "no exception for " << solid_type_name(type);
  } catch (const std::invalid_argument& e) {
    const std::string what = e.what();
    EXPECT_NE(what.find(solid_type_name(type)), std::string::npos) << what;
    for (const std::string& fragment : fragments)
      EXPECT_NE(what.find(fragment), std::string::npos) << what;
  }
}

TEST(SolidElements, InvertedOrDegenerateElementsThrow) {
  // Swapping bottom and top faces mirrors the hex: det J = -1/8 everywhere.
  Eigen::Matrix3Xd mirrored(3, 8);
  mirrored << UnitCubeHex().rightCols<4>(), UnitCubeHex().leftCols<4>();
  ExpectInvalid(SolidType::Hex8, mirrored, {"inverted or degenerate element: det J = -0.125"});

  // Node 6 pulled through the element: det J > 0 at Gauss points 0..5, negative at point 6
  // (the one nearest node 6).
  Eigen::Matrix3Xd folded = UnitCubeHex();
  folded.col(6) = Vec3(0.1, 0.1, 0.1);
  ExpectInvalid(SolidType::Hex8, folded, {"inverted or degenerate element", "quadrature point 6"});

  Eigen::Matrix3Xd flat = UnitTet4();
  flat.col(3) = Vec3(0.3, 0.3, 0.0);
  ExpectInvalid(SolidType::Tet4, flat, {"inverted or degenerate element: det J = 0"});
  ExpectInvalid(SolidType::Tet10, WithMidNodes(flat), {"inverted or degenerate element"});

  Eigen::Matrix3Xd swapped = UnitTet4();
  swapped.col(1).swap(swapped.col(2));
  ExpectInvalid(SolidType::Tet4, swapped, {"inverted or degenerate element: det J = -1"});
}

TEST(SolidElements, WrongNodeCountThrows) {
  EXPECT_THROW(solid_element_matrices(SolidType::Hex8, UnitCubeHex().leftCols<7>()),
               std::invalid_argument);
  EXPECT_THROW(solid_element_matrices(SolidType::Tet10, UnitTet4()), std::invalid_argument);
  EXPECT_THROW(solid_element_matrices(SolidType::Tet4, WithMidNodes(UnitTet4())),
               std::invalid_argument);
}

Mat3 SomeRotation() {
  return Eigen::Quaterniond(0.8, -0.3, 0.4, 0.2).normalized().toRotationMatrix();
}

TEST(JointElements, TranslationalComponentEnergy) {
  const Mat3 frame = SomeRotation();
  detail::Uniform rng_draws(3);
  auto u = [&] { return rng_draws(-1.0, 1.0); };
  Eigen::Matrix<double, 12, 12> sum = Eigen::Matrix<double, 12, 12>::Zero();
  for (int c = 0; c < 3; ++c) {
    const Eigen::Matrix<double, 12, 12> K = joint_component_matrix(frame, c);
    sum += K;
    Eigen::Matrix<double, 12, 1> q;
    for (int i = 0; i < 12; ++i) q(i) = u();
    const Vec3 d = q.segment<3>(6) - q.segment<3>(0);
    const double e_d = frame.row(c).dot(d);
    EXPECT_NEAR(0.5 * q.dot(K * q), 0.5 * e_d * e_d, 1e-15);
    // Rotations neither load nor are loaded.
    EXPECT_EQ(MaxAbs(K.middleRows(3, 3)), 0.0);
    EXPECT_EQ(MaxAbs(K.middleRows(9, 3)), 0.0);
    EXPECT_EQ(MaxAbs(K - K.transpose()), 0.0);
  }
  // The three components of an orthonormal frame add up to an isotropic spring.
  Eigen::Matrix<double, 12, 12> iso = Eigen::Matrix<double, 12, 12>::Zero();
  iso.block<3, 3>(0, 0) = iso.block<3, 3>(6, 6) = Mat3::Identity();
  iso.block<3, 3>(0, 6) = iso.block<3, 3>(6, 0) = -Mat3::Identity();
  EXPECT_LT((sum - iso).cwiseAbs().maxCoeff(), 1e-15);
}

TEST(JointElements, RotationalComponentsActOnRotationsOnly) {
  const Mat3 frame = SomeRotation();
  Eigen::Matrix<double, 12, 1> q;
  q << 0.3, -0.7, 0.2, 0.11, -0.05, 0.4, 1.3, 0.9, -0.6, -0.2, 0.25, 0.1;
  const Vec3 dtheta = q.segment<3>(9) - q.segment<3>(3);
  for (int c = 3; c < 6; ++c) {
    const Eigen::Matrix<double, 12, 12> K = joint_component_matrix(frame, c);
    const double e_t = frame.row(c - 3).dot(dtheta);
    EXPECT_NEAR(0.5 * q.dot(K * q), 0.5 * e_t * e_t, 1e-15);
    EXPECT_EQ(MaxAbs(K.middleRows(0, 3)), 0.0);
    EXPECT_EQ(MaxAbs(K.middleRows(6, 3)), 0.0);
    EXPECT_EQ(MaxAbs(K.middleCols(0, 3)), 0.0);
    EXPECT_EQ(MaxAbs(K.middleCols(6, 3)), 0.0);
  }
}

TEST(JointElements, InvalidComponentThrows) {
  EXPECT_THROW(joint_component_matrix(Mat3::Identity(), -1), std::invalid_argument);
  EXPECT_THROW(joint_component_matrix(Mat3::Identity(), 6), std::invalid_argument);
}

TEST(JointElements, IsRotation) {
  const Mat3 R = SomeRotation();
  EXPECT_TRUE(is_rotation(Mat3::Identity()));
  EXPECT_TRUE(is_rotation(R));
  Mat3 nearly = R;
  nearly(0, 1) += 1e-10;
  EXPECT_TRUE(is_rotation(nearly));
  Mat3 off = R;
  off(0, 1) += 1e-6;
  EXPECT_FALSE(is_rotation(off));
  Mat3 reflected = R;
  reflected.row(2) *= -1.0;
  EXPECT_FALSE(is_rotation(reflected));
  EXPECT_FALSE(is_rotation(1.001 * R));
  EXPECT_FALSE(is_rotation(Mat3::Zero()));
}

}  // namespace
}  // namespace modalcal
