#include "pcvr/stride.h"

#include <algorithm>
#include <cmath>

#include "pcvr/math.h"

namespace pcvr {

int automatic_stride(double pixels_per_voxel) {
    // The small tolerance keeps an exact magnification of 4 (computed as 3.9999999) at stride 4.
    return clamp_to_int(std::floor(pixels_per_voxel + 1e-6), 1, kMaxStride);
}

int nearest_stride(double pixels_per_voxel) { return clamp_to_int(std::round(pixels_per_voxel), 1, kMaxStride); }

double fractional_stride(double pixels_per_voxel, double least) {
    double base = std::clamp(least, 1.0, double(kMaxStride));
    // An exact magnification of 4 (computed as 3.9999999) keeps stride 4, as the whole strides do.
    if (std::abs(base - std::round(base)) < 1e-6 * base) base = std::round(base);
    if (!(pixels_per_voxel > base)) return base;
    const double band = std::floor(std::log(pixels_per_voxel / base) / std::log(kStrideBandRatio) + 1e-9);
    return std::min(base * std::pow(kStrideBandRatio, band), double(kMaxStride));
}

double perspective_stride(double most_pixels_per_voxel, double most) {
    double top = std::clamp(most, 1.0, double(kMaxStride));
    if (std::abs(top - std::round(top)) < 1e-6 * top) top = std::round(top);
    if (!(most_pixels_per_voxel < top)) return top;
    const double band = std::floor(std::log(top / std::max(most_pixels_per_voxel, 1e-300)) / std::log(kPerspectiveBandRatio) + 1e-9);
    return std::max(1.0, top / std::pow(kPerspectiveBandRatio, band));
}

}  // namespace pcvr
