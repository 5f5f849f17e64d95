#pragma once
/// \file problem_file.hpp
/// The files of a problem: reading a problem file (YAML, docs/problem-format.md) into a Problem,
/// reading a list of model changes, writing a measured-data file. A problem file gives its model
/// or mesh file, parameters, sensors, measured modes (inline, from a data file, from test data, or
/// synthesized from a truth model), noise, declared effects and options, each checked with the
/// file and line of what is wrong.
///
/// \code
/// modalcal::Problem problem = modalcal::load_problem("problems/lfu/synthetic.yaml");
/// modalcal::synthesize_measured(&problem);  // synthesis.hpp: a `measured: synthetic:` section's modes
/// \endcode

#include <optional>
#include <string>
#include <vector>

#include "modalcal/export.hpp"
#include "modalcal/measured_data.hpp"
#include "modalcal/model_change.hpp"
#include "modalcal/problem.hpp"

namespace modalcal {

/// Settings that override a problem file at load time.
struct MODALCAL_EXPORT LoadOptions {
  double refinement = 0;       ///< > 0 overrides a generated mesh's refinement factor (an error with a mesh file)
  /// Sensors placed at a point, and a data file's sensors, take the nearest node however far it
  /// is: for a copy of a problem on a finer mesh, where the points may fall between nodes.
  bool nearest_sensor_nodes = false;
  /// > 0: the memory (bytes) a mesh's estimated modal solve must fit in, instead of the machine's
  /// physical memory; a larger mesh is refused like one too large for the machine (the fuzz
  /// targets keep meshes small this way).
  double memory_bytes = 0;
};

/// Reads and validates a problem file. A `measured: synthetic:` section is read and checked, but
/// its modes are not computed: Problem::measured stays empty until synthesize_measured()
/// (synthesis.hpp) solves the truth model, so that reading a file never runs a modal solve.
/// \throws ProblemError naming the file, the line and what is wrong, also for a file that is not
///         a regular one or has more than 16 MB, and for a generated mesh whose modal solve would
///         need more memory than the machine has (estimated from its size before it is made);
///         std::invalid_argument for a refinement that is negative or not finite.
MODALCAL_EXPORT Problem load_problem(const std::string& path, const LoadOptions& options = {});

/// Reads a changes file: a YAML map with a list `changes:` of change strings and an optional
/// `description:`. Returns nullopt if the file has no `changes` key (it is then a problem file).
/// \throws ProblemError (problem.hpp) naming the file and line of an unreadable file, a
///   malformed change, or a key beside `changes` and `description`.
MODALCAL_EXPORT std::optional<std::vector<ModelChange>> load_model_changes(const std::string& path);

/// Why `path` cannot be read as a `what` (for the message, e.g. "calibration report"), or "" if
/// it can: it does not exist, is a directory, or is not a regular file (a device such as
/// /dev/zero or a FIFO, which would hang a reader). Every input file passes this check first.
/// Example: `if (auto why = unreadable_input(path, "report"); !why.empty()) throw ...(why);`
MODALCAL_EXPORT std::string unreadable_input(const std::string& path, const std::string& what);

/// Writes `data` as a YAML data file (atomically; numbers in their shortest round-trip form, so
/// reading it back gives the same doubles).
/// \throws std::invalid_argument if `path` is one of `inputs`, std::runtime_error if it cannot be written.
MODALCAL_EXPORT void write_measured_data(const std::string& path, const MeasuredData& data,
                                         const std::vector<std::string>& inputs);

}  // namespace modalcal
