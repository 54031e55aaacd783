/// @file shaded_levels.h
/// @brief The levels of detail a shaded or MIP render draws its volumes from (ShadedParams::level).
///
/// Shaded rendering and MIP see the density beyond the active voxels as the grid's background (air at
/// -1000 in a CT scan), so their levels count inactive voxels as the background, where the X-ray's
/// count them as nothing: a CT scan's skin averaged with 0 would turn into soft tissue. Shaded levels
/// are means (LevelReduction::MeanOverBackground), MIP's maxima (MaxOverBackground: a mean is lower
/// than the maximum it stands for, and a skull two voxels thick lost 28% of its MIP at level 1). A
/// level stands in for its grid with the same kernel in its own index units, and the sheets are spaced
/// in its voxels. A transfer function's default unit is its grid's voxel spacing; that is taken from
/// level 0, so that a level changes the opacities only through the densities it averages.
#pragma once

#include <algorithm>
#include <deque>
#include <vector>

#include "pcvr/shaded.h"
#include "view/level_of_detail.h"

namespace pcvr {

/// Automatic levels keep the coarse voxels at most this many pixels wide (where they are most
/// magnified). Against level 0 itself a level's image differs at every magnification (both sample
/// the volume at the pixels' centres, and the transfer function is not linear: a level-1 CT phantom is
/// 16-18% off in RGBA from 1/2 to 1/32), so the measure is level 0's pixel means (rendered at 4 x 4 times
/// the pixels, box-averaged), from which level 0 itself is 20-63 dB away when minified: at most 1/8 of a
/// pixel, a level was never more than 1.8 dB farther from them than level 0 (CT phantom and blobs, 64^3
/// and 128^3, magnifications 1/2 to 1/64, tests/bench/shaded_levels.py), often nearer; at 1/4, level 3
/// of the 128^3 phantom lost 3.1 dB (its skull, two voxels thick, averaged into air). Not the default:
/// docs/how-it-works.md, "Levels of detail in shaded rendering and MIP".
constexpr double kShadedLevelPixelsPerVoxel = 1.0 / 8.0;

/// The smallest distance between neighbouring voxels in world units (a transfer function's default unit).
inline double smallest_voxel_spacing(const Grid& grid) {
    const Mat4& m = grid.index_to_world();
    return std::min({length(m.column(0)), length(m.column(1)), length(m.column(2))});
}

/// The volumes of a render at their levels of detail, their transfer functions' units resolved. Holds what they point to: not copyable.
class LevelledVolumes {
public:
    /// `level` >= 0 for every grid, -1 for each grid's automatic level.
    LevelledVolumes(const std::vector<ShadedVolume>& volumes, const Camera& camera, int level, LevelReduction reduction) {
        grids_.reserve(volumes.size());  // volumes_ point into both
        transfer_functions_.reserve(volumes.size());
        for (const ShadedVolume& v : volumes) {
            const int k = level >= 0 ? level : automatic_level(*v.grid, camera, kShadedLevelPixelsPerVoxel);
            level_ = std::max(level_, k);
            grids_.push_back(v.grid->level(k, reduction));
            ShadedVolume at_level = v;
            at_level.grid = &grids_.back();
            // Colours per voxel follow their grid to its level (means, as the density's).
            for (const Grid*& colour : at_level.albedo_grids)
                if (colour && k > 0) colour = &albedo_grids_.emplace_back(colour->level(k, reduction));
            if (v.transfer_function) {
                transfer_functions_.push_back(*v.transfer_function);
                if (!(transfer_functions_.back().unit_distance > 0))
                    transfer_functions_.back().unit_distance = smallest_voxel_spacing(*v.grid);
                at_level.transfer_function = &transfer_functions_.back();
            }
            volumes_.push_back(at_level);
        }
    }
    LevelledVolumes(const LevelledVolumes&) = delete;
    LevelledVolumes& operator=(const LevelledVolumes&) = delete;

    const std::vector<ShadedVolume>& volumes() const { return volumes_; }
    /// The coarsest level of any grid.
    int level() const { return level_; }

private:
    std::vector<Grid> grids_;
    std::deque<Grid> albedo_grids_;  // a deque: volumes_ point into it as it grows
    std::vector<TransferFunction> transfer_functions_;
    std::vector<ShadedVolume> volumes_;
    int level_ = 0;
};

}  // namespace pcvr
