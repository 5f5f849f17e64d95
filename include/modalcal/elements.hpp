#pragma once
/// \file elements.hpp
/// Element matrices of the solid elements and of the discrete elements (joints, springs,
/// point masses). Solid stiffness is returned split into a volumetric and a deviatoric
/// part, so that the block stiffness is *linear* in the bulk modulus \f$\kappa\f$ and the
/// shear modulus \f$G\f$:
/// \f[ K_e = \kappa\, K_e^{vol} + G\, K_e^{dev},\qquad
///     K_e^{vol} = \int B^T m m^T B\,dV,\quad K_e^{dev} = \int B^T\, 2(I_0 - \tfrac13 m m^T)\, B\,dV \f]
/// with \f$m = (1,1,1,0,0,0)^T\f$ and \f$I_0 = \mathrm{diag}(1,1,1,\tfrac12,\tfrac12,\tfrac12)\f$
/// (Voigt notation, engineering shear strains). Mass is consistent: \f$M_e = \rho \int N^T N\,dV\f$.
/// This split makes exact parameter derivatives of K trivial and lets every block's matrices
/// be assembled once and rescaled for each new parameter value.

#include <array>
#include <string>
#include <vector>

#include "modalcal/export.hpp"
#include "modalcal/types.hpp"

namespace modalcal {

enum class SolidType { Hex8, Tet4, Tet10 };

/// Number of nodes of a solid element type (8, 4 or 10).
MODALCAL_EXPORT int nodes_per_element(SolidType type);
/// Lower-case name used in problem files ("hex8", "tet4", "tet10").
MODALCAL_EXPORT std::string solid_type_name(SolidType type);

/// Unit-property element matrices of one solid element, DOFs ordered node-major
/// (u_x, u_y, u_z of node 0, then node 1, ...).
struct MODALCAL_EXPORT SolidElementMatrices {
  Matrix volumetric;  ///< per unit bulk modulus
  Matrix deviatoric;  ///< per unit shear modulus
  Matrix mass;        ///< per unit density (consistent)
};

/// Element matrices for nodal coordinates `coords` (3 x nodes_per_element, columns are nodes,
/// Exodus/Gmsh node ordering: hex8 bottom face counter-clockwise then top face; tet10 corners
/// then edge mid-nodes 01, 12, 20, 03, 13, 23).
/// Quadrature: hex8 2x2x2 Gauss; tet4 exact; tet10 4-point (stiffness) and an exact
/// degree-4 rule (mass).
/// \throws std::invalid_argument if the Jacobian determinant is not positive at a quadrature
///         point (inverted or degenerate element) or the column count does not match `type`.
MODALCAL_EXPORT SolidElementMatrices solid_element_matrices(SolidType type, const Eigen::Matrix3Xd& coords);

/// Smallest Jacobian determinant \f$\det J = \det(\partial x / \partial \xi)\f$ over the
/// element's corners and the quadrature points solid_element_matrices() evaluates. Positive:
/// the element maps one-to-one and can be assembled. Negative: inverted (nodes in the wrong
/// order, or a curved tet10 folded over); zero: degenerate (no volume). For a straight-sided
/// tet it is 6 × volume, for a parallelepiped hex volume / 8.
/// `coords` as for solid_element_matrices().
/// \throws std::invalid_argument if the column count does not match `type`.
/// \code
/// if (modalcal::min_jacobian_determinant(SolidType::Tet4, x) <= 0) { /* reject the element */ }
/// \endcode
MODALCAL_EXPORT double min_jacobian_determinant(SolidType type, const Eigen::Matrix3Xd& coords);

/// Number of sides (faces) of a solid element: 6 for hex8, 4 for tets.
MODALCAL_EXPORT int num_solid_sides(SolidType type);

/// Local node indices (0-based) on side `side` of an element, in Exodus side numbering
/// (1-based): hex8 sides 1–6 are the faces 0-1-5-4, 1-2-6-5, 2-3-7-6, 0-4-7-3, 0-3-2-1, 4-5-6-7;
/// tet sides 1–4 are 0-1-3, 1-2-3, 0-3-2, 0-2-1, and a tet10 side adds the mid-edge nodes of its
/// three edges. Corners come first, ordered counter-clockwise seen from outside the element.
/// \throws std::invalid_argument if `side` is not in 1..num_solid_sides(type).
MODALCAL_EXPORT std::vector<int> solid_side_nodes(SolidType type, int side);

/// Stiffness matrix per unit stiffness of one component of a two-node joint spring
/// (Sierra-SD Joint2G), DOFs ordered (u, θ) of node a then (u, θ) of node b (12 x 12).
/// `frame` has the joint's local x, y, z axes as its rows (orthonormal). Component 0..2 couples
/// the relative translation along local x, y, z; 3..5 the relative rotation about them:
/// \f[ K_c = \begin{pmatrix} e e^T & -e e^T \\ -e e^T & e e^T \end{pmatrix} \f]
/// placed on the translational (c < 3) or rotational (c ≥ 3) DOFs, e = frame.row(c % 3).
/// The spring has zero length: the two nodes should coincide (an offset transmits no moment).
MODALCAL_EXPORT Eigen::Matrix<double, 12, 12> joint_component_matrix(const Mat3& frame, int component);

/// Checks that `frame` is orthonormal and right-handed to 1e-8. Returns false otherwise.
MODALCAL_EXPORT bool is_rotation(const Mat3& frame);

}  // namespace modalcal
