#pragma once
/// \file identifiability.hpp
/// Which parameters the measured data determine. The scaled sensitivity matrix
/// \f$S = \partial r / \partial x\f$ (residuals with respect to the optimizer's variables, so log10
/// for log-scaled parameters) has the singular value decomposition \f$S = W \Sigma V^T\f$. A
/// direction \f$v_k\f$ with a small \f$\sigma_k\f$ changes the misfit little: moving the parameters
/// along it by \f$\delta\f$ changes \f$\tfrac12|r|^2\f$ by only \f$\tfrac12\sigma_k^2\delta^2\f$.
/// Near a fit, \f$S^T S\f$ is the Gauss-Newton Hessian, i.e. the Fisher information for unit noise;
/// \f$1/\sigma_k\f$ is then the standard deviation of x along \f$v_k\f$ per unit residual noise.
///
/// A parameter is flagged as poorly identified when it carries most of a weak direction:
/// \f$\sigma_k < \text{threshold}\cdot\sigma_1\f$ and \f$v_{jk}^2 \ge 0.5\f$ — or, when there are fewer
/// independent data than parameters, the null directions (σ = 0) count as weak.

#include <string>
#include <vector>

#include "modalcal/export.hpp"
#include "modalcal/objective.hpp"
#include "modalcal/reduced.hpp"

namespace modalcal {

struct MODALCAL_EXPORT Identifiability {
  Vector singular_values;          ///< descending, padded with zeros up to the parameter count
  Matrix directions;               ///< V: columns are parameter-space directions (scaled variables)
  std::vector<bool> poorly_identified;  ///< per parameter
  /// Per parameter: the share of its variance along weak directions, sum_k v_jk^2 over weak k.
  Vector weak_share;
  std::string report;              ///< singular values, directions and the verdict, for people
};

/// \param relative_threshold a direction is weak if sigma_k < relative_threshold * sigma_1.
MODALCAL_EXPORT Identifiability analyze_identifiability(Objective& objective, const Vector& p,
                                                        const ParameterScaling& scaling,
                                                        double relative_threshold = 1e-3);

}  // namespace modalcal
