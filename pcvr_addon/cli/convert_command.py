# SPDX-License-Identifier: GPL-3.0-or-later

"""The command line's scans: `convert INPUT -o OUTPUT.vdb`, and `render` of a scan through a cached .vdb.

    python -m pcvr_addon convert ct_series/ -o ct.vdb [--series INDEX|UID] [--frame N]
    python -m pcvr_addon render brain.nii.gz -o brain.png --mode shaded --preset "MR Default"

INPUT: a DICOM folder (searched with its subfolders) or one file of a series, .nii/.nii.gz, .nrrd/.nhdr,
.mha/.mhd, .tif/.tiff (OME-TIFF and ImageJ stacks included), a folder of single-plane .tif files. See
volume_import for the conventions.
"""

import os
import sys

from .. import volume_import


def add_parser(commands):
    convert = commands.add_parser(
        "convert", help="Convert a DICOM series, NIfTI, NRRD, MetaImage or TIFF stack to a .vdb",
        description="Convert a scan to a .vdb: a float grid 'density' in the scan's units (HU for CT), "
                    "placed in LPS millimetres, with the scan's modality, units and a description (nothing "
                    "that identifies a patient) as metadata.")
    convert.add_argument("input", metavar="INPUT", help="a DICOM folder or file, .nii(.gz), .nrrd, .nhdr, "
                                                        ".mha, .mhd, .tif or .tiff, or a folder of .tif planes")
    convert.add_argument("-o", "--output", metavar="OUTPUT", required=True, help="the .vdb to write")
    add_scan_options(convert)
    convert.add_argument("--frame", type=int, help="4-D NIfTI or TIFF time series: the volume to convert")


def add_scan_options(parser):
    parser.add_argument("--series", metavar="INDEX|UID",
                        help="DICOM: the series to convert when a folder holds several (they are listed)")


def main(args):
    """`convert`: 0 on success, 1 with the cause on stderr."""
    if not args.output.lower().endswith(".vdb"):
        print(f"pcvr: OUTPUT must be a .vdb file, not '{args.output}'", file=sys.stderr)
        return 1
    try:
        volume = volume_import.convert(args.input, args.output, series=args.series, frame=args.frame)
    except volume_import.ScanError as ex:
        print(f"pcvr: {ex}", file=sys.stderr)
        return 1
    print(f"pcvr: wrote {args.output}: {volume.description()}")
    return 0


def render_input(args):
    """For `render` of a scan: convert it (or reuse its cached .vdb) and point args.input at the .vdb.
    Returns 0, or 1 with the cause on stderr."""
    if not volume_import.is_scan(args.input):
        if args.series is not None:
            print("pcvr: --series picks a DICOM series; INPUT is a .vdb or .blend", file=sys.stderr)
            return 1
        return 0
    from ..volume_import.vdb_cache import cached_vdb

    try:
        args.input, volume = cached_vdb(os.path.abspath(args.input), series=args.series, frame=args.frame)
    except volume_import.ScanError as ex:
        print(f"pcvr: {ex}", file=sys.stderr)
        return 1
    print(f"pcvr: {volume.description()}, as {args.input}")
    return 0
