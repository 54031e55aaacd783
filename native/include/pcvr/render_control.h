/// @file render_control.h
/// @brief Progress and cancellation shared between a render running on worker threads and its caller.
///
/// The caller polls `fraction()` and may call `request_cancel()` from any thread; workers call
/// `advance()` and `throw_if_cancelled()` between small chunks of work, so a cancelled render stops
/// within a few milliseconds. All members are lock-free atomics.
#pragma once

#include <atomic>
#include <cstdint>

namespace pcvr {

class RenderControl {
public:
    /// Start a new phase of `units` work units; fraction() runs from `begin` to `end` across it.
    void begin_phase(uint64_t units, double begin, double end);
    void advance(uint64_t units = 1) { done_.fetch_add(units, std::memory_order_relaxed); }
    double fraction() const;
    /// Map every phase from here on into [begin, end] of the whole: a render made of several renders
    /// (one per batch of a streamed grid) gives each its share.
    void set_span(double begin, double end);

    void request_cancel() { cancelled_.store(true, std::memory_order_relaxed); }
    bool cancelled() const { return cancelled_.load(std::memory_order_relaxed); }
    /// Throws Cancelled when cancellation was requested.
    void throw_if_cancelled() const;

private:
    std::atomic<uint64_t> done_{0}, total_{1};
    std::atomic<double> begin_{0.0}, end_{1.0};
    std::atomic<double> span_begin_{0.0}, span_end_{1.0};
    std::atomic<bool> cancelled_{false};
};

}  // namespace pcvr
