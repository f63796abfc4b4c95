// bvh/parallel.h — the threads: parallel_for, Crew, threads_for.
//
// parallel_for (one loop on several threads, the first exception
// rethrown), Crew (threads kept across the loops of one call), and the
// thread count a call may use (threads_for, kMaxThreads). The only room
// that starts threads. Includes config.h only.
#ifndef BVH_PARALLEL_H
#define BVH_PARALLEL_H

#include <algorithm>
#include <atomic>
#include <condition_variable>
#include <cstddef>
#include <exception>
#include <mutex>
#include <thread>
#include <utility>
#include <vector>

#include "config.h"

namespace bvh {
namespace detail {

/// Scenes smaller than this are built without threads, and ranges smaller
/// than this are not split between threads.
constexpr std::size_t kParallelMin = std::size_t(1) << 16;

/// Calls f(0) ... f(count - 1), spread over `threads` threads (the caller
/// is one of them). If a thread cannot be started (no thread left, or no
/// memory for it), the others do its share; the first exception thrown by
/// f is rethrown once all have finished.
template <class F> void parallel_for(std::size_t count, unsigned threads, F &&f) {
  std::atomic<std::size_t> next{0};
  std::exception_ptr error;
  std::mutex error_lock;
  auto work = [&] {
    for (std::size_t i; (i = next++) < count;) {
      try {
        f(i);
      } catch (...) {
        std::lock_guard<std::mutex> hold(error_lock);
        if (!error) error = std::current_exception();
      }
    }
  };
  // The pool's room first, so that starting a thread is the only step
  // that can fail once one runs: whatever it throws (system_error,
  // bad_alloc), no thread is left running past an exception, and the
  // threads started and the caller do the work.
  std::vector<std::thread> pool;
  try {
    pool.reserve(std::min<std::size_t>(threads, count));
    for (unsigned k = 1; k < threads && k < count; ++k) pool.emplace_back(work);
  } catch (...) {
  }
  work();
  for (std::thread &t : pool) t.join();
  if (error) std::rethrow_exception(error);
}

/// The most threads any call starts. A larger request gets this many: the
/// batch sizes scale with the thread count (64 * threads and more), which
/// past this would overflow or reserve more threads than a system has.
constexpr unsigned kMaxThreads = 1024;

/// The threads a build may use: `wanted`, or with 0 the hardware's, at
/// most kMaxThreads.
inline unsigned threads_for(unsigned wanted) {
  if (wanted != 0) return std::min(wanted, kMaxThreads);
  const unsigned hw = std::thread::hardware_concurrency();
  return hw == 0 ? 1 : std::min(hw, kMaxThreads);
}

/// Threads kept for a run of parallel loops: one driver calls run() for
/// each loop, the others sit in help() between loops. run(chunks, job) calls
/// job(0) ... job(chunks - 1) on the driver and on whichever helpers are
/// awake, returns once every call has returned, and then rethrows the first
/// exception of any (the remaining chunks are skipped after one). A helper
/// woken late finds the loop closed and waits for the next; finish() sends
/// every helper home. All shared state is under the mutex but the chunk
/// counter; a helper's writes reach the driver through the mutex (busy_).
class Crew {
public:
  template <class F> void run(std::size_t chunks, F &job) {
    {
      std::lock_guard<std::mutex> hold(lock_);
      call_ = [](void *f, std::size_t i) { (*static_cast<F *>(f))(i); };
      job_ = &job;
      chunks_ = chunks;
      next_ = 0;
      failed_ = false;
      error_ = nullptr;
      open_ = true;
      ++generation_;
    }
    wake_.notify_all();
    work();
    std::exception_ptr error;
    {
      std::unique_lock<std::mutex> hold(lock_);
      open_ = false;
      idle_.wait(hold, [&] { return busy_ == 0; });
      std::swap(error, error_);
    }
    if (error) std::rethrow_exception(error);
  }
  void help() {
    std::unique_lock<std::mutex> hold(lock_);
    for (std::size_t seen = 0;;) {
      wake_.wait(hold, [&] { return done_ || (open_ && generation_ != seen); });
      if (done_) return;
      seen = generation_;
      ++busy_;
      hold.unlock();
      work();
      hold.lock();
      if (--busy_ == 0) idle_.notify_all();
    }
  }
  void finish() {
    {
      std::lock_guard<std::mutex> hold(lock_);
      done_ = true;
    }
    wake_.notify_all();
  }

private:
  void work() {
    for (std::size_t i; !failed_.load(std::memory_order_relaxed) && (i = next_++) < chunks_;) {
      try {
        call_(job_, i);
      } catch (...) {
        std::lock_guard<std::mutex> hold(lock_);
        if (!error_) error_ = std::current_exception();
        failed_ = true;
      }
    }
  }
  std::mutex lock_;
  std::condition_variable wake_, idle_;
  void (*call_)(void *, std::size_t) = nullptr;
  void *job_ = nullptr;
  std::size_t chunks_ = 0, generation_ = 0, busy_ = 0;
  std::atomic<std::size_t> next_{0};
  std::atomic<bool> failed_{false};
  std::exception_ptr error_;
  bool open_ = false, done_ = false;
};
} // namespace detail
} // namespace bvh

#endif // BVH_PARALLEL_H
