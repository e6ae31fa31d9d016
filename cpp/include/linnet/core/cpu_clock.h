// CPU-time clocks (POSIX) and the process's resident memory. Unlike wall time, the CPU clocks do not count time
// slices given to other threads or processes, so per-stage costs stay meaningful on a loaded machine or when several
// threads share one core.
#pragma once

#include <cstdio>
#include <ctime>

#include <unistd.h>

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

/// The process's resident set size now, MB (10^6 bytes), from /proc/self/statm; 0 where that is not available.
inline double residentSetMb() {
  std::FILE* f = std::fopen("/proc/self/statm", "r");
  if (f == nullptr) return 0.0;
  long pages_total = 0, pages_resident = 0;
  const bool ok = std::fscanf(f, "%ld %ld", &pages_total, &pages_resident) == 2;
  std::fclose(f);
  return ok ? static_cast<double>(pages_resident) * static_cast<double>(sysconf(_SC_PAGESIZE)) * 1e-6 : 0.0;
}

}  // namespace linnet
