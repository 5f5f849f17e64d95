#pragma once
// Internal: sensors and measured modes of a problem from a test-data file
// (`measured: test_data:` in a problem file; docs/problem-format.md).
#include <string>
#include <vector>

#include "modalcal/problem.hpp"
#include "modalcal/test_data.hpp"

namespace modalcal::detail {

/// What `measured: test_data:` asks for, with the problem-file lines of its keys for messages.
struct TestDataSelection {
  std::string problem_file;  ///< the file the section is written in
  int line = 0;              ///< of 'test_data'
  std::string path;          ///< the test-data file, resolved against problem_file's folder
  int file_line = 0;
  std::vector<int> modes;  ///< mode numbers in the file; empty: all, in file order
  std::vector<int> mode_lines;
  NodeMapOptions map;
  std::vector<int> directions{0, 1, 2};  ///< global translations measured at every matched node
  LengthConversion lengths;
};

/// Why a measured frequency cannot be calibrated against, or "": not positive, or outside 1 µHz to
/// 1 GHz, where no structure has modes and its eigenvalue (2πf)² and the relative misfits divided
/// by it overflow or underflow (1e-300 Hz ended in a NaN blamed on "a parameter without bounds").
std::string unusable_frequency(double hz);

/// Reads the file, converts its lengths, maps its nodes onto the model and sets
/// problem->sensors (matched nodes × directions that every selected mode has) and
/// problem->measured (frequency and shape at the sensors, paired by MAC); adds the mapping
/// report, the file's warnings and the unit conversion to problem->warnings.
/// Lengths are converted by convert_lengths() with problem->units.
/// \throws ProblemError naming the test-data file, line and dataset for a bad file, or the
///         problem file and the key's line for a selection that cannot be met.
void measured_from_test_data(const TestDataSelection& selection, Problem* problem);

}  // namespace modalcal::detail
