#include "pcvr/zeroed_buffer.h"

#include <sys/mman.h>
#include <unistd.h>

#include <tbb/parallel_for.h>

#include <cerrno>
#include <cstdint>
#include <cstring>
#include <new>

namespace pcvr::detail {

namespace {
constexpr size_t kHugePage = size_t(2) << 20;

/// Faults the pages in writable now. The renderer's first access to a node is a read (it adds into
/// it): left lazy, that read would map the shared zero page and the write after it would replace
/// it, flushing the other cores' TLBs each time, which costs more than the zeroing itself on a
/// virtual machine. Huge pages in parallel; the kernel clears them.
void populate(char* data, size_t bytes) {
    const size_t chunks = (bytes + kHugePage - 1) / kHugePage;
    tbb::parallel_for(size_t(0), chunks, [&](size_t c) {
        char* begin = data + c * kHugePage;
        const size_t size = std::min(kHugePage, bytes - c * kHugePage);
        if (madvise(begin, size, MADV_POPULATE_WRITE) != 0) {
            // Out of memory: fail here rather than touch the pages and wake the out-of-memory killer.
            if (errno != EINVAL) throw std::bad_alloc();
            // Kernels before 5.14: touch one byte per page instead.
            const size_t page = size_t(sysconf(_SC_PAGESIZE));
            for (size_t off = 0; off < size; off += page) std::memset(begin + off, 0, 1);
        }
    });
}
}  // namespace

void* map_zero_pages(size_t bytes) {
    const size_t page = size_t(sysconf(_SC_PAGESIZE));
    bytes = (bytes + page - 1) / page * page;
    // Large buffers get a huge-page-aligned range: map the slack too, then return what lies outside.
    const size_t slack = bytes >= kHugePage ? kHugePage : 0;
    void* mapped = mmap(nullptr, bytes + slack, PROT_READ | PROT_WRITE, MAP_PRIVATE | MAP_ANONYMOUS, -1, 0);
    if (mapped == MAP_FAILED) throw std::bad_alloc();
    uintptr_t start = reinterpret_cast<uintptr_t>(mapped);
    if (slack) {
        const uintptr_t aligned = (start + kHugePage - 1) & ~(kHugePage - 1);
        if (aligned > start) munmap(mapped, aligned - start);
        if (const size_t tail = start + slack - aligned) munmap(reinterpret_cast<void*>(aligned + bytes), tail);
        start = aligned;
        madvise(reinterpret_cast<void*>(start), bytes, MADV_HUGEPAGE);  // a hint: kernels without THP ignore it
    }
    try {
        populate(reinterpret_cast<char*>(start), bytes);
    } catch (...) {
        munmap(reinterpret_cast<void*>(start), bytes);
        throw;
    }
    return reinterpret_cast<void*>(start);
}

void unmap_pages(void* data, size_t bytes) noexcept { munmap(data, bytes); }  // the kernel rounds up to whole pages

}  // namespace pcvr::detail
