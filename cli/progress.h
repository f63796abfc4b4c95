// cli/progress.h — bvh.out's progress line (cli/progress.cpp).
// Progress on a terminal: one line on stderr, rewritten in place, from a
// ticker thread (construct() and write_svg() are single calls), shown once
// the run has lasted kProgressDelay and only when stderr is a terminal, so
// redirected output never holds it. stdout is never touched; pause() clears
// the line before the program prints there or reports an error.
// BVH_PROGRESS_DELAY (seconds, in the environment) replaces the one-second
// delay (docs/cli.txt).
#ifndef BVH_CLI_PROGRESS_H
#define BVH_CLI_PROGRESS_H

#include <atomic>
#include <chrono>
#include <condition_variable>
#include <cstdint>
#include <mutex>
#include <string>
#include <thread>

namespace bvh_cli {

class Progress {
public:
  Progress();
  ~Progress();
  Progress(const Progress &) = delete;
  Progress &operator=(const Progress &) = delete;

  /// A new stage ("reading x.disks"); `total` > 0 shows "done of total" with `unit`.
  void stage(const std::string &what, std::uint64_t total = 0, const char *unit = "");
  /// How far the stage is (cheap: the ticker reads it).
  void advance(std::uint64_t done) {
    if (enabled_) done_.store(done, std::memory_order_relaxed);
  }
  /// A second count shown after the first, as ", N tries" (--generate).
  void detail(long tries) {
    if (enabled_) tries_.store(tries, std::memory_order_relaxed);
  }
  /// Clears the line until the next stage().
  void pause();

private:
  using Clock = std::chrono::steady_clock;

  void tick();
  // Under mutex_.
  void show();
  void clear();

  const Clock::time_point start_;
  std::chrono::duration<double> delay_{1.0};
  const bool enabled_;
  std::mutex mutex_;
  std::condition_variable wake_;
  std::thread ticker_;
  std::string what_;
  std::uint64_t total_ = 0;
  const char *unit_ = "";
  std::atomic<std::uint64_t> done_{0};
  std::atomic<long> tries_{-1};
  bool paused_ = false, shown_ = false, stopping_ = false;
};

} // namespace bvh_cli

#endif
