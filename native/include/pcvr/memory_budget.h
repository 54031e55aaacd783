/// @file memory_budget.h
/// @brief What a render is about to allocate, checked against a limit before it allocates any of it.
///
/// Image-sized buffers are faulted in up front (zeroed_buffer.h); under Linux's overcommit a render
/// that does not fit would not fail cleanly but bring the out-of-memory killer down on Blender. A
/// renderer adds up its large buffers here (the image, splat grids, one per worker thread) and calls
/// check() before allocating: a request that cannot fit fails at once, saying what it needs.
///
/// | limit          | source                                                                     |
/// |----------------|----------------------------------------------------------------------------|
/// | explicit bytes | the caller's (render_xray's `memory_limit=`)                               |
/// | 0 (default)    | default_memory_limit(): the memory the machine (or its cgroup) has available |
#pragma once

#include <cstdint>
#include <string>
#include <utility>
#include <vector>

namespace pcvr {

/// Memory available now: MemAvailable of /proc/meminfo, lowered to what a cgroup memory limit or
/// RLIMIT_AS still allows. Without any of them (non-Linux), no limit.
uint64_t default_memory_limit();

class MemoryBudget {
public:
    /// `limit` in bytes; 0: default_memory_limit().
    explicit MemoryBudget(uint64_t limit = 0);

    void add(std::string what, uint64_t bytes);
    uint64_t total() const { return total_; }
    uint64_t limit() const { return limit_; }

    /// Throws OutOfMemory naming `task`, the total and every item when the total exceeds the limit.
    void check(const std::string& task) const;

private:
    uint64_t limit_;
    bool default_limit_;
    uint64_t total_ = 0;
    std::vector<std::pair<std::string, uint64_t>> items_;
};

/// "1.5 GiB", "340 MiB", "12 KiB", "100 bytes".
std::string format_bytes(uint64_t bytes);

}  // namespace pcvr
