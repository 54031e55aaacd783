#include "pcvr/attenuation_map.h"

#include <openvdb/tools/ValueTransformer.h>

#include <algorithm>
#include <cmath>
#include <string>

#include "pcvr/errors.h"
#include "volume/grid_data.h"

namespace pcvr {

namespace {

/// The value of `values[0]` beyond which the Hounsfield line is never evaluated: about 10^4 times bone's
/// densest, so the map is the line within float precision wherever CT scanners write values.
constexpr double kHounsfieldTop = 1e7;

}  // namespace

AttenuationMap::AttenuationMap(std::vector<double> values, std::vector<double> attenuation)
    : values_(std::move(values)), attenuation_(std::move(attenuation)) {
    if (values_.empty() || values_.size() != attenuation_.size())
        throw InvalidArgument("AttenuationMap needs as many attenuation values as values, at least one (got " +
                              std::to_string(values_.size()) + " values and " + std::to_string(attenuation_.size()) +
                              " attenuation values)");
    for (size_t i = 0; i < values_.size(); ++i) {
        if (!std::isfinite(values_[i]) || !std::isfinite(attenuation_[i]))
            throw InvalidArgument("AttenuationMap: point " + std::to_string(i) + " is not finite");
        if (i > 0 && !(values_[i] > values_[i - 1]))
            throw InvalidArgument("AttenuationMap: values must increase (value " + std::to_string(i) + " is " +
                                  std::to_string(values_[i]) + " after " + std::to_string(values_[i - 1]) + ")");
    }
}

AttenuationMap AttenuationMap::hounsfield(double mu_water, double mu_air) {
    if (!(std::isfinite(mu_water) && std::isfinite(mu_air) && mu_air >= 0 && mu_water > mu_air))
        throw InvalidArgument("AttenuationMap.hounsfield: need 0 <= mu_air < mu_water, both finite (got mu_water " +
                              std::to_string(mu_water) + ", mu_air " + std::to_string(mu_air) + ")");
    // The line mu_water (1 + HU / 1000) meets mu_air at this HU; below it the map is constant.
    const double knee = 1000.0 * (mu_air / mu_water - 1.0);
    return AttenuationMap({knee, kHounsfieldTop}, {mu_air, mu_water * (1.0 + kHounsfieldTop / 1000.0)});
}

double AttenuationMap::operator()(double value) const {
    if (!(value > values_.front())) return attenuation_.front();
    if (!(value < values_.back())) return attenuation_.back();
    const size_t i = size_t(std::upper_bound(values_.begin(), values_.end(), value) - values_.begin());
    const double t = (value - values_[i - 1]) / (values_[i] - values_[i - 1]);
    return attenuation_[i - 1] + t * (attenuation_[i] - attenuation_[i - 1]);
}

Grid AttenuationMap::apply(const Grid& grid) const {
    const openvdb::FloatGrid& source = *grid.data()->vdb;
    openvdb::FloatGrid::Ptr mapped = source.deepCopy();
    // Inactive voxels are nothing to an X-ray: a background of 0 keeps them so for the levels too.
    mapped->tree().root().setBackground(0.0f, /*updateChildNodes=*/true);
    openvdb::tools::foreach(mapped->beginValueOn(), [this](const openvdb::FloatGrid::ValueOnIter& it) {
        it.setValue(float((*this)(double(*it))));
    });
    return Grid(std::make_shared<Grid::Data>(std::move(mapped), grid.source_path()), grid.index_to_world(), grid.name());
}

}  // namespace pcvr
