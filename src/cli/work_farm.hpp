#pragma once
// Independent calibrations spread over the processes of an MPI job (`mpirun -np N fullspace_calib
// campaign|study|diagnose ...`), or run by a process alone, in turn or in threads (set_threads).
//
// Every process runs the same command on the same input (SPMD) and reaches the same maps in the
// same order. In a map, rank 0 only hands out work: it gives the next index to whichever process
// asks (calibrations differ in length), collects each result, and at the end sends all of them,
// in index order, to every process, which then goes on as one. So the results, and the output
// rank 0 alone writes, are the same for any number of processes. Processes other than rank 0 write
// nothing to the standard output. Waiting processes poll with short sleeps instead of spinning,
// so that an MPI job may have more processes than cores. A process alone with several threads
// keeps the same contract: results in index order, progress reported in index order.

#include <algorithm>
#include <functional>
#include <string>
#include <vector>

#include "modalcal/task_map.hpp"

namespace modalcal::cli {

/// The pieces of work to run at a time asked for by a `--jobs` option: `jobs`, or one per core
/// when it is 0.
int threads_for_jobs(int jobs);

/// While it lives (and `active`), OpenBLAS runs each call in the calling thread; afterwards its
/// earlier thread count is back. Made and let go where no BLAS call runs: around a threaded map,
/// or around work that calls BLAS from threads of its own (the diagnosis's walks side by side).
class OneBlasThreadWhile {
 public:
  explicit OneBlasThreadWhile(bool active);
  ~OneBlasThreadWhile();
  OneBlasThreadWhile(const OneBlasThreadWhile&) = delete;
  OneBlasThreadWhile& operator=(const OneBlasThreadWhile&) = delete;

 private:
  void (*set_)(int) = nullptr;
  int before_ = 0;
};

class WorkFarm {
 public:
  /// The farm of this process: the MPI job's when the program was started by an MPI launcher
  /// (and built with MPI), this process alone otherwise. The first call joins the job (MPI_Init),
  /// silences the standard output of every rank but 0, and arranges MPI_Finalize at exit; with
  /// several ranks, each uses one BLAS thread unless OPENBLAS_NUM_THREADS says otherwise.
  static WorkFarm& join();

  int rank() const { return rank_; }
  int size() const { return size_; }
  bool is_root() const { return rank_ == 0; }

  /// Runs work(i) for i in [0, n) and returns every result in index order, on every rank.
  /// `on_result(i, result)`, on rank 0 only, sees each result in index order as soon as every
  /// earlier one is in (progress lines). An exception from work(i) on any rank is rethrown on every
  /// rank (std::invalid_argument stays one, any other becomes std::runtime_error).
  std::vector<std::string> map(size_t n, const std::function<std::string(size_t)>& work,
                               const std::function<void(size_t, const std::string&)>& on_result = {});

  /// map() as a TaskMap for the library (the diagnosis's refits).
  TaskMap task_map();

  /// A process alone runs up to `threads` pieces of a map at a time, each in a thread
  /// (run_in_threads), with one BLAS thread each while they run, so that the pieces, not BLAS,
  /// share the cores. The ranks of an MPI job run one piece at a time each. Default 1.
  /// The pieces of maps called at once from several threads share the `threads` (run_in_threads).
  void set_threads(int threads) {
    threads_ = threads;
    in_threads_ = run_in_threads(std::max(1, threads));
  }
  /// The pieces of a map that run at a time in this process (1 in an MPI job).
  int threads() const { return size_ > 1 ? 1 : threads_; }

 private:
  WorkFarm(int rank, int size) : rank_(rank), size_(size) {}
  std::vector<std::string> map_alone(size_t n, const std::function<std::string(size_t)>& work,
                                     const std::function<void(size_t, const std::string&)>& on_result);
  int rank_ = 0, size_ = 1, threads_ = 1;
  TaskMap in_threads_ = run_in_threads(1);
};

}  // namespace modalcal::cli
