#pragma once
// Internal: fills Problem::measured from a forward solve at the truth parameters.
#include "modalcal/problem.hpp"

namespace modalcal::detail {

/// Replaces problem->measured with the modes `spec.modes` of the model at the truth values
/// (frequency, and shape at the sensors if spec.shapes; noise free), paired by MAC with shapes
/// and by model mode index without; sets problem->synthetic_truth (no hidden effect).
/// \throws ProblemError (at spec.source_line) if a parameter has no truth or the solve fails.
void synthesize_measured(Problem* problem, const SyntheticSpec& spec);

}  // namespace modalcal::detail
