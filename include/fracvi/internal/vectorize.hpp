// Loop annotations for the hand-vectorised kernels of the memory layer (internal).
#pragma once

// GCC does not vectorise loops over several columns of one array given as restrict pointers
// ("no vectype"), but does with the promise that the iterations are independent.
#if defined(__GNUC__) && !defined(__clang__)
#define FRACVI_INDEPENDENT_ITERATIONS _Pragma("GCC ivdep")
#else
#define FRACVI_INDEPENDENT_ITERATIONS
#endif

// The kernels that are most of a large system's step (bench/RESULTS.md) carry an x86-64-v3 clone
// (AVX2 + FMA) that the dynamic loader picks on CPUs that have it (GCC's target_clones: an ifunc
// resolved once at load time, no per-call dispatch); the README's build is portable x86-64 (SSE2,
// no FMA), and other compilers and architectures get the portable loop.
#if defined(__GNUC__) && !defined(__clang__) && defined(__x86_64__) && !defined(__AVX2__)
#define FRACVI_HOT_KERNEL __attribute__((target_clones("default", "arch=x86-64-v3")))
#else
#define FRACVI_HOT_KERNEL
#endif
