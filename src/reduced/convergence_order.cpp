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
    if (c <= limit || !(b < a && c < b)) continue;
    return std::log(c / b) / std::log(b / a);
  }
  return NAN;
}

}  // namespace modalcal
