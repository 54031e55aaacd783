"""Cameras, framing, index-to-world transforms and rendering wrappers shared by the native and the
stress tests (importable from any test folder: tests/ is on sys.path).

Conventions (CONTRACT section 1): camera space looks down -Z, `projection` is an OpenGL clip matrix,
pixel (c, r) has its centre at NDC x = (c + 0.5) / W * 2 - 1, y = 1 - (r + 0.5) / H * 2, row 0 on top.
Images are (H, W). "Magnification" is pixels per index unit along the least magnified image
direction: the smallest singular value of the 2x3 Jacobian from index space to pixel coordinates
(the renderer picks its automatic subgrid stride from the same quantity).
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np

import pcvr_native as pn
from pcvr_native import phantoms
from pcvr_native.cameras import frustum, look_at, ortho

@dataclasses.dataclass
class CameraSpec:
    """The four arguments of pn.Camera, kept as numpy so tests can reason about the rays."""
    world_to_camera: np.ndarray
    projection: np.ndarray
    width: int
    height: int

    def camera(self):
        return pn.Camera(self.world_to_camera, self.projection, self.width, self.height)

    @property
    def orthographic(self) -> bool:
        return self.projection[3, 3] == 1.0 and not self.projection[3, :3].any()

    @property
    def pixel_size(self) -> tuple[float, float]:
        """World size of a pixel (x, y); orthographic cameras only."""
        assert self.orthographic
        return 2.0 / self.projection[0, 0] / self.width, 2.0 / self.projection[1, 1] / self.height

    def padded(self, pad: int) -> "CameraSpec":
        """The same pixel lattice extended by `pad` pixels on every side: pixel (c, r) here is
        pixel (c + pad, r + pad) there. Scaling clip x and y by W / (W + 2 pad) does it for both
        kinds of projection, because NDC is clip / w."""
        w, h = self.width + 2 * pad, self.height + 2 * pad
        s = np.diag([self.width / w, self.height / h, 1.0, 1.0])
        return CameraSpec(self.world_to_camera, s @ self.projection, w, h)

    def shifted(self, dx: float, dy: float) -> "CameraSpec":
        """The window moved by (dx, dy) pixels (right, up) in the image plane. NDC x' = x - 2 dx / W is
        clip x' = x - (2 dx / W) w, the same matrix for both kinds of projection."""
        shift = np.eye(4)
        shift[0, 3] = -2.0 * dx / self.width
        shift[1, 3] = -2.0 * dy / self.height
        return CameraSpec(self.world_to_camera, shift @ self.projection, self.width, self.height)


def volume_parts(volume):
    """(index_to_world, index bbox lo (3,), hi (3,)) of a Phantom, (values, xf) pair or pn.Grid."""
    if isinstance(volume, tuple):
        values, xf = volume
        nz = np.argwhere(np.asarray(values) != 0)
        return np.asarray(xf, dtype=np.float64), nz.min(axis=0).astype(float), nz.max(axis=0).astype(float)
    bb = np.asarray(volume.index_bbox, dtype=float).reshape(-1)  # (i0, j0, k0), (i1, j1, k1)
    return np.asarray(volume.index_to_world, dtype=np.float64), bb[:3], bb[3:]


def _corners(lo, hi):
    return np.array([[x, y, z] for x in (lo[0], hi[0]) for y in (lo[1], hi[1]) for z in (lo[2], hi[2])])


def min_singular(j: np.ndarray) -> float:
    return float(np.linalg.svd(j, compute_uv=False).min())


def frame_ortho(volume, magnification: float, direction=(0.0, 0.0, -1.0), up=(0.0, 0.0, 1.0), margin: int = 3,
                radius: float = 2.0, offset=(0.0, 0.0)) -> CameraSpec:
    """Orthographic camera looking along `direction` at the volume, with one voxel spanning
    `magnification` pixels in the least magnified image direction, the whole volume (plus `radius`
    index units for the kernels and `margin` pixels) in view. `offset` moves the window by a
    fraction of a pixel (so voxel centres need not fall on pixel centres)."""
    xf, lo, hi = volume_parts(volume)
    lo, hi = lo - radius, hi + radius
    world = _corners(lo, hi) @ xf[:3, :3].T + xf[:3, 3]
    centre = world.mean(axis=0)
    diag = float(np.linalg.norm(world.max(axis=0) - world.min(axis=0)))
    d = np.asarray(direction, dtype=np.float64)
    d /= np.linalg.norm(d)
    w2c = look_at(centre - d * (diag + 1.0), centre, up)
    j = w2c[:2, :3] @ xf[:3, :3]  # camera xy per index unit
    px = min_singular(j) / magnification
    cam_xy = (world @ w2c[:3, :3].T + w2c[:3, 3])[:, :2]
    half = np.abs(cam_xy).max(axis=0)
    width = int(math.ceil(2.0 * half[0] / px)) + 2 * margin
    height = int(math.ceil(2.0 * half[1] / px)) + 2 * margin
    cx, cy = offset[0] * px, offset[1] * px
    proj = ortho(-width * px / 2 + cx, width * px / 2 + cx, -height * px / 2 + cy, height * px / 2 + cy,
                 0.5, 2.0 * diag + 2.0)
    return CameraSpec(w2c, proj, width, height)


def frame_perspective(volume, magnification: float, direction=(0.0, 0.0, -1.0), up=(0.0, 0.0, 1.0),
                      distance: float = 3.0, margin: int = 3, radius: float = 2.0) -> CameraSpec:
    """Perspective camera looking along `direction` at the volume centre from `distance` times the
    volume's half diagonal, with `magnification` pixels per voxel (least magnified direction) at the
    depth of the centre, the whole volume in view."""
    xf, lo, hi = volume_parts(volume)
    lo, hi = lo - radius, hi + radius
    world = _corners(lo, hi) @ xf[:3, :3].T + xf[:3, 3]
    centre = world.mean(axis=0)
    half_diag = 0.5 * float(np.linalg.norm(world.max(axis=0) - world.min(axis=0)))
    d = np.asarray(direction, dtype=np.float64)
    d /= np.linalg.norm(d)
    dist = distance * half_diag
    w2c = look_at(centre - d * dist, centre, up)
    j = w2c[:2, :3] @ xf[:3, :3]
    focal = magnification * dist / min_singular(j)  # pixels per unit of x / depth
    cam = world @ w2c[:3, :3].T + w2c[:3, 3]
    x = np.abs(cam[:, 0] / -cam[:, 2]).max() * focal
    y = np.abs(cam[:, 1] / -cam[:, 2]).max() * focal
    width, height = int(math.ceil(2 * x)) + 2 * margin, int(math.ceil(2 * y)) + 2 * margin
    near, far = 0.05 * dist, 4.0 * dist
    proj = frustum(-width / 2 / focal * near, width / 2 / focal * near, -height / 2 / focal * near,
                   height / 2 / focal * near, near, far)
    return CameraSpec(w2c, proj, width, height)


# --------------------------------------------------------------------------------------------
# Index-to-world transforms used across the tests (3x3 linear parts; phantoms.centred_transform adds
# the translation).

def rotation(axis, angle) -> np.ndarray:
    axis = np.asarray(axis, dtype=np.float64)
    axis /= np.linalg.norm(axis)
    k = np.array([[0, -axis[2], axis[1]], [axis[2], 0, -axis[0]], [-axis[1], axis[0], 0]])
    return np.eye(3) + math.sin(angle) * k + (1 - math.cos(angle)) * k @ k


LINEAR_PARTS = {
    "identity": np.eye(3),
    "rotated": rotation((1.0, 2.0, 3.0), 0.7),
    "sheared": np.array([[1.0, 0.35, 0.0], [0.0, 1.0, -0.25], [0.2, 0.0, 1.0]]),
    "scaled": np.diag([1.0, 1.6, 0.7]),
    "mirrored": rotation((0.3, -1.0, 0.5), 0.4) @ np.diag([1.0, -1.0, 1.0]),
    # Voxels 20x longer along k, tilted: a block's footprints span more nodes than PCVR's block
    # tiles hold (about 100 x 70 at magnification 2), so those blocks are splatted straight into the grid.
    "stretched": rotation((1.0, 0.0, 0.0), 0.785) @ np.diag([0.3, 0.3, 6.0]),
}


# --------------------------------------------------------------------------------------------
# Rendering wrappers

def render(grid, cam: CameraSpec, method: str, kernel: str = "gauss1.4", post: str = "bilinear", stride: int = 0,
           threads: int = 0, passband: str = "paper", **kw) -> np.ndarray:
    """render_xray, with the paper's passband unless told otherwise: the tests hold the paper's pipeline to
    `exact` and to numpy models of its stages; the compensated passband (the default of render_xray) is that
    pipeline followed by a known filter, held to its own model and to analytic truth in test_xray_passband."""
    img = pn.render_xray(grid, cam.camera(), method, kernel, post, stride, threads, passband=passband, **kw)
    assert img.dtype == np.float32 and img.shape == (cam.height, cam.width) or kw.get("pixel_step", 1) > 1
    return np.asarray(img, dtype=np.float64)


def render_xray_paper(*args, **kw):
    """pn.render_xray with the paper's passband unless told otherwise: what the tests compare with `exact` and
    with numpy models of the paper's pipeline (as `render` does)."""
    kw.setdefault("passband", "paper")
    return pn.render_xray(*args, **kw)


def pixel_means(grid, cam: CameraSpec, factor: int = 8, kernel: str = "gauss1.4") -> np.ndarray:
    """The reference for anti-aliased images: `exact` at `factor` x the resolution (the same view, each
    pixel split into factor x factor sub-pixels sampled at their centres), averaged over each pixel."""
    fine = CameraSpec(cam.world_to_camera, cam.projection, cam.width * factor, cam.height * factor)
    img = render(grid, fine, "exact", kernel)
    return img.reshape(cam.height, factor, cam.width, factor).mean(axis=(1, 3))


def kernel_variance(name: str) -> float:
    info = getattr(pn, "kernel_info", None)
    return float(info(name)["variance"]) if info else phantoms.kernel_variance(name)


def rel_rmse(a, b) -> float:
    """RMS of a - b relative to the RMS of b (the reference)."""
    a, b = np.asarray(a, dtype=np.float64), np.asarray(b, dtype=np.float64)
    return float(np.sqrt(np.mean((a - b) ** 2)) / max(np.sqrt(np.mean(b ** 2)), 1e-300))


# --------------------------------------------------------------------------------------------
# PCVR's second stage in numpy. The subgrid nodes are the pixels (L i, L j) (column, row from the
# top); a pixel at offset delta (pixels) from a node gets weight w(delta / L), normalised over the
# nodes for each output phase: bilinear w(t) = 1 - |t| (|t| < 1), gaussA w(t) = exp(-A t^2) (|t| < 2).

def post_weight(post: str, t: np.ndarray) -> np.ndarray:
    t = np.abs(np.asarray(t, dtype=np.float64))
    if post == "bilinear":
        return np.maximum(1.0 - t, 0.0)
    a = {"gauss1.4": 1.4, "gauss2.0": 2.0}[post]
    return np.where(t < 2.0, np.exp(-a * t * t), 0.0)


def post_matrix(post: str, stride: int, n_out: int, nodes: np.ndarray) -> np.ndarray:
    """(n_out, len(nodes)) weights from nodes (integer node numbers; node i sits at pixel stride * i)."""
    pix = np.arange(n_out, dtype=np.float64)[:, None]
    w = post_weight(post, (pix - stride * nodes[None, :]) / stride)
    return w / w.sum(axis=1, keepdims=True)


def predict_pcvr(padded_image: np.ndarray, pad: int, stride: int, post: str, height: int, width: int):
    """PCVR's output predicted from an image rendered on cam.padded(pad): sample it at the subgrid
    nodes and post-convolve. `pad` must be at least 2 * stride (the widest filter's reach)."""
    assert pad >= 2 * stride
    nodes_x = np.arange(-((pad) // stride), (width - 1 + pad) // stride + 1)
    nodes_y = np.arange(-((pad) // stride), (height - 1 + pad) // stride + 1)
    samples = padded_image[np.ix_(stride * nodes_y + pad, stride * nodes_x + pad)]
    return post_matrix(post, stride, height, nodes_y) @ samples @ post_matrix(post, stride, width, nodes_x).T
