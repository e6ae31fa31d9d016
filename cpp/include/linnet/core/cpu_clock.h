// CPU-time clocks (POSIX). Unlike wall time, they do not count time slices given to other threads or processes, so
// per-stage costs stay meaningful on a loaded machine or when several threads share one core.
#pragma once

#include <ctime>

namespace linnet {

/// CPU time consumed by the calling thread, milliseconds.
inline double threadCpuMs() {
  timespec ts{};
  clock_gettime(CLOCK_THREAD_CPUTIME_ID, &ts);
  return static_cast<double>(ts.tv_sec) * 1e3 + static_cast<double>(ts.tv_nsec) * 1e-6;
}

/// CPU time consumed by the whole process (every thread), seconds.
inline double processCpuSeconds() {
  timespec ts{};
  clock_gettime(CLOCK_PROCESS_CPUTIME_ID, &ts);
  return static_cast<double>(ts.tv_sec) + static_cast<double>(ts.tv_nsec) * 1e-9;
}

}  // namespace linnet
