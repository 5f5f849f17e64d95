#pragma once
// Internal: parts of the diagnosis's recommendation, for the tests.

#include <string>

#include "modalcal/diagnosis.hpp"

namespace modalcal::detail {

/// " The data hardly tell X from A and B." for each kept effect of `d` whose step had
/// alternatives the data do not tell from it by 20 : 1 (DiagnosisStep::data_favour()), at most
/// three named, then where the readings that would tell them apart are listed; "" when none has.
std::string hardly_told_apart_text(const Diagnosis& d);

}  // namespace modalcal::detail
