#include "io/input_file.hpp"

#include <cstdio>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <vector>

#include "support/text_util.hpp"
#include "modalcal/problem.hpp"
#include "modalcal/problem_file.hpp"

namespace modalcal::detail {

namespace fs = std::filesystem;

std::string unreadable_reason(const std::string& path, const std::string& what, std::uintmax_t most_bytes) {
  const std::string quoted = "'" + excerpt(path) + "'";
  std::error_code ec;
  const fs::file_status status = fs::status(path, ec);
  if (status.type() == fs::file_type::not_found) return "cannot open the " + what + " " + quoted + ": no such file";
  if (ec) return "cannot open the " + what + " " + quoted + ": " + ec.message();
  if (fs::is_directory(status)) return quoted + " is a directory, not a " + what;
  if (!fs::is_regular_file(status))
    return quoted + " is not a regular file (a device, FIFO or socket) and cannot be a " + what;
  const std::uintmax_t bytes = fs::file_size(path, ec);
  if (!ec && bytes > most_bytes) {
    char sizes[96];
    std::snprintf(sizes, sizeof sizes, "%.3g MB; a %s has at most %.3g MB", bytes / 1e6, what.c_str(),
                  most_bytes / 1e6);
    return quoted + " has " + sizes + " (is it the right file?)";
  }
  return "";
}

}  // namespace modalcal::detail

namespace modalcal {

std::string unreadable_input(const std::string& path, const std::string& what) {
  return detail::unreadable_reason(path, what);
}

}  // namespace modalcal

namespace modalcal::detail {

namespace {

// yaml-cpp ends lines at LF only; a file saved with classic-Mac CR line ends would read as one
// line. A lone CR becomes LF (CRLF stays), so line numbers in messages match an editor's.
std::string with_line_feeds(std::string text) {
  for (size_t i = 0; i < text.size(); ++i)
    if (text[i] == '\r' && (i + 1 == text.size() || text[i + 1] != '\n')) text[i] = '\n';
  return text;
}

// Content after a `---` would otherwise be dropped without a word; empty documents drop nothing.
YAML::Node only_document(const std::string& path, const std::string& what, const std::vector<YAML::Node>& documents) {
  for (size_t k = 1; k < documents.size(); ++k)
    if (!documents[k].IsNull())
      throw ProblemError(path, documents[k].Mark().is_null() ? 0 : documents[k].Mark().line + 1,
                         "a second YAML document (after '---') starts here; a " + what +
                             " is one document: join them or remove the '---'");
  return documents.empty() ? YAML::Node() : documents.front();
}

}  // namespace

YAML::Node load_yaml_file(const std::string& path, const std::string& what) {
  if (const std::string reason = unreadable_reason(path, what, kMostYamlBytes); !reason.empty())
    throw ProblemError(path, 0, reason);
  std::ifstream in(path, std::ios::binary);
  const std::string text{std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()};
  if (!in.is_open() || in.bad())
    throw ProblemError(path, 0, "cannot read the " + what + " '" + path + "'; check its permissions");
  try {
    return only_document(path, what, YAML::LoadAll(with_line_feeds(text)));
  } catch (const YAML::DeepRecursion& e) {
    // yaml-cpp reports it as "bad file".
    throw ProblemError(path, e.mark.is_null() ? 0 : e.mark.line + 1,
                       "lists or maps nested " + std::to_string(e.depth()) + " or more levels deep; a " + what +
                           " needs a few (is it the right file?)");
  } catch (const YAML::Exception& e) {
    throw ProblemError(path, e.mark.is_null() ? 0 : e.mark.line + 1, "YAML syntax error: " + e.msg);
  }
}

}  // namespace modalcal::detail
