# SPDX-License-Identifier: GPL-3.0-or-later

"""What a render tells the user: the progress line while it runs, the status line and the interface's rows after."""

import time

# The statistics of the last render of each scene, for the interface: {scene.session_uid: (mode, stats)}
# (session_uid: unique in this Blender session, so a scene of another file never shows these).
last_render = {}


def format_strides(strides):
    """Subgrid strides for display: X-ray strides are pixels between nodes and need not be whole."""
    return ", ".join(f"{stride:.2f}".rstrip("0").rstrip(".") for stride in strides) or "-"


class ProgressReport:
    """The progress callback of an F12 render: Blender's progress bar, and a status line with the voxels
    splatted so far (X-ray, where the native progress runs over them) and an estimate of the time left."""

    INTERVAL = 0.25  # seconds between status lines

    def __init__(self, engine, voxels=None, clock=time.monotonic):
        self.engine, self.voxels, self.clock = engine, voxels, clock
        self.start = clock()
        self.shown = None

    def __call__(self, fraction):
        self.engine.update_progress(fraction)
        now = self.clock()
        if self.shown is not None and now - self.shown < self.INTERVAL:
            return
        self.shown = now
        self.engine.update_stats("", progress_line(fraction, now - self.start, self.voxels))


def progress_line(fraction, elapsed, voxels=None):
    """"Splatting 12.3M of 134.2M voxels | 4 s left": the status line of a render `fraction` done after
    `elapsed` seconds (the time left extrapolated once 2% is done)."""
    done = f"Splatting {_millions(fraction * voxels)} of {_millions(voxels)} voxels" if voxels \
        else f"Rendering {100 * fraction:.0f}%"
    if fraction < 0.02 or fraction >= 1:
        return done
    return f"{done} | {elapsed * (1 - fraction) / fraction:.0f} s left"


def _millions(count):
    return f"{count / 1e6:.1f}M"


def format_stats(stats):
    """One line for the status bar from render_xray's statistics."""
    if not stats:
        return "No volume in view"
    low, high = stats["magnification"], stats["magnification_max"]
    magnification = f"{low:.2f}" if high - low < 0.005 else f"{low:.2f}-{high:.2f}"
    strides = format_strides(stats["strides"])
    streamed = ""
    if stats.get("streamed"):
        count, batches = stats["streamed"], stats["batches"]
        streamed = (f" | Streamed {count} volume{'s' if count > 1 else ''} from "
                    f"{'their files' if count > 1 else 'its file'} in {batches} batch{'es' if batches > 1 else ''}")
    return (f"Voxels {stats['voxels']:,} | Magnification {magnification} px/voxel | Stride {strides} | "
            f"Time {stats['seconds']:.2f} s{streamed}{_automatic_choices(stats)}")


def _automatic_choices(stats):
    """What the renderer chose for itself: a coarser level of detail or sub-pixels it averaged (zoomed
    out), sheets following the voxels' shape (anisotropic voxels, shaded and MIP), sheets sampled
    rather than splatted (low magnification, shaded)."""
    level = f" | Level of detail {stats['level']}" if stats.get("level") else ""
    sub = stats.get("supersampling", 1)
    metric = " | Sheets in the voxels' metric" if stats.get("sheet_metric") == "voxels" else ""
    sampled = stats.get("grids_sampled", 0)
    subgrids = [s for s in stats.get("sampled_strides", []) if s > 1]
    post = f", post-convolved at stride {format_strides(subgrids)}" if subgrids else ""
    sampling = f" | Sheets sampled ({sampled} volume{'s' if sampled > 1 else ''}{post})" if sampled else ""
    octaves = stats.get("scattering_octaves", 1)
    scattering = f" | Multiple scattering ({octaves} octaves)" if octaves > 1 else ""
    return level + (f" | Supersampled {sub} x {sub}" if sub > 1 else "") + metric + sampling + scattering


def status_line(mode, stats):
    """The status bar's line after a render in `mode` with the native statistics `stats`."""
    return format_stats(stats) if mode == 'XRAY' else format_sheet_stats(stats)


def format_sheet_stats(stats):
    """One line for the status bar from render_shaded's or render_mip's statistics."""
    if not stats:
        return "No volume in view"
    culled = stats["blocks_outside"] + stats["blocks_transparent"]
    strides = format_strides(stats["strides"])
    return (f"{_drawn(stats)} | Culled blocks {culled:,} of {stats['blocks']:,} | "
            f"Sheets {stats['sheets']:,} | Stride {strides} | Time {stats['seconds']:.2f} s{_automatic_choices(stats)}")


def _drawn(stats):
    """What a shaded or MIP render drew from: the voxels it splatted, the values it sampled into the sheets
    (low magnification), or both."""
    voxels, samples = stats["voxels"], stats.get("sheet_samples", 0)
    parts = ([f"Voxels {voxels:,}"] if voxels or not samples else []) + ([f"Samples {samples:,}"] if samples else [])
    return " | ".join(parts)


def _share(part, whole):
    return f"{part:,} ({100 * part / whole:.0f}%)" if whole else f"{part:,}"


# What clipping (scene/clipping.py) saved and cost: (label, native statistic).
CLIP_ROWS = (("Blocks cut away", "blocks_clipped"), ("Voxels cut through", "voxels_cut"))


def statistics_rows(mode, stats):
    """(label, value) rows of a render's statistics, for the interface."""
    if not stats:
        return [("Volumes", "none in view")]
    return _mode_rows(mode, stats) + [(label, f"{stats[key]:,}") for label, key in CLIP_ROWS if stats.get(key)]


def _mode_rows(mode, stats):
    if mode == 'XRAY':
        return [("Voxels", f"{stats['voxels']:,}"),
                ("Magnification", f"{stats['magnification']:.2f} - {stats['magnification_max']:.2f} px/voxel"),
                ("Stride", format_strides(stats["strides"])),
                ("Level of detail", f"{stats.get('level', 0)}"),
                ("Supersampling", f"{stats.get('supersampling', 1)} x {stats.get('supersampling', 1)} sub-pixels"),
                ("Time", f"{stats['seconds']:.3f} s")]
    seconds = [("Planning", "seconds_plan"), ("Splatting", "seconds_splat"), ("Sampling", "seconds_sampling"),
               ("Post-convolution", "seconds_post_convolution"), ("Shading", "seconds_shading")]
    return [
        ("Blocks", f"{stats['blocks']:,}"),
        ("Outside view", _share(stats["blocks_outside"], stats["blocks"])),
        ("Transparent", _share(stats["blocks_transparent"], stats["blocks"])),
        # Of the listed blocks' voxels, those left out one by one (their neighbourhood is transparent).
        ("Transparent voxels", _share(stats.get("voxels_transparent", 0),
                                      stats["voxels"] + stats["voxels_occluded"] + stats.get("voxels_transparent", 0))),
        ("Voxels splatted", f"{stats['voxels']:,}"),
        # Low magnification: sheets filled from the volume where samples may be seen (sheet_sampling.h).
        ("Sheets sampled", f"{stats.get('grids_sampled', 0):,} volume(s), {stats.get('sheet_samples', 0):,} values, "
                           f"{stats.get('sheet_samples_skipped', 0):,} left transparent"
                           + (f", subgrid strides {format_strides(stats['sampled_strides'])}" if stats.get("sampled_strides") else "")),
        ("Behind opaque", _share(stats["voxels_occluded"], stats["voxels"] + stats["voxels_occluded"])),
        ("Sheets", f"{stats['sheets']:,}" + (" (in the voxels' metric)" if stats.get("sheet_metric") == "voxels" else "")),
        ("Tiles", f"{stats['tiles']:,} of {stats['tile_size']} px" if stats.get("tile_size") else f"{stats['tiles']:,}"),
        ("Tiles finished early", _share(stats["tiles_terminated"], stats["tiles"])),
        ("Empty tile sheets", _share(stats["tile_sheets_skipped"],
                                     stats["tile_sheets_skipped"] + stats["tile_sheets_composited"])),
        ("Stride", format_strides(stats["strides"])),
        ("Time", f"{stats['seconds']:.3f} s"),
    ] + [(label, f"{stats[key]:.3f} s (threads)") for label, key in seconds] + _shadow_rows(stats)


def _shadow_rows(stats):
    """The lights' transmittance volumes, where the render had shadows."""
    if not stats.get("shadow_texels"):
        return []
    octaves = stats.get("scattering_octaves", 1)
    scattering = [("Scattering octaves", f"{octaves}")] if octaves > 1 else []
    return [("Shadow texels", f"{stats['shadow_texels']:,}"), ("Shadows", f"{stats['seconds_shadows']:.3f} s")] + scattering
