#pragma once
/// \file types.hpp
/// Linear-algebra aliases shared by every module.

#include <Eigen/Core>
#include <Eigen/SparseCore>

namespace modalcal {

using Vec3 = Eigen::Vector3d;
using Mat3 = Eigen::Matrix3d;
using Vector = Eigen::VectorXd;
using Matrix = Eigen::MatrixXd;
/// Column-major sparse matrix with int indices (what CHOLMOD's int interface takes).
using SparseMatrix = Eigen::SparseMatrix<double, Eigen::ColMajor, int>;

/// Degree-of-freedom components of a node: three translations, three rotations.
enum class Component : int { X = 0, Y = 1, Z = 2, RX = 3, RY = 4, RZ = 5 };

}  // namespace modalcal
