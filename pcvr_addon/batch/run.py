# SPDX-License-Identifier: GPL-3.0-or-later

"""`python -m pcvr_addon render` with batch options: expand the jobs, plan them (plan.py), render them here or on
Dask (render_task.py, dask_runner.py) with a progress bar, and write the manifest (manifest.py).

    python -m pcvr_addon render DIR/frame_####.vdb --frames 1-250 -o OUT/out_####.exr --workers 4
    python -m pcvr_addon render ct.vdb --angles 0:360:2 -o drr/ct_###.exr --scheduler tcp://head:8786
    python -m pcvr_addon render jobs.json -o results.json --skip-existing
"""

import os
import sys
import time
import uuid

from ..cli import command_scene, drr
from ..io import image_io
from . import jobs as batch_jobs
from . import manifest

# The options this module adds to the render command (cli names); the others are the render's own.
BATCH_OPTIONS = ("frames", "angles", "workers", "scheduler", "skip_existing", "split")
NOT_RENDER_OPTIONS = {"command", "input", "output", *BATCH_OPTIONS}
MiB = 1 << 20


def add_arguments(render):
    """The batch options of the render command's argparse parser."""
    group = render.add_argument_group("batch (see docs/rendering-at-scale.md)")
    group.add_argument("--frames", metavar="A-B", help="render frames A to B: '#'s in INPUT and OUTPUT stand for "
                       "the frame number, e.g. smoke_####.vdb and out_####.exr")
    group.add_argument("--angles", metavar="START:STOP:STEP", help="orbit the camera about the volume (degrees, "
                       "STOP excluded): '#'s in OUTPUT stand for the angle's index")
    group.add_argument("--workers", type=int, metavar="N", help="render on a local Dask cluster of N processes")
    group.add_argument("--scheduler", metavar="ADDRESS", help="render on a running Dask cluster, e.g. tcp://head:8786")
    group.add_argument("--skip-existing", action="store_true", help="render only the images not there yet")
    group.add_argument("--split", type=int, metavar="N", help="render each frame in N shares over the workers, its "
                       "volumes above Stream Above cut into bricks (X-ray: batches) and composited in visibility order")


def wants_batch(args):
    given = [getattr(args, name) for name in BATCH_OPTIONS]
    return args.input.lower().endswith(".json") or any(value is not None and value is not False for value in given)


def run(args, parser):
    """Render the batch the command line describes; the exit status (1 when an image failed)."""
    if args.workers is not None and args.scheduler is not None:
        parser.error("--workers starts a cluster, --scheduler joins one: give one of them")
    if args.workers is not None and args.workers < 1:
        parser.error("--workers needs at least 1")
    if args.split is not None and args.split < 1:
        parser.error("--split needs at least 1")
    try:
        jobs, manifest_file = _jobs(args, parser)
    except ValueError as ex:
        parser.error(str(ex))
    for job in jobs:
        if os.path.splitext(job.output)[1].lower() not in image_io.FORMATS:
            parser.error(f"'{job.output}': OUTPUT must end in one of {', '.join(image_io.FORMATS)}")
        command_scene.check_preset(parser, job.options.get("preset"))
        problem = (command_scene.clipping_problem(job.options.get("clip_box"), job.options.get("clip_plane"))
                   or drr.problem(job.options, job.input, job.output))
        if problem:
            parser.error(f"'{job.output}': {problem}")
    if not command_scene.can_write_images():
        return 1
    client = None
    if args.workers is not None or args.scheduler is not None:
        from . import dask_runner
        try:
            client = dask_runner.connect(args.workers, args.scheduler)
        except (ImportError, OSError) as ex:  # OSError: no scheduler at that address
            print(f"pcvr: {ex}", file=sys.stderr)
            return 1
    try:
        return render_batch(jobs, manifest_file, _render_defaults(parser), client, args.skip_existing, split=args.split or 1)
    finally:
        if client is not None:
            dask_runner.close(client)


def _jobs(args, parser):
    if args.input.lower().endswith(".json"):
        if args.frames or args.angles:
            raise ValueError("a job file lists its own frames and angles: no --frames or --angles with it")
        if not args.output.lower().endswith(".json"):
            raise ValueError("with a job file as INPUT, OUTPUT is the manifest to write (.json)")
        return batch_jobs.load_job_file(args.input), args.output
    defaults = vars(_render_defaults(parser))
    options = {name: value for name, value in vars(args).items()
               if name not in NOT_RENDER_OPTIONS and value != defaults.get(name)}
    if args.angles and args.cone_beam is not None and args.gantry is not None:
        raise ValueError("--angles sweeps the C-arm's gantry: no --gantry with it")
    frames = batch_jobs.parse_frames(args.frames) if args.frames else None
    angles = batch_jobs.parse_angles(args.angles) if args.angles else None
    jobs = batch_jobs.expand(args.input, args.output, frames, angles, options)
    return jobs, manifest.manifest_path(args.output)


def _render_defaults(parser):
    """The render command's options as they are when none is given."""
    defaults = parser.parse_args(["render", "in.vdb", "-o", "out.exr"])
    for name in NOT_RENDER_OPTIONS:
        delattr(defaults, name)
    return defaults


def render_batch(jobs, manifest_file, defaults, client=None, skip_existing=False, stream=None, run_id=None, split=1):
    """Render `jobs` (batch_jobs.Job) in this process, or on the Dask cluster of `client`, and write the
    manifest to `manifest_file`. `defaults`: the render options the jobs do not set (cli's); `split`: shares of
    each frame (split_frame.py). Returns the exit status: 0 when every image is there, 1 when one failed, 130
    when interrupted."""
    from ..render import prepared_scene
    from . import dask_runner, plan, render_task, split_frame
    from .progress import ProgressBar

    stream = stream or sys.stderr
    run_id = run_id or uuid.uuid4().hex[:12]
    started = rendering = time.time()
    todo = [job for job in jobs if not (skip_existing and os.path.exists(job.output))]
    entries = {job.output: manifest.job_entry(job, status="skipped") for job in jobs}
    document = {"run_id": run_id, "scheduler": None if client is None else client.scheduler.address}

    def record(results):
        for result in results:
            entries[result.output] = manifest.job_entry(by_index[result.index], result)
            if result.errors:
                print(f"pcvr: {result.output}: {'; '.join(result.errors)}", file=stream)
        progress.advance(len(results))

    try:
        if client is not None:
            worker_total = dask_runner.worker_count(client)
            memory = dask_runner.smallest_memory_limit(client)
        else:
            import pcvr_native
            worker_total, memory = 1, pcvr_native.default_memory_limit()
        # Every image streams the volumes above the same size (unless --stream-above says), a quarter of the
        # smallest worker's memory: the threshold is part of the render's settings, not of where it runs.
        stream_above = max(1, memory // 4 // MiB) if memory else 0
        document.update(worker_count=worker_total, stream_above_mib=stream_above, split=split)
        planned = plan.plan(todo, defaults, stream_above)
        by_index = {p.index: p for p in planned}
        for p in planned:
            entries[p.job.output] = manifest.job_entry(p, status="not rendered")
        progress = ProgressBar(len(planned), stream)
        rendering = time.time()  # planned: the images' own time from here
        tasks = batch_jobs.in_groups(planned, dask_runner.task_size(len(planned), worker_total),
                                     key=lambda p: p.job.scene_key)
        if split > 1 and client is None:
            for planned_job in planned:
                record([split_frame.render_here(planned_job, run_id, split)])
        elif split > 1:
            split_frame.run_split(client, planned, run_id, split, record)
        elif client is None:
            prepare = prepared_scene.Preparer()  # shared by the tasks of this run, all in this process
            for task in tasks:
                render_task.render_task(task, run_id, progress=lambda result: record([result]), prepare=prepare)
        else:
            dask_runner.run_tasks(client, tasks, run_id, record)
    except (plan.PlanError, OSError) as ex:  # OSError: a cluster without workers
        print(f"pcvr: {ex}", file=stream)
        return 1
    except KeyboardInterrupt:
        print(f"\npcvr: interrupted; --skip-existing renders the rest (manifest {manifest_file})", file=stream)
        return 130
    finally:
        seconds = time.time() - started
        statuses = [entry["status"] for entry in entries.values()]
        counts = {status: statuses.count(status) for status in sorted(set(statuses))}
        rate = counts.get("rendered", 0) / max(time.time() - rendering, 1e-9)
        document.update(started=time.strftime("%Y-%m-%dT%H:%M:%SZ", time.gmtime(started)),
                        seconds=round(seconds, 3), images_per_second=round(rate, 3), counts=counts,
                        jobs=list(entries.values()))
        manifest.write(manifest_file, document)
        _remove_leftovers(todo)
    kind = "DRRs" if any(job.options.get("cone_beam") is not None for job in jobs) else "images"
    print(f"pcvr: {len(jobs)} images: {', '.join(f'{n} {s}' for s, n in counts.items())} in {seconds:.1f} s "
          f"({rate:.1f} {kind} per second after planning); manifest {manifest_file}", file=stream)
    return 0 if set(counts) <= {"rendered", "kept", "skipped"} else 1


def _remove_leftovers(jobs):
    """The temporary files of images whose writer died mid-write (a worker killed), found beside the images."""
    by_directory = {}
    for job in jobs:
        directory, name = os.path.split(os.path.abspath(job.output))
        by_directory.setdefault(directory, set()).add(name)
    for directory, names in by_directory.items():
        try:
            entries = os.listdir(directory)
        except OSError:
            continue
        for entry in entries:
            parts = entry.split(".")
            # image_io.write_image's temporaries: .NAME.PID.TAG.EXT
            if entry.startswith(".") and len(parts) >= 5 and ".".join(parts[1:-3]) in names:
                try:
                    os.remove(os.path.join(directory, entry))
                except OSError:
                    pass
