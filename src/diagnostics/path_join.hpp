#pragma once
// Internal: when a path walked after the greedy one has nothing new ahead of it.

#include <algorithm>
#include <string>
#include <vector>

namespace modalcal::detail {

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
