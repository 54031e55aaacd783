// Shared by the render bindings: grids and scales from Python, and running a long native call with
// the GIL released while its progress and cancel callbacks are polled.
#pragma once

#include <nanobind/nanobind.h>
#include <nanobind/stl/string.h>

#include <algorithm>
#include <chrono>
#include <condition_variable>
#include <mutex>
#include <optional>
#include <string>
#include <thread>
#include <vector>

#include "bindings.h"
#include "pcvr/clip_region.h"
#include "pcvr/errors.h"
#include "pcvr/grid.h"
#include "pcvr/render_control.h"

namespace pcvr::python {

namespace nb = nanobind;

inline constexpr auto kPollInterval = std::chrono::milliseconds(20);

/// `grids` is one Grid or a sequence of them; `scales` one number or one per grid.
inline std::vector<Grid> grids_from_python(nb::handle grids, const char* function) {
    if (nb::isinstance<Grid>(grids)) return {nb::cast<Grid>(grids)};
    std::vector<Grid> out;
    try {
        for (nb::handle item : grids) out.push_back(nb::cast<Grid>(item));
    } catch (const std::exception&) {
        throw nb::type_error((std::string(function) + ": `grid` must be a pcvr_native.Grid or a sequence of them").c_str());
    }
    return out;
}

/// The items of a sequence argument, or TypeError naming `function`.
inline nb::list grid_sequence(nb::handle grids, const char* function) {
    try {
        return nb::list(grids);
    } catch (const std::exception&) {
        throw nb::type_error((std::string(function) + ": `grid` must be a pcvr_native.Grid or a sequence of them").c_str());
    }
}

inline std::vector<double> scales_from_python(nb::handle scales, size_t count, const char* function) {
    if (nb::isinstance<nb::float_>(scales) || nb::isinstance<nb::int_>(scales))
        return std::vector<double>(count, nb::cast<double>(scales));
    std::vector<double> out;
    for (nb::handle item : scales) out.push_back(nb::cast<double>(item));
    if (out.size() != count)
        throw nb::value_error((std::string(function) + ": density_scale must be one number or one per grid").c_str());
    return out;
}

/// The clip keywords' docstring, shared by every render function.
#define CLIP_DOC                                                                                                     \
    "clip_planes: world-space planes (a, b, c, d), each keeping a*x + b*y + c*z + d >= 0, for every grid, or one\n"  \
    "list of them (or None) per grid. clip_box: a 4 x 4 world-to-box matrix keeping the box's [-1, 1]^3 (an\n"       \
    "object's inverted world matrix crops to that object's cube), or one (or None) per grid. Planes and box\n"       \
    "intersect, and cut the reconstructed field exactly (a kernel half across a plane counts half);\n"             \
    "stats['blocks_clipped'] counts the blocks wholly outside."

/// One plane (a, b, c, d), or nothing when `item` is not a sequence of four numbers.
inline std::optional<ClipPlane> plane_from_python(nb::handle item) {
    if (item.is_none() || nb::isinstance<nb::str>(item)) return std::nullopt;
    try {
        std::vector<double> numbers;
        for (nb::handle x : item) {
            if (!nb::isinstance<nb::float_>(x) && !nb::isinstance<nb::int_>(x) && !nb::hasattr(x, "__float__")) return std::nullopt;
            numbers.push_back(nb::cast<double>(x));
        }
        if (numbers.size() != 4) return std::nullopt;
        return ClipPlane{{numbers[0], numbers[1], numbers[2]}, numbers[3]};
    } catch (const std::exception&) {
        return std::nullopt;
    }
}

/// A sequence of planes, or TypeError naming `function`.
inline std::vector<ClipPlane> planes_from_python(nb::handle planes, const char* function) {
    std::vector<ClipPlane> out;
    if (planes.is_none()) return out;
    try {
        for (nb::handle item : planes) {
            const std::optional<ClipPlane> plane = plane_from_python(item);
            if (!plane) throw std::invalid_argument("");
            out.push_back(*plane);
        }
    } catch (const std::exception&) {
        throw nb::type_error((std::string(function) + ": clip_planes must be planes (a, b, c, d), or one list of them (or None) per grid").c_str());
    }
    return out;
}

/// Each grid's clip region from `clip_planes` (planes for every grid, or one list of planes or None per
/// grid) and `clip_box` (a 4 x 4 world-to-box matrix for every grid, or one matrix or None per grid).
inline std::vector<ClipRegion> clip_regions_from_python(nb::handle clip_planes, nb::handle clip_box, size_t count, const char* function) {
    const std::string name(function);
    std::vector<std::vector<ClipPlane>> planes(count);
    if (!clip_planes.is_none()) {
        const nb::list items = nb::list(clip_planes);
        bool per_grid = false;
        for (nb::handle item : items) per_grid |= !plane_from_python(item);
        if (!per_grid) {
            planes.assign(count, planes_from_python(clip_planes, function));
        } else {
            if (items.size() != count)
                throw nb::value_error((name + ": clip_planes must be planes (a, b, c, d) for every grid, or one list of them (or None) per grid (" +
                                       std::to_string(count) + ")").c_str());
            for (size_t i = 0; i < count; ++i) planes[i] = planes_from_python(items[i], function);
        }
    }
    std::vector<std::optional<Mat4>> boxes(count);
    if (!clip_box.is_none()) {
        std::optional<Mat4> shared;
        try {
            shared = mat4_from_python(clip_box, "clip_box");
        } catch (const std::exception&) {
        }
        if (shared) {
            boxes.assign(count, shared);
        } else {
            const nb::list items = nb::list(clip_box);
            if (items.size() != count)
                throw nb::value_error((name + ": clip_box must be a 4 x 4 world-to-box matrix, or one (or None) per grid (" +
                                       std::to_string(count) + ")").c_str());
            for (size_t i = 0; i < count; ++i)
                if (!items[i].is_none()) boxes[i] = mat4_from_python(items[i], "clip_box");
        }
    }
    std::vector<ClipRegion> regions;
    for (size_t i = 0; i < count; ++i) {
        try {
            regions.push_back(ClipRegion::from(planes[i], boxes[i] ? &*boxes[i] : nullptr));
        } catch (const InvalidArgument& e) {
            throw InvalidArgument(name + (count > 1 ? " (grid " + std::to_string(i) + ")" : std::string()) + ": " + e.what());
        }
    }
    return regions;
}

/// `level` is "auto" (-1) or a level of detail from 0 to 30.
inline int level_from_python(nb::handle level, const char* function) {
    if (nb::isinstance<nb::str>(level) && nb::cast<std::string>(level) == "auto") return -1;
    if (nb::isinstance<nb::int_>(level) && nb::cast<int64_t>(level) >= 0 && nb::cast<int64_t>(level) <= 30)
        return int(nb::cast<int64_t>(level));
    throw InvalidArgument(std::string(function) + ": level must be 'auto' or a level of detail from 0 (the grid itself) to 30");
}

inline bool cancel_requested(nb::handle cancel) {
    if (nb::hasattr(cancel, "is_set")) return nb::cast<bool>(cancel.attr("is_set")());
    return nb::cast<bool>(nb::bool_(cancel()));
}

/// Runs `work` with the GIL released. With callbacks, the work runs on a worker thread while this
/// thread polls them every few milliseconds, holding the GIL only for the calls.
template <class Work>
void run_polled(Work&& work, RenderControl& control, nb::handle progress, nb::handle cancel) {
    std::exception_ptr failure;
    std::optional<nb::python_error> callback_error;
    const bool polled = !progress.is_none() || !cancel.is_none();
    {
        nb::gil_scoped_release release;
        if (!polled) {
            try {
                work();
            } catch (...) {
                failure = std::current_exception();
            }
        } else {
            std::mutex mutex;
            std::condition_variable done_cv;
            bool done = false;
            std::thread worker([&] {
                try {
                    work();
                } catch (...) {
                    failure = std::current_exception();
                }
                std::lock_guard<std::mutex> lock(mutex);
                done = true;
                done_cv.notify_all();
            });
            // Progress never goes back: a render made of several (a streamed grid's batches) moves from one
            // part's span to the next while its phase restarts, and a poll may fall between the two.
            double reported = 0.0;
            std::unique_lock<std::mutex> lock(mutex);
            while (!done_cv.wait_for(lock, kPollInterval, [&] { return done; })) {
                lock.unlock();
                {
                    nb::gil_scoped_acquire acquire;
                    try {
                        reported = std::max(reported, control.fraction());
                        if (!progress.is_none()) progress(reported);
                        if (!cancel.is_none() && cancel_requested(cancel)) control.request_cancel();
                    } catch (nb::python_error& e) {
                        // A failing callback stops the render; its exception is what the caller sees.
                        if (!callback_error) callback_error.emplace(std::move(e));
                        control.request_cancel();
                    }
                }
                lock.lock();
            }
            lock.unlock();
            worker.join();
        }
    }
    if (callback_error) throw std::move(*callback_error);
    if (failure) std::rethrow_exception(failure);
    if (!progress.is_none()) progress(1.0);
}

}  // namespace pcvr::python
