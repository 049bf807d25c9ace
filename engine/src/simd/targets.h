// Which instruction sets a Highway source compiles for; included before <hwy/...> by every
// file that runs foreach_target (the engine's kernels, the benchmark's arithmetic bound), so
// they all carry the same targets.
#pragma once

// AVX3_DL (Ice Lake and later AVX-512) as a target of its own: Highway 1.0.3 leaves it out
// unless asked, and then fails to build with -march=native on a CPU that has it (the baseline
// target must be one of the targets).
#ifndef HWY_WANT_AVX3_DL
#define HWY_WANT_AVX3_DL
#endif
// Every target the compiler can emit, also those below a -march=native baseline and the
// portable scalar target: the tests run each on this CPU, in either build.
#ifndef HWY_COMPILE_ALL_ATTAINABLE
#define HWY_COMPILE_ALL_ATTAINABLE
#endif
