# SPDX-License-Identifier: GPL-3.0-or-later

"""Grids read from files, kept between renders so that an unchanged file is read only once.

A file is identified by its path, modification time and size: re-rendering a scene, or rendering the
next frame of a volume that does not change, reads nothing. The least recently used grids are
dropped once the cache holds more than `max_voxels` active voxels.
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
    def _key(filepath, grid_name):
        stat = os.stat(filepath)
        return (os.path.realpath(filepath), stat.st_mtime_ns, stat.st_size, grid_name)

    def get(self, filepath, grid_name, read):
        """The grid `grid_name` of `filepath`, calling `read(filepath, grid_name)` only when it is not
        cached. Raises FileNotFoundError for a missing file and whatever `read` raises."""
        key = self._key(filepath, grid_name)
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
            for stale in [k for k in self._grids if k[0] == key[0] and k[3] == grid_name]:
                del self._grids[stale]
            self._grids[key] = grid
            self._evict(keep=key)
        return grid

    def peek(self, filepath, grid_name):
        """The cached grid, or None; never reads."""
        try:
            key = self._key(filepath, grid_name)
        except OSError:
            return None
        with self._lock:
            return self._grids.get(key)

    def clear(self):
        with self._lock:
            self._grids.clear()
            self.stats = CacheStats()

    def _evict(self, keep):
        total = sum(grid.active_voxel_count for grid in self._grids.values())
        for key in list(self._grids):
            if total <= self.max_voxels:
                break
            if key != keep:
                total -= self._grids.pop(key).active_voxel_count


# The one cache of this Blender session.
grids = GridCache()
