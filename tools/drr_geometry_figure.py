# SPDX-License-Identifier: GPL-3.0-or-later

"""docs/img/drr_geometry.png: the C-arm geometry of pcvr_native.cameras.cone_beam seen from the feet (LPS, patient's
left on the right, anterior at the top), beside DRRs it gives of the CT head phantom (tools/ct_head.py) at gantry 0
and 90 (line integrals, white where they are largest). Needs matplotlib (the bench's dependencies):

    PYTHONPATH=. .venv/bin/python tools/drr_geometry_figure.py [OUTPUT.png]
"""

import math
import os
import sys

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

import pcvr_native as pn  # noqa: E402
from pcvr_native.cameras import cone_beam  # noqa: E402

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import ct_head  # noqa: E402

SAD, SID = 600.0, 1000.0           # millimetres: a short C-arm, so that the drawing stays readable
DETECTOR, SPACING = (200, 200), (2.0, 2.0)
GANTRY = 30.0                      # the drawn gantry angle
HEAD_MM = 200.0                    # the phantom's [-1, 1]^3 spans this many millimetres
MU_WATER_PER_MM = 0.0193


def _dimension(ax, start, end, side, text):
    """A double arrow from `start` to `end` moved by `side`, labelled `text` beside its middle."""
    start, end = np.asarray(start) + side, np.asarray(end) + side
    ax.annotate("", end, start, arrowprops=dict(arrowstyle="<->", lw=0.8))
    ax.annotate(text, (start + end) / 2 + 1.6 * side, fontsize=8, ha="center", va="center")


def draw_geometry(ax):
    g = math.radians(GANTRY)
    to_source = np.array([math.sin(g), -math.cos(g)])         # Rz(gantry) (0, -1), in the axial plane
    right = np.array([math.cos(g), math.sin(g)])              # the image's right, seen from the source
    source = SAD * to_source
    centre = source - SID * to_source
    half = DETECTOR[0] * SPACING[0] / 2
    ends = [centre - half * right, centre + half * right]
    ax.add_patch(matplotlib.patches.Ellipse((0, 0), 0.69 * HEAD_MM, 0.92 * HEAD_MM, color="0.85"))
    for end in ends:
        ax.plot(*zip(source, end), color="tab:orange", lw=0.8)
    ax.plot(*zip(*ends), color="k", lw=4, solid_capstyle="butt")
    ax.plot(*zip(source, centre), "k--", lw=0.8)
    ax.plot(*source, "o", color="tab:red", ms=7)
    ax.plot(0, 0, "k+", ms=10)
    ax.plot([0, 0], [0, -SAD * 1.05], ":", color="0.4", lw=0.8)
    arc = np.radians(np.linspace(0, GANTRY, 20))
    ax.plot(0.5 * SAD * np.sin(arc), -0.5 * SAD * np.cos(arc), color="tab:blue")
    ax.annotate(f"gantry {GANTRY:g}°", (-0.02 * SAD, -0.62 * SAD), color="tab:blue", fontsize=8, ha="right")
    ax.annotate("source", source + (30, 0), fontsize=8, color="tab:red", va="center")
    _dimension(ax, source, (0, 0), 70 * right, "SAD")
    _dimension(ax, source, centre, -260 * right, "SID")
    ax.annotate("detector", ends[0] + (-20, 70), fontsize=8, ha="center")
    ax.annotate("image right", ends[1] + (10, 40), fontsize=8)
    ax.annotate("isocentre", (25, 70), fontsize=8)
    ax.set_xlim(-650, 650)
    ax.set_ylim(650, -700)  # y (posterior) down: anterior at the top
    ax.set_aspect("equal")
    ax.set_xticks([])
    ax.set_yticks([])
    ax.set_xlabel("+x: patient's left", fontsize=8)
    ax.set_ylabel("-y: anterior (up)", fontsize=8)
    ax.set_title("seen from the feet (LPS, mm)", fontsize=9)


def drr(grid, gantry):
    """The line integrals of the attenuation from the gantry angle `gantry`."""
    cam = cone_beam(SAD, SID, DETECTOR, SPACING, (0.0, 0.0, 0.0), gantry)
    return pn.render_xray(grid, cam, attenuation=pn.AttenuationMap.hounsfield(MU_WATER_PER_MM))


def main(output):
    values, index_to_world = ct_head.hounsfield_head(128)
    index_to_world = np.diag([HEAD_MM / 2] * 3 + [1.0]) @ index_to_world
    # The phantom's +z is its top; LPS has the head at +z too.
    grid = pn.Grid.from_dense(values, index_to_world, background=ct_head.AIR)
    fig, axes = plt.subplots(1, 3, figsize=(8.4, 3.0), gridspec_kw={"width_ratios": [1.15, 1, 1]})
    draw_geometry(axes[0])
    for ax, gantry in zip(axes[1:], (0.0, 90.0)):
        ax.imshow(drr(grid, gantry), cmap="gray", vmin=0)
        ax.set_title(f"DRR (line integral), gantry {gantry:g}°", fontsize=9)
        ax.set_xticks([])
        ax.set_yticks([])
    fig.tight_layout()
    fig.savefig(output, dpi=90)
    print(f"wrote {output} ({os.path.getsize(output) // 1024} KB)")


if __name__ == "__main__":
    main(sys.argv[1] if len(sys.argv) > 1 else os.path.join(os.path.dirname(__file__), "..", "docs", "img",
                                                             "drr_geometry.png"))
