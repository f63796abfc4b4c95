// cli/progress.cpp — bvh.out's progress line (cli/progress.h).
#include "progress.h"

#include <unistd.h>

#include <algorithm>
#include <cstdio>
#include <cstdlib>

namespace bvh_cli {

Progress::Progress() : start_(Clock::now()), enabled_(isatty(STDERR_FILENO) == 1) {
  // BVH_PROGRESS_DELAY (seconds) replaces the 1 s delay: tests set 0.
  if (const char *d = std::getenv("BVH_PROGRESS_DELAY")) delay_ = std::chrono::duration<double>(std::atof(d));
  if (enabled_) ticker_ = std::thread([this] { tick(); });
}

Progress::~Progress() {
  if (!enabled_) return;
  {
    std::lock_guard<std::mutex> lock(mutex_);
    stopping_ = true;
    clear();
  }
  wake_.notify_all();
  ticker_.join();
}

void Progress::stage(const std::string &what, std::uint64_t total, const char *unit) {
  if (!enabled_) return;
  std::lock_guard<std::mutex> lock(mutex_);
  what_ = what;
  total_ = total;
  unit_ = unit;
  done_.store(0, std::memory_order_relaxed);
  tries_.store(-1, std::memory_order_relaxed);
  paused_ = false;
  show();
}

void Progress::pause() {
  if (!enabled_) return;
  std::lock_guard<std::mutex> lock(mutex_);
  paused_ = true;
  clear();
}

void Progress::tick() {
  std::unique_lock<std::mutex> lock(mutex_);
  while (!stopping_) {
    wake_.wait_for(lock, std::chrono::milliseconds(200));
    if (!stopping_) show();
  }
}

void Progress::show() {
  const std::chrono::duration<double> elapsed = Clock::now() - start_;
  if (paused_ || what_.empty() || elapsed < delay_) return;
  char buf[160];
  std::string line = "bvh.out: " + what_;
  if (total_ > 0) {
    const std::uint64_t done = std::min(done_.load(std::memory_order_relaxed), total_);
    const bool mb = unit_ == std::string("MB");
    std::snprintf(buf, sizeof buf, mb ? ": %.1f of %.1f %s (%.0f%%)" : ": %.0f of %.0f %s (%.0f%%)",
                  double(done) * (mb ? 1e-6 : 1.0), double(total_) * (mb ? 1e-6 : 1.0), unit_,
                  100.0 * double(done) / double(total_));
    line += buf;
    const long tries = tries_.load(std::memory_order_relaxed);
    if (tries >= 0) {
      std::snprintf(buf, sizeof buf, tries >= 1000000 ? ", %.1fM tries" : ", %.0f tries",
                    tries >= 1000000 ? double(tries) * 1e-6 : double(tries));
      line += buf;
    }
  } else {
    line += "...";
  }
  std::snprintf(buf, sizeof buf, "  %.1f s", elapsed.count());
  line += buf;
  line = "\r\033[K" + line;
  std::fputs(line.c_str(), stderr);
  std::fflush(stderr);
  shown_ = true;
}

void Progress::clear() {
  if (!shown_) return;
  std::fputs("\r\033[K", stderr);
  std::fflush(stderr);
  shown_ = false;
}

} // namespace bvh_cli
