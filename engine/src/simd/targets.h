// Which instruction sets a Highway source compiles for; included before <hwy/...> by every
// file that runs foreach_target (the engine's kernels, the benchmark's arithmetic bound), so
// they all carry the same targets.
#pragma once

// AVX3_DL (Ice Lake and later AVX-512): Highway 1.0.3 leaves it out of the attainable
// targets unless asked, and then fails to build with -march=native on a CPU that has it
// (the baseline target must be one of the targets). Asked for, then disabled below: the
// baseline of such a CPU becomes AVX3.
#ifndef HWY_WANT_AVX3_DL
#define HWY_WANT_AVX3_DL
#endif
// Two targets left out, as each one compiles the whole row sweep and the obstacle term
// again (forces.cpp and obstacles.cpp took 5.1 minutes in the sanitizer build with six
// targets, 3.3 with these four):
// AVX3_DL, Ice Lake's AVX-512 extensions, add nothing to floating-point kernels over AVX3
// (an AVX3_DL CPU runs the AVX3 code), and SSSE3 only serves CPUs from before 2008 without
// SSE4.1, which then run the scalar code.
#ifndef HWY_DISABLED_TARGETS
#define HWY_DISABLED_TARGETS (HWY_AVX3_DL | HWY_SSSE3)
#endif
// Every target the compiler can emit, also those below a -march=native baseline and the
// portable scalar target: the tests run each on this CPU, in either build.
#ifndef HWY_COMPILE_ALL_ATTAINABLE
#define HWY_COMPILE_ALL_ATTAINABLE
#endif
