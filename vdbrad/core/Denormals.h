// Denormals: float values below 2^-126 (1.2e-38) are processed by microcode on x86, tens of
// cycles per operation instead of one. A linear solve scaled into that range (emission 1e-37,
// or the faint tail of light deep in shadow or in an absorbing cloud) would then sweep slower
// for nothing: such values are below float's resolution of any result above 1e-30. The sweeps
// therefore run with flush-to-zero and denormals-are-zero set in the SSE control register, per
// task, since every TBB worker thread has its own; the previous mode is restored on leaving.
// Results in float's normal range are unchanged, bit for bit (measured: bench_extremes).
// Elsewhere than x86 this is a no-op.
#pragma once

#if defined(__SSE__) || defined(__x86_64__) || defined(_M_X64)
#include <xmmintrin.h>
#define VDBRAD_HAVE_MXCSR 1
#endif

namespace vdbrad {

class ScopedFlushDenormals
{
public:
#ifdef VDBRAD_HAVE_MXCSR
    // FTZ (bit 15): denormal results become 0; DAZ (bit 6): denormal inputs read as 0.
    ScopedFlushDenormals() : mSaved(_mm_getcsr()) { _mm_setcsr(mSaved | 0x8040u); }
    ~ScopedFlushDenormals() { _mm_setcsr(mSaved); }
#else
    ScopedFlushDenormals() {}
#endif
    ScopedFlushDenormals(const ScopedFlushDenormals&) = delete;
    ScopedFlushDenormals& operator=(const ScopedFlushDenormals&) = delete;

private:
#ifdef VDBRAD_HAVE_MXCSR
    unsigned mSaved;
#endif
};

} // namespace vdbrad
