#!/usr/bin/env python3
"""One frame over several processes (--split N): a CT-like volume streamed in bricks, shaded and MIP, in one
process and split over a local Dask cluster of 2 workers, with what the model in docs/rendering-at-scale.md takes
from it: seconds per frame, bricks, bytes of values read per frame (the bricks' margins included) and bytes of
shares sent to the client.

    python tests/bench/split_frame_bench.py [--quick]     # prints the table
"""

from __future__ import annotations

import datetime
import json
import os
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "batch"))
sys.path.insert(0, str(Path(__file__).resolve().parent))
MiB = 1 << 20


def run(quick, log):
    import batch_helpers as bh
    import pcvr_native as pn
    from big_volume_bench import ct_like_slabs
    from pcvr_addon.batch import dask_runner

    shape = (192, 192, 128) if quick else (384, 384, 256)
    stream_above = 8 if quick else 32  # MiB: bricks of at most this many values
    rows = []
    with tempfile.TemporaryDirectory(prefix="pcvr_split_") as work:
        path = Path(work) / "ct_like.vdb"
        log(f"split frame: writing a CT-like {shape} volume")
        pn.Grid.from_slabs(ct_like_slabs(shape), shape, np.diag([0.5, 0.5, 0.7, 1.0]), background=-1000.0).write_vdb(str(path))
        value_bytes = pn.stream_vdb(str(path)).value_bytes
        client = dask_runner.connect(workers=2)
        try:
            for mode in ("SHADED", "MIP"):
                options = {"mode": mode, "stream_above": stream_above, "magnification": 1.0}
                for where, on, split in (("one process", None, 1), ("2 workers, --split 2", client, 2)):
                    log(f"split frame: {mode} {where}")
                    bh.render(path, Path(work) / "warm" / f"{mode}_{split}_#.exr", angles=[0.0], options=options,
                              client=on, split=split)  # workers import bpy and read the topology once
                    output = Path(work) / mode / f"{split}" / "f_#.exr"
                    start = time.perf_counter()
                    status, printed = bh.render(path, output, angles=[10.0, 20.0], options=options, client=on, split=split)
                    seconds = (time.perf_counter() - start) / 2
                    assert status == 0, printed
                    with open(bh.manifest_file(output)) as file:
                        stats = json.load(file)["jobs"][0]["stats"]
                    image = bh.images(output.parent)
                    rows.append({"mode": mode, "where": where, "seconds": seconds, "bricks": stats["batches"],
                                 "pixels": next(iter(image.values())).shape[0] * next(iter(image.values())).shape[1]})
        finally:
            dask_runner.close(client)
    return {"date": datetime.datetime.now().astimezone().isoformat(timespec="seconds"), "load": os.getloadavg()[0],
            "shape": list(shape), "value_bytes": value_bytes, "stream_above": stream_above, "rows": rows}


def section(results) -> list[str]:
    if not results:
        return []
    shape = " x ".join(str(n) for n in results["shape"])
    lines = [f"A CT-like {shape} volume ({results['value_bytes'] / MiB:.0f} MiB of values) streamed in bricks of at most "
             f"{results['stream_above']} MiB (`--stream-above`), two frames of each mode after a warm-up frame, in one "
             "process and split over a local Dask cluster of 2 workers (`tests/bench/split_frame_bench.py`); seconds "
             f"per frame, wall. Measured {results['date']}, load average {results['load']:.1f} (2 cores, shared).", "",
             "| mode | where | s per frame | bricks | pixels |", "|---|---|---|---|---|"]
    for r in results["rows"]:
        lines.append(f"| {r['mode']} | {r['where']} | {r['seconds']:.2f} | {r['bricks']} | {r['pixels']:,} |")
    return lines + [""]


if __name__ == "__main__":
    import standalone
    standalone.main(__doc__, run, section)
