// The instruction set the engine's kernels run with (in the JSON's context, so the report
// names it), and the arithmetic bound of the spring step: every spring of eq (6) needs one
// square root and one division, and nothing the code does can run them faster than the
// CPU's divider does. BM_ArithmeticBound runs just those two, 1/√x, with Highway on the
// widest target, over an L1-resident array: its rate is the most springs per second this CPU
// can evaluate, reported as point-steps of a 64×64 sheet.
#include "simd/targets.h"

#undef HWY_TARGET_INCLUDE
#define HWY_TARGET_INCLUDE "bench_simd.cpp"
#include <hwy/foreach_target.h>  // IWYU pragma: keep
#include <hwy/highway.h>

#include <cstddef>

HWY_BEFORE_NAMESPACE();
namespace drape::bench {
namespace HWY_NAMESPACE {
namespace hn = hwy::HWY_NAMESPACE;

// out = 1/√in, whole vectors only (count is a multiple of every target's lanes).
template <class Real>
HWY_INLINE void inv_sqrt(std::size_t count, const Real* HWY_RESTRICT in, Real* HWY_RESTRICT out) {
  const hn::ScalableTag<Real> d;
  const auto one = hn::Set(d, Real(1));
  for (std::size_t i = 0; i < count; i += hn::Lanes(d))
    hn::StoreU(hn::Div(one, hn::Sqrt(hn::LoadU(d, in + i))), d, out + i);
}

void InvSqrtF64(std::size_t count, const double* in, double* out) { inv_sqrt(count, in, out); }
void InvSqrtF32(std::size_t count, const float* in, float* out) { inv_sqrt(count, in, out); }

}  // namespace HWY_NAMESPACE
}  // namespace drape::bench
HWY_AFTER_NAMESPACE();

#if HWY_ONCE
#include <cstdio>
#include <cstdlib>
#include <string>
#include <vector>

#include "bench_common.h"
#include "simd/kernels.h"

namespace drape::bench {
namespace {

HWY_EXPORT(InvSqrtF64);
HWY_EXPORT(InvSqrtF32);

// Read by tools/bench_report.py: the kernels' instruction set, and every one this build
// could have used on this CPU.
// DRAPE_SIMD_TARGET=AVX2 (a name from simd_targets) runs the whole suite on that target,
// to price each instruction set on one machine; a name this build or CPU lacks stops the run.
const bool context_added = [] {
  std::string all;
  const char* wanted = std::getenv("DRAPE_SIMD_TARGET");
  bool found = false;
  for (std::int64_t t : detail::simd::supported_targets()) {
    if (!all.empty()) all += ' ';
    all += hwy::TargetName(t);
    if (wanted && std::string(wanted) == hwy::TargetName(t)) {
      detail::simd::use_target(t);
      found = true;
    }
  }
  if (wanted && *wanted && !found) {
    std::fprintf(stderr, "drape_bench: DRAPE_SIMD_TARGET=%s is not one of this build's targets on this CPU: %s\n",
                 wanted, all.c_str());
    std::exit(2);
  }
  benchmark::AddCustomContext("simd_target", detail::simd::target_name());
  benchmark::AddCustomContext("simd_targets", all);
  return true;
}();

// Springs per point of a 64×64 sheet: 2·64·63 springs on 64² points.
constexpr double springs_per_point = 2.0 * 64 * 63 / (64.0 * 64);

template <class Real>
void BM_ArithmeticBound(benchmark::State& state) {
  const std::size_t count = 2048;  // 16 KiB of doubles in, 16 out: L1
  std::vector<Real> in(count), out(count);
  for (std::size_t i = 0; i < count; ++i) in[i] = Real(1) + Real(i) / Real(count);
  for (auto _ : state) {
    if constexpr (sizeof(Real) == 8)
      HWY_DYNAMIC_DISPATCH(InvSqrtF64)(count, in.data(), out.data());
    else
      HWY_DYNAMIC_DISPATCH(InvSqrtF32)(count, in.data(), out.data());
    benchmark::DoNotOptimize(out.data());
    benchmark::ClobberMemory();
  }
  state.counters["sqrt_div_per_s"] = benchmark::Counter(double(count) * double(state.iterations()),
                                                        benchmark::Counter::kIsRate);
  set_point_rate(state, double(count) / springs_per_point);
  state.SetLabel(detail::simd::target_name());
}
BENCHMARK(BM_ArithmeticBound<double>)->Name("BM_ArithmeticBound/f64");
BENCHMARK(BM_ArithmeticBound<float>)->Name("BM_ArithmeticBound/f32");

}  // namespace
}  // namespace drape::bench
#endif
