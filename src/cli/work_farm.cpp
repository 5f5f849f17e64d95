// WorkFarm (work_farm.hpp): independent work over the ranks of an MPI job, or in turn alone.

#include "cli/work_farm.hpp"

#include <dlfcn.h>

#include <algorithm>
#include <chrono>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <mutex>
#include <stdexcept>
#include <thread>

#ifdef MODALCAL_HAVE_MPI
#include <mpi.h>
#endif

namespace modalcal::cli {

namespace {

/// A result as it travels: how the work ended, then its text.
enum class Outcome : char { Result = 'R', InputError = 'I', Failure = 'E' };

struct Piece {
  Outcome outcome = Outcome::Result;
  std::string text;  // the result, or the exception's message
};

Piece run_one(const std::function<std::string(size_t)>& work, size_t i) {
  try {
    return {Outcome::Result, work(i)};
  } catch (const std::invalid_argument& e) {
    return {Outcome::InputError, e.what()};
  } catch (const std::exception& e) {
    return {Outcome::Failure, e.what()};
  }
}

/// The results of a map, or the first failure among them rethrown.
std::vector<std::string> results_of(std::vector<Piece>&& pieces) {
  std::vector<std::string> results;
  results.reserve(pieces.size());
  for (Piece& p : pieces) {
    if (p.outcome == Outcome::InputError) throw std::invalid_argument(p.text);
    if (p.outcome == Outcome::Failure) throw std::runtime_error(p.text);
    results.push_back(std::move(p.text));
  }
  return results;
}

/// OpenBLAS's thread-count setter, or null when the BLAS loaded is another one.
using SetBlasThreads = void (*)(int);
SetBlasThreads blas_thread_setter() {
  return reinterpret_cast<SetBlasThreads>(dlsym(RTLD_DEFAULT, "openblas_set_num_threads"));
}

/// One BLAS thread per rank: ranks share the cores. OPENBLAS_NUM_THREADS, read when OpenBLAS
/// loaded, wins when set; children (the study's calibrations) inherit the variable.
void one_blas_thread() {
  if (std::getenv("OPENBLAS_NUM_THREADS")) return;
  setenv("OPENBLAS_NUM_THREADS", "1", 0);
  if (const SetBlasThreads set = blas_thread_setter()) set(1);
}

#ifdef MODALCAL_HAVE_MPI

/// True when an MPI launcher (Open MPI's, or a PMI/PMIx one such as MPICH's or Slurm's) started
/// this process.
bool launched_by_mpi() {
  for (const char* name : {"OMPI_COMM_WORLD_SIZE", "PMIX_RANK", "PMI_RANK", "PMI_SIZE"})
    if (std::getenv(name)) return true;
  return false;
}

enum Tag : int { Ask = 1, Give = 2, All = 3 };

/// A message's bytes: integers and texts appended, read back in order.
struct Bytes {
  std::string data;
  size_t read = 0;
  void put_int(std::int64_t v) { data.append(reinterpret_cast<const char*>(&v), sizeof v); }
  void put_piece(const Piece& p) {
    data.push_back(static_cast<char>(p.outcome));
    put_int(static_cast<std::int64_t>(p.text.size()));
    data += p.text;
  }
  std::int64_t get_int() {
    std::int64_t v = 0;
    if (read + sizeof v > data.size()) throw std::runtime_error("MPI: a message between ranks is cut short");
    std::memcpy(&v, data.data() + read, sizeof v);
    read += sizeof v;
    return v;
  }
  Piece get_piece() {
    if (read >= data.size()) throw std::runtime_error("MPI: a message between ranks is cut short");
    Piece p;
    p.outcome = static_cast<Outcome>(data[read++]);
    const std::int64_t length = get_int();
    if (length < 0 || static_cast<size_t>(length) > data.size() - read)
      throw std::runtime_error("MPI: a message between ranks is cut short");
    p.text = data.substr(read, static_cast<size_t>(length));
    read += static_cast<size_t>(length);
    return p;
  }
};

void send(const Bytes& b, int to, int tag) {
  MPI_Send(b.data.data(), static_cast<int>(b.data.size()), MPI_CHAR, to, tag, MPI_COMM_WORLD);
}

/// The next message with `tag` from `from` (MPI_ANY_SOURCE: anyone), waiting in short sleeps
/// rather than in MPI's busy poll, which would take a core from the ranks at work; *source is
/// who sent it.
Bytes receive(int from, int tag, int* source = nullptr) {
  MPI_Status status;
  int arrived = 0;
  std::chrono::microseconds pause(100);
  for (;;) {
    MPI_Iprobe(from, tag, MPI_COMM_WORLD, &arrived, &status);
    if (arrived) break;
    std::this_thread::sleep_for(pause);
    pause = std::min(pause * 2, std::chrono::microseconds(20000));
  }
  int count = 0;
  MPI_Get_count(&status, MPI_CHAR, &count);
  Bytes b;
  b.data.resize(static_cast<size_t>(count));
  MPI_Recv(b.data.data(), count, MPI_CHAR, status.MPI_SOURCE, tag, MPI_COMM_WORLD, MPI_STATUS_IGNORE);
  if (source) *source = status.MPI_SOURCE;
  return b;
}

void abort_job(const std::string& why) {
  std::fprintf(stderr, "error: %s\n", why.c_str());
  MPI_Abort(MPI_COMM_WORLD, 1);
}

/// Rank 0: hands out indices to whoever asks and collects the results, reporting them in order.
std::vector<Piece> hand_out(size_t n, int size, const std::function<void(size_t, const std::string&)>& on_result) {
  std::vector<Piece> pieces(n);
  std::vector<bool> done(n, false);
  size_t next = 0, reported = 0;
  int stopped = 0;
  while (stopped < size - 1) {
    int worker = 0;
    Bytes ask = receive(MPI_ANY_SOURCE, Ask, &worker);
    if (ask.get_int() != static_cast<std::int64_t>(n))
      abort_job("the MPI ranks disagree on the work to share (different inputs, or nodes that compute differently)");
    const std::int64_t finished = ask.get_int();
    if (finished >= 0) {
      pieces[static_cast<size_t>(finished)] = ask.get_piece();
      done[static_cast<size_t>(finished)] = true;
    }
    for (; reported < n && done[reported]; ++reported)
      if (on_result && pieces[reported].outcome == Outcome::Result) {
        try {
          on_result(reported, pieces[reported].text);
        } catch (const std::exception& e) {
          abort_job(e.what());
        }
      }
    const std::int64_t assigned = next < n ? static_cast<std::int64_t>(next++) : -1;
    Bytes give;
    give.put_int(assigned);
    send(give, worker, Give);
    if (assigned < 0) ++stopped;
  }
  Bytes all;
  for (const Piece& p : pieces) all.put_piece(p);
  for (int r = 1; r < size; ++r) send(all, r, All);
  return pieces;
}

/// A rank other than 0: asks for work until there is none, then receives every result.
std::vector<Piece> work_on(size_t n, const std::function<std::string(size_t)>& work) {
  std::int64_t finished = -1;
  Piece piece;
  for (;;) {
    Bytes ask;
    ask.put_int(static_cast<std::int64_t>(n));
    ask.put_int(finished);
    if (finished >= 0) ask.put_piece(piece);
    send(ask, 0, Ask);
    Bytes give = receive(0, Give);
    finished = give.get_int();
    if (finished < 0) break;
    piece = run_one(work, static_cast<size_t>(finished));
  }
  Bytes all = receive(0, All);
  std::vector<Piece> pieces(n);
  for (Piece& p : pieces) p = all.get_piece();
  return pieces;
}

void finalize_mpi() {
  int finalized = 0;
  MPI_Finalized(&finalized);
  if (!finalized) MPI_Finalize();
}

#endif  // MODALCAL_HAVE_MPI

}  // namespace

OneBlasThreadWhile::OneBlasThreadWhile(bool active) : set_(blas_thread_setter()) {
  using GetThreads = int (*)();
  const auto get = reinterpret_cast<GetThreads>(dlsym(RTLD_DEFAULT, "openblas_get_num_threads"));
  if (!active || !get || !set_) return;
  before_ = get();
  if (before_ > 1) set_(1);
}

OneBlasThreadWhile::~OneBlasThreadWhile() {
  if (before_ > 1) set_(before_);
}

int threads_for_jobs(int jobs) {
  return jobs > 0 ? jobs : std::max(1, static_cast<int>(std::thread::hardware_concurrency()));
}

WorkFarm& WorkFarm::join() {
  static WorkFarm farm = [] {
    int rank = 0, size = 1;
#ifdef MODALCAL_HAVE_MPI
    if (launched_by_mpi()) {
      if (MPI_Init(nullptr, nullptr) != MPI_SUCCESS) throw std::runtime_error("MPI_Init failed");
      std::atexit(finalize_mpi);
      MPI_Comm_rank(MPI_COMM_WORLD, &rank);
      MPI_Comm_size(MPI_COMM_WORLD, &size);
    }
#endif
    if (size > 1) one_blas_thread();
    if (rank != 0 && !std::freopen("/dev/null", "w", stdout))
      throw std::runtime_error("rank " + std::to_string(rank) + " could not silence its standard output");
    return WorkFarm(rank, size);
  }();
  return farm;
}

std::vector<std::string> WorkFarm::map_alone(size_t n, const std::function<std::string(size_t)>& work,
                                             const std::function<void(size_t, const std::string&)>& on_result) {
  std::vector<Piece> pieces(n);
  std::vector<bool> done(n, false);
  std::mutex reporting;
  size_t reported = 0;
  // Each piece's result in its place; on_result sees them in index order, as soon as every
  // earlier one is in, from whichever thread completes that run.
  auto run_and_report = [&](size_t i) {
    Piece piece = run_one(work, i);
    const std::lock_guard<std::mutex> lock(reporting);
    pieces[i] = std::move(piece);
    done[i] = true;
    for (; reported < n && done[reported]; ++reported)
      if (on_result && pieces[reported].outcome == Outcome::Result) on_result(reported, pieces[reported].text);
    return std::string();
  };
  const OneBlasThreadWhile one(threads_ > 1 && n > 1);
  in_threads_(n, run_and_report);
  return results_of(std::move(pieces));
}

std::vector<std::string> WorkFarm::map(size_t n, const std::function<std::string(size_t)>& work,
                                       const std::function<void(size_t, const std::string&)>& on_result) {
  if (size_ == 1 || n == 0) return map_alone(n, work, on_result);
#ifdef MODALCAL_HAVE_MPI
  std::fflush(stdout);
  return results_of(is_root() ? hand_out(n, size_, on_result) : work_on(n, work));
#else
  return map_alone(n, work, on_result);
#endif
}

TaskMap WorkFarm::task_map() {
  return [this](size_t n, const std::function<std::string(size_t)>& work) { return map(n, work); };
}

}  // namespace modalcal::cli
