# SPDX-License-Identifier: GPL-3.0-or-later

"""Batches: many images (sequences, view sweeps, job files) rendered in one process or over Dask distributed,
and X-rays of volumes bigger than one worker summed over several (split_xray.py). See
docs/rendering-at-scale.md. Nothing here is imported by the add-on in Blender; only dask_runner.py and
split_xray.py import `distributed`, when they run."""
