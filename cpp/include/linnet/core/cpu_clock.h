// CPU-time clocks (POSIX) and the process's resident memory. Unlike wall time, the CPU clocks do not count time
// slices given to other threads or processes, so per-stage costs stay meaningful on a loaded machine or when several
// threads share one core.
#pragma once

#include <cstdlib>
#include <ctime>

#include <fcntl.h>
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
/// Read with one read(2) into a stack buffer: it runs for every frame, and stdio's fopen allocates a buffer each time.
inline double residentSetMb() {
  const int fd = ::open("/proc/self/statm", O_RDONLY | O_CLOEXEC);
  if (fd < 0) return 0.0;
  char text[128];
  const ssize_t n = ::read(fd, text, sizeof(text) - 1);
  ::close(fd);
  if (n <= 0) return 0.0;
  text[n] = '\0';
  // "size resident shared ...", in pages.
  char* end = nullptr;
  std::strtol(text, &end, 10);
  if (end == text) return 0.0;
  const char* resident = end;
  const long pages_resident = std::strtol(resident, &end, 10);
  if (end == resident || pages_resident < 0) return 0.0;
  return static_cast<double>(pages_resident) * static_cast<double>(sysconf(_SC_PAGESIZE)) * 1e-6;
}

}  // namespace linnet
