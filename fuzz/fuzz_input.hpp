#pragma once
// What every fuzz target shares: the input becomes a file in a scratch folder, a reader reads it,
// and only the errors the readers document for bad input (ProblemError, which the CLI reports with
// the file and line and exit code 2) are accepted. Any other exception escapes to libFuzzer (or to
// the replay driver) and is a finding, as are crashes, sanitizer reports, leaks and hangs.
#include <cstddef>
#include <cstdint>
#include <functional>
#include <string>

namespace modalcal::fuzz {

/// A folder of this process's own, created at the first call, on a RAM disk when there is one
/// (/dev/shm): every execution writes its input there.
const std::string& scratch_dir();

/// Writes `size` bytes to `path`, replacing what it held.
void write_file(const std::string& path, const uint8_t* data, size_t size);

/// Writes the input to scratch_dir()/`name` (or to `folder`/`name`) and calls `read` with that
/// path; a ProblemError is the expected outcome of most inputs and is swallowed, anything else
/// propagates. Returns 0, as LLVMFuzzerTestOneInput must.
int read_as_file(const uint8_t* data, size_t size, const std::string& name,
                 const std::function<void(const std::string& path)>& read, const std::string& folder = "");

}  // namespace modalcal::fuzz
