#pragma once
// Internal: small text helpers for messages and the test-data readers and writers.
#include <charconv>
#include <cmath>
#include <cstdlib>
#include <sstream>
#include <string>
#include <string_view>
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

/// What read_number() made of a text.
enum class NumberRead {
  kOk,          ///< a finite number (an underflow, 1e-320, is the tiny or zero value it is)
  kNotANumber,  ///< no number, or one followed by more text
  kTooLarge,    ///< beyond a double's range (1e400)
  kNotFinite,   ///< nan or inf
};

/// Reads the number at the start of `text`, the one grammar of every reader of numbers: an
/// optional sign ('+' too), digits with an optional point, an optional exponent; no blanks
/// before it, no hexadecimal. `*length` gets how many characters it took (0 when kNotANumber).
/// Each reader keeps its own words for what it refuses, and its own fields: a whole token
/// (read_number) or, in UFF's fixed columns, numbers that touch (1.0-2.0).
inline NumberRead read_leading_number(std::string_view text, double* v, size_t* length) {
  *length = 0;
  const size_t sign = !text.empty() && text[0] == '+' && text.size() > 1 && text[1] != '-' ? 1 : 0;
  const auto [end, error] = std::from_chars(text.data() + sign, text.data() + text.size(), *v);
  if (error == std::errc::invalid_argument) return NumberRead::kNotANumber;
  *length = static_cast<size_t>(end - text.data());
  if (error == std::errc::result_out_of_range) {
    // from_chars leaves the value alone on a range error; strtod tells an underflow (its value
    // stands) from an overflow (HUGE_VAL).
    const std::string copy(text.substr(sign, *length - sign));
    *v = std::strtod(copy.c_str(), nullptr);
    if (std::abs(*v) >= 1) return NumberRead::kTooLarge;
    return NumberRead::kOk;
  }
  return std::isfinite(*v) ? NumberRead::kOk : NumberRead::kNotFinite;
}

/// read_leading_number() over the whole of `text`: more text after the number is kNotANumber.
inline NumberRead read_number(std::string_view text, double* v) {
  size_t length = 0;
  const NumberRead read = read_leading_number(text, v, &length);
  if (read != NumberRead::kNotANumber && length != text.size()) return NumberRead::kNotANumber;
  return read;
}

}  // namespace modalcal::detail
