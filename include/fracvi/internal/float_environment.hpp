// The floating-point environment of the step loop: subnormal numbers flushed to zero (internal).
//
// Why: a localised pulse in a chain at rest has values in the subnormal range (below DBL_MIN ≈
// 2.2e-308) on its flanks for the whole run, and the fast history's recursions keep such values
// for thousands of steps (a slowly decaying exponential takes 52·ln 2/(λh) steps to cross that
// range). On x86-64 every operation with a subnormal input or result takes a microcode assist of
// ≈ 100 cycles instead of one: examples/fractional_chain.toml (d = 1000, 14–20 of the 1000
// positions subnormal at every stored time) stepped 2.4–2.9× slower than with them flushed
// (bench/RESULTS.md). IntegratorOptions::flush_subnormals (the default) sets SSE's flush-to-zero
// (FTZ: a subnormal result becomes 0) and denormals-are-zero (DAZ: a subnormal input reads as 0)
// for the duration of each step, and the library's own threads (the history's run-ahead thread,
// OpenMP's team, the mirror run alongside) take the caller's two bits with their work, so that a
// run computes the same numbers on any number of threads. The cost: an absolute floor of DBL_MIN
// instead of 4.9e-324 (gradual underflow keeps fewer significant digits there anyway). Only these
// two bits are touched: the rounding mode and the sticky exception flags stay the caller's.
// Other architectures keep subnormals: only x86-64's MXCSR is set (kCanFlushSubnormals = false
// elsewhere, where the option has no effect and its tests skip).
#pragma once

#if defined(__x86_64__) || defined(_M_X64)
#include <xmmintrin.h>
#endif

namespace fracvi::internal {

#if defined(__x86_64__) || defined(_M_X64)
inline constexpr bool kCanFlushSubnormals = true;
/// MXCSR's FTZ (bit 15) and DAZ (bit 6).
inline constexpr unsigned kFlushSubnormalBits = 0x8040u;
/// This thread's flush bits (0, or some of kFlushSubnormalBits).
inline unsigned flush_bits() noexcept {
  return _mm_getcsr() & kFlushSubnormalBits;
}
/// Sets this thread's flush bits to `bits`, the rest of MXCSR unchanged.
inline void set_flush_bits(unsigned bits) noexcept {
  _mm_setcsr((_mm_getcsr() & ~kFlushSubnormalBits) | (bits & kFlushSubnormalBits));
}
#else
inline constexpr bool kCanFlushSubnormals = false;
inline constexpr unsigned kFlushSubnormalBits = 0u;
inline unsigned flush_bits() noexcept {
  return 0u;
}
inline void set_flush_bits(unsigned /*bits*/) noexcept {}
#endif

/// Work handed to this thread by another: compute with the other thread's flush bits (read there
/// with flush_bits() when the work was posted). One read of MXCSR when they already agree.
inline void adopt_flush_bits(unsigned bits) noexcept {
  if (flush_bits() != bits) set_flush_bits(bits);
}

/// While it lives, this thread computes with the flush bits `bits` (those of the computation whose
/// numbers its work must reproduce, e.g. the pushes of a history evened out for a checkpoint
/// between steps, outside the step's SubnormalsFlushed); then its own bits again. MXCSR is written
/// only when the bits differ, on entry and on exit.
class FlushBitsAdopted {
 public:
  explicit FlushBitsAdopted(unsigned bits) noexcept { adopt(bits); }
  ~FlushBitsAdopted() {
    if (restore_) set_flush_bits(saved_);
  }
  FlushBitsAdopted(const FlushBitsAdopted&) = delete;
  FlushBitsAdopted& operator=(const FlushBitsAdopted&) = delete;

 protected:
  FlushBitsAdopted() noexcept = default;  // adopts nothing until adopt()
  void adopt(unsigned bits) noexcept {
    saved_ = flush_bits();
    restore_ = saved_ != bits;
    if (restore_) set_flush_bits(bits);
  }

 private:
  unsigned saved_ = 0;
  bool restore_ = false;
};

/// While it lives, this thread flushes subnormals (when `flush`); then its own bits again. A
/// thread that already flushes (a nested guard, or a caller that set FTZ and DAZ itself) is left
/// as it is; with flush = false MXCSR is not even read.
class SubnormalsFlushed : private FlushBitsAdopted {
 public:
  explicit SubnormalsFlushed(bool flush) noexcept {
    if (flush) adopt(kFlushSubnormalBits);
  }
};

}  // namespace fracvi::internal
