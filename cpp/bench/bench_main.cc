// The main() of linnet_bench (Google Benchmark's library does not provide one).
#include <benchmark/benchmark.h>

BENCHMARK_MAIN();
