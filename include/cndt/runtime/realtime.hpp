// Optional real-time setup: locked memory, SCHED_FIFO, CPU affinity and nice values. Without the
// privilege each step fails with a message (logged once as a warning by the caller); the
// daemon then runs on without it.
#pragma once

#include <optional>
#include <string>
#include <vector>

namespace cndt::runtime {

struct ThreadSetup {
  int fifo_priority = 0;  ///< SCHED_FIFO priority 1..99; 0 leaves the policy alone
  int cpu = -1;           ///< pin to this CPU; -1 any
  int nice = 0;           ///< nice value of this thread (0 leaves it)
};

/// Applies `setup` to the calling thread; returns one message per step that failed.
std::vector<std::string> apply_thread_setup(const ThreadSetup& setup);

/// mlockall(MCL_CURRENT | MCL_FUTURE); a message when it failed.
std::optional<std::string> lock_memory();

}  // namespace cndt::runtime
