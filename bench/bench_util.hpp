#pragma once
// Small helpers shared by the benchmark executables (header-only: benchmarks are not part of the
// library).

#include <cstddef>
#include <sstream>
#include <stdexcept>
#include <string>
#include <vector>

namespace modalcal::bench {

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

}  // namespace modalcal::bench
