# SPDX-License-Identifier: GPL-3.0-or-later

"""Grids read from files, kept between renders so that an unchanged file is read only once.

A file is identified by its path, modification time and size: re-rendering a scene, or rendering the
next frame of a volume that does not change, reads nothing. The least recently used grids are
dropped once the cache holds more than `max_voxels` active voxels. Streamed grids (pcvr_native.GridStream)
are cached beside them under their own kind; they hold only their topology, about 100 bytes a leaf.
"""

import os
import threading
from collections import OrderedDict
from dataclasses import dataclass

# About 1 GiB of float voxels; a grid larger than this on its own is still kept until the next one.
MAX_VOXELS = 1 << 28


@dataclass
class CacheStats:
    reads: int = 0  # grids read from disk
    hits: int = 0   # grids served from memory


class GridCache:
    def __init__(self, max_voxels=MAX_VOXELS):
        self.max_voxels = max_voxels
        self.stats = CacheStats()
        self._grids = OrderedDict()  # key -> grid, least recently used first
        # The render thread fills the cache while the interface may look into it.
        self._lock = threading.Lock()

    @staticmethod
    def _key(filepath, grid_name, kind):
        stat = os.stat(filepath)
        return (os.path.realpath(filepath), stat.st_mtime_ns, stat.st_size, grid_name, kind)

    def get(self, filepath, grid_name, read, kind="grid"):
        """The grid `grid_name` of `filepath`, calling `read(filepath, grid_name)` only when it is not
        cached as `kind` ("grid", "stream", or "vector": a vector grid's three components). Raises
        FileNotFoundError for a missing file and whatever `read` raises."""
        key = self._key(filepath, grid_name, kind)
        with self._lock:
            grid = self._grids.get(key)
            if grid is not None:
                self._grids.move_to_end(key)
                self.stats.hits += 1
                return grid

        grid = read(filepath, grid_name)

        with self._lock:
            self.stats.reads += 1
            # An older version of the same file is stale.
            for stale in [k for k in self._grids if k[0] == key[0] and k[3:] == key[3:]]:
                del self._grids[stale]
            self._grids[key] = grid
            self._evict(keep=key)
        return grid

    def peek(self, filepath, grid_name, kind="grid"):
        """The cached grid, or None; never reads."""
        try:
            key = self._key(filepath, grid_name, kind)
        except OSError:
            return None
        with self._lock:
            return self._grids.get(key)

    def cached(self):
        """The cached grids and streams, least recently used first."""
        with self._lock:
            return list(self._grids.values())

    def clear(self):
        with self._lock:
            self._grids.clear()
            self.stats = CacheStats()

    def _evict(self, keep):
        total = sum(resident_voxels(grid) for grid in self._grids.values())
        for key in list(self._grids):
            if total <= self.max_voxels:
                break
            if key != keep:
                total -= resident_voxels(self._grids.pop(key))


def resident_voxels(grid):
    """What a cached grid holds in memory, in float voxels: a stream only its leaves' topology; a vector grid's
    components (a tuple of grids) all their voxels."""
    if isinstance(grid, tuple):
        return sum(resident_voxels(part) for part in grid)
    leaf_count = getattr(grid, "leaf_count", None)  # GridStream: about 100 bytes a leaf
    return leaf_count * 25 if leaf_count is not None else grid.active_voxel_count


# The one cache of this Blender session.
grids = GridCache()
