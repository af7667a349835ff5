// v4r - robust model-based object tracking. MIT licence.
#include <benchmark/benchmark.h>

BENCHMARK_MAIN();
