// The in-process TaskMap and the exact text encoding of task results (task_map.hpp).

#include "modalcal/task_map.hpp"

#include <algorithm>
#include <atomic>
#include <condition_variable>
#include <cstdio>
#include <cstdlib>
#include <exception>
#include <memory>
#include <mutex>
#include <stdexcept>
#include <system_error>
#include <thread>

namespace modalcal {

std::vector<std::string> run_in_turn(size_t n, const std::function<std::string(size_t)>& work) {
  std::vector<std::string> results;
  results.reserve(n);
  for (size_t i = 0; i < n; ++i) results.push_back(work(i));
  return results;
}

namespace {

/// The pieces one run_in_threads() map may run at a time, shared by every call of it: calls made
/// at once from several threads (walks side by side) take turns within it.
class PieceBudget {
 public:
  explicit PieceBudget(int pieces) : free_(pieces) {}
  /// Runs work(i) once a place is free, and frees it again.
  std::string run(const std::function<std::string(size_t)>& work, size_t i) {
    {
      std::unique_lock<std::mutex> lock(mutex_);
      freed_.wait(lock, [&] { return free_ > 0; });
      --free_;
    }
    struct Release {
      PieceBudget* budget;
      ~Release() {
        {
          const std::lock_guard<std::mutex> lock(budget->mutex_);
          ++budget->free_;
        }
        budget->freed_.notify_one();
      }
    } release{this};
    return work(i);
  }

 private:
  std::mutex mutex_;
  std::condition_variable freed_;
  int free_;
};

}  // namespace

TaskMap run_in_threads(int threads) {
  if (threads < 1) throw std::invalid_argument("run_in_threads: threads = " + std::to_string(threads) + ": must be >= 1");
  auto budget = std::make_shared<PieceBudget>(threads);
  return [threads, budget](size_t n, const std::function<std::string(size_t)>& work) {
    const auto in_budget = [&](size_t i) { return budget->run(work, i); };
    const size_t workers = std::min(static_cast<size_t>(threads), n);
    if (workers <= 1) return run_in_turn(n, in_budget);
    std::vector<std::string> results(n);
    std::vector<std::exception_ptr> failures(n);
    std::atomic<size_t> next{0};
    auto take_work = [&] {
      for (size_t i = next++; i < n; i = next++) {
        try {
          results[i] = in_budget(i);
        } catch (...) {
          failures[i] = std::current_exception();
        }
      }
    };
    std::vector<std::thread> helpers;
    helpers.reserve(workers - 1);
    try {
      while (helpers.size() + 1 < workers) helpers.emplace_back(take_work);
    } catch (const std::system_error&) {  // no more threads: those running share the work
    }
    take_work();
    for (std::thread& t : helpers) t.join();
    for (const std::exception_ptr& failure : failures)
      if (failure) std::rethrow_exception(failure);
    return results;
  };
}

// Each value is a line: "n <%.17g>" for a number (strtod reads nan and inf back), "t <length>"
// then the bytes for a text, so that any text survives.
void TaskCodec::put(double value) {
  char line[48];
  std::snprintf(line, sizeof line, "n %.17g\n", value);
  text_ += line;
}

void TaskCodec::put(const std::string& text) {
  text_ += "t " + std::to_string(text.size()) + "\n" + text;
}

void TaskCodec::put(const Vector& values) {
  put(static_cast<double>(values.size()));
  for (double v : values) put(v);
}

Vector TaskCodec::get_vector() {
  const double size = get_number();
  if (!(size >= 0 && size < 1e9)) throw std::runtime_error("a task's result holds no vector where one was expected");
  Vector values(static_cast<Eigen::Index>(size));
  for (double& v : values) v = get_number();
  return values;
}

double TaskCodec::get_number() {
  const size_t end = text_.find('\n', read_);
  if (text_.compare(read_, 2, "n ") != 0 || end == std::string::npos)
    throw std::runtime_error("a task's result holds no number where one was expected");
  const double value = std::strtod(text_.c_str() + read_ + 2, nullptr);
  read_ = end + 1;
  return value;
}

std::string TaskCodec::get_text() {
  const size_t end = text_.find('\n', read_);
  if (text_.compare(read_, 2, "t ") != 0 || end == std::string::npos)
    throw std::runtime_error("a task's result holds no text where one was expected");
  const size_t length = std::strtoull(text_.c_str() + read_ + 2, nullptr, 10);
  if (length > text_.size() - end - 1) throw std::runtime_error("a task's result is cut short");
  std::string text = text_.substr(end + 1, length);
  read_ = end + 1 + length;
  return text;
}

}  // namespace modalcal
