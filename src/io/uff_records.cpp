#include "io/uff_records.hpp"

#include <algorithm>
#include <charconv>
#include <cmath>

#include "support/text_util.hpp"
#include "modalcal/problem.hpp"

namespace modalcal::detail {

namespace {

bool is_blank(char c) { return c == ' ' || c == '\t' || c == '\r'; }

bool is_delimiter(const std::string& line) { return trim(line) == "-1"; }

std::string line_excerpt(const std::string& line) {
  const std::string t = trim(line);
  return t.size() > 40 ? t.substr(0, 40) + "..." : t;
}

}  // namespace

bool parse_numbers(const std::string& line, std::vector<double>* numbers, std::string* bad) {
  numbers->clear();
  std::string s = line;
  // Fortran writes double precision as 1.0D+00; no other letter belongs in a numeric record.
  std::replace_if(
      s.begin(), s.end(), [](char c) { return c == 'D' || c == 'd'; }, 'E');
  size_t i = 0;
  while (true) {
    while (i < s.size() && is_blank(s[i])) ++i;
    if (i >= s.size()) return true;
    const size_t start = i;
    double v = 0;
    size_t length = 0;
    const NumberRead read = read_leading_number(std::string_view(s).substr(i), &v, &length);
    const size_t stop = i + length;
    // A field ends at a blank, the line's end, or the sign of a touching next field.
    const bool ends_well = stop >= s.size() || is_blank(s[stop]) || s[stop] == '+' || s[stop] == '-';
    if (read != NumberRead::kOk || !ends_well) {
      const size_t end = line.find_first_of(" \t\r", start);
      *bad = line_excerpt(line.substr(start, end == std::string::npos ? std::string::npos : end - start));
      return false;
    }
    numbers->push_back(v);
    i = stop;
  }
}

namespace {

/// The byte count of a 58b header line ("58b", byte order, float format, ASCII lines, bytes,
/// ...) and its count of ASCII lines, or false if it is not one.
bool binary_58_header(const std::string& line, long* ascii_lines, long* bytes) {
  const std::string t = trim(line);
  if (t.rfind("58b", 0) != 0) return false;
  std::vector<double> fields;
  std::string bad;
  if (!parse_numbers(t.substr(3), &fields, &bad) || fields.size() < 4) return false;
  // In range before the conversion: a double beyond a long's range converts to nothing defined.
  if (!(fields[2] >= 0 && fields[3] >= 0 && fields[2] < 1e6 && fields[3] < 1e12)) return false;
  *ascii_lines = static_cast<long>(fields[2]);
  *bytes = static_cast<long>(fields[3]);
  return true;
}

}  // namespace

std::vector<std::string> uff_lines(const std::string& text, std::map<int, long>* binary) {
  std::vector<std::string> lines;
  size_t at = 0;
  auto next_line = [&] {  // a line ends at LF, CRLF or a lone CR (classic Mac)
    const size_t end = text.find_first_of("\r\n", at);
    lines.push_back(text.substr(at, end == std::string::npos ? std::string::npos : end - at));
    const bool crlf = end != std::string::npos && text[end] == '\r' && end + 1 < text.size() && text[end + 1] == '\n';
    at = end == std::string::npos ? text.size() : end + (crlf ? 2 : 1);
  };
  while (at < text.size()) {
    next_line();
    long ascii = 0, bytes = 0;
    const bool opens = lines.size() >= 2 && is_delimiter(lines[lines.size() - 2]);
    if (!opens || !binary_58_header(lines.back(), &ascii, &bytes)) continue;
    const int header = static_cast<int>(lines.size()) - 1;
    for (long k = 0; k < ascii && at < text.size(); ++k) next_line();
    if (static_cast<size_t>(bytes) > text.size() - at) continue;  // not what it claims: refused as binary
    (*binary)[header] = bytes;
    lines.resize(lines.size() + static_cast<size_t>(std::count(text.begin() + static_cast<long>(at),
                                                               text.begin() + static_cast<long>(at) + bytes, '\n')));
    at += static_cast<size_t>(bytes);
  }
  return lines;
}

std::vector<UffBlock> split_uff(const std::string& file, const std::vector<std::string>& lines,
                                const std::map<int, long>& binary) {
  std::vector<UffBlock> blocks;
  const int n = static_cast<int>(lines.size());
  int i = 0;
  while (i < n) {
    if (trim(lines[i]).empty()) {
      ++i;
      continue;
    }
    if (!is_delimiter(lines[i])) {
      std::string message = "expected '-1', which opens a dataset, found '" + line_excerpt(lines[i]) + "'";
      if (!blocks.empty())
        message += "; did dataset " + std::to_string(blocks.back().number) + " (line " +
                   std::to_string(blocks.back().number_line) +
                   ") lose its closing '-1', or the next dataset its opening one?";
      throw ProblemError(file, i + 1, message);
    }
    const int open = i++;
    if (i >= n) throw ProblemError(file, open + 1, "the file ends after a '-1' line; a dataset number should follow");
    const std::string id = trim(lines[i]).substr(0, trim(lines[i]).find_first_of(" \t"));
    UffBlock block;
    block.number_line = i + 1;
    const auto [ptr, ec] = std::from_chars(id.data(), id.data() + id.size(), block.number);
    if (ec != std::errc() || id.empty() || block.number <= 0)
      throw ProblemError(file, i + 1,
                         "expected a dataset number after the '-1' at line " + std::to_string(open + 1) + ", found '" +
                             line_excerpt(lines[i]) + "'");
    if (const auto skipped = binary.find(i); skipped != binary.end())
      block.binary_bytes = skipped->second;
    else if (ptr != id.data() + id.size())
      throw ProblemError(file, i + 1,
                         "dataset " + id + " is binary ('" + id + "'), which is not read; export the file as ASCII");
    block.first = ++i;
    while (i < n && !is_delimiter(lines[i])) ++i;
    if (i >= n)
      throw ProblemError(file, block.number_line,
                         "dataset " + std::to_string(block.number) +
                             " starting here has no closing '-1' line before the end of the file (line " +
                             std::to_string(n) + "); the file may be truncated");
    block.end = i++;
    blocks.push_back(block);
  }
  return blocks;
}

UffRecords::UffRecords(const std::string& file, const std::vector<std::string>& lines, const UffBlock& block)
    : file_(file), lines_(lines), block_(block), next_(block.first) {}

void UffRecords::fail(int line, const std::string& message) const {
  throw ProblemError(file_, line, "dataset " + std::to_string(block_.number) + ": " + message);
}

std::string UffRecords::text(const std::string& what) {
  if (at_end())
    fail(line(), "the dataset ends (its closing '-1' is here) where " + what + " should be; the file may be truncated");
  std::string s = lines_[next_++];
  while (!s.empty() && is_blank(s.back())) s.pop_back();
  return s;
}

std::vector<double> UffRecords::peek(const std::string& what) const {
  std::vector<double> row;
  std::string bad;
  if (!at_end() && !parse_numbers(lines_[next_], &row, &bad)) fail(line(), what + ": '" + bad + "' is not a number");
  return row;
}

std::vector<double> UffRecords::numbers(int count, const std::string& what, int per_line) {
  std::vector<double> out, row;
  std::string bad;
  const size_t full = per_line > 0 ? static_cast<size_t>(per_line) : static_cast<size_t>(count);
  while (out.size() < static_cast<size_t>(count)) {
    const size_t remaining = static_cast<size_t>(count) - out.size();
    if (at_end())
      fail(line(), "the dataset ends (its closing '-1' is here) where " + what + " should " +
                       (out.empty() ? "be"
                                    : "continue (" + std::to_string(out.size()) + " of " + std::to_string(count) +
                                          " numbers read)") +
                       "; the file may be truncated or a count in the dataset be wrong");
    const int at = line();
    if (!parse_numbers(lines_[next_++], &row, &bad)) fail(at, what + ": '" + bad + "' is not a number");
    const size_t least = std::min(full, remaining);
    if (row.size() < least || row.size() > remaining) {
      const size_t expected = row.size() < least ? least : remaining;
      fail(at, what + ": expected " + std::string(row.size() > remaining ? "at most " : "") + std::to_string(expected) +
                   " number" + (expected == 1 ? "" : "s") +
                   (out.empty() ? "" : " more (" + std::to_string(count) + " in all)") + " on this line, found " +
                   std::to_string(row.size()));
    }
    out.insert(out.end(), row.begin(), row.end());
  }
  return out;
}

std::vector<double> UffRecords::whole_numbers(int count, const std::string& what, int per_line) {
  const int at = line();
  std::vector<double> out = numbers(count, what, per_line);
  for (double v : out)
    if (v != std::floor(v))
      fail(at, what + ": expected whole numbers, found " + option_text(v));
    else if (std::abs(v) > 2e9)
      fail(at, what + ": " + option_text(v) + " is too large; whole-number fields hold at most 2e9 here");
  return out;
}

}  // namespace modalcal::detail
