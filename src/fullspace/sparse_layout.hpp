#pragma once
// Internal: the one indexing helper of the full-space derivatives. Every block of the
// constraint Jacobian or the Lagrangian Hessian is registered once; the layout produces the
// (row, column) structure Ipopt asks for, and the block's offset is where its values go, in the
// same order. Structure and values therefore cannot drift apart.

#include <vector>

#include "modalcal/types.hpp"

namespace modalcal::detail {

class SparseLayout {
 public:
  /// A registered block: its values occupy [offset, offset + size) of the value array.
  struct Block {
    int offset = 0;
    int size = 0;
  };
  enum class Triangle { All, Lower };

  /// The entries of `pattern` (column-major storage order), shifted by the offsets; with
  /// Triangle::Lower only those with row >= column. `pattern` must outlive the layout.
  Block add_matrix(const SparseMatrix& pattern, int row_offset, int col_offset, Triangle triangle);
  /// Entries (rows[k], col) for k = 0..rows.size()-1.
  Block add_column(std::vector<int> rows, int col);
  /// Entries (row, cols[k]).
  Block add_row(int row, std::vector<int> cols);
  /// Entries (rows[k] + row_offset, col) - a column whose rows are a shifted list.
  Block add_column(const std::vector<int>& rows, int row_offset, int col);

  int nonzeros() const { return nonzeros_; }
  /// Writes the structure: irow/jcol of length nonzeros().
  void structure(int* irow, int* jcol) const;

 private:
  struct Entry {
    const SparseMatrix* pattern = nullptr;  // matrix block, or explicit lists below
    Triangle triangle = Triangle::All;
    int row_offset = 0, col_offset = 0;
    std::vector<int> rows, cols;
    int offset = 0, size = 0;
  };
  std::vector<Entry> blocks_;
  int nonzeros_ = 0;
};

/// Number of stored entries of a matrix block with the given triangle.
int count_entries(const SparseMatrix& pattern, SparseLayout::Triangle triangle);

}  // namespace modalcal::detail
