// Counts heap allocations in a test executable (the idea of Drake's limit_malloc). Include it in
// exactly ONE translation unit of the executable: it interposes malloc, calloc, realloc,
// aligned_alloc and posix_memalign (glibc exports the real ones as __libc_*); operator new and
// Eigen's aligned_malloc both end in malloc, so every heap allocation of the process is counted
// while g_counting is on. Under AddressSanitizer (which owns malloc) FRACVI_COUNT_MALLOC is 0 and
// tests should skip.
#pragma once

#include <cstddef>
#include <cstdlib>

#if defined(__SANITIZE_ADDRESS__)
#define FRACVI_COUNT_MALLOC 0  // the sanitizer owns malloc
#elif defined(__GLIBC__)
#define FRACVI_COUNT_MALLOC 1
#else
#define FRACVI_COUNT_MALLOC 0
#endif

namespace {
bool g_counting = false;
std::size_t g_allocations = 0;
}  // namespace

#if FRACVI_COUNT_MALLOC
extern "C" {
void* __libc_malloc(std::size_t size);
void* __libc_calloc(std::size_t n, std::size_t size);
void* __libc_realloc(void* p, std::size_t size);
void* __libc_memalign(std::size_t alignment, std::size_t size);

void* malloc(std::size_t size) {
  if (g_counting) ++g_allocations;
  return __libc_malloc(size);
}
void* calloc(std::size_t n, std::size_t size) {
  if (g_counting) ++g_allocations;
  return __libc_calloc(n, size);
}
void* realloc(void* p, std::size_t size) {
  if (g_counting) ++g_allocations;
  return __libc_realloc(p, size);
}
void* aligned_alloc(std::size_t alignment, std::size_t size) {
  if (g_counting) ++g_allocations;
  return __libc_memalign(alignment, size);
}
int posix_memalign(void** out, std::size_t alignment, std::size_t size) {
  if (g_counting) ++g_allocations;
  *out = __libc_memalign(alignment, size);
  return *out != nullptr ? 0 : 12;  // ENOMEM
}
}
#endif
