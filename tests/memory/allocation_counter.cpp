#include "allocation_counter.hpp"

#include <malloc.h>  // memalign

#include <Eigen/Core>
#include <atomic>
#include <cstdlib>
#include <new>

#if defined(BLOCKMAP_SANITIZED)
// From the sanitizer runtime's public interface (sanitizer/allocator_interface.h, which
// clang ships and gcc's packages do not): the hooks run on every allocation it serves.
extern "C" int __sanitizer_install_malloc_and_free_hooks(  // NOLINT(bugprone-reserved-identifier)
    void (*malloc_hook)(const volatile void* pointer, std::size_t size),
    void (*free_hook)(const volatile void* pointer));
#endif

namespace blockmap::testing {
namespace {

std::atomic<std::uint64_t> g_calls{0};
std::atomic<std::uint64_t> g_bytes{0};
// The calling thread's own (plain integers: initial-exec TLS, nothing allocated to reach it).
thread_local std::uint64_t t_calls = 0;
thread_local std::uint64_t t_bytes = 0;

void note_allocation(std::size_t bytes) noexcept {
  g_calls.fetch_add(1, std::memory_order_relaxed);
  g_bytes.fetch_add(bytes, std::memory_order_relaxed);
  ++t_calls;
  t_bytes += bytes;
}

#if defined(BLOCKMAP_SANITIZED)
// ASan's allocator serves malloc and operator new alike and reports each to this hook.
void on_sanitizer_malloc(const volatile void* /*pointer*/, std::size_t bytes) {
  note_allocation(bytes);
}
void on_sanitizer_free(const volatile void* /*pointer*/) {}

const bool g_hooks_installed =
    __sanitizer_install_malloc_and_free_hooks(on_sanitizer_malloc, on_sanitizer_free) != 0;
#endif

}  // namespace

AllocationTally allocations_since_start() noexcept {
  return AllocationTally{g_calls.load(std::memory_order_relaxed),
                         g_bytes.load(std::memory_order_relaxed)};
}

AllocationTally allocations_on_this_thread() noexcept {
  return AllocationTally{t_calls, t_bytes};
}

bool allocation_counting_active() noexcept {
#if defined(BLOCKMAP_SANITIZED)
  if (!g_hooks_installed) {
    return false;
  }
#endif
  const std::uint64_t before = g_calls.load(std::memory_order_relaxed);
  void* probe = std::malloc(1);
  escape(probe);
  std::free(probe);
  return g_calls.load(std::memory_order_relaxed) > before;
}

SteadyStateScope::SteadyStateScope() noexcept
    : mark_(allocations_since_start()), eigen_was_allowed_(Eigen::internal::is_malloc_allowed()) {
  Eigen::internal::set_is_malloc_allowed(false);
}

SteadyStateScope::~SteadyStateScope() {
  Eigen::internal::set_is_malloc_allowed(eigen_was_allowed_);
}

std::uint64_t SteadyStateScope::allocations() const noexcept {
  return allocations_since_start().calls - mark_.calls;
}

std::uint64_t SteadyStateScope::allocated_bytes() const noexcept {
  return allocations_since_start().bytes - mark_.bytes;
}

void escape(const void* pointer) noexcept {
  // An empty asm that claims to read the pointer and clobber memory: the allocation is used.
  asm volatile("" : : "g"(pointer) : "memory");
}

}  // namespace blockmap::testing

#if !defined(BLOCKMAP_SANITIZED)
// ---------------------------------------------------------------------------------------------
// Interposition on glibc: the executable's definitions take precedence over libc.so's, and the
// __libc_* entry points reach glibc's allocator itself. free() is not replaced: the memory
// comes from the same allocator. Interposing means using glibc's reserved names and keeping the
// prototypes' own shapes, hence the NOLINT.
// NOLINTBEGIN(bugprone-reserved-identifier,readability-inconsistent-declaration-parameter-name)
extern "C" {
void* __libc_malloc(std::size_t size);
void* __libc_calloc(std::size_t count, std::size_t size);
void* __libc_realloc(void* pointer, std::size_t size);
void* __libc_memalign(std::size_t alignment, std::size_t size);

void* malloc(std::size_t size) noexcept {
  blockmap::testing::note_allocation(size);
  return __libc_malloc(size);
}
void* calloc(std::size_t count, std::size_t size) noexcept {
  blockmap::testing::note_allocation(count * size);
  return __libc_calloc(count, size);
}
void* realloc(void* pointer, std::size_t size) noexcept {
  blockmap::testing::note_allocation(size);
  return __libc_realloc(pointer, size);
}
void* memalign(std::size_t alignment, std::size_t size) noexcept {
  blockmap::testing::note_allocation(size);
  return __libc_memalign(alignment, size);
}
void* aligned_alloc(std::size_t alignment, std::size_t size) noexcept {
  blockmap::testing::note_allocation(size);
  return __libc_memalign(alignment, size);
}
int posix_memalign(void** out, std::size_t alignment, std::size_t size) noexcept {
  if (alignment < sizeof(void*) || (alignment & (alignment - 1)) != 0) {
    return 22;  // EINVAL
  }
  blockmap::testing::note_allocation(size);
  void* pointer = __libc_memalign(alignment, size);
  if (pointer == nullptr) {
    return 12;  // ENOMEM
  }
  *out = pointer;
  return 0;
}
}  // extern "C"
// NOLINTEND(bugprone-reserved-identifier,readability-inconsistent-declaration-parameter-name)

// ---------------------------------------------------------------------------------------------
// Replaceable global allocation functions ([new.delete]). The counted malloc above serves them,
// so each new is counted once.
namespace {
void* allocate_or_throw(std::size_t size) {
  void* pointer = std::malloc(size == 0 ? 1 : size);
  if (pointer == nullptr) {
    throw std::bad_alloc();
  }
  return pointer;
}
void* allocate_aligned_or_throw(std::size_t size, std::align_val_t alignment) {
  void* pointer = aligned_alloc(static_cast<std::size_t>(alignment), size == 0 ? 1 : size);
  if (pointer == nullptr) {
    throw std::bad_alloc();
  }
  return pointer;
}
}  // namespace

void* operator new(std::size_t size) {
  return allocate_or_throw(size);
}
void* operator new[](std::size_t size) {
  return allocate_or_throw(size);
}
void* operator new(std::size_t size, const std::nothrow_t&) noexcept {
  return std::malloc(size == 0 ? 1 : size);
}
void* operator new[](std::size_t size, const std::nothrow_t&) noexcept {
  return std::malloc(size == 0 ? 1 : size);
}
void* operator new(std::size_t size, std::align_val_t alignment) {
  return allocate_aligned_or_throw(size, alignment);
}
void* operator new[](std::size_t size, std::align_val_t alignment) {
  return allocate_aligned_or_throw(size, alignment);
}
void* operator new(std::size_t size, std::align_val_t alignment, const std::nothrow_t&) noexcept {
  return aligned_alloc(static_cast<std::size_t>(alignment), size == 0 ? 1 : size);
}
void* operator new[](std::size_t size, std::align_val_t alignment, const std::nothrow_t&) noexcept {
  return aligned_alloc(static_cast<std::size_t>(alignment), size == 0 ? 1 : size);
}
void operator delete(void* pointer) noexcept {
  std::free(pointer);
}
void operator delete[](void* pointer) noexcept {
  std::free(pointer);
}
void operator delete(void* pointer, std::size_t) noexcept {
  std::free(pointer);
}
void operator delete[](void* pointer, std::size_t) noexcept {
  std::free(pointer);
}
void operator delete(void* pointer, const std::nothrow_t&) noexcept {
  std::free(pointer);
}
void operator delete[](void* pointer, const std::nothrow_t&) noexcept {
  std::free(pointer);
}
void operator delete(void* pointer, std::align_val_t) noexcept {
  std::free(pointer);
}
void operator delete[](void* pointer, std::align_val_t) noexcept {
  std::free(pointer);
}
void operator delete(void* pointer, std::size_t, std::align_val_t) noexcept {
  std::free(pointer);
}
void operator delete[](void* pointer, std::size_t, std::align_val_t) noexcept {
  std::free(pointer);
}
void operator delete(void* pointer, std::align_val_t, const std::nothrow_t&) noexcept {
  std::free(pointer);
}
void operator delete[](void* pointer, std::align_val_t, const std::nothrow_t&) noexcept {
  std::free(pointer);
}
#endif  // !BLOCKMAP_SANITIZED
