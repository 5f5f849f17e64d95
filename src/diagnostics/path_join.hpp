#pragma once
// Internal: when a path walked after the greedy one has nothing new ahead of it, and when two
// points of the loop are one.

#include <algorithm>
#include <cmath>
#include <string>
#include <vector>

namespace modalcal::detail {

/// True when `chi2` is the fit `reference` is, to rounding: within 1e-3 relative (of the larger of
/// 1 and `reference`), as two refits of one model to the same minimum differ.
inline bool same_fit(double chi2, double reference) {
  return std::abs(chi2 - reference) <= 1e-3 * std::max(1.0, reference);
}

/// True when two points of paths through the loop hold the same effects (names, any order) at the
/// same fit (same_fit()). From there both paths take the same steps.
///
///     same_effects_and_fit({"a", "b"}, 350.2, {"b", "a"}, 350.3);  // true
///     same_effects_and_fit({"a", "b"}, 350.2, {"b", "a"}, 351.0);  // false: another minimum
inline bool same_effects_and_fit(std::vector<std::string> here, double chi2_here, std::vector<std::string> there,
                                 double chi2_there) {
  std::sort(here.begin(), here.end());
  std::sort(there.begin(), there.end());
  return here == there && same_fit(chi2_here, chi2_there);
}

/// True when the effects `here` (names, any order) are the effects `ended` an earlier path ended
/// with, and exactly one more whose likelihood-ratio gain over that end, `gain`, is below the
/// backward pass's `critical` value: the backward pass would drop that one and end where the
/// earlier path did. A gain at the critical value itself is significant, and keeps the path going.
///
///     holds_the_end_and_one_unneeded({"a", "b", "c"}, {"b", "a"}, 3.0, 6.6);  // true
///     holds_the_end_and_one_unneeded({"a", "b", "c"}, {"b", "a"}, 9.0, 6.6);  // false: c is needed
inline bool holds_the_end_and_one_unneeded(std::vector<std::string> here, std::vector<std::string> ended, double gain,
                                           double critical) {
  if (here.size() != ended.size() + 1) return false;
  std::sort(here.begin(), here.end());
  std::sort(ended.begin(), ended.end());
  return std::includes(here.begin(), here.end(), ended.begin(), ended.end()) && gain < critical;
}

}  // namespace modalcal::detail
