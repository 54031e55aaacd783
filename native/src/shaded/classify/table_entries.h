/// @file table_entries.h
/// @brief A transfer function evaluated at the entries of its tables (ClassificationTable's and the
/// pre-integration's): the same kEntries + 1 densities, so both classifications read one function.
#pragma once

#include <array>
#include <vector>

#include "pcvr/transfer_function.h"

namespace pcvr {

/// Opacities this close to 1 are treated as opaque: the extinction stays finite (1 - 1e-7 per unit).
constexpr double kMostOpacity = 1.0 - 1e-7;

struct TableEntries {
    double first = 0, step = 1;  ///< entry e lies at density first + e step
    std::vector<std::array<double, 4>> rgba;      ///< kEntries + 1 of them; the opacity capped at kMostOpacity
    std::vector<std::array<double, 3>> emission;  ///< as many, or none without emission
};

/// `tf` (valid) at ClassificationTable::kEntries + 1 densities from its first control point to its last.
TableEntries table_entries(const TransferFunction& tf);

}  // namespace pcvr
