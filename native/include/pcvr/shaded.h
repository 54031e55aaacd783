/// @file shaded.h
/// @brief Shaded volume rendering and maximum intensity projection by image-aligned sheet-buffered
/// splatting, with post-convolution on every sheet (the paper's full volume rendering).
///
/// Sheets are planes of constant depth `sheet_spacing` voxels apart, from the near clip plane on. Each
/// voxel's kernel is cut into slabs by them (slab_footprint.h) and splatted front to back into the few
/// sheets it reaches; each sheet is then post-convolved from the subgrid to the pixels (pcvr, bilinear
/// spreading) before anything nonlinear happens to it, classified through the transfer function,
/// shaded with the density gradient and composited front to back:
///
/// | method            | a sheet is splatted into      | then, per sheet                            |
/// |-------------------|-------------------------------|--------------------------------------------|
/// | "regular"         | the image (stride 1)          | classify, shade, composite                 |
/// | "pcvr"            | the stride-L subgrid          | post-convolve, classify, shade, composite  |
/// | "bilinear_spread" | the subgrid, 2 x 2 per slab   | post-convolve, classify, shade, composite  |
/// | "raycast"         | - (raycast_reference.h: point samples along each ray, the reference) |
///
/// A sheet holds the integral of the density over its slab along each pixel's ray; divided by the
/// ray's length in the slab it is the slab's mean density, which the transfer function classifies
/// (opacity corrected for that length). The gradient comes from central differences within the sheet,
/// one subgrid node (L pixels) apart, and across the sheets before and after. Space where no voxel's
/// kernel reaches (reconstructed density exactly 0) is empty whatever the transfer function says.
///
/// Work is split into image tiles that each walk their sheets front to back on one thread (results do
/// not depend on the thread count). What cannot change the image is skipped and counted: blocks outside
/// the view or clip range, blocks whose values (with their neighbours') are transparent under the
/// transfer function, voxels whose footprint lies on pixels already opaque (the occlusion map), tiles
/// a sheet did not touch, and tiles that became opaque.
#pragma once

#include <algorithm>

#include <array>
#include <cstdint>
#include <string>
#include <vector>

#include "pcvr/camera.h"
#include "pcvr/clip_region.h"
#include "pcvr/grid.h"
#include "pcvr/grid_stream.h"
#include "pcvr/render_control.h"
#include "pcvr/shading.h"
#include "pcvr/transfer_function.h"
#include "pcvr/zeroed_buffer.h"

namespace pcvr {

enum class ShadedMethod { Regular, Pcvr, BilinearSpread, Raycast };

/// Parses "regular", "pcvr", "bilinear_spread" or "raycast"; throws InvalidArgument listing the names.
ShadedMethod shaded_method_from_name(const std::string& name);

/// How the sheet renderer fills a grid's sheets (src/shaded/sheets/sheet_sampling.h).
enum class SheetFill {
    /// `pcvr`'s shaded renders sample a grid's sheets where every block of it is splatted at stride 1
    /// (no post-convolution: the footprints are a few pixels) and its lattice fits (PrefilteredLattice::bytes
    /// at most a quarter of default_memory_limit()); they splat elsewhere, and other methods and MIP always do.
    Automatic,
    Splat,   ///< always splat
    Sample,  ///< `pcvr`'s shaded renders sample every grid whose lattice fits, at stride 1
};

/// Parses "auto", "splat" or "sample"; throws InvalidArgument listing the names.
SheetFill sheet_fill_from_name(const std::string& name);

/// How the sheet renderers classify the density between consecutive samples along a ray.
enum class Classification {
    Automatic,      ///< the measured best (docs/how-it-works.md, "Pre-integrated classification")
    Point,          ///< the transfer function at each sample, for its stretch of ray
    Preintegrated,  ///< each stretch from the densities at its two ends (src/shaded/classify/preintegration.h)
};

/// Parses "auto", "point" or "preintegrated"; throws InvalidArgument listing the names.
Classification classification_from_name(const std::string& name);

struct ShadedParams {
    ShadedMethod method = ShadedMethod::Pcvr;
    std::string splat_kernel = "gauss1.4";
    /// Catmull-Rom by default: it interpolates the subgrid with continuous slopes, which measured as
    /// good as or better than the bilinear filter on every shaded scene, by up to 3.6 dB on coarse data
    /// (docs/how-it-works.md, "Choosing the defaults"); the Gaussians blur surfaces.
    std::string post_filter = "catmull_rom";
    int stride = 0;               ///< subgrid stride in pixels; 0 = automatic per grid; at most 256, the tile size and the image's smaller side
    double sheet_spacing = 1.0;   ///< voxels along the view direction between sheets (raycast: between samples)
    /// Classified samples from one sheet to the next (density and gradient interpolated between them):
    /// 2 halves the sheets' terraces for 10-30% more time, 2-3 dB nearer the ray caster.
    int samples_per_sheet = 2;
    double opacity_cutoff = 0.99; ///< a pixel this opaque takes no more samples (1: never stop)
    int threads = 0;              ///< 0 = all cores
    int tile_size = 0;            ///< pixels per tile side; 0 = automatic
    int pixel_step = 1;           ///< raycast only: render every step-th pixel in each direction
    bool cull_transparent = true; ///< skip blocks the transfer function makes invisible (exact; off to compare)
    bool depth = false;           ///< also fill RgbaImage::depth (for a Depth pass)
    /// Level of detail (Grid::level, inactive voxels counting as the background: means for shaded
    /// rendering, maxima for MIP) every grid is rendered from, by every method; -1: each grid's coarsest
    /// level whose voxels project small enough that the image stays near level 0's (src/shaded/classify/shaded_levels.h).
    /// Sheets are `sheet_spacing` voxels of the level apart. 0 (the grids themselves) by default.
    int level = 0;
    /// Lights whose Light::shadow is Default cast shadows: their light reaches each sample through the
    /// volumes (every grid, its transfer function and clip region), attenuated by exp(-optical depth).
    /// The sheet renderers read it from a transmittance volume per light built once per render
    /// (src/shaded/light/light_volume.h); the ray caster marches a shadow ray per sample.
    bool shadows = false;
    /// Splat the sheets, or sample them where that costs less (SheetFill; ShadedStats::grids_sampled).
    SheetFill sheet_fill = SheetFill::Automatic;
    /// Point-sampled or pre-integrated classification (the ray caster always samples points, finely).
    Classification classification = Classification::Automatic;
    /// Raycast only: > 0 renders scattering media by Monte Carlo path tracing (light scattered any number of
    /// times), this many paths per pixel, seeded by `seed` (src/shaded/reference/path_tracer.h).
    int paths = 0;
    uint64_t seed = 0;
};

/// One grid in a shaded render: its transfer function, the factor its values are multiplied by
/// before classification, and its material (null: the lighting's).
struct ShadedVolume {
    const Grid* grid;
    const TransferFunction* transfer_function;
    double density_scale = 1.0;
    const Shading* material = nullptr;
    /// When set, only the part of the reconstructed field inside it is seen (world space): samples count
    /// for the share of their stretch of ray inside, and cut faces are lit by the plane's normal
    /// (src/shaded/classify/sample_clip.h).
    const ClipRegion* clip = nullptr;
    /// A colour per voxel (red, green, blue grids on this grid's voxels: the same index_to_world) that
    /// multiplies the transfer function's colour, density-weighted at each sample (src/shaded/light/albedo_field.h;
    /// Blender's Color Attribute). All null: none.
    std::array<const Grid*, 3> albedo_grids{};

    /// The render's lights with this volume's material.
    Lighting lit_by(const Lighting& lighting) const {
        Lighting out = lighting;
        if (material) out.material = *material;
        return out;
    }
};

/// Whether any volume's material asks for ambient occlusion: the renderer then builds its occluders.
inline bool any_ambient_occlusion(const std::vector<ShadedVolume>& volumes, const Lighting& lighting) {
    return std::any_of(volumes.begin(), volumes.end(),
                       [&](const ShadedVolume& v) { return (v.material ? *v.material : lighting.material).ambient_occlusion; });
}

struct ShadedStats {
    uint64_t blocks_total = 0;
    uint64_t blocks_outside = 0;      ///< outside the view or the clip range
    uint64_t blocks_clipped = 0;      ///< wholly outside their grid's clip region
    uint64_t blocks_transparent = 0;  ///< values (with their neighbours') transparent under the transfer function
    uint64_t bricks_transparent = 0;  ///< 4^3 bricks of the listed blocks left out the same way
    uint64_t voxels_transparent = 0;  ///< active voxels of the listed bricks left out one by one the same way
    uint64_t blocks_listed = 0;       ///< (block, tile) pairs to splat
    uint64_t blocks_linearised = 0;   ///< perspective: blocks whose footprints come from a model per block
    /// The sheets follow the grids' voxel metric (their voxels are cubes in it: tilted planes, spheres
    /// in index space) rather than the world's: an automatic choice, shown in the add-on's last-render line.
    bool sheets_in_voxel_metric = false;
    uint64_t voxels_splatted = 0;     ///< voxel deposits (a voxel reaching k tiles counts k times)
    uint64_t voxels_occluded = 0;     ///< deposits skipped: footprint wholly on opaque pixels
    uint64_t taps = 0;                ///< node-slab pairs the deposits covered (window nodes times slabs)
    uint64_t samples_classified = 0;  ///< pixel-samples classified (some voxel reaches them, pixel not opaque)
    uint64_t samples_shaded = 0;      ///< of those, with extinction: gradient, lighting and compositing
    uint64_t sheets = 0;              ///< sheets between the first and last reached by any voxel
    uint64_t tiles = 0;
    int tile_size = 0;                ///< pixels a tile's side (ShadedParams::tile_size, or the automatic choice)
    uint64_t tiles_terminated = 0;    ///< tiles that became opaque before their last sheet
    uint64_t tile_sheets_composited = 0;
    uint64_t tile_sheets_skipped = 0; ///< (tile, sheet) pairs between a tile's first and last sheet that no splat touched
    /// Grids whose sheets were sampled rather than splatted (SheetFill): an automatic choice, shown in
    /// the add-on's last-render line; the pixel values so interpolated, (tile, sheet, pixel) triples, and
    /// those left at 0 because no sample that may be visible reads them.
    uint64_t grids_sampled = 0;
    uint64_t sheet_samples = 0;
    uint64_t sheet_samples_skipped = 0;
    /// Sampled layers whose lattice brick visibility this render made, and those that took it from their
    /// lattice, made by an earlier render with the same transfer function's visible span (BrickVisibilityCache).
    uint64_t brick_visibility_built = 0, brick_visibility_reused = 0;
    /// The subgrid strides sampled sheets took, an automatic choice per sheet: 1 where the values are the
    /// pixels, L where a lattice element spans L pixels or more and the sheet was sampled at its stride-L
    /// subgrid and post-convolved.
    std::vector<int> sampled_strides;
    std::vector<int> strides;         ///< per grid
    int level = 0;                    ///< the coarsest level of detail a grid was rendered from
    double seconds = 0;
    double seconds_plan = 0;          ///< thread seconds per stage
    double seconds_splat = 0;
    double seconds_post_convolution = 0;
    double seconds_sampling = 0;      ///< sampled sheets' values
    double seconds_shading = 0;       ///< classification, shading and compositing
    /// "point" or "preintegrated" (ShadedParams::classification as resolved; the ray caster's: "point"),
    /// "none" for MIP; the pre-integration tables this render built (0 where each transfer function's
    /// was kept from an earlier render) and the bytes of those it used.
    std::string classification = "none";
    uint64_t preintegration_tables_built = 0;
    uint64_t preintegration_table_bytes = 0;
    uint64_t shadow_texels = 0;       ///< texels of the lights' transmittance volumes
    double seconds_shadows = 0;       ///< building them (wall seconds)
    uint64_t batches = 0;             ///< a GridStream's bricks read and rendered (0: grids in memory)
    /// A GridStream's: the most bytes the render held at once, as counted against BrickedParams::memory_limit.
    uint64_t memory_bytes = 0;
    /// Octaves of multiple scattering built (Shading::scattering_octaves; 1: single scattering only).
    int scattering_octaves = 1;
};

/// Premultiplied linear RGBA, row 0 on top.
struct RgbaImage {
    int width = 0, height = 0;
    ZeroedBuffer<float> pixels;  ///< width * height * 4
    /// With ShadedParams::depth: per pixel, the depth (camera-space units along the view axis) of the
    /// sample at which the accumulated opacity first reached one half; infinity where it never did.
    ZeroedBuffer<float> depth;
};

/// Maximum density along each ray, row 0 on top.
struct MipImage {
    int width = 0, height = 0;
    ZeroedBuffer<float> pixels;
};

/// Throws InvalidArgument, GridError or CameraError up front; Cancelled when `control` asks. With
/// pixel_step > 1 (raycast) the image is ceil(height / step) x ceil(width / step).
RgbaImage render_shaded(const std::vector<ShadedVolume>& volumes, const Camera& camera, const Lighting& lighting,
                        const ShadedParams& params, RenderControl& control, ShadedStats* stats = nullptr);

/// The maximum of each grid's reconstructed density (times its scale) along each ray: the largest slab
/// mean over the sheets, and never less than mip_background (every ray also crosses the background).
/// Transfer functions are not used.
MipImage render_mip(const std::vector<ShadedVolume>& volumes, const Camera& camera, const ShadedParams& params,
                    RenderControl& control, ShadedStats* stats = nullptr);

/// How a GridStream renders shaded or MIP: in bricks (boxes of voxels, each read with the margin its
/// kernels, filters and gradients reach across its faces), front to back in visibility order, each continuing
/// the image the ones before it left; bricks as large as `memory_limit` (0: none) lets the render's working set
/// be (the image, the threads' tile buffers, one brick's values and what the renderer builds over them) and
/// of at most `brick_bytes` of values (0: the stream's batch_bytes, or GridStream::kDefaultBatchBytes where
/// there is no memory_limit either). `shares` > 1 renders only share `share` of the bricks in that order: the
/// shares' images composited front to back in share order (over for shaded, the maximum for MIP) make the whole
/// image (pcvr_addon/batch splits a frame so).
struct BrickedParams {
    uint64_t memory_limit = 0;
    uint64_t brick_bytes = 0;
    size_t share = 0, shares = 1;
};

/// A GridStream's shaded image: as render_shaded of the grid read whole (`volume` says everything but the
/// grid, which is ignored), to within float rounding. Refused (InvalidArgument, naming the grid and file):
/// shadows, ambient occlusion and albedo grids (they need every voxel at once), method "raycast".
/// ShadedParams::level > 0 or -1 ("auto", where it picks a coarse level) renders that level, made from
/// the file a batch at a time and kept with the stream, whole.
RgbaImage render_shaded(const GridStream& stream, const ShadedVolume& volume, const Camera& camera, const Lighting& lighting,
                        const ShadedParams& params, const BrickedParams& bricked, RenderControl& control, ShadedStats* stats = nullptr);
/// A GridStream's MIP, as render_mip of the grid read whole.
MipImage render_mip(const GridStream& stream, const ShadedVolume& volume, const Camera& camera, const ShadedParams& params,
                    const BrickedParams& bricked, RenderControl& control, ShadedStats* stats = nullptr);

/// The largest background (times its scale) of the volumes, 0 for none: beyond its active voxels a
/// grid's density is its background, so this is the maximum along a ray that meets no voxel.
double mip_background(const std::vector<ShadedVolume>& volumes);

}  // namespace pcvr
