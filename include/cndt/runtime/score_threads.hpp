// Helper threads for the odometry's NDT scorings: a scoring's fixed chunks (ndt::kScoreChunks)
// are shared between the odometry thread and these helpers, so a scan is matched on more than
// one core. The results are the same as on one thread (ndt::TaskRunner). Nothing is allocated
// per run; between runs a helper spins briefly, then sleeps on a condition variable.
#pragma once

#include <atomic>
#include <condition_variable>
#include <cstddef>
#include <cstdint>
#include <mutex>
#include <thread>
#include <vector>

#include "cndt/ndt/ndt_score.hpp"
#include "cndt/runtime/realtime.hpp"

namespace cndt::runtime {

class ScoreThreads final : public ndt::TaskRunner {
 public:
  /// Starts `helpers` threads (0: run() works on the calling thread alone), each set up with
  /// `setup` (problems are logged once as warnings).
  ScoreThreads(std::size_t helpers, const ThreadSetup& setup);
  ~ScoreThreads();
  ScoreThreads(const ScoreThreads&) = delete;
  ScoreThreads& operator=(const ScoreThreads&) = delete;

  /// Runs the tasks on the calling thread and the helpers; one caller at a time.
  void run(std::size_t count, void (*task)(void* context, std::size_t i), void* context) override;

 private:
  void helper_loop();
  // Claims and runs tasks of run `generation` until it has none left or another run began.
  void work(std::uint32_t generation);

  std::vector<std::thread> threads_;
  // Published with claim_ (release) and read by whoever claims a task of the run (acquire);
  // written again only when every claimed task of the run is done.
  void (*task_)(void*, std::size_t) = nullptr;
  void* context_ = nullptr;
  // The run's generation (high 32 bits), task count (next 16) and next unclaimed task (low 16):
  // a task is claimed by a compare-and-swap on the whole word, so a helper that wakes late
  // cannot take a task of a run other than the one it saw, and the caller never waits for a
  // helper that took none.
  alignas(64) std::atomic<std::uint64_t> claim_{0};
  alignas(64) std::atomic<std::size_t> done_{0};  // tasks of the current run finished
  alignas(64) std::atomic<std::uint32_t> generation_{0};
  std::atomic<bool> stop_{false};
  // Helpers asleep in wake_ (run() notifies only when there are some).
  std::atomic<std::size_t> sleeping_{0};
  std::mutex mutex_;
  std::condition_variable wake_;
};

}  // namespace cndt::runtime
