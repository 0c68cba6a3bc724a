#include "cndt/runtime/score_threads.hpp"

#include <spdlog/spdlog.h>

#include <chrono>

namespace cndt::runtime {
namespace {

inline void cpu_relax() {
#if defined(__x86_64__) || defined(__i386__)
  __builtin_ia32_pause();
#endif
}

// How long a helper keeps looking for the next run before it sleeps: a Newton solve's scorings
// follow each other within microseconds; between a scan's stages and between scans it sleeps.
constexpr auto kHelperSpin = std::chrono::microseconds(200);

}  // namespace

ScoreThreads::ScoreThreads(std::size_t helpers, const ThreadSetup& setup) {
  threads_.reserve(helpers);
  for (std::size_t h = 0; h < helpers; ++h) {
    threads_.emplace_back([this, setup, h] {
      const auto problems = apply_thread_setup(setup);
      for (const auto& p : problems) {
        if (h == 0) spdlog::warn("scoring thread: {}; running on without it", p);  // one for all
      }
      helper_loop();
    });
  }
}

ScoreThreads::~ScoreThreads() {
  stop_.store(true, std::memory_order_relaxed);
  {
    const std::lock_guard lock(mutex_);
    generation_.fetch_add(1, std::memory_order_seq_cst);
  }
  wake_.notify_all();
  for (auto& t : threads_) t.join();
}

void ScoreThreads::work() {
  for (;;) {
    const std::size_t i = next_.fetch_add(1, std::memory_order_relaxed);
    if (i >= count_) return;
    task_(context_, i);
  }
}

void ScoreThreads::run(std::size_t count, void (*task)(void*, std::size_t), void* context) {
  if (threads_.empty()) {
    for (std::size_t i = 0; i < count; ++i) task(context, i);
    return;
  }
  count_ = count;
  task_ = task;
  context_ = context;
  next_.store(0, std::memory_order_relaxed);
  finished_.store(0, std::memory_order_relaxed);
  // A helper counts itself asleep, then checks the generation, both under the mutex; this side
  // bumps the generation, then reads the count (both sequentially consistent): either the
  // helper sees the new generation or this side sees it asleep and notifies it after it waits.
  generation_.fetch_add(1, std::memory_order_seq_cst);
  if (sleeping_.load(std::memory_order_seq_cst) > 0) {
    { const std::lock_guard lock(mutex_); }
    wake_.notify_all();
  }
  work();
  // The helpers' last tasks are short (one chunk at most each): wait for them actively, and
  // let the CPU go now and then in case a helper waits for this one (same CPU, SCHED_FIFO).
  for (unsigned spins = 1; finished_.load(std::memory_order_acquire) < threads_.size(); ++spins) {
    if (spins % 4096 == 0) {
      std::this_thread::yield();
    } else {
      cpu_relax();
    }
  }
}

void ScoreThreads::helper_loop() {
  // Every run counts: one may have started before this thread did.
  std::uint32_t seen = 0;
  for (;;) {
    std::uint32_t now = generation_.load(std::memory_order_acquire);
    if (now == seen) {
      const auto until = std::chrono::steady_clock::now() + kHelperSpin;
      while ((now = generation_.load(std::memory_order_acquire)) == seen &&
             std::chrono::steady_clock::now() < until) {
        cpu_relax();
      }
      if (now == seen) {
        std::unique_lock lock(mutex_);
        sleeping_.fetch_add(1, std::memory_order_seq_cst);
        while ((now = generation_.load(std::memory_order_seq_cst)) == seen) wake_.wait(lock);
        sleeping_.fetch_sub(1, std::memory_order_relaxed);
      }
    }
    seen = now;
    if (stop_.load(std::memory_order_relaxed)) return;
    work();
    finished_.fetch_add(1, std::memory_order_release);
  }
}

}  // namespace cndt::runtime
