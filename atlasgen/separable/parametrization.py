"""The maps pi1, pi2 that split a BRDF's directions into the two factor domains.

An isotropic BRDF depends on three angles (Rusinkiewicz 1998), so a separable
term g(pi1) h(pi2) splits those three angles into a one-dimensional factor and a
two-dimensional one. Two angle systems are offered:

``half_diff``
    The half/difference angles of Rusinkiewicz 1998, the isotropic form of the
    "Gram-Schmidt half-angle" parametrization of Kautz & McCool 1999 (sec. 4):
    theta_h = angle(n, h), theta_d = angle(l, h), phi_d = the azimuth of l about h,
    measured from the plane of n and h (phi_d = 0: l leans towards n).
``in_out``
    The plain incident/outgoing split: theta_l, theta_v and the relative azimuth
    phi = angle between the tangent-plane projections of l and v.

Every angle is frame-free (it is computed from n, l and v alone), so a
deferred renderer needs no tangent frame. Azimuths are folded to [0, pi]: an
isotropic BRDF is mirror-symmetric about the plane that defines them.

Each factor texture has ``resolution`` texels per axis, texel i centred at
t = i / (resolution - 1); the angle at t is ``lo + (hi - lo) * warp(t)``.
``sqrt`` warps (s = t^2) put texels where sharp lobes live (theta_h near 0);
``sqrt_hi`` warps (s = 1 - (1 - t)^2) put them near the range's end (theta_d near
90 degrees, where Fresnel and masking change fast); ``cos`` warps space texels
uniformly in the cosine (like the atlas's N.L, N.V axes).
"""

from __future__ import annotations

import enum
from dataclasses import dataclass

import numpy as np

__all__ = [
    "ANGLE_RANGES",
    "Parametrization",
    "Warp",
    "PARAMETRIZATIONS",
    "DEFAULT_PARAMETRIZATION",
    "get_parametrization",
    "angles_of_directions",
    "directions_of_angles",
    "clamp_phi_d",
    "lift_above_horizon",
    "HORIZON_COS",
    "PROXY_FLOOR",
]

HALF_PI = 0.5 * np.pi

#: Range (lo, hi) of each angle, radians.
ANGLE_RANGES = {
    "theta_h": (0.0, HALF_PI),
    "theta_d": (0.0, HALF_PI),
    "phi_d": (0.0, np.pi),
    "theta_l": (0.0, HALF_PI),
    "theta_v": (0.0, HALF_PI),
    "phi": (0.0, np.pi),
}

SYSTEM_ANGLES = {
    "half_diff": ("theta_h", "theta_d", "phi_d"),
    "in_out": ("theta_l", "theta_v", "phi"),
}

# Below this length a projection is degenerate and its azimuth is taken as 0;
# the isotropic BRDF does not depend on that azimuth there.
_TINY = 1e-12


class Warp(enum.IntEnum):
    """Texel spacing along a factor axis (module docstring); the value is the code the
    generated WGSL's ``separable_unwarp`` takes (:mod:`atlasgen.shaders.separable`)."""

    LINEAR = 0
    SQRT = 1
    SQRT_HI = 2
    COS = 3

    @classmethod
    def of(cls, kind) -> Warp:
        """A member from itself or its name in any case (``"sqrt_hi"``)."""
        return kind if isinstance(kind, cls) else cls[str(kind).upper()]


def _warp(t, kind: Warp):
    if kind is Warp.COS:  # texels uniform in cos(angle), for angles in [0, pi/2]
        return np.arccos(np.clip(1.0 - t, -1.0, 1.0)) / HALF_PI
    if kind is Warp.SQRT:
        return t * t
    if kind is Warp.SQRT_HI:
        return 1.0 - (1.0 - t) * (1.0 - t)
    return t


def _unwarp(s, kind: Warp):
    s = np.clip(s, 0.0, 1.0)
    if kind is Warp.COS:
        return 1.0 - np.cos(s * HALF_PI)
    if kind is Warp.SQRT:
        return np.sqrt(s)
    if kind is Warp.SQRT_HI:
        return 1.0 - np.sqrt(1.0 - s)
    return s


def _warp_slope(t, kind: Warp):
    if kind is Warp.COS:
        return 1.0 / (HALF_PI * np.sqrt(np.maximum(t * (2.0 - t), 1e-12)))
    if kind is Warp.SQRT:
        return 2.0 * t
    if kind is Warp.SQRT_HI:
        return 2.0 * (1.0 - t)
    return np.ones_like(t)


@dataclass(frozen=True)
class Parametrization:
    """A split of the three isotropic angles into pi1 (one angle) and pi2 (two angles).

    Parameters
    ----------
    name : str
        Key in :data:`PARAMETRIZATIONS`, recorded in the manifest.
    system : str
        ``"half_diff"`` or ``"in_out"``.
    single : str
        The angle of the 1D factor g(pi1); the other two, in system order, are
        pi2 = (x axis, y axis) of the 2D factor h.
    warps : tuple of (angle, Warp or its name) pairs
        Non-linear texel spacing per angle; unnamed angles are linear.
    """

    name: str
    system: str
    single: str
    warps: tuple = ()

    @property
    def pair(self) -> tuple[str, str]:
        return tuple(a for a in SYSTEM_ANGLES[self.system] if a != self.single)

    def __post_init__(self):
        object.__setattr__(self, "warps", tuple((angle, Warp.of(kind)) for angle, kind in self.warps))

    def warp_of(self, angle: str) -> Warp:
        return dict(self.warps).get(angle, Warp.LINEAR)

    def angle_at(self, angle: str, t):
        """The angle at normalised texel position t in [0, 1]."""
        lo, hi = ANGLE_RANGES[angle]
        return lo + (hi - lo) * _warp(np.asarray(t, dtype=np.float64), self.warp_of(angle))

    def texel_of(self, angle: str, value, resolution: int):
        """Continuous texel coordinate in [0, resolution - 1] of an angle (clamped)."""
        lo, hi = ANGLE_RANGES[angle]
        s = np.clip((np.asarray(value, dtype=np.float64) - lo) / (hi - lo), 0.0, 1.0)
        return _unwarp(s, self.warp_of(angle)) * (resolution - 1)

    def grid(self, resolution: int):
        """Angles at the texel centres: ``(a1 (n,), (ax (n,), ay (n,)))``."""
        t = np.arange(resolution, dtype=np.float64) / (resolution - 1)
        ax, ay = self.pair
        return self.angle_at(self.single, t), (self.angle_at(ax, t), self.angle_at(ay, t))

    def grid_directions(self, resolution: int, extend: bool = True, lift: bool = True):
        """(l, v) unit vectors, n = +z, for every (pi1 texel, pi2 texel) pair.

        Returns arrays shaped ``(n1, n2y, n2x, 3)``: row i of the factor matrix is
        pi1 texel i, column ``y * n2x + x`` is pi2 texel (x, y).

        With ``extend``, texels whose configuration has l or v below the horizon get
        the nearest valid configuration instead (:func:`clamp_phi_d`): the rebuild
        never looks there, but linear filtering blends them into valid neighbours, so
        they must continue the BRDF smoothly rather than drop to 0 (at grazing, f cos
        does not go to 0). With ``lift`` too, directions on the horizon are raised to
        cos = 1e-4 (:func:`lift_above_horizon`), for sources that return 0 at cos = 0.
        """
        a1, (ax, ay) = self.grid(resolution)
        named = {
            self.single: a1[:, None, None],
            self.pair[0]: ax[None, None, :],
            self.pair[1]: ay[None, :, None],
        }
        shape = (a1.size, ay.size, ax.size)
        angles = [np.broadcast_to(named[a], shape) for a in SYSTEM_ANGLES[self.system]]
        if extend and self.system == "half_diff":
            # theta_d = 90 deg exactly makes l = -v, whose half vector is undefined; a
            # hair less keeps h, and so the texel's own angles, recoverable.
            angles[1] = np.minimum(angles[1], HALF_PI - 1e-4)
            angles[2] = clamp_phi_d(*angles)
        l, v = directions_of_angles(self.system, *angles)
        if extend and lift:
            l, v = lift_above_horizon(l), lift_above_horizon(v)
        return l, v

    def coordinates(self, n, l, v, resolution: int):
        """Texel coordinates of (n, l, v): ``x1`` of g and ``(x2, y2)`` of h, plus validity.

        ``valid`` is n.l > 0 and n.v > 0; the rebuilt BRDF is zero elsewhere.
        """
        angles, valid = angles_of_directions(self.system, n, l, v)
        named = dict(zip(SYSTEM_ANGLES[self.system], angles))
        x1 = self.texel_of(self.single, named[self.single], resolution)
        x2 = self.texel_of(self.pair[0], named[self.pair[0]], resolution)
        y2 = self.texel_of(self.pair[1], named[self.pair[1]], resolution)
        return x1, x2, y2, valid

    @property
    def proxy_angle(self) -> str:
        """The angle whose cosine stands in for cos(theta_l) in the ``f_proxy`` target.

        In/out: theta_l itself. Half/difference: theta_d, which equals theta_l where a
        lobe lives (theta_h ~ 0; cos theta_l = cos th cos td + sin th sin td cos pd).
        """
        return "theta_l" if self.system == "in_out" else "theta_d"

    def cosine_proxy(self, resolution: int):
        """max(cos(proxy angle), PROXY_FLOOR) at the texels: ``(c1 (n,), c2 (n*n,))``.

        The proxy depends on one factor's angles only, so f * proxy keeps f's rank,
        while it still tames f where it is huge and f cos is not (grazing mirror
        directions), which 8-bit storage needs. The other factor gets 1.
        """
        a1, (ax, ay) = self.grid(resolution)
        key = self.proxy_angle

        def c(angles, name):
            return np.maximum(np.cos(angles), PROXY_FLOOR) if name == key else np.ones(resolution)

        return c(a1, self.single), np.outer(c(ay, self.pair[1]), c(ax, self.pair[0])).ravel()

    def proxy_at(self, n, l, v):
        """max(cos(proxy angle), PROXY_FLOOR) at (n, l, v), as the rebuild divides by it."""
        angles, _ = angles_of_directions(self.system, n, l, v)
        named = dict(zip(SYSTEM_ANGLES[self.system], angles))
        return np.maximum(np.cos(named[self.proxy_angle]), PROXY_FLOOR)

    def quadrature_weights(self, resolution: int):
        """Weights of the pi1 texels and the pi2 texels for uniform (l, v) on the hemisphere.

        Uniform solid angle for l and v has density sin(theta_l) sin(theta_v) in the
        in/out angles, and 4 cos(theta_d) sin(theta_h) sin(theta_d) in the
        half/difference ones (the half-vector Jacobian d(omega_h) = d(omega_o) /
        (4 cos theta_d), Walter et al. 2007, eq. 14). Both factor as a product of a
        pi1 part and a pi2 part, so weighting the matrix keeps SVD exact (weighted
        Eckart-Young). Each texel gets the integral over its cell (half-way to its
        neighbours), so no weight is zero and unweighting never divides by zero.
        """
        density = {
            "theta_h": lambda a: np.sin(a),
            "theta_d": lambda a: np.sin(a) * np.cos(a),
            "theta_l": lambda a: np.sin(a),
            "theta_v": lambda a: np.sin(a),
            "phi_d": lambda a: np.ones_like(a),
            "phi": lambda a: np.ones_like(a),
        }

        def cells(angle):
            # Midpoint rule inside each texel cell (half-way to the neighbours).
            fine = 64
            lo, hi = ANGLE_RANGES[angle]
            edges = np.concatenate([[0.0], (np.arange(resolution - 1) + 0.5) / (resolution - 1), [1.0]])
            width = np.diff(edges)
            t = edges[:-1, None] + width[:, None] * (np.arange(fine) + 0.5)[None, :] / fine
            slope = (hi - lo) * _warp_slope(t, self.warp_of(angle))
            w = np.mean(density[angle](self.angle_at(angle, t)) * slope, axis=1) * width
            return np.maximum(w, 1e-12)

        ax, ay = self.pair
        w1 = cells(self.single)
        w2 = np.outer(cells(ay), cells(ax)).ravel()
        return w1 / w1.sum(), w2 / w2.sum()


#: Smallest value of the cosine proxy (see :meth:`Parametrization.cosine_proxy`).
PROXY_FLOOR = 1e-3

#: Smallest cosine of a grid direction after :func:`lift_above_horizon`.
HORIZON_COS = 1e-4


def clamp_phi_d(theta_h, theta_d, phi_d):
    """phi_d moved into the range where both l and v are above the horizon.

    cos(theta_l, theta_v) = cos th cos td +- sin th sin td cos pd (Rusinkiewicz 1998), so
    both are >= 0 exactly when |cos pd| <= cot th cot td. For fixed (th, td) that
    range always holds pd = pi/2, so clamping pd to it is a continuous extension.
    """
    a = np.cos(theta_h) * np.cos(theta_d)
    b = np.sin(theta_h) * np.sin(theta_d)
    limit = np.where(b > 0.0, np.clip(a / np.maximum(b, 1e-300), 0.0, 1.0), 1.0)
    return np.arccos(np.clip(np.cos(phi_d), -limit, limit))


def lift_above_horizon(d, min_cos: float = HORIZON_COS):
    """Unit directions with z raised to at least ``min_cos``, keeping their azimuth.

    Mitsuba's BSDFs return 0 at cos = 0 exactly, while f cos at grazing has a finite
    limit; a grid texel on the horizon takes that limit instead.
    """
    d = np.asarray(d, dtype=np.float64)
    z = np.maximum(d[..., 2], min_cos)
    xy = d[..., :2]
    r = np.linalg.norm(xy, axis=-1)
    s = np.where(r > 0.0, np.sqrt(np.maximum(1.0 - z * z, 0.0)) / np.where(r > 0.0, r, 1.0), 0.0)
    return np.concatenate([xy * s[..., None], z[..., None]], axis=-1)


def angles_of_directions(system: str, n, l, v):
    """The three angles of ``system`` for unit vectors n, l, v (arrays ``(..., 3)``).

    Returns ``(angles, valid)``; degenerate azimuths (a projection shorter than
    1e-6) are 0. Half/difference: h = normalize(l + v); theta_h = angle(n, h),
    theta_d = angle(l, h), phi_d = angle between l - (l.h) h and n - (n.h) h
    (Rusinkiewicz 1998, sec. 3). Polar angles are atan2(|tangential part|, cosine),
    exactly as the shader include computes them.
    """
    n = np.asarray(n, dtype=np.float64)
    l = np.asarray(l, dtype=np.float64)
    v = np.asarray(v, dtype=np.float64)
    nl = np.sum(n * l, axis=-1)
    nv = np.sum(n * v, axis=-1)
    valid = (nl > 0.0) & (nv > 0.0)
    if system == "in_out":
        lt = l - nl[..., None] * n
        vt = v - nv[..., None] * n
        ll = np.linalg.norm(lt, axis=-1)
        lv = np.linalg.norm(vt, axis=-1)
        # atan2(sin, cos) keeps full precision near 0, where a sqrt warp magnifies angles.
        return (np.arctan2(ll, nl), np.arctan2(lv, nv), _azimuth(lt, vt, ll, lv)), valid
    hsum = l + v
    hlen = np.linalg.norm(hsum, axis=-1)
    # l = -v (both on the horizon, opposite): h is the limit from above, n.
    h = np.where((hlen > 1e-6)[..., None], hsum / np.maximum(hlen, _TINY)[..., None], n)
    nh = np.sum(n * h, axis=-1)
    lh = np.sum(l * h, axis=-1)
    t = n - nh[..., None] * h
    p = l - lh[..., None] * h
    tl = np.linalg.norm(t, axis=-1)
    pl = np.linalg.norm(p, axis=-1)
    return (np.arctan2(tl, nh), np.arctan2(pl, lh), _azimuth(t, p, tl, pl)), valid


def _azimuth(a, b, la, lb):
    """Angle in [0, pi] between two vectors of lengths la, lb; 0 when either is < 1e-6."""
    ok = (la > 1e-6) & (lb > 1e-6)
    cosphi = np.where(ok, np.sum(a * b, axis=-1) / np.where(ok, la * lb, 1.0), 1.0)
    return np.arccos(np.clip(cosphi, -1.0, 1.0))


def directions_of_angles(system: str, a, b, c):
    """Unit (l, v) with n = +z from the three angles of ``system`` (inverse of the above).

    Half/difference: h = (sin th, 0, cos th), t = (-cos th, 0, sin th) points from h
    towards n, l = cos td h + sin td (cos pd t + sin pd y), v = 2 (l.h) h - l.
    """
    a, b, c = np.broadcast_arrays(*(np.asarray(x, dtype=np.float64) for x in (a, b, c)))
    if system == "in_out":
        tl, tv, phi = a, b, c
        l = np.stack([np.sin(tl) * np.cos(phi), np.sin(tl) * np.sin(phi), np.cos(tl)], axis=-1)
        v = np.stack([np.sin(tv), np.zeros_like(tv), np.cos(tv)], axis=-1)
        return l, v
    th, td, pd = a, b, c
    zero = np.zeros_like(th)
    h = np.stack([np.sin(th), zero, np.cos(th)], axis=-1)
    t = np.stack([-np.cos(th), zero, np.sin(th)], axis=-1)
    y = np.stack([zero, np.ones_like(th), zero], axis=-1)
    l = np.cos(td)[..., None] * h + np.sin(td)[..., None] * (np.cos(pd)[..., None] * t + np.sin(pd)[..., None] * y)
    v = 2.0 * np.cos(td)[..., None] * h - l
    return l, v


#: The named parametrizations; ``half_diff`` is the default (see docs/separable.md).
PARAMETRIZATIONS = {
    p.name: p
    for p in (
        Parametrization("half_diff", "half_diff", "theta_h", (("theta_h", "sqrt"), ("theta_d", "sqrt_hi"))),
        Parametrization("half_diff_sqrt_h", "half_diff", "theta_h", (("theta_h", "sqrt"),)),
        Parametrization("half_diff_cos_d", "half_diff", "theta_h", (("theta_h", "sqrt"), ("theta_d", "cos"))),
        Parametrization("half_diff_linear", "half_diff", "theta_h"),
        Parametrization("half_diff_theta_d", "half_diff", "theta_d", (("theta_h", "sqrt"),)),
        Parametrization("half_diff_phi_d", "half_diff", "phi_d", (("theta_h", "sqrt"),)),
        Parametrization("in_out", "in_out", "theta_v", (("theta_l", "cos"), ("theta_v", "cos"))),
        Parametrization("in_out_linear", "in_out", "theta_v"),
        Parametrization("in_out_theta_l", "in_out", "theta_l", (("theta_l", "cos"), ("theta_v", "cos"))),
        Parametrization("in_out_phi", "in_out", "phi", (("theta_l", "cos"), ("theta_v", "cos"))),
    )
}

DEFAULT_PARAMETRIZATION = "half_diff"


def get_parametrization(name: str) -> Parametrization:
    """The parametrization called ``name``; ``KeyError`` if unknown."""
    return PARAMETRIZATIONS[name]
