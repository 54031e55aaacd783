#include "pcvr/zeroed_buffer.h"

#include <sys/mman.h>
#include <unistd.h>

#include <cstdint>
#include <new>

namespace pcvr::detail {

namespace {
constexpr size_t kHugePage = size_t(2) << 20;
}

void* map_zero_pages(size_t bytes) {
    const size_t page = size_t(sysconf(_SC_PAGESIZE));
    bytes = (bytes + page - 1) / page * page;
    // Large buffers get a huge-page-aligned range: map the slack too, then return what lies outside.
    const size_t slack = bytes >= kHugePage ? kHugePage : 0;
    void* mapped = mmap(nullptr, bytes + slack, PROT_READ | PROT_WRITE, MAP_PRIVATE | MAP_ANONYMOUS, -1, 0);
    if (mapped == MAP_FAILED) throw std::bad_alloc();
    if (!slack) return mapped;
    const uintptr_t start = reinterpret_cast<uintptr_t>(mapped);
    const uintptr_t aligned = (start + kHugePage - 1) & ~(kHugePage - 1);
    if (aligned > start) munmap(mapped, aligned - start);
    if (const size_t tail = start + slack - aligned) munmap(reinterpret_cast<void*>(aligned + bytes), tail);
    madvise(reinterpret_cast<void*>(aligned), bytes, MADV_HUGEPAGE);  // a hint: kernels without THP ignore it
    return reinterpret_cast<void*>(aligned);
}

void unmap_pages(void* data, size_t bytes) noexcept { munmap(data, bytes); }  // the kernel rounds up to whole pages

}  // namespace pcvr::detail
