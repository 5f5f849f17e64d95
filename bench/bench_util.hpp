#pragma once
// Small helpers shared by the benchmark executables (header-only: benchmarks are not part of the
// library).

#include <chrono>
#include <cmath>
#include <cstddef>
#include <cstdio>
#include <fstream>
#include <sstream>
#include <stdexcept>
#include <string>
#include <vector>

namespace modalcal::bench {

using Clock = std::chrono::steady_clock;
inline double seconds_since(Clock::time_point t0) { return std::chrono::duration<double>(Clock::now() - t0).count(); }

/// The load average "x (1 min), y (5 min)": wall times are only comparable on an otherwise idle
/// machine, so benchmarks print it next to them.
inline std::string load_average() {
  std::ifstream in("/proc/loadavg");
  double one = NAN, five = NAN;
  in >> one >> five;
  char text[64];
  std::snprintf(text, sizeof text, "%.1f (1 min), %.1f (5 min)", one, five);
  return text;
}

/// Items of a comma-separated command-line list ("lbfgs,newton"), in order; "" gives no items.
inline std::vector<std::string> split_list(const std::string& text) {
  std::vector<std::string> out;
  std::stringstream s(text);
  std::string item;
  while (std::getline(s, item, ',')) out.push_back(item);
  return out;
}

/// Numbers of a comma-separated command-line list ("1,1.5", "3e4,1e5").
/// \throws std::invalid_argument naming the item that is not a number (trailing text included).
inline std::vector<double> parse_list(const std::string& text) {
  std::vector<double> out;
  for (const std::string& item : split_list(text)) {
    std::size_t used = 0;
    double value = 0;
    try {
      value = std::stod(item, &used);
    } catch (const std::exception&) {
      used = 0;
    }
    if (used == 0 || used != item.size())
      throw std::invalid_argument("'" + item + "' in the list '" + text + "' is not a number");
    out.push_back(value);
  }
  return out;
}

/// A benchmark's main(): `run`'s exit code, or its exception's message on stderr and exit 1.
inline int run_guarded(const char* name, int (*run)(int, char**), int argc, char** argv) {
  try {
    return run(argc, argv);
  } catch (const std::exception& e) {
    std::fprintf(stderr, "%s: %s\n", name, e.what());
    return 1;
  }
}

}  // namespace modalcal::bench
