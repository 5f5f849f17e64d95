#include "fuzz_input.hpp"

#include <unistd.h>

#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <stdexcept>

#include "modalcal/problem.hpp"

namespace modalcal::fuzz {

namespace fs = std::filesystem;

const std::string& scratch_dir() {
  static const std::string dir = [] {
    std::error_code ec;
    fs::path base = fs::is_directory("/dev/shm", ec) ? fs::path("/dev/shm") : fs::temp_directory_path();
    fs::path d = base / ("modalcal-fuzz-" + std::to_string(::getpid()));
    fs::create_directories(d);
    return d.string();
  }();
  return dir;
}

void write_file(const std::string& path, const uint8_t* data, size_t size) {
  std::ofstream out(path, std::ios::binary | std::ios::trunc);
  out.write(reinterpret_cast<const char*>(data), static_cast<std::streamsize>(size));
  if (!out) throw std::runtime_error("fuzz harness: cannot write " + path);
}

int read_as_file(const uint8_t* data, size_t size, const std::string& name,
                 const std::function<void(const std::string& path)>& read, const std::string& folder) {
  const std::string path = (folder.empty() ? scratch_dir() : folder) + "/" + name;
  write_file(path, data, size);
  try {
    read(path);
  } catch (const ProblemError& e) {
    // The documented answer to bad input; MODALCAL_FUZZ_VERBOSE=1 shows it (to check a seed).
    static const bool verbose = std::getenv("MODALCAL_FUZZ_VERBOSE") != nullptr;
    if (verbose) std::fprintf(stderr, "input error: %s\n", e.what());
  }
  return 0;
}

}  // namespace modalcal::fuzz
