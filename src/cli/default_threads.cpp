#include "cli/default_threads.h"

#include <sched.h>

#include <algorithm>
#include <cstdlib>
#include <thread>

namespace millkit::cli {

int DefaultThreads() {
  int cores = 0;
  cpu_set_t mask;
  CPU_ZERO(&mask);
  if (::sched_getaffinity(0, sizeof(mask), &mask) == 0) cores = CPU_COUNT(&mask);
  if (cores < 1) cores = static_cast<int>(std::thread::hardware_concurrency());
  int ranks_here = 1;
  for (const char* name : {"OMPI_COMM_WORLD_LOCAL_SIZE", "MPI_LOCALNRANKS"}) {
    if (const char* value = std::getenv(name)) {
      ranks_here = std::max(1, std::atoi(value));
      break;
    }
  }
  return std::clamp(cores / ranks_here, 1, 256);
}

}  // namespace millkit::cli
