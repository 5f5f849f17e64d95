#include "fullspace/sparse_layout.hpp"

#include <utility>

namespace modalcal::detail {

int count_entries(const SparseMatrix& pattern, SparseLayout::Triangle triangle) {
  if (triangle == SparseLayout::Triangle::All) return static_cast<int>(pattern.nonZeros());
  int count = 0;
  for (int c = 0; c < pattern.outerSize(); ++c)
    for (SparseMatrix::InnerIterator it(pattern, c); it; ++it)
      if (it.row() >= c) ++count;
  return count;
}

SparseLayout::Block SparseLayout::add_matrix(const SparseMatrix& pattern, int row_offset, int col_offset,
                                             Triangle triangle) {
  Entry e;
  e.pattern = &pattern;
  e.triangle = triangle;
  e.row_offset = row_offset;
  e.col_offset = col_offset;
  e.offset = nonzeros_;
  e.size = count_entries(pattern, triangle);
  nonzeros_ += e.size;
  blocks_.push_back(std::move(e));
  return {blocks_.back().offset, blocks_.back().size};
}

SparseLayout::Block SparseLayout::add_column(std::vector<int> rows, int col) {
  Entry e;
  e.cols.assign(rows.size(), col);
  e.rows = std::move(rows);
  e.offset = nonzeros_;
  e.size = static_cast<int>(e.rows.size());
  nonzeros_ += e.size;
  blocks_.push_back(std::move(e));
  return {blocks_.back().offset, blocks_.back().size};
}

SparseLayout::Block SparseLayout::add_column(const std::vector<int>& rows, int row_offset, int col) {
  std::vector<int> shifted(rows);
  for (int& r : shifted) r += row_offset;
  return add_column(std::move(shifted), col);
}

SparseLayout::Block SparseLayout::add_row(int row, std::vector<int> cols) {
  Entry e;
  e.rows.assign(cols.size(), row);
  e.cols = std::move(cols);
  e.offset = nonzeros_;
  e.size = static_cast<int>(e.cols.size());
  nonzeros_ += e.size;
  blocks_.push_back(std::move(e));
  return {blocks_.back().offset, blocks_.back().size};
}

void SparseLayout::structure(int* irow, int* jcol) const {
  for (const Entry& e : blocks_) {
    int k = e.offset;
    if (e.pattern) {
      for (int c = 0; c < e.pattern->outerSize(); ++c)
        for (SparseMatrix::InnerIterator it(*e.pattern, c); it; ++it) {
          if (e.triangle == Triangle::Lower && it.row() < c) continue;
          irow[k] = static_cast<int>(it.row()) + e.row_offset;
          jcol[k] = c + e.col_offset;
          ++k;
        }
    } else {
      for (size_t m = 0; m < e.rows.size(); ++m, ++k) {
        irow[k] = e.rows[m];
        jcol[k] = e.cols[m];
      }
    }
  }
}

}  // namespace modalcal::detail
