#pragma once
// Internal: optimal one-to-one assignment (Hungarian method, Kuhn-Munkres with potentials,
// O(rows^2 cols)). Used to pair measured with model modes by the largest total MAC: greedy
// pairing can lock in a locally best pair that forces the rest into poor matches.
#include <vector>

#include "modalcal/types.hpp"

namespace modalcal::detail {

/// For a rows x cols matrix of scores (rows <= cols; -infinity forbids a pair), returns for
/// each row the column assigned to it, maximizing the total score.
std::vector<int> maximize_assignment(const Matrix& score);

}  // namespace modalcal::detail
