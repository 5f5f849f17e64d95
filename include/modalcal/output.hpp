#pragma once
/// \file output.hpp
/// Writing results without ever losing what a user gave: every output is written to a
/// temporary file in the target directory and renamed over the target, so a crash leaves
/// either the old file or the new one, never half of one; and no output may replace an input.

#include <string>
#include <vector>
#include "modalcal/export.hpp"

namespace modalcal {

/// \throws std::invalid_argument if `path` exists and is one of `inputs` (the same file on disk).
/// For writers of several files, which check every target before writing the first.
MODALCAL_EXPORT void check_not_input(const std::string& path, const std::vector<std::string>& inputs);

/// check_not_input(), and that `path` can be written: its folder exists and takes a new file
/// (one is created there and removed), its name is within the file system's limit, and it is
/// not a directory. What a command checks of each output before it runs, so that a bad output
/// name costs no computation.
/// \throws std::invalid_argument naming the path and the cause.
MODALCAL_EXPORT void check_output_path(const std::string& path, const std::vector<std::string>& inputs);

/// Writes `content` to `path` atomically (temporary file + rename in the same directory) when
/// `path` is a regular file or does not exist; straight through it, as a shell redirection would,
/// when it is a device, a FIFO or a symbolic link (so /dev/stdout, /dev/null and pipes work and
/// stay what they are).
/// \throws std::invalid_argument if `path` is one of `inputs` (same file on disk), a directory,
///         or in a folder that does not exist; std::runtime_error naming the path if it cannot
///         be written.
MODALCAL_EXPORT void write_file_atomically(const std::string& path, const std::string& content,
                                           const std::vector<std::string>& inputs = {});

}  // namespace modalcal
