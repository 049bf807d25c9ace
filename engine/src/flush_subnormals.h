// Subnormal numbers read and written as zero, on this thread, while an object of this class
// lives (the previous mode back when it goes). A sparse factor's fill decays with its distance
// in the elimination graph, so a stiff sheet's factor in float reaches numbers below 1.2e-38,
// and every multiply that reads or makes one takes a microcoded assist (on x86 about a hundred
// cycles): with them, a 64×64 sheet's factor at k = 1e8 N/m ran about a third slower. Numbers
// that small are zero to a preconditioner. The mode belongs to the thread, so the factor gets
// the same bits on whichever thread makes it. x86 (MXCSR's FTZ and DAZ) and AArch64 (FPCR.FZ);
// elsewhere a no-op, where results may differ from those by the flushed subnormals alone.
#pragma once

#if defined(__x86_64__) || defined(_M_X64) || defined(__i386__)
#include <xmmintrin.h>
#endif

namespace drape::detail {

class FlushSubnormals {
 public:
#if defined(__x86_64__) || defined(_M_X64) || defined(__i386__) || defined(__aarch64__)
  static constexpr bool kFlushes = true;
#else
  static constexpr bool kFlushes = false;
#endif
#if defined(__x86_64__) || defined(_M_X64) || defined(__i386__)
  FlushSubnormals() : saved_(_mm_getcsr()) { _mm_setcsr(saved_ | kFlushToZero | kDenormalsAreZero); }
  ~FlushSubnormals() { _mm_setcsr(saved_); }

 private:
  static constexpr unsigned kFlushToZero = 0x8000, kDenormalsAreZero = 0x0040;
  unsigned saved_;
#elif defined(__aarch64__)
  FlushSubnormals() {
    asm volatile("mrs %0, fpcr" : "=r"(saved_));
    set(saved_ | kFlushToZero);
  }
  ~FlushSubnormals() { set(saved_); }

 private:
  static void set(unsigned long long fpcr) { asm volatile("msr fpcr, %0" : : "r"(fpcr)); }
  static constexpr unsigned long long kFlushToZero = 1ull << 24;
  unsigned long long saved_;
#else
  FlushSubnormals() = default;
#endif

 public:
  FlushSubnormals(const FlushSubnormals&) = delete;
  FlushSubnormals& operator=(const FlushSubnormals&) = delete;
};

}  // namespace drape::detail
