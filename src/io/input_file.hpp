#pragma once
// Internal: the checks every input file passes before it is read, so that a device, a FIFO, a
// loop of symbolic links or a huge file is refused with its name instead of hanging the program or
// exhausting its memory; and YAML files read after them.
#include <yaml-cpp/depthguard.h>
#include <yaml-cpp/yaml.h>

#include <cstdint>
#include <string>

namespace modalcal::detail {

/// Problem, data and changes files are written by people or by this program: at most 16 MB.
constexpr std::uintmax_t kMostYamlBytes = 16000000;

/// Why `path` cannot be read as a `what` (e.g. "problem file"), or "" if it can: it does not exist
/// (the reason then ends in "no such file"), is a directory or another file that is not a regular
/// one (a device such as /dev/zero, a FIFO), lies behind a loop of symbolic links, or has more
/// than `most_bytes`.
std::string unreadable_reason(const std::string& path, const std::string& what,
                              std::uintmax_t most_bytes = UINTMAX_MAX);

/// Reads a YAML file that passes those checks (at most kMostYamlBytes).
/// \throws ProblemError naming the file, and the line of a syntax error.
YAML::Node load_yaml_file(const std::string& path, const std::string& what);

}  // namespace modalcal::detail
