"""Test volumes (phantoms) and the closed-form X-ray images that some of them have.

Pure numpy: the volumes need nothing compiled, so tests, the demo and benchmarks can make them
anywhere. Every generator returns a :class:`Phantom`, a ``(values, index_to_world)`` pair (values
float32 indexed ``[i, j, k]``, index_to_world (4, 4) float64 in the column-vector convention of
``pcvr_native.Grid``); ``phantom.grid()`` turns it into a ``pcvr_native.Grid``.

| generator          | what                                                                  | analytic X-ray |
|--------------------|-----------------------------------------------------------------------|----------------|
| ``ct_phantom``     | 3-D modified Shepp-Logan head, CT-like densities, edges ~1 voxel wide | no             |
| ``gaussian_blobs`` | sums of sampled isotropic 3-D Gaussians                              | ``gaussian_blobs_xray`` |
| ``marschner_lobb`` | Marschner and Lobb's test signal (f_M = 6, alpha = 0.25, [-1, 1]^3)    | no             |
| ``sparse_cloud``   | thresholded fractal noise in a soft ball: most voxels zero            | no             |
| ``dense_volume``   | smooth positive noise, every voxel active                             | no             |

The kernel helpers (``kernel_profile``, ``kernel_variance``, ``kernel_line_integral``) restate the
renderer's reconstruction kernels in numpy: the closed forms below need their second moments, and
tests use them as an independent reference.
"""

from __future__ import annotations

import math
from typing import NamedTuple, Sequence

import numpy as np

__all__ = [
    "Phantom", "centred_transform", "ct_phantom", "gaussian_blobs", "gaussian_blobs_xray", "marschner_lobb",
    "sparse_cloud", "dense_volume", "pixel_rays", "kernel_profile", "kernel_variance", "kernel_line_integral",
    "KERNEL_NAMES",
]

KERNEL_NAMES = ("gauss1.4", "gauss2.0", "linear", "box")


class Phantom(NamedTuple):
    values: np.ndarray          # float32, [i, j, k]
    index_to_world: np.ndarray  # (4, 4) float64, world = M @ [i, j, k, 1]

    def grid(self, background: float = 0.0):
        """The phantom as a ``pcvr_native.Grid`` (voxels equal to `background` stay inactive)."""
        from . import Grid  # the compiled module: imported only when a grid is wanted
        return Grid.from_dense(self.values, self.index_to_world, background)


def centred_transform(shape: Sequence[int], spacing: float | Sequence[float] = 1.0,
                      linear: np.ndarray | None = None) -> np.ndarray:
    """index_to_world placing the centre of an array of `shape` at the world origin.

    `spacing` scales the index axes; `linear` (3x3, optional) is applied after the scaling, so a
    rotation, shear or mirror can be given there.
    """
    scale = np.diag(np.broadcast_to(np.asarray(spacing, dtype=np.float64), (3,)))
    a = scale if linear is None else np.asarray(linear, dtype=np.float64) @ scale
    centre = (np.asarray(shape, dtype=np.float64) - 1.0) / 2.0
    m = np.eye(4)
    m[:3, :3] = a
    m[:3, 3] = -a @ centre
    return m


# --------------------------------------------------------------------------------------------
# Kernels (index space, spherically symmetric, truncated, normalised to unit 3-D integral)

def kernel_profile(name: str):
    """(raw profile h(r) before normalisation, radius, normalisation) of a splat kernel."""
    if name == "gauss1.4" or name == "gauss2.0":
        a = 1.4 if name == "gauss1.4" else 2.0
        radius = 2.0
        # 4 pi * integral_0^R exp(-a r^2) r^2 dr
        integral = 4.0 * math.pi * (math.sqrt(math.pi) / (4.0 * a ** 1.5) * math.erf(math.sqrt(a) * radius)
                                    - radius * math.exp(-a * radius * radius) / (2.0 * a))

        def raw(r, a=a, radius=radius):
            r = np.asarray(r, dtype=np.float64)
            return np.where(r < radius, np.exp(-a * r * r), 0.0)
    elif name == "linear":
        radius = 1.0
        integral = math.pi / 3.0  # 4 pi * (1/3 - 1/4)

        def raw(r):
            r = np.asarray(r, dtype=np.float64)
            return np.where(r < 1.0, 1.0 - r, 0.0)
    elif name == "box":
        radius = (3.0 / (4.0 * math.pi)) ** (1.0 / 3.0)
        integral = 1.0

        def raw(r, radius=radius):
            r = np.asarray(r, dtype=np.float64)
            return np.where(r < radius, 1.0, 0.0)
    else:
        raise ValueError(f"unknown splat kernel {name!r} (expected one of {', '.join(KERNEL_NAMES)})")
    return raw, radius, 1.0 / integral


def kernel_variance(name: str) -> float:
    """Per-axis second moment of the normalised kernel, in index units squared, in closed form:
    (1/3) * integral r^4 h(r) dr / integral r^2 h(r) dr over [0, radius]."""
    raw, radius, norm = kernel_profile(name)
    if name.startswith("gauss"):
        a = 1.4 if name == "gauss1.4" else 2.0
        e = math.exp(-a * radius * radius)
        m4 = 3.0 * math.sqrt(math.pi) * math.erf(math.sqrt(a) * radius) / (8.0 * a ** 2.5) \
            - e * (radius ** 3 / (2.0 * a) + 3.0 * radius / (4.0 * a * a))
        m2 = 1.0 / (4.0 * math.pi * norm)
        return m4 / m2 / 3.0
    if name == "linear":
        return (radius ** 5 / 30.0) / (radius ** 3 / 12.0) / 3.0  # 2 R^2 / 15
    return radius * radius / 5.0  # uniform ball


_kernel_variance = kernel_variance  # gaussian_blobs_xray's parameter of the same name hides it


def _erf(x: np.ndarray) -> np.ndarray:
    """Vectorised erf: Maclaurin series below 3 (error < 1e-13), Abramowitz-Stegun 7.1.26 above (< 2e-7)."""
    x = np.asarray(x, dtype=np.float64)
    shape = x.shape
    x = x.reshape(-1)
    a = np.abs(x)
    t = 1.0 / (1.0 + 0.3275911 * a)
    y = 1.0 - t * (0.254829592 + t * (-0.284496736 + t * (1.421413741 + t * (-1.453152027 + t * 1.061405429)))) \
        * np.exp(-a * a)
    small = a < 3.0
    if np.any(small):
        z = a[small]
        z2 = z * z
        term = z.copy()
        total = z.copy()
        for n in range(1, 120):  # erf(z) = 2/sqrt(pi) sum (-1)^n z^(2n+1) / (n! (2n + 1))
            term = term * (-z2) / n
            total = total + term / (2 * n + 1)
        y[small] = total * (2.0 / math.sqrt(math.pi))
    return (np.sign(x) * y).reshape(shape)


def kernel_line_integral(name: str, rho: np.ndarray) -> np.ndarray:
    """Integral of the normalised kernel along a line at distance `rho` (index units) from its centre.

    The footprint of the kernel (its Abel transform); its 2-D integral is 1.
    """
    _, radius, norm = kernel_profile(name)
    rho = np.abs(np.asarray(rho, dtype=np.float64))
    inside = rho < radius
    half = np.sqrt(np.where(inside, radius * radius - rho * rho, 0.0))
    if name.startswith("gauss"):
        a = 1.4 if name == "gauss1.4" else 2.0
        raw = np.exp(-a * rho * rho) * math.sqrt(math.pi / a) * _erf(math.sqrt(a) * half)
    elif name == "linear":
        # integral over the chord of 1 - sqrt(rho^2 + s^2): h - (rho^2 / 2) ln((1 + h) / (1 - h))
        with np.errstate(divide="ignore", invalid="ignore"):
            log_term = np.where(half < 1.0, np.log((1.0 + half) / np.maximum(1.0 - half, 1e-300)), 0.0)
        raw = half - 0.5 * rho * rho * log_term
    else:
        raw = 2.0 * half
    return np.where(inside, raw * norm, 0.0)


# --------------------------------------------------------------------------------------------
# Volumes

def _index_grid(shape):
    return [np.arange(n, dtype=np.float32) for n in shape]


def ct_phantom(n: int = 128, edge_width: float = 1.0) -> Phantom:
    """A 3-D modified Shepp-Logan head phantom on an n^3 grid spanning [-1, 1]^3.

    Ten ellipsoids (Kak and Slaney's 3-D head, with the "modified" contrasts of Toft/Schabel) add up
    to CT-like relative attenuation: skull 1.0, brain 0.2, ventricles 0.0, lesions 0.3. Ellipsoid edges
    are linear ramps `edge_width` voxels wide, so the sampled volume is not badly aliased.
    """
    # amplitude, semi-axes (a, b, c), centre (x, y, z), Euler angles phi, theta, psi (degrees)
    ellipsoids = [
        (1.0, (0.6900, 0.920, 0.810), (0.0, 0.0, 0.0), (0.0, 0.0, 0.0)),
        (-0.8, (0.6624, 0.874, 0.780), (0.0, -0.0184, 0.0), (0.0, 0.0, 0.0)),
        (-0.2, (0.1100, 0.310, 0.220), (0.22, 0.0, 0.0), (-18.0, 0.0, 10.0)),
        (-0.2, (0.1600, 0.410, 0.280), (-0.22, 0.0, 0.0), (18.0, 0.0, 10.0)),
        (0.1, (0.2100, 0.250, 0.410), (0.0, 0.35, -0.15), (0.0, 0.0, 0.0)),
        (0.1, (0.0460, 0.046, 0.050), (0.0, 0.1, 0.25), (0.0, 0.0, 0.0)),
        (0.1, (0.0460, 0.046, 0.050), (0.0, -0.1, 0.25), (0.0, 0.0, 0.0)),
        (0.1, (0.0460, 0.023, 0.050), (-0.08, -0.605, 0.0), (0.0, 0.0, 0.0)),
        (0.1, (0.0230, 0.023, 0.020), (0.0, -0.606, 0.0), (0.0, 0.0, 0.0)),
        (0.1, (0.0230, 0.046, 0.020), (0.06, -0.605, 0.0), (0.0, 0.0, 0.0)),
    ]
    spacing = 2.0 / n
    xf = centred_transform((n, n, n), spacing)
    values = np.zeros((n, n, n), dtype=np.float32)
    half_ramp = 0.5 * edge_width * spacing
    for amp, axes, centre, angles in ellipsoids:
        rot = _euler_zxz(*np.radians(angles))
        axes = np.asarray(axes)
        # Index box holding the ellipsoid (any rotation) and its ramp.
        reach = axes.max() + half_ramp + spacing
        lo = np.maximum(np.floor((np.asarray(centre) - reach + 1.0) / spacing - 0.5).astype(int), 0)
        hi = np.minimum(np.ceil((np.asarray(centre) + reach + 1.0) / spacing - 0.5).astype(int) + 1, n)
        if np.any(hi <= lo):
            continue
        # World coordinates of the box's voxel centres, relative to the ellipsoid centre.
        coords = [(np.arange(lo[d], hi[d], dtype=np.float32) - (n - 1) / 2.0) * spacing - centre[d]
                  for d in range(3)]
        x, y, z = np.meshgrid(*coords, indexing="ij", sparse=True)
        # Ellipsoid frame: p' = R^T p.
        xr = rot[0, 0] * x + rot[1, 0] * y + rot[2, 0] * z
        yr = rot[0, 1] * x + rot[1, 1] * y + rot[2, 1] * z
        zr = rot[0, 2] * x + rot[1, 2] * y + rot[2, 2] * z
        q = np.sqrt((xr / axes[0]) ** 2 + (yr / axes[1]) ** 2 + (zr / axes[2]) ** 2, dtype=np.float32)
        # Signed distance to the surface along the ray from the centre: (q - 1) * |p| / q.
        dist = np.sqrt(xr * xr + yr * yr + zr * zr) * (1.0 - 1.0 / np.maximum(q, 1e-6))
        inside = np.clip(0.5 - dist / (2.0 * half_ramp), 0.0, 1.0)
        values[lo[0]:hi[0], lo[1]:hi[1], lo[2]:hi[2]] += np.float32(amp) * inside.astype(np.float32)
    # Overlapping negative ellipsoids can leave tiny negative rounding residues: densities are >= 0.
    np.maximum(values, 0.0, out=values)
    values[values < 1e-6] = 0.0
    return Phantom(values, xf)


def _euler_zxz(phi, theta, psi):
    def rz(a):
        c, s = math.cos(a), math.sin(a)
        return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])

    def rx(a):
        c, s = math.cos(a), math.sin(a)
        return np.array([[1.0, 0.0, 0.0], [0.0, c, -s], [0.0, s, c]])

    return rz(phi) @ rx(theta) @ rz(psi)


def gaussian_blobs(n, blobs, index_to_world: np.ndarray | None = None, cutoff: float = 1e-9) -> Phantom:
    """Sampled isotropic Gaussians: value[i] = sum A exp(-|i - c|^2 / (2 sigma^2)), in index space.

    `n`: an int (cube) or a shape; `blobs`: (centre_ijk, sigma_index, amplitude) triples; values below
    `cutoff` times the largest amplitude are zeroed (and so stay inactive in a grid).
    `index_to_world` defaults to the identity.
    """
    shape = (n, n, n) if np.isscalar(n) else tuple(int(s) for s in n)
    values = np.zeros(shape, dtype=np.float64)
    ax = [np.arange(s, dtype=np.float64) for s in shape]
    peak = 0.0
    for centre, sigma, amp in blobs:
        g = [np.exp(-(ax[d] - centre[d]) ** 2 / (2.0 * sigma * sigma)) for d in range(3)]
        values += amp * g[0][:, None, None] * g[1][None, :, None] * g[2][None, None, :]
        peak = max(peak, abs(amp))
    values[np.abs(values) < cutoff * peak] = 0.0
    xf = np.eye(4) if index_to_world is None else np.asarray(index_to_world, dtype=np.float64)
    return Phantom(values.astype(np.float32), xf)


def _camera_parts(camera):
    """(world_to_camera, projection, width, height) from a pcvr_native.Camera-like object or a tuple."""
    if isinstance(camera, (tuple, list)):
        w2c, proj, width, height = camera
    else:
        w2c, proj = camera.world_to_camera, camera.projection
        width, height = camera.width, camera.height
    return np.asarray(w2c, dtype=np.float64), np.asarray(proj, dtype=np.float64), int(width), int(height)


def pixel_rays(camera, pixel_step: int = 1):
    """World-space rays through the pixel centres: (origins, unit directions), each (rows, cols, 3).

    `camera`: a pcvr_native.Camera (or anything with world_to_camera, projection, width, height) or a
    (world_to_camera, projection, width, height) tuple. Origins lie on the near plane. Rows run from
    the top, as in rendered images; `pixel_step` > 1 keeps pixels [::step, ::step].
    """
    w2c, proj, width, height = _camera_parts(camera)
    clip_to_world = np.linalg.inv(proj @ w2c)
    cols = np.arange(0, width, pixel_step, dtype=np.float64)
    rows = np.arange(0, height, pixel_step, dtype=np.float64)
    nx = (cols + 0.5) / width * 2.0 - 1.0
    ny = 1.0 - (rows + 0.5) / height * 2.0
    X, Y = np.meshgrid(nx, ny)  # (rows, cols)

    def unproject(z):
        p = np.stack([X, Y, np.full_like(X, z), np.ones_like(X)], axis=-1) @ clip_to_world.T
        return p[..., :3] / p[..., 3:4]

    near, far = unproject(-1.0), unproject(1.0)
    d = far - near
    return near, d / np.linalg.norm(d, axis=-1, keepdims=True)


def gaussian_blobs_xray(blobs, camera, index_to_world: np.ndarray | None = None, kernel_variance=1.0 / 2.8,
                        pixel_step: int = 1) -> np.ndarray:
    """Closed-form X-ray image (float64, rows from the top) of ``gaussian_blobs(..., blobs, index_to_world)``.

    A sampled Gaussian of variance sigma^2 reconstructed with a kernel of per-axis variance s^2 is very
    nearly a Gaussian of variance sigma^2 + s^2 with the same integral, A (2 pi sigma^2)^(3/2) index
    units (the lattice sum of a Gaussian with sigma >= 1 equals its integral to 1e-8; the kernel's
    higher cumulants change the result by O(kurtosis / (sigma^2 + s^2)^2)). In world space it is the
    Gaussian of covariance C = (sigma^2 + s^2) A A^T around A c + t and mass A (2 pi sigma^2)^(3/2)|det A|
    (A, t: index_to_world's linear part and translation). Its integral along the line o + t d
    (|d| = 1, t over the whole line) is

        mass / (2 pi sqrt(det C * d'Pd)) * exp(-(y'Py - (d'Py)^2 / d'Pd) / 2),  P = C^-1, y = o - mu.

    `kernel_variance`: a number or a kernel name. Orthographic and perspective cameras alike: each
    pixel's ray comes from the camera matrices (:func:`pixel_rays`).
    """
    if isinstance(kernel_variance, str):
        kernel_variance = _kernel_variance(kernel_variance)
    m = np.eye(4) if index_to_world is None else np.asarray(index_to_world, dtype=np.float64)
    a, t = m[:3, :3], m[:3, 3]
    det = abs(np.linalg.det(a))
    origins, dirs = pixel_rays(camera, pixel_step)
    image = np.zeros(origins.shape[:2], dtype=np.float64)
    for centre, sigma, amp in blobs:
        var = sigma * sigma + kernel_variance
        cov = var * (a @ a.T)
        prec = np.linalg.inv(cov)
        mass = amp * (2.0 * math.pi * sigma * sigma) ** 1.5 * det
        mu = a @ np.asarray(centre, dtype=np.float64) + t
        y = origins - mu
        py = y @ prec.T
        pd = dirs @ prec.T
        dpd = np.einsum("...i,...i", dirs, pd)
        ypy = np.einsum("...i,...i", y, py)
        dpy = np.einsum("...i,...i", dirs, py)
        image += mass / (2.0 * math.pi * np.sqrt(np.linalg.det(cov) * dpd)) * np.exp(-0.5 * (ypy - dpy * dpy / dpd))
    return image


def marschner_lobb(n: int = 41, f_m: float = 6.0, alpha: float = 0.25) -> Phantom:
    """Marschner and Lobb's test signal sampled at n^3 points spanning [-1, 1]^3 (values in [0, 1]).

    rho(x, y, z) = (1 - sin(pi z / 2) + alpha (1 + cos(2 pi f_M cos(pi r / 2)))) / (2 (1 + alpha)),
    r = sqrt(x^2 + y^2).
    """
    x = np.linspace(-1.0, 1.0, n)
    X, Y, Z = np.meshgrid(x, x, x, indexing="ij", sparse=True)
    r = np.sqrt(X * X + Y * Y)
    rho_r = np.cos(2.0 * math.pi * f_m * np.cos(math.pi * r / 2.0))
    values = (1.0 - np.sin(math.pi * Z / 2.0) + alpha * (1.0 + rho_r)) / (2.0 * (1.0 + alpha))
    return Phantom(np.ascontiguousarray(values, dtype=np.float32), centred_transform((n, n, n), 2.0 / (n - 1)))


def _filtered_noise(n: int, seed: int, envelope) -> np.ndarray:
    """Periodic white noise shaped in frequency by envelope(|f|, f in cycles per voxel); unit std."""
    rng = np.random.default_rng(seed)
    noise = rng.standard_normal((n, n, n), dtype=np.float32)
    spec = np.fft.rfftn(noise)
    fx = np.fft.fftfreq(n).astype(np.float32)
    fz = np.fft.rfftfreq(n).astype(np.float32)
    f = np.sqrt(fx[:, None, None] ** 2 + fx[None, :, None] ** 2 + fz[None, None, :] ** 2)
    spec *= envelope(f)
    field = np.fft.irfftn(spec, s=(n, n, n)).astype(np.float32)
    field -= field.mean()
    field /= max(float(field.std()), 1e-30)
    return field


def sparse_cloud(n: int = 64, seed: int = 0, fill: float = 0.15) -> Phantom:
    """Fractal-noise cloud in a soft ball: about `fill` of the voxels are non-zero, the rest exactly 0.

    1/f^(5/3) spectrum (Kolmogorov-like) with a Gaussian roll-off at 0.2 cycles/voxel, times a radial
    envelope, then thresholded at its (1 - fill) quantile. Values in [0, 1]; spacing 2/n, centred.
    """
    f0 = 1.0 / n
    field = _filtered_noise(n, seed, lambda f: (f * f + f0 * f0) ** (-11.0 / 12.0) * np.exp(-(f / 0.2) ** 2))
    c = (n - 1) / 2.0
    ax = (np.arange(n, dtype=np.float32) - c) / (n / 2.0)
    r2 = ax[:, None, None] ** 2 + ax[None, :, None] ** 2 + ax[None, None, :] ** 2
    field += 2.0 * (1.0 - 2.0 * r2)  # denser in the middle, empty towards the corners
    k = int(round((1.0 - fill) * field.size))
    threshold = np.partition(field.ravel(), min(max(k, 0), field.size - 1))[min(max(k, 0), field.size - 1)]
    values = np.maximum(field - threshold, 0.0)
    peak = float(values.max())
    if peak > 0:
        values /= peak
    return Phantom(values.astype(np.float32), centred_transform((n, n, n), 2.0 / n))


def dense_volume(n: int = 32, seed: int = 0, contrast: float = 0.4) -> Phantom:
    """Smooth noise, positive everywhere: 1 + contrast * field / max|field|, so values in [1 - c, 1 + c].

    Gaussian spectrum with sigma 0.08 cycles/voxel: features of a few voxels. Spacing 2/n, centred.
    """
    field = _filtered_noise(n, seed, lambda f: np.exp(-0.5 * (f / 0.08) ** 2))
    field /= max(float(np.abs(field).max()), 1e-30)
    values = 1.0 + contrast * field
    return Phantom(values.astype(np.float32), centred_transform((n, n, n), 2.0 / n))
