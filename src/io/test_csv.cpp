// The plain CSV form of test data, for users without a test system:
// `mode,frequency_hz,node,direction,value`, one shape value per row, global directions.
#include <algorithm>
#include <cctype>
#include <charconv>
#include <cmath>
#include <fstream>
#include <limits>
#include <map>

#include "support/text_util.hpp"
#include "modalcal/output.hpp"
#include "modalcal/problem.hpp"
#include "modalcal/test_data.hpp"

namespace modalcal {

namespace {

using detail::excerpt;
using detail::trim;
using detail::NumberRead;
using detail::read_number;

const char* const kHeader = "mode,frequency_hz,node,direction,value";
const char* const kDirections[] = {"x", "y", "z", "rx", "ry", "rz"};

std::string lower(std::string s) {
  std::transform(s.begin(), s.end(), s.begin(), [](unsigned char c) { return static_cast<char>(std::tolower(c)); });
  return s;
}

std::vector<std::string> split(const std::string& line) {
  std::vector<std::string> fields;
  size_t start = 0;
  while (true) {
    const size_t comma = line.find(',', start);
    fields.push_back(trim(line.substr(start, comma == std::string::npos ? std::string::npos : comma - start)));
    if (comma == std::string::npos) return fields;
    start = comma + 1;
  }
}

bool parse_double(const std::string& text, double* v) { return read_number(text, v) == NumberRead::kOk; }

bool parse_long(const std::string& text, long* v) {
  const auto [ptr, ec] = std::from_chars(text.data(), text.data() + text.size(), *v);
  return ec == std::errc() && ptr == text.data() + text.size() && !text.empty();
}

std::string shortest(double v) {
  char buffer[32];
  const auto [ptr, ec] = std::to_chars(buffer, buffer + sizeof(buffer), v);
  return std::string(buffer, ptr);
}

}  // namespace

TestData read_test_csv(const std::string& path) {
  std::ifstream in(path);
  if (!in) throw ProblemError(path, 0, "cannot open the test-data file '" + path + "'");
  TestData data;
  data.path = path;
  data.format = TestData::Format::Csv;
  std::map<long, size_t> mode_index;
  std::map<std::tuple<long, long, int>, int> row_of;  // (mode, node, component) -> line
  bool header_seen = false;
  int line_number = 0;
  for (std::string line; std::getline(in, line);) {
    ++line_number;
    // Excel writes "CSV UTF-8" with a byte-order mark, which is no part of the header.
    if (line_number == 1 && line.rfind("\xEF\xBB\xBF", 0) == 0) line.erase(0, 3);
    const std::string text = trim(line);
    if (text.empty() || text[0] == '#') continue;
    auto fail = [&](const std::string& message) { throw ProblemError(path, line_number, message); };
    if (!header_seen) {
      std::string compact = lower(text);
      compact.erase(std::remove_if(compact.begin(), compact.end(), [](char c) { return c == ' ' || c == '\t'; }),
                    compact.end());
      if (compact != kHeader)
        fail("expected the header line '" + std::string(kHeader) + "', found '" + excerpt(text) + "'");
      header_seen = true;
      continue;
    }
    const std::vector<std::string> f = split(text);
    if (f.size() != 5)
      fail("expected 5 comma-separated fields (" + std::string(kHeader) + "), found " + std::to_string(f.size()));
    long mode = 0, node = 0;
    double frequency = 0, value = 0;
    if (!parse_long(f[0], &mode)) fail("mode '" + excerpt(f[0]) + "' is not a whole number");
    if (mode < std::numeric_limits<int>::min() || mode > std::numeric_limits<int>::max())  // TestMode::number is an int
      fail("mode " + std::to_string(mode) + " is outside the range of mode numbers, ±" +
           std::to_string(std::numeric_limits<int>::max()));
    if (!parse_double(f[1], &frequency) || frequency < 0)
      fail("frequency_hz '" + excerpt(f[1]) + "' is not a finite number ≥ 0");
    if (!parse_long(f[2], &node)) fail("node '" + excerpt(f[2]) + "' is not a whole number");
    const auto direction = std::find(std::begin(kDirections), std::end(kDirections), lower(f[3]));
    if (direction == std::end(kDirections)) fail("direction '" + excerpt(f[3]) + "' is not one of x, y, z, rx, ry, rz");
    if (!parse_double(f[4], &value)) fail("value '" + excerpt(f[4]) + "' is not a finite number");
    const int component = static_cast<int>(direction - std::begin(kDirections));

    const auto [it, is_new] = mode_index.try_emplace(mode, data.modes.size());
    if (is_new) {
      TestMode m;
      m.number = static_cast<int>(mode);
      m.frequency_hz = frequency;
      m.line = line_number;
      data.modes.push_back(m);
    }
    TestMode& m = data.modes[it->second];
    if (std::abs(frequency - m.frequency_hz) > 1e-9 * std::max(frequency, m.frequency_hz))
      fail("mode " + std::to_string(mode) + " has frequency " + excerpt(f[1]) + " Hz here but " +
           shortest(m.frequency_hz) + " Hz at line " + std::to_string(m.line) + "; give each mode one frequency");
    const auto [row, inserted] = row_of.try_emplace({mode, node, component}, line_number);
    if (!inserted)
      fail("mode " + std::to_string(mode) + ", node " + std::to_string(node) + ", direction " + excerpt(f[3]) +
           " is given twice (first at line " + std::to_string(row->second) + ")");
    m.values.push_back({node, component, value});
    if (component >= 3) m.values_per_node = 6;
  }
  if (!header_seen)
    throw ProblemError(path, line_number, "the file is empty; expected the header line '" + std::string(kHeader) + "'");
  if (data.modes.empty()) throw ProblemError(path, line_number, "no data rows after the header");
  for (TestMode& m : data.modes)
    std::sort(m.values.begin(), m.values.end(), [](const TestShapeValue& a, const TestShapeValue& b) {
      return a.node != b.node ? a.node < b.node : a.component < b.component;
    });
  return data;
}

std::string test_data_to_csv(const TestData& data) {
  std::string out = std::string(kHeader) + "\n";
  for (const TestMode& m : data.modes)
    for (const TestShapeValue& v : m.values)
      out += std::to_string(m.number) + "," + shortest(m.frequency_hz) + "," + std::to_string(v.node) + "," +
             kDirections[v.component] + "," + shortest(v.value) + "\n";
  return out;
}

void write_test_csv(const TestData& data, const std::string& path, const std::vector<std::string>& inputs) {
  write_file_atomically(path, test_data_to_csv(data), inputs);
}

}  // namespace modalcal
