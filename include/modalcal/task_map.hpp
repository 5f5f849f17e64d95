#pragma once
/// \file task_map.hpp
/// How a stage runs independent pieces of work (the diagnosis's refits): in turn, in threads of
/// this process, or spread over the processes of an MPI job by the command-line tool.

#include <cstddef>
#include <functional>
#include <string>
#include <vector>

#include "modalcal/export.hpp"
#include "modalcal/types.hpp"

namespace modalcal {

/// Runs `work(i)` for every i in [0, n), each independent of the others, and returns their
/// results in index order. A result is text because it may be computed in another process; the
/// caller encodes what it needs (TaskCodec below) and decodes it from the returned strings.
/// Every process of a job calls it with the same n and the same work, and every process gets all
/// the results. An exception thrown by a piece of work is rethrown by the map on every process.
///
/// Example: squares of 0..3 in turn:
/// \code
///   const TaskMap map = run_in_turn;
///   auto squares = map(4, [](size_t i) { return std::to_string(i * i); });  // {"0","1","4","9"}
/// \endcode
using TaskMap = std::function<std::vector<std::string>(size_t n, const std::function<std::string(size_t)>& work)>;

/// The default TaskMap: each piece of work in index order, in this process.
MODALCAL_EXPORT std::vector<std::string> run_in_turn(size_t n, const std::function<std::string(size_t)>& work);

/// A TaskMap that runs up to `threads` pieces at a time, each in a thread of this process, the
/// next free thread taking the next index. The results are in index order, as run_in_turn()'s, so
/// that what a caller computes from them does not depend on the number of threads. Every piece
/// runs even when one fails; then the failure of the lowest index is rethrown. `work` must be
/// safe to call concurrently: the diagnosis's refits are (each builds its own model, objective
/// and factorizations). With threads = 1, or a single piece, the pieces run in the calling
/// thread. When the system cannot start another thread, the pieces go to the threads already
/// running. The map may be called from several threads at once (the diagnosis's walks side by
/// side); `threads` then bounds the pieces of all those calls together, the others waiting for a
/// place. So a piece must not call the same map: it could wait for a place it holds itself.
///
/// Example: \code
///   const TaskMap map = run_in_threads(4);
///   auto squares = map(8, [](size_t i) { return std::to_string(i * i); });  // {"0","1",..,"49"}
/// \endcode
/// \throws std::invalid_argument when threads < 1.
MODALCAL_EXPORT TaskMap run_in_threads(int threads);

/// Numbers written to and read from a task's result text exactly (17 significant digits, NaN and
/// infinities included), in the order they were written.
class MODALCAL_EXPORT TaskCodec {
 public:
  void put(double value);
  void put(const std::string& text);  ///< any bytes; length-prefixed
  void put(const Vector& values);     ///< its size, then its entries
  std::string str() const { return text_; }

  explicit TaskCodec(std::string text = {}) : text_(std::move(text)) {}
  /// \throws std::runtime_error when the text holds no more values or is not a TaskCodec's.
  double get_number();
  std::string get_text();
  Vector get_vector();

 private:
  std::string text_;
  size_t read_ = 0;
};

}  // namespace modalcal
