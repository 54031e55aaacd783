/// @file preintegration.h
/// @brief Pre-integrated classification (Engel, Kraus and Ertl 2001): a stretch of ray whose density goes
/// linearly from d_f at its front to d_b at its back gets the transfer function's mean over [d_f, d_b].
///
/// Point sampling puts a sample's whole stretch at the density of one point, so a transfer function that
/// changes faster than the samples do (a step at a bone's threshold) is seen only where a sample happens to
/// fall, and a surface crossing the sheets obliquely shows as rings. Pre-integration takes the integral of
/// the transfer function along the stretch instead. With the density linear in the ray parameter,
///
///     optical depth = L / (d_b - d_f) * (K(d_b) - K(d_f)),   K the integral of the extinction over density,
///
/// exactly, for any length L (so no table per slab length is needed where the samples are not equally
/// spaced: each ray's own length multiplies the mean), and the colour is the extinction-weighted mean
/// (K_c(d_b) - K_c(d_f)) / (K(d_b) - K(d_f)), K_c the integral of extinction times colour: the
/// opacity-corrected form without self-attenuation (Engel et al.'s integral functions; light emitted at
/// the back of a thick stretch is not dimmed by its front more than its share of the opacity says).
/// Emission is pre-integrated the same way (its mean over [d_f, d_b]).
///
/// The density is not linear between two samples: a one-voxel bone is a thin peak along each ray, and one straight
/// line from end to end cuts under it. Each stretch is split at its middle, where the sheets' reconstruction gives
/// a third density, into two linear halves integrated apart; its optical depth and colour are the halves' sums.
/// It is lit at its middle (the sheet walk's choice: at the extinction's centroid it measured the same).
///
/// The integral functions are kept per transfer function in double (a float's 2^-24 of K over 4096
/// entries lost the extinction of a faint range behind an opaque one), unit-free (the extinction times
/// unit_distance, divided out per render), as a cumulative sum of the same 4096 entries ClassificationTable
/// interpolates: where the three densities lie within one entry of each other the mean is the point table's
/// value at their mean, so the two classifications agree where the density is constant.
#pragma once

#include <array>
#include <memory>
#include <vector>

#include "pcvr/lanes.h"
#include "pcvr/transfer_function.h"

namespace pcvr {

class PreintegrationTable {
public:
    static constexpr int kEntries = ClassificationTable::kEntries;

    explicit PreintegrationTable(const TransferFunction& tf);

    /// The table of `tf`, built on the first call and kept with it (TransferFunction::tables, which its
    /// copies share); rebuilt if tf's points changed since. `built` (optional) is set when this call built it.
    static std::shared_ptr<const PreintegrationTable> of(const TransferFunction& tf, bool* built = nullptr);
    /// How many tables have been built in this process (tests: once per transfer function).
    static uint64_t tables_built();

    size_t bytes() const;
    bool has_emission() const { return !emission_.empty(); }

    struct Slabs {  ///< eight stretches of ray
        ClassificationTable::Samples light;  ///< mean colour (extinction-weighted) and mean extinction per world unit
        ClassificationTable::Emissions glow; ///< mean emitted radiance per world unit (zero without emission)
    };
    /// Stretches from density `front` through `middle` (at their middle) to `back`, each half linear, in the lanes
    /// `lanes` (the others zero). `point` is the same transfer function's ClassificationTable for this render's
    /// unit distance.
    Slabs operator()(const ClassificationTable& point, float8 front, float8 middle, float8 back, int8x lanes) const;

private:
    bool made_from(const TransferFunction& tf) const;

    /// Per entry e of kEntries + 2 (the last repeated): the integral from entry 0 to e of channel c and its value
    /// there (piecewise linear between entries, as ClassificationTable's), channels interleaved per entry.
    template <int C>
    struct Entry {
        double integral[C];
        double value[C];
    };
    template <int C>
    static void integral_at(const std::vector<Entry<C>>& table, double x, double (&out)[C]);
    template <int C>
    static void mean_over(const std::vector<Entry<C>>& table, double x0, double x1, double (&out)[C]);
    /// One linear half of a stretch, from x0 to x1 (in entries): its means of absorption's four channels
    /// (extinction, and extinction times colour) and of the emission.
    struct Half {
        double absorption[4], emission[3];
    };
    Half half(double x0, double x1) const;

    double first_, scale_;  // entry index = (density - first) * scale, as ClassificationTable's
    std::vector<Entry<4>> absorption_;  // extinction * unit_distance, and that times red, green, blue
    std::vector<Entry<3>> emission_;    // radiance; empty without emission
    // What it was built from, to notice a changed transfer function.
    std::vector<double> density_;
    std::vector<std::array<double, 4>> rgba_;
    std::vector<std::array<double, 3>> emission_points_;
};

}  // namespace pcvr
