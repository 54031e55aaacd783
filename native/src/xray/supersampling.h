/// @file supersampling.h
/// @brief Which X-rays may render a zoomed-out view supersampled (src/view/level_of_detail.h says how far).
#pragma once

#include "pcvr/xray.h"

namespace pcvr {

/// Whether an X-ray with these parameters supersamples where zoomed out: an automatic level, footprints
/// integrated over pixels, and a method whose sub-pixels are its footprints' samples (bilinear spreading's
/// tents over them were 0.52% off the pixel means at 1/8, against 0.018% integrated pixel by pixel).
inline bool may_supersample(const XrayParams& params) {
    return params.level < 0 && params.antialias &&
           (params.method == XrayMethod::Pcvr || params.method == XrayMethod::Regular);
}


}  // namespace pcvr
