#pragma once
// Internal: small text helpers for messages and the test-data readers and writers.
#include <charconv>
#include <sstream>
#include <string>
#include <type_traits>

namespace modalcal::detail {

/// `s` without leading and trailing blanks (space, tab, carriage return).
inline std::string trim(const std::string& s) {
  const size_t first = s.find_first_not_of(" \t\r");
  if (first == std::string::npos) return "";
  return s.substr(first, s.find_last_not_of(" \t\r") - first + 1);
}

/// `s` for a message, at most about `most` characters: a longer text (a whole file given where a
/// name belongs, a 2 MB field) keeps its start and end with the count of what is left out.
inline std::string excerpt(const std::string& s, size_t most = 200) {
  if (s.size() <= most) return s;
  return s.substr(0, most / 2) + " ... (" + std::to_string(s.size() - most) + " characters left out) ... " +
         s.substr(s.size() - most / 2);
}

/// A number for messages, with `precision` significant digits.
inline std::string number_text(double v, int precision = 6) {
  std::ostringstream s;
  s.precision(precision);
  s << v;
  return s.str();
}

/// An option's value for a message: a whole number as it is, a floating-point one in the fewest
/// digits that read back to it (1e+308, not std::to_string's 309 digits; 1e-09, not 0.000000).
template <typename T>
std::string option_text(T value) {
  if constexpr (std::is_integral_v<T>) {
    return std::to_string(value);
  } else {
    char buffer[32];
    const auto result = std::to_chars(buffer, buffer + sizeof buffer, static_cast<double>(value));
    return std::string(buffer, result.ptr);
  }
}

}  // namespace modalcal::detail
