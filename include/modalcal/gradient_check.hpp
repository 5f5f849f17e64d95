#pragma once
/// \file gradient_check.hpp
/// A public gradient checker (as in Ceres): compares the adjoint gradient of an Objective with
/// central finite differences, parameter by parameter.
///
/// \f[ g^{FD}_j = \frac{J(p + h_j e_j) - J(p - h_j e_j)}{2 h_j},\quad h_j = \text{relative\_step}\,|p_j|,
///     \qquad \text{error}_j = \frac{|g_j - g^{FD}_j|}{\max(|g_j|, |g^{FD}_j|, \text{floor})} \f]
/// with floor = 1e-8 max_j |g_j| so that a component that is zero in both does not count.
///
/// \code
/// modalcal::GradientCheck check = modalcal::check_gradient(objective, p);
/// std::cout << check.report;   // one line per parameter, then the maximum relative error
/// \endcode

#include <string>

#include "modalcal/export.hpp"
#include "modalcal/objective.hpp"

namespace modalcal {

struct MODALCAL_EXPORT GradientCheckOptions {
  /// h_j / |p_j|. Range: (0, 0.1). 1e-5 balances truncation error O(h^2) against round-off
  /// in J (eigen-solves carry ~1e-14 relative noise, amplified as noise / h).
  double relative_step = 1e-5;
  double tolerance = 1e-4;      ///< a component passes if its relative error is below. Range: > 0.
};

struct MODALCAL_EXPORT GradientCheck {
  bool ok = false;              ///< every component within tolerance, and every evaluation succeeded
  Vector analytic, finite_difference, relative_error;
  double max_relative_error = 0;
  std::string report;           ///< a table, one row per parameter
};

MODALCAL_EXPORT GradientCheck check_gradient(Objective& objective, const Vector& p,
                                             const GradientCheckOptions& options = {});

}  // namespace modalcal
