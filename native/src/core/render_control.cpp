#include "pcvr/render_control.h"

#include <algorithm>

#include "pcvr/errors.h"

namespace pcvr {

void RenderControl::begin_phase(uint64_t units, double begin, double end) {
    done_.store(0, std::memory_order_relaxed);
    total_.store(std::max<uint64_t>(units, 1), std::memory_order_relaxed);
    begin_.store(begin, std::memory_order_relaxed);
    end_.store(end, std::memory_order_relaxed);
}

double RenderControl::fraction() const {
    const double part = std::min(1.0, double(done_.load(std::memory_order_relaxed)) /
                                          double(total_.load(std::memory_order_relaxed)));
    const double b = begin_.load(std::memory_order_relaxed), e = end_.load(std::memory_order_relaxed);
    const double sb = span_begin_.load(std::memory_order_relaxed), se = span_end_.load(std::memory_order_relaxed);
    return sb + (se - sb) * (b + (e - b) * part);
}

void RenderControl::set_span(double begin, double end) {
    span_begin_.store(begin, std::memory_order_relaxed);
    span_end_.store(end, std::memory_order_relaxed);
}

void RenderControl::throw_if_cancelled() const {
    if (cancelled()) throw Cancelled("render cancelled");
}

}  // namespace pcvr
