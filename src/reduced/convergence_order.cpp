// The measured order of convergence, shared by the reduced-space and full-space reports.

#include <algorithm>
#include <cmath>

#include "modalcal/reduced.hpp"

namespace modalcal {

double estimate_convergence_order(const std::vector<double>& errors, double floor) {
  std::vector<double> e;
  for (double v : errors)
    if (v > 0 && std::isfinite(v)) e.push_back(v);
  if (e.size() < 3) return NAN;
  // The last iterate usually sits on the rounding floor it reached; errors within 2x of that
  // floor (or below `floor`) say nothing about the rate.
  const double reached = *std::min_element(e.begin(), e.end());
  const double limit = std::max(floor, 2 * reached);
  for (size_t k = e.size() - 1; k >= 2; --k) {
    const double a = e[k - 2], b = e[k - 1], c = e[k];
    // A rate shows only where both steps gain at least a factor 2: a nearly stalled step and then
    // a large one (Newton entered close to the solution, 1e-2 -> 0.99e-2 -> 1e-8) would give
    // an "order" of 1e3.
    if (c <= limit || !(b <= 0.5 * a && c <= 0.5 * b)) continue;
    return std::log(c / b) / std::log(b / a);
  }
  return NAN;
}

}  // namespace modalcal
