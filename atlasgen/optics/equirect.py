"""Equirectangular (latitude-longitude) environment images, in the convention of Mitsuba 3's ``envmap``.

Mitsuba 3's ``envmap`` emitter (``src/emitters/envmap.cpp``, ``direction_to_uv`` and
``uv_to_direction``) maps a direction d (towards the environment, +y up) to

    u = atan2(d.x, -d.z) / (2 pi), wrapped to [0, 1)        v = acos(d.y) / pi
    d = (sin(2 pi u) sin(pi v), cos(pi v), -cos(2 pi u) sin(pi v))

so u = 0 looks along -z, u = 1/4 along +x, u = 1/2 along +z, u = 3/4 along -x, and v = 0 is the
zenith. Its lookup (``eval_spectrum``) is bilinear, periodic in u, with **column i at
u = (i + 1/2) / W but row j at v = j / (H - 1)**: the first row is the zenith itself and the last
the nadir (the sampling weights use sin(pi j / (H - 1)) likewise). Every function here follows
that, so an image means the same radiance here, in the renderer and in Mitsuba. A shader that
reads such an image through a hardware sampler (repeat in u, clamp-to-edge in v) uses
u as is and v_tex = (1/2 + v (H - 1)) / H, the atlas's own form of v.

Radiance is linear, float, in W/(m^2 sr), as everywhere in atlasgen (docs/scenes.md).
"""

from __future__ import annotations

import math

import numpy as np

from atlasgen.optics.quadrature import gauss_legendre_rule

__all__ = [
    "direction_to_uv",
    "uv_to_direction",
    "uv_to_texel",
    "texel_uv",
    "texel_directions",
    "nearest_texel",
    "texel_solid_angles",
    "sample_equirect",
    "rotation_matrix",
    "rotate",
    "resample_equirect",
]


def direction_to_uv(directions):
    """(u, v) of unit ``directions`` ``(..., 3)``: u = atan2(d.x, -d.z) / (2 pi) in [0, 1), v = acos(d.y) / pi.

    >>> [round(float(c), 6) for c in direction_to_uv([1.0, 0.0, 0.0])]
    [0.25, 0.5]
    """
    d = np.asarray(directions, dtype=np.float64)
    u = np.arctan2(d[..., 0], -d[..., 2]) / (2.0 * np.pi)
    u = u - np.floor(u)
    u = np.where(u >= 1.0, 0.0, u)  # -tiny wraps to 1 - tiny, which can round to 1
    # atan2(|d.xz|, d.y) is acos(d.y) for a unit d, without acos's loss of digits near the poles.
    return u, np.arctan2(np.hypot(d[..., 0], d[..., 2]), d[..., 1]) / np.pi


def uv_to_direction(u, v) -> np.ndarray:
    """The unit direction of (u, v): (sin(2 pi u) sin(pi v), cos(pi v), -cos(2 pi u) sin(pi v)), ``(..., 3)``.

    >>> uv_to_direction(0.5, 0.5).round(12).tolist()  # the middle of the image looks along +z
    [0.0, 0.0, 1.0]
    """
    phi = 2.0 * np.pi * np.asarray(u, dtype=np.float64)
    theta = np.pi * np.asarray(v, dtype=np.float64)
    phi, theta = np.broadcast_arrays(phi, theta)
    s = np.sin(theta)
    return np.stack([np.sin(phi) * s, np.cos(theta), -np.cos(phi) * s], axis=-1)


def uv_to_texel(u, v, height: int, width: int):
    """Continuous texel coordinates (x, y) of (u, v): x = u W - 1/2 wrapped to [0, W), y = v (H - 1).

    Column i's sample sits at x = i and row j's at y = j (Mitsuba's ``eval_spectrum``).

    >>> [float(c) for c in uv_to_texel(0.5 / 8, 1.0, 4, 8)]
    [0.0, 3.0]
    """
    x = np.asarray(u, dtype=np.float64) * width - 0.5
    x = np.mod(x, width)
    x = np.where(x >= width, 0.0, x)
    return x, np.clip(np.asarray(v, dtype=np.float64), 0.0, 1.0) * (height - 1)


def texel_uv(height: int, width: int):
    """(u of each column ``(W,)``, v of each row ``(H,)``): u_i = (i + 1/2) / W, v_j = j / (H - 1)."""
    if height < 2 or width < 1:
        raise ValueError(f"an equirectangular image needs at least 2 rows and 1 column, got {height}x{width}")
    return (np.arange(width) + 0.5) / width, np.arange(height) / (height - 1)


def texel_directions(height: int, width: int) -> np.ndarray:
    """The direction of every texel's sample, ``(H, W, 3)``; row 0 is the zenith +y, the last row the nadir."""
    u, v = texel_uv(height, width)
    return uv_to_direction(u[None, :], v[:, None])


def nearest_texel(directions, height: int, width: int):
    """(row, column) of the texel whose sample is nearest in (u, v) to each of ``directions``."""
    u, v = direction_to_uv(directions)
    x, y = uv_to_texel(u, v, height, width)
    return np.rint(y).astype(np.intp), np.rint(x).astype(np.intp) % width


def texel_solid_angles(height: int, width: int) -> np.ndarray:
    """Each texel's share of the sphere, ``(H, W)``: the integral of its bilinear hat, so they sum to 4 pi.

    The reconstruction is sum_ij L_ij hat_i(phi) hat_j(theta); hat_i integrates to 2 pi / W and
    int hat_j(theta) sin(theta) dtheta is, with D = pi / (H - 1),
    sin(theta_j) (2 - 2 cos D) / D for an inner row and 1 - sin(D) / D for the two pole rows,
    exactly: int L dw = sum_ij Omega_ij L_ij for every image.

    >>> round(float(texel_solid_angles(32, 64).sum() / np.pi), 12)
    4.0
    """
    _, v = texel_uv(height, width)
    d = np.pi / (height - 1)
    rows = np.sin(np.pi * v) * (2.0 - 2.0 * np.cos(d)) / d
    rows[0] = rows[-1] = 1.0 - np.sin(d) / d
    return np.broadcast_to((2.0 * np.pi / width) * rows[:, None], (height, width)).copy()


def _column_stencil(width: int, x):
    i0 = np.floor(x).astype(np.intp)
    f = x - i0
    i0 = i0 % width
    return i0, (i0 + 1) % width, f


def _row_stencil(height: int, y):
    y = np.clip(y, 0.0, height - 1)
    i0 = np.minimum(np.floor(y).astype(np.intp), max(height - 2, 0))
    return i0, np.minimum(i0 + 1, height - 1), y - i0


def sample_equirect(image, directions) -> np.ndarray:
    """The radiance of ``image`` ``(H, W, C)`` towards ``directions`` ``(..., 3)``, as Mitsuba's ``envmap`` evaluates it.

    Bilinear between samples, periodic in u, rows from the zenith (v = 0) to the nadir (v = 1);
    returns ``(..., C)``. At a texel's own direction it returns that texel exactly.
    """
    img = np.asarray(image)
    h, w = img.shape[:2]
    u, v = direction_to_uv(directions)
    x, y = uv_to_texel(u, v, h, w)
    x0, x1, fx = _column_stencil(w, x)
    y0, y1, fy = _row_stencil(h, y)
    fx, fy = fx[..., None], fy[..., None]
    top = img[y0, x0] * (1.0 - fx) + img[y0, x1] * fx
    bottom = img[y1, x0] * (1.0 - fx) + img[y1, x1] * fx
    return top * (1.0 - fy) + bottom * fy


def rotation_matrix(degrees: float) -> np.ndarray:
    """R_y, the right-handed rotation by ``degrees`` about +y: +z turns towards +x and +x towards -z.

    [[cos, 0, sin], [0, 1, 0], [-sin, 0, cos]]: the y rotation of a scene object's ``rotate``
    (:func:`atlasgen.materials.scene.object_matrix`) and of Mitsuba's
    ``ScalarTransform4f().rotate([0, 1, 0], degrees)``.

    >>> (rotation_matrix(90.0) @ [0.0, 0.0, 1.0]).round(12).tolist()
    [1.0, 0.0, 0.0]
    """
    a = math.radians(degrees)
    c, s = math.cos(a), math.sin(a)
    return np.array([[c, 0.0, s], [0.0, 1.0, 0.0], [-s, 0.0, c]])


def rotate(image, degrees: float) -> np.ndarray:
    """``image`` turned by ``degrees`` about +y (:func:`rotation_matrix`): L'(d) = L(R_y^-1 d).

    Radiance that came from direction d now comes from R_y d, as Mitsuba's ``to_world`` turns an
    ``envmap``. R_y shifts u by -degrees / 360, so a multiple of 360 / W degrees moves whole
    columns and is exact; any other angle interpolates linearly between columns
    (:func:`resample_equirect`), which softens the image by up to half a column. A renderer can
    instead rotate its lookup direction, which is exact.
    """
    img = np.asarray(image)
    return resample_equirect(img, img.shape[0], img.shape[1], degrees)


def _axis_point_matrix(n_src: int, positions, stencil) -> np.ndarray:
    i0, i1, f = stencil(n_src, positions)
    m = np.zeros((len(positions), n_src))
    rows = np.arange(len(positions))
    np.add.at(m, (rows, i0), 1.0 - f)
    np.add.at(m, (rows, i1), f)
    return m


def _axis_average_matrix(n_src: int, n_tgt: int, src_of, tgt_of, breaks, stencil_src, stencil_tgt, weight) -> np.ndarray:
    """A[t, s] = int hat_t hat_s w / int hat_t w over the axis, by Gauss-Legendre between all hats' knots."""
    t, wt = gauss_legendre_rule(4)
    b = np.unique(breaks)
    half = 0.5 * np.diff(b)
    x = ((0.5 * (b[1:] + b[:-1]))[:, None] + half[:, None] * t).ravel()
    w = (half[:, None] * wt).ravel() * weight(x)
    s0, s1, fs = stencil_src(n_src, src_of(x))
    t0, t1, ft = stencil_tgt(n_tgt, tgt_of(x))
    m = np.zeros((n_tgt, n_src))
    for ti, tw in ((t0, 1.0 - ft), (t1, ft)):
        for si, sw in ((s0, 1.0 - fs), (s1, fs)):
            np.add.at(m, (ti, si), w * tw * sw)
    return m / m.sum(axis=1, keepdims=True)


def resample_equirect(image, height: int, width: int, degrees: float = 0.0) -> np.ndarray:
    """``image`` ``(H, W, C)`` at ``height`` x ``width``, turned by ``degrees`` about +y (:func:`rotate`): float32.

    Per axis, separably: where the target has at least as many samples as the source, each target
    sample is the source's bilinear reconstruction at its direction (exact at the source's own
    samples); where it has fewer, each target sample is the average of the reconstruction under
    its own hat, int hat_t L dw / int hat_t dw (sin(theta) weighted across rows). The averages
    keep the image's integral int L dw exactly (the target hats sum to 1), so a downsampled sun
    keeps its irradiance; a constant image stays that constant.
    """
    img = np.asarray(image, dtype=np.float64)
    hs, ws = img.shape[:2]
    if height < 2 or width < 1:
        raise ValueError(f"an equirectangular image needs at least 2 rows and 1 column, got {height}x{width}")
    # Rows: theta = pi y / (n - 1).
    if height >= hs:
        rows = _axis_point_matrix(hs, np.arange(height) * (hs - 1) / (height - 1), _row_stencil)
    else:
        breaks = np.concatenate([np.linspace(0.0, np.pi, hs), np.linspace(0.0, np.pi, height)])
        rows = _axis_average_matrix(hs, height, lambda th: th * (hs - 1) / np.pi, lambda th: th * (height - 1) / np.pi,
                                    breaks, _row_stencil, _row_stencil, np.sin)  # fmt: skip
    # Columns: target column i reads the source at phi_i + a (L'(phi) = L(phi + a), R_y shifts phi by -a).
    # In turns, whole turns taken off first (exactly): 1e20 degrees would leave no column index an integer holds.
    a = math.radians(math.fmod(degrees, 360.0)) / (2.0 * np.pi)
    if width >= ws:
        src_x = ((np.arange(width) + 0.5) / width + a) * ws - 0.5
        cols = _axis_point_matrix(ws, src_x, _column_stencil)
    else:
        knots = np.concatenate([((np.arange(ws) + 0.5) / ws) % 1.0, ((np.arange(width) + 0.5) / width + a) % 1.0, [0.0, 1.0]])
        cols = _axis_average_matrix(ws, width, lambda u: u * ws - 0.5, lambda u: (u - a) * width - 0.5, knots,
                                    _column_stencil, _column_stencil, np.ones_like)  # fmt: skip
    return np.einsum("ts,swc,uw->tuc", rows, img, cols, optimize=True).astype(np.float32)
