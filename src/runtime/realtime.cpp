#include "cndt/runtime/realtime.hpp"

#include <fmt/format.h>
#include <pthread.h>
#include <sched.h>
#include <sys/mman.h>
#include <sys/resource.h>
#include <sys/syscall.h>
#include <unistd.h>

#include <cerrno>
#include <cstring>

namespace cndt::runtime {

std::vector<std::string> apply_thread_setup(const ThreadSetup& s) {
  std::vector<std::string> problems;
  if (s.cpu >= 0) {
    cpu_set_t set;
    CPU_ZERO(&set);
    CPU_SET(static_cast<unsigned>(s.cpu), &set);
    if (const int e = pthread_setaffinity_np(pthread_self(), sizeof set, &set); e != 0) {
      problems.push_back(
          fmt::format("cannot pin the thread to CPU {}: {}", s.cpu, std::strerror(e)));
    }
  }
  if (s.fifo_priority > 0) {
    sched_param p{};
    p.sched_priority = s.fifo_priority;
    if (const int e = pthread_setschedparam(pthread_self(), SCHED_FIFO, &p); e != 0) {
      problems.push_back(
          fmt::format("cannot run the thread SCHED_FIFO at priority {}: {} (needs CAP_SYS_NICE, "
                      "LimitRTPRIO= or CPUSchedulingPolicy= in the unit)",
                      s.fifo_priority, std::strerror(e)));
    }
  }
  if (s.nice != 0) {
    // On Linux the nice value is per thread (setpriority on the thread id).
    const auto tid = static_cast<id_t>(::syscall(SYS_gettid));
    if (::setpriority(PRIO_PROCESS, tid, s.nice) != 0) {
      problems.push_back(fmt::format("cannot set the thread's nice value to {}: {}", s.nice,
                                     std::strerror(errno)));
    }
  }
  return problems;
}

std::optional<std::string> lock_memory() {
  if (::mlockall(MCL_CURRENT | MCL_FUTURE) == 0) return std::nullopt;
  const int e = errno;
  rlimit rl{};
  ::getrlimit(RLIMIT_MEMLOCK, &rl);
  return fmt::format(
      "cannot lock memory (mlockall): {} (RLIMIT_MEMLOCK {} bytes; set "
      "LimitMEMLOCK=infinity in the unit)",
      std::strerror(e), rl.rlim_cur);
}

}  // namespace cndt::runtime
