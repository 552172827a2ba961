#pragma once
/// @file
/// Counts heap allocations while `g_count_allocations` is set (as drake's limit_malloc): the
/// executable's malloc takes precedence over libc's, so operator new, std::vector, Eigen and
/// Bullet all come through here. Include it in exactly one file of a test executable.

#include <cstddef>

extern "C" void* __libc_malloc(std::size_t size);

namespace {
bool g_count_allocations = false;
long long g_num_allocations = 0;
}  // namespace

extern "C" void* malloc(std::size_t size) {
  if (g_count_allocations) ++g_num_allocations;
  return __libc_malloc(size);
}
