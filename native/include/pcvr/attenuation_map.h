/// @file attenuation_map.h
/// @brief What a grid's values mean to an X-ray: a piecewise-linear map from values to linear attenuation
/// (per world unit), applied to every active voxel before splatting, as DRR tools do.
///
/// A CT scan stores Hounsfield units: air -1000, water 0, bone several hundred to a few thousand. Its line
/// integral is meaningless (air and fat are negative); a digitally reconstructed radiograph integrates the
/// linear attenuation mu = mu_water (1 + HU / 1000), never below air's (plastimatch, ITK/RTK and DiffDRR map
/// so). The X-ray stays linear after the map: the image is the integral of the mapped field.
#pragma once

#include <vector>

#include "pcvr/grid.h"

namespace pcvr {

class AttenuationMap {
public:
    /// Piecewise linear through (values[i], attenuation[i]), constant beyond the ends. Throws InvalidArgument
    /// unless there is at least one point, values strictly increase and everything is finite.
    AttenuationMap(std::vector<double> values, std::vector<double> attenuation);

    /// mu = mu_water (1 + HU / 1000), never below mu_air (which must lie below mu_water; both finite, >= 0).
    static AttenuationMap hounsfield(double mu_water, double mu_air = 0.0);

    const std::vector<double>& values() const { return values_; }
    const std::vector<double>& attenuation() const { return attenuation_; }

    double operator()(double value) const;

    /// The grid with every active voxel's value mapped; inactive voxels stay inactive, and count as 0 in an
    /// X-ray as before. Runs on all threads; the result shares nothing with `grid`.
    Grid apply(const Grid& grid) const;

private:
    std::vector<double> values_, attenuation_;
};

}  // namespace pcvr
