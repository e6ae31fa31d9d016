#include "linnet/core/cpu_clock.h"

#include <cstring>
#include <fstream>
#include <memory>
#include <string>

#include <gtest/gtest.h>

namespace linnet {
namespace {

// VmRSS from /proc/self/status (kB), an independent reading of the same figure.
double statusRssMb() {
  std::ifstream in("/proc/self/status");
  std::string key;
  while (in >> key) {
    if (key == "VmRSS:") {
      double kb = 0.0;
      in >> kb;
      return kb * 1024.0 * 1e-6;
    }
    std::getline(in, key);
  }
  return 0.0;
}

TEST(CpuClock, ResidentSetFollowsTouchedMemory) {
  const double before = residentSetMb();
  ASSERT_GT(before, 0.0);
  EXPECT_NEAR(before, statusRssMb(), 1.0);
  constexpr std::size_t kBytes = 64u << 20;
  std::unique_ptr<char[]> block(new char[kBytes]);
  std::memset(block.get(), 1, kBytes);  // touched, so resident
  const double after = residentSetMb();
  EXPECT_GT(after - before, 0.9 * static_cast<double>(kBytes) * 1e-6);
  EXPECT_NEAR(after, statusRssMb(), 1.0);
  EXPECT_EQ(block[kBytes - 1], 1);
}

TEST(CpuClock, CpuClocksAdvanceWithWork) {
  const double t0 = threadCpuMs(), p0 = processCpuSeconds();
  volatile double x = 0.0;
  for (int i = 0; i < 20000000; ++i) x = x + 1e-9 * i;
  EXPECT_GT(threadCpuMs(), t0);
  EXPECT_GT(processCpuSeconds(), p0);
}

}  // namespace
}  // namespace linnet
