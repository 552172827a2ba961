#pragma once
/// @file
/// Counts heap allocations while `g_count_allocations` is set (as drake's limit_malloc): the
/// executable's malloc takes precedence over libc's, so operator new, std::vector, Eigen and
/// Bullet all come through here. Include it in exactly one file of a test executable.
///
/// Under AddressSanitizer (GCC's -fsanitize=address) the sanitizer owns malloc, and a second
/// definition broke its start-up ("tsd_key_inited" CHECK); its allocation hook counts instead,
/// and sees the same calls (operator new included).

#include <cstddef>

namespace {
bool g_count_allocations = false;
long long g_num_allocations = 0;
}  // namespace

#if defined(__SANITIZE_ADDRESS__)
// From the sanitizers' allocator_interface.h, which GCC 12 does not install (libasan has it).
extern "C" int __sanitizer_install_malloc_and_free_hooks(
    void (*malloc_hook)(const volatile void*, std::size_t), void (*free_hook)(const volatile void*));

namespace {
void CountAllocation(const volatile void*, std::size_t) {
  if (g_count_allocations) ++g_num_allocations;
}
void IgnoreFree(const volatile void*) {}
// Both hooks must be given: with a null one the sanitizer installs neither (returns 0).
[[maybe_unused]] const int g_hooks_installed =
    __sanitizer_install_malloc_and_free_hooks(CountAllocation, IgnoreFree);
}  // namespace
#else
extern "C" void* __libc_malloc(std::size_t size);

extern "C" void* malloc(std::size_t size) {
  if (g_count_allocations) ++g_num_allocations;
  return __libc_malloc(size);
}
#endif
