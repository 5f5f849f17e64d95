#include "modalcal/elements.hpp"

#include <algorithm>
#include <array>
#include <iterator>
#include <limits>
#include <cmath>
#include <sstream>
#include <stdexcept>
#include <vector>

#include <Eigen/LU>

namespace modalcal {

namespace {

constexpr int kMaxNodes = 10;
using ShapeValues = Eigen::Matrix<double, Eigen::Dynamic, 1, Eigen::ColMajor, kMaxNodes, 1>;
/// Row i holds the gradient of N_i (natural or physical coordinates, depending on use).
using ShapeGradients = Eigen::Matrix<double, Eigen::Dynamic, 3, Eigen::ColMajor, kMaxNodes, 3>;
using StrainMatrix = Eigen::Matrix<double, 6, Eigen::Dynamic, Eigen::ColMajor, 6, 3 * kMaxNodes>;

struct QuadraturePoint {
  Vec3 xi;
  double weight;
};
using QuadratureRule = std::vector<QuadraturePoint>;

// Hex8 natural coordinates of the nodes, Exodus HEX8 / Gmsh hexahedron order.
constexpr double kHexCorners[8][3] = {{-1, -1, -1}, {1, -1, -1}, {1, 1, -1}, {-1, 1, -1},
                                      {-1, -1, 1},  {1, -1, 1},  {1, 1, 1},  {-1, 1, 1}};

// Tet10 mid-edge nodes 4..9 in Exodus TETRA10 order (edges 01, 12, 20, 03, 13, 23). Gmsh's
// 10-node tetrahedron lists the last two the other way round (node 8 on edge 23, node 9 on 13),
// so a Gmsh mesh must swap its nodes 8 and 9 before reaching this function.
constexpr int kTetEdges[6][2] = {{0, 1}, {1, 2}, {2, 0}, {0, 3}, {1, 3}, {2, 3}};

// Tet natural coordinates are (L1, L2, L3), so that L0 = 1 - xi - eta - zeta and the Jacobian's
// columns are x1 - x0, x2 - x0, x3 - x0 for a straight-sided tet (det J = 6 V).
QuadraturePoint tet_point(const std::array<double, 4>& L, double weight) {
  return {Vec3(L[1], L[2], L[3]), weight};
}

// The 4 points whose barycentric coordinates are a permutation of (a, a, a, 1 - 3a).
void add_orbit_31(QuadratureRule& rule, double a, double weight) {
  for (int odd = 0; odd < 4; ++odd) {
    std::array<double, 4> L = {a, a, a, a};
    L[odd] = 1.0 - 3.0 * a;
    rule.push_back(tet_point(L, weight));
  }
}

// The 6 points whose barycentric coordinates are a permutation of (b, b, 1/2 - b, 1/2 - b).
void add_orbit_22(QuadratureRule& rule, double b, double weight) {
  for (int i = 0; i < 4; ++i)
    for (int j = i + 1; j < 4; ++j) {
      std::array<double, 4> L = {0.5 - b, 0.5 - b, 0.5 - b, 0.5 - b};
      L[i] = L[j] = b;
      rule.push_back(tet_point(L, weight));
    }
}

// 2x2x2 Gauss-Legendre: exact for polynomials of degree 3 in each natural coordinate, which
// covers the hex8 mass integrand (degree <= 2 in each) and, for a parallelepiped, the stiffness.
const QuadratureRule& hex_gauss_2x2x2() {
  static const QuadratureRule rule = [] {
    const double g = 1.0 / std::sqrt(3.0);
    QuadratureRule r;
    for (const auto& corner : kHexCorners)
      r.push_back({Vec3(g * corner[0], g * corner[1], g * corner[2]), 1.0});
    return r;
  }();
  return rule;
}

// Centroid rule (degree 1): tet4 B is constant.
const QuadratureRule& tet_centroid() {
  static const QuadratureRule rule = {tet_point({0.25, 0.25, 0.25, 0.25}, 1.0 / 6.0)};
  return rule;
}

// 4-point degree-2 rule, a = (5 - sqrt 5) / 20 (Hammer, Marlowe & Stroud 1956). Exact for the
// tet4 mass (N_i N_j is quadratic) and for the tet10 stiffness of a straight-sided tet
// (B is linear).
const QuadratureRule& tet_degree2() {
  static const QuadratureRule rule = [] {
    QuadratureRule r;
    add_orbit_31(r, (5.0 - std::sqrt(5.0)) / 20.0, 1.0 / 24.0);
    return r;
  }();
  return rule;
}

// 14-point degree-5 rule with positive weights (Walkington, "Quadrature on simplices of
// arbitrary dimension", 2000; the degree-5 tet rule of FreeFEM and MFEM). Points and weights
// were re-solved from the symmetric moment equations to 25 digits; weights sum to the reference
// volume 1/6. The tet10 mass integrand N_i N_j is degree 4 on a straight-sided tet.
const QuadratureRule& tet_degree5() {
  static const QuadratureRule rule = [] {
    QuadratureRule r;
    add_orbit_31(r, 0.09273525031089122640232391, 0.01224884051939365825728503);
    add_orbit_31(r, 0.3108859192633006097973457, 0.01878132095300264179986428);
    add_orbit_22(r, 0.04550370412564964949188053, 0.007091003462846911073011571);
    return r;
  }();
  return rule;
}

/// Shape functions and their natural-coordinate gradients at `xi`.
void shape_functions(SolidType type, const Vec3& xi, ShapeValues& N, ShapeGradients& dN) {
  const int n = nodes_per_element(type);
  N.resize(n);
  dN.resize(n, 3);
  switch (type) {
    case SolidType::Hex8:
      // N_i = (1 + xi xi_i)(1 + eta eta_i)(1 + zeta zeta_i) / 8
      for (int i = 0; i < 8; ++i) {
        const double a = 1.0 + kHexCorners[i][0] * xi.x();
        const double b = 1.0 + kHexCorners[i][1] * xi.y();
        const double c = 1.0 + kHexCorners[i][2] * xi.z();
        N(i) = 0.125 * a * b * c;
        dN(i, 0) = 0.125 * kHexCorners[i][0] * b * c;
        dN(i, 1) = 0.125 * a * kHexCorners[i][1] * c;
        dN(i, 2) = 0.125 * a * b * kHexCorners[i][2];
      }
      return;
    case SolidType::Tet4:
    case SolidType::Tet10: {
      const double L[4] = {1.0 - xi.sum(), xi.x(), xi.y(), xi.z()};
      Eigen::Matrix<double, 4, 3> dL;
      dL << -1, -1, -1, 1, 0, 0, 0, 1, 0, 0, 0, 1;
      if (type == SolidType::Tet4) {
        for (int i = 0; i < 4; ++i) N(i) = L[i];
        dN = dL;
        return;
      }
      // Corners L_i (2 L_i - 1), mid-edge nodes 4 L_a L_b.
      for (int i = 0; i < 4; ++i) {
        N(i) = L[i] * (2.0 * L[i] - 1.0);
        dN.row(i) = (4.0 * L[i] - 1.0) * dL.row(i);
      }
      for (int e = 0; e < 6; ++e) {
        const int a = kTetEdges[e][0], b = kTetEdges[e][1];
        N(4 + e) = 4.0 * L[a] * L[b];
        dN.row(4 + e) = 4.0 * (L[b] * dL.row(a) + L[a] * dL.row(b));
      }
      return;
    }
  }
  throw std::invalid_argument("unknown solid element type");
}

/// Shape values, physical gradients and det J at one quadrature point; throws on det J <= 0.
struct PointData {
  ShapeValues N;
  ShapeGradients dNdx;
  double detJ;
};

PointData evaluate_point(SolidType type, const Eigen::Matrix3Xd& coords, const Vec3& xi,
                         int point_index, const char* rule_name) {
  PointData p;
  ShapeGradients dNdxi;
  shape_functions(type, xi, p.N, dNdxi);
  const Mat3 J = coords * dNdxi;  // J_kl = d x_k / d xi_l
  p.detJ = J.determinant();
  if (!(p.detJ > 0.0)) {
    std::ostringstream msg;
    msg << solid_type_name(type) << ": inverted or degenerate element: det J = " << p.detJ
        << " at quadrature point " << point_index << " of the " << rule_name << " rule";
    throw std::invalid_argument(msg.str());
  }
  // dN/dx = dN/dxi * dxi/dx = dN/dxi * J^-1
  p.dNdx = dNdxi * J.inverse();
  return p;
}

void check_node_count(SolidType type, const Eigen::Matrix3Xd& coords) {
  const int n = nodes_per_element(type);
  if (coords.cols() != n) {
    std::ostringstream msg;
    msg << solid_type_name(type) << " element needs " << n << " nodes, got " << coords.cols();
    throw std::invalid_argument(msg.str());
  }
}

const QuadratureRule& stiffness_quadrature(SolidType type) {
  if (type == SolidType::Tet4) return tet_centroid();
  if (type == SolidType::Tet10) return tet_degree2();
  return hex_gauss_2x2x2();
}

const QuadratureRule& mass_quadrature(SolidType type) {
  if (type == SolidType::Tet4) return tet_degree2();
  if (type == SolidType::Tet10) return tet_degree5();
  return hex_gauss_2x2x2();
}

// Side corners in Exodus numbering, counter-clockwise seen from outside.
constexpr int kHexSides[6][4] = {{0, 1, 5, 4}, {1, 2, 6, 5}, {2, 3, 7, 6},
                                 {0, 4, 7, 3}, {0, 3, 2, 1}, {4, 5, 6, 7}};
constexpr int kTetSides[4][3] = {{0, 1, 3}, {1, 2, 3}, {0, 3, 2}, {0, 2, 1}};

}  // namespace

double min_jacobian_determinant(SolidType type, const Eigen::Matrix3Xd& coords) {
  check_node_count(type, coords);
  // The corners catch a curved tet10 folded at a vertex, which the quadrature points can miss.
  QuadratureRule corners;
  if (type == SolidType::Hex8)
    for (const auto& c : kHexCorners) corners.push_back({Vec3(c[0], c[1], c[2]), 0.0});
  else
    for (const Vec3& xi : {Vec3(0, 0, 0), Vec3(1, 0, 0), Vec3(0, 1, 0), Vec3(0, 0, 1)}) corners.push_back({xi, 0.0});
  double smallest = std::numeric_limits<double>::infinity();
  ShapeValues N;
  ShapeGradients dNdxi;
  for (const QuadratureRule* rule : {static_cast<const QuadratureRule*>(&corners), &stiffness_quadrature(type), &mass_quadrature(type)})
    for (const QuadraturePoint& q : *rule) {
      shape_functions(type, q.xi, N, dNdxi);
      smallest = std::min(smallest, (coords * dNdxi).determinant());
    }
  return smallest;
}

int num_solid_sides(SolidType type) { return type == SolidType::Hex8 ? 6 : 4; }

std::vector<int> solid_side_nodes(SolidType type, int side) {
  if (side < 1 || side > num_solid_sides(type))
    throw std::invalid_argument(solid_type_name(type) + " has sides 1.." + std::to_string(num_solid_sides(type)) +
                                ", not " + std::to_string(side));
  if (type == SolidType::Hex8) return {std::begin(kHexSides[side - 1]), std::end(kHexSides[side - 1])};
  std::vector<int> nodes(std::begin(kTetSides[side - 1]), std::end(kTetSides[side - 1]));
  if (type == SolidType::Tet10)
    for (int e = 0; e < 6; ++e) {
      const auto on_side = [&](int corner) { return std::find(nodes.begin(), nodes.begin() + 3, corner) != nodes.begin() + 3; };
      if (on_side(kTetEdges[e][0]) && on_side(kTetEdges[e][1])) nodes.push_back(4 + e);
    }
  return nodes;
}

int nodes_per_element(SolidType type) {
  switch (type) {
    case SolidType::Hex8:
      return 8;
    case SolidType::Tet4:
      return 4;
    case SolidType::Tet10:
      return 10;
  }
  throw std::invalid_argument("unknown solid element type");
}

std::string solid_type_name(SolidType type) {
  switch (type) {
    case SolidType::Hex8:
      return "hex8";
    case SolidType::Tet4:
      return "tet4";
    case SolidType::Tet10:
      return "tet10";
  }
  throw std::invalid_argument("unknown solid element type");
}

SolidElementMatrices solid_element_matrices(SolidType type, const Eigen::Matrix3Xd& coords) {
  check_node_count(type, coords);
  const int n = nodes_per_element(type);
  const int ndof = 3 * n;
  const QuadratureRule* stiffness_rule = &stiffness_quadrature(type);
  const QuadratureRule* mass_rule = &mass_quadrature(type);

  // With d = B^T m (the divergence row) and W = diag(2,2,2,1,1,1) = 2 I0:
  //   vol = sum w detJ d d^T,   dev = sum w detJ (B^T W B - 2/3 d d^T).
  Eigen::Matrix<double, 6, 1> W;
  W << 2, 2, 2, 1, 1, 1;
  Matrix vol = Matrix::Zero(ndof, ndof);
  Matrix dev = Matrix::Zero(ndof, ndof);
  StrainMatrix B(6, ndof);
  Vector div(ndof);
  for (size_t k = 0; k < stiffness_rule->size(); ++k) {
    const QuadraturePoint& q = (*stiffness_rule)[k];
    const PointData p = evaluate_point(type, coords, q.xi, static_cast<int>(k), "stiffness");
    const double dV = q.weight * p.detJ;
    // Voigt rows: eps_xx, eps_yy, eps_zz, gamma_xy, gamma_yz, gamma_zx.
    B.setZero();
    for (int i = 0; i < n; ++i) {
      const double gx = p.dNdx(i, 0), gy = p.dNdx(i, 1), gz = p.dNdx(i, 2);
      const int c = 3 * i;
      B(0, c) = gx;
      B(1, c + 1) = gy;
      B(2, c + 2) = gz;
      B(3, c) = gy;
      B(3, c + 1) = gx;
      B(4, c + 1) = gz;
      B(4, c + 2) = gy;
      B(5, c) = gz;
      B(5, c + 2) = gx;
      div.segment<3>(c) = p.dNdx.row(i).transpose();
    }
    vol.noalias() += dV * div * div.transpose();
    dev.noalias() += B.transpose() * (dV * W).asDiagonal() * B;
    dev.noalias() -= (2.0 / 3.0 * dV) * div * div.transpose();
  }

  // Consistent mass is N^T N per direction: integrate the scalar n x n matrix, then spread it
  // over the three translations.
  Matrix scalar_mass = Matrix::Zero(n, n);
  for (size_t k = 0; k < mass_rule->size(); ++k) {
    const QuadraturePoint& q = (*mass_rule)[k];
    const PointData p = evaluate_point(type, coords, q.xi, static_cast<int>(k), "mass");
    scalar_mass.noalias() += (q.weight * p.detJ) * p.N * p.N.transpose();
  }

  // Averaging with the transpose makes the results bitwise symmetric (the accumulated products
  // differ from their transposes by rounding), which sparse solvers reading one triangle expect.
  SolidElementMatrices out;
  out.volumetric = 0.5 * (vol + vol.transpose());
  out.deviatoric = 0.5 * (dev + dev.transpose());
  out.mass = Matrix::Zero(ndof, ndof);
  for (int i = 0; i < n; ++i)
    for (int j = 0; j < n; ++j) {
      const double mij = 0.5 * (scalar_mass(i, j) + scalar_mass(j, i));
      for (int c = 0; c < 3; ++c) out.mass(3 * i + c, 3 * j + c) = mij;
    }
  return out;
}

Eigen::Matrix<double, 12, 12> joint_component_matrix(const Mat3& frame, int component) {
  if (component < 0 || component > 5) {
    throw std::invalid_argument("joint_component_matrix: component must be in 0..5, got " +
                                std::to_string(component));
  }
  const Vec3 e = frame.row(component % 3).transpose();
  const Mat3 eet = e * e.transpose();
  const int offset = component < 3 ? 0 : 3;  // translations or rotations of each node
  Eigen::Matrix<double, 12, 12> K = Eigen::Matrix<double, 12, 12>::Zero();
  K.block<3, 3>(offset, offset) = eet;
  K.block<3, 3>(offset, 6 + offset) = -eet;
  K.block<3, 3>(6 + offset, offset) = -eet;
  K.block<3, 3>(6 + offset, 6 + offset) = eet;
  return K;
}

bool is_rotation(const Mat3& frame) {
  constexpr double kTol = 1e-8;
  const double orthonormality_error =
      (frame * frame.transpose() - Mat3::Identity()).cwiseAbs().maxCoeff();
  return orthonormality_error <= kTol && frame.determinant() > 0.0;
}

}  // namespace modalcal
