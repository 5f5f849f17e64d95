#pragma once
// Internal: the lines of a universal file split into datasets, and a cursor that reads one
// dataset record by record, with errors naming the file, the line and the dataset.
#include <map>
#include <string>
#include <vector>

namespace modalcal::detail {

/// Numbers on one line: Fortran fixed-width fields (which may touch, "1.0E+00-2.0E+00") or
/// whitespace-separated values, with 'E' or 'D' exponents. Returns false and sets *bad to the
/// offending text if a field is not a finite number.
bool parse_numbers(const std::string& line, std::vector<double>* numbers, std::string* bad);

/// One dataset: its number and the range of file lines between its "-1" delimiters.
struct UffBlock {
  int number = 0;
  int number_line = 0;     ///< 1-based line of the dataset number
  int first = 0, end = 0;  ///< 0-based indices of its records: [first, end)
  long binary_bytes = -1;  ///< a binary dataset skipped by its byte count (58b), else -1
};

/// The lines of a universal file's text (line ends \n or \r\n). The binary data of each
/// binary function dataset (58b), whose header gives the count of ASCII lines and of bytes after
/// them, is skipped by that count: it becomes as many empty lines as it holds line feeds (so that
/// later line numbers stay right), and `binary` maps the 0-based index of its header line to its
/// byte count.
std::vector<std::string> uff_lines(const std::string& text, std::map<int, long>* binary);

/// Splits `lines` into datasets. \throws ProblemError for a dataset without its closing "-1",
/// a line outside any dataset, a missing or non-numeric dataset number, a binary dataset other
/// than those `binary` lists (uff_lines).
std::vector<UffBlock> split_uff(const std::string& file, const std::vector<std::string>& lines,
                                const std::map<int, long>& binary = {});

/// Reads the records of one dataset in order.
class UffRecords {
 public:
  UffRecords(const std::string& file, const std::vector<std::string>& lines, const UffBlock& block);

  bool at_end() const { return next_ >= block_.end; }
  /// 1-based line number of the next record.
  int line() const { return next_ + 1; }
  /// A free-text record (the whole line, trailing blanks removed).
  std::string text(const std::string& what);
  /// `count` numbers written `per_line` to a full line (Fortran "6E13.5" wraps after six; 0:
  /// all on one line). A line may hold more (whitespace-separated writers), never fewer than
  /// a full line or the rest, nor more than the rest.
  std::vector<double> numbers(int count, const std::string& what, int per_line = 0);
  /// numbers(), each checked to be a whole number.
  std::vector<double> whole_numbers(int count, const std::string& what, int per_line = 0);
  /// The numbers on the next line without consuming it (empty at the end of the dataset).
  std::vector<double> peek(const std::string& what) const;
  /// Throws ProblemError at `line` with "dataset N: " before the message.
  [[noreturn]] void fail(int line, const std::string& message) const;

 private:
  const std::string& file_;
  const std::vector<std::string>& lines_;
  UffBlock block_;
  int next_;  ///< 0-based index of the next line
};

}  // namespace modalcal::detail
