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

void ScoreThreads::work(std::uint32_t generation) {
  std::uint64_t word = claim_.load(std::memory_order_acquire);
  for (;;) {
    const auto next = static_cast<std::size_t>(word & 0xFFFF);
    const auto count = static_cast<std::size_t>((word >> 16) & 0xFFFF);
    if (static_cast<std::uint32_t>(word >> 32) != generation || next >= count) return;
    if (!claim_.compare_exchange_weak(word, word + 1, std::memory_order_acq_rel,
                                      std::memory_order_acquire)) {
      continue;  // another thread took a task (or a new run began): `word` holds the new value
    }
    // The task is this thread's: the run cannot end, nor task_ and context_ change, before it
    // is done.
    task_(context_, next);
    done_.fetch_add(1, std::memory_order_acq_rel);
    word = claim_.load(std::memory_order_acquire);
  }
}

void ScoreThreads::run(std::size_t count, void (*task)(void*, std::size_t), void* context) {
  if (threads_.empty() || count > 0xFFFF) {
    for (std::size_t i = 0; i < count; ++i) task(context, i);
    return;
  }
  // Every task of the run before is done (run() waited for them), so no thread reads these.
  task_ = task;
  context_ = context;
  done_.store(0, std::memory_order_relaxed);
  const std::uint32_t generation = generation_.load(std::memory_order_relaxed) + 1;
  claim_.store((static_cast<std::uint64_t>(generation) << 32) | (count << 16),
               std::memory_order_release);
  // A helper counts itself asleep, then checks the generation, both under the mutex; this side
  // bumps the generation, then reads the count (both sequentially consistent): either the
  // helper sees the new generation or this side sees it asleep and notifies it after it waits.
  generation_.store(generation, std::memory_order_seq_cst);
  if (sleeping_.load(std::memory_order_seq_cst) > 0) {
    { const std::lock_guard lock(mutex_); }
    wake_.notify_all();
  }
  work(generation);
  // Only tasks a helper took are left: each is short (one chunk). A helper that has not woken
  // yet took none and is not waited for. Wait actively, but let the CPU go every few polls: the
  // scheduler may have woken the helper on this thread's CPU, where it cannot finish its task
  // while this thread spins.
  for (unsigned spins = 1; done_.load(std::memory_order_acquire) < count; ++spins) {
    if (spins % 16 == 0) {
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
      // Yielding as it polls: on the caller's CPU it would otherwise hold up the caller.
      while ((now = generation_.load(std::memory_order_acquire)) == seen &&
             std::chrono::steady_clock::now() < until) {
        cpu_relax();
        std::this_thread::yield();
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
    work(now);
  }
}

}  // namespace cndt::runtime
