"""The volumes the X-ray comparison runs on: chosen so that the methods come apart.

| key      | volume (``pcvr_native.phantoms``)           | what it tells apart                              | analytic X-ray |
|----------|---------------------------------------------|--------------------------------------------------|----------------|
| blobs    | ``gaussian_blobs``: 9 Gaussians, sigma 1.2-4 | blur of each reconstruction (kernel + post filter) | yes            |
| ct       | ``ct_phantom``: Shepp-Logan head, 1-voxel edges | aliasing of the splat kernel (the paper's case)  | no             |
| ml       | ``marschner_lobb`` at 41^3: the standard test | reconstruction of a signal close to Nyquist      | no             |
| sparse   | ``sparse_cloud``: 15% of voxels non-zero    | empty-space cost, soft-edged structure           | no             |

Sizes are small enough for the peers (Cycles path-traces every pixel, so its time grows with the
magnification squared) and large enough for PCVR to be timed reliably. Every volume spans [-1, 1]^3,
axis-aligned, so VTK's image data (origin + spacing) holds it as Blender and PCVR see it.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Callable

import numpy as np
from pcvr_native import phantoms


@dataclass(frozen=True)
class Dataset:
    key: str
    label: str
    what: str
    make: Callable[[int], phantoms.Phantom]
    size: int
    quick_size: int
    blobs: tuple | None = None   # (centre_ijk, sigma, amplitude) triples when the X-ray is analytic

    def phantom(self, quick: bool = False) -> phantoms.Phantom:
        return self.make(self.quick_size if quick else self.size)

    def truth(self, phantom: phantoms.Phantom, camera, pixel_step: int = 1, quick: bool = False):
        """The analytic X-ray of the continuous signal that was sampled (no reconstruction kernel:
        kernel_variance 0), or None. Every method's blur then counts as error."""
        if self.blobs is None:
            return None
        n = self.quick_size if quick else self.size
        return phantoms.gaussian_blobs_xray(blob_list(self.blobs, n), camera, phantom.index_to_world,
                                            kernel_variance=0.0, pixel_step=pixel_step)


# Blob centres as fractions of the volume edge, sigmas in voxels at the full size (scaled with the
# size, so the quick run shows the same picture), amplitudes.
BLOBS = (
    ((0.50, 0.50, 0.50), 4.0, 1.0),
    ((0.30, 0.35, 0.55), 2.5, 1.5),
    ((0.70, 0.30, 0.40), 1.6, 2.0),
    ((0.65, 0.70, 0.60), 2.0, 1.2),
    ((0.35, 0.70, 0.35), 1.2, 2.5),
    ((0.50, 0.25, 0.70), 1.4, 2.0),
    ((0.25, 0.50, 0.30), 3.0, 0.8),
    ((0.75, 0.55, 0.75), 1.3, 2.2),
    ((0.55, 0.60, 0.25), 2.2, 1.0),
)
BLOB_SIZE = 64


def blob_list(blobs, n: int):
    # Sigmas stay at least 1.2 voxels, where a sampled Gaussian's lattice sum equals its integral
    # (the analytic image's premise, see phantoms.gaussian_blobs_xray).
    return [(tuple(f * (n - 1) for f in c), max(1.2, s * n / BLOB_SIZE), a) for c, s, a in blobs]


def _blobs(n: int) -> phantoms.Phantom:
    return phantoms.gaussian_blobs(n, blob_list(BLOBS, n), phantoms.centred_transform((n, n, n), 2.0 / n))


DATASETS = [
    Dataset("blobs", "Gaussian blobs", "9 sampled Gaussians, sigma 1.2 to 4 voxels; analytic X-ray", _blobs,
            BLOB_SIZE, 40, blobs=BLOBS),
    Dataset("ct", "CT head phantom", "3-D Shepp-Logan head, edges 1 voxel wide", lambda n: phantoms.ct_phantom(n),
            96, 48),
    Dataset("ml", "Marschner-Lobb", "the standard 41^3 test signal (f_M = 6, alpha = 0.25)",
            lambda n: phantoms.marschner_lobb(n), 41, 41),
    Dataset("sparse", "sparse cloud", "thresholded fractal noise, 15% of the voxels non-zero",
            lambda n: phantoms.sparse_cloud(n, seed=2), 64, 40),
]
BY_KEY = {d.key: d for d in DATASETS}


def voxel_spacing(phantom: phantoms.Phantom) -> float:
    return float(np.abs(np.linalg.det(phantom.index_to_world[:3, :3])) ** (1.0 / 3.0))
