"""The atlas contract: dimensions and the (N.L, N.V) <-> texel mapping.

Every other module (baker, shader include, renderer, readers) takes its numbers
from here, so the contract is written down exactly once.
"""

from __future__ import annotations

import re

import numpy as np

__all__ = [
    "FORMAT_VERSION",
    "WIDTH",
    "HEIGHT",
    "LAYERS",
    "ARRAY_MIP_COUNT",
    "VOLUME_MIP_COUNT",
    "MAPPING",
    "SPECULAR_ALPHA_MIN",
    "SPECULAR_ROUGHNESS_MIN",
    "SPECULAR_LOBE",
    "NAME_PATTERN",
    "material_constant",
    "texel_centres",
    "texel_grid",
    "atlas_uv",
]

# v2: a separable entry's BRDF source moved from 'source' to 'brdf_source'.
# v3: atlas_sha256 pairs the manifest with its texture; sources relative to the manifest.
# v4: the renderer's specular lobe became GGX with height-correlated Smith visibility
#     (``specular_lobe``); slices baked for the Blinn-Phong lobe mean something else.
# v5: a separable entry may end with a transmission slice (``transmission``; the separable
#     table's directory row says so in w, table version 2), read where N.L <= 0.
FORMAT_VERSION = 5
WIDTH = 64  # u: N.L in [-1, 1]
HEIGHT = 32  # v: N.V in [0, 1]
LAYERS = 256
ARRAY_MIP_COUNT = 7  # 64x32 -> 1x1
VOLUME_MIP_COUNT = 9  # 64x32x256 -> 1x1x1

MAPPING = {
    "u_axis": "N.L in [-1, 1]; texel i centre at N.L = -1 + 2*i/63",
    "v_axis": "N.V in [0, 1]; texel j centre at N.V = j/31; row 0 is N.V = 0",
    "u": "u = (0.5 + 63*(N.L + 1)/2) / 64",
    "v": "v = (0.5 + 31*N.V) / 32",
    "layer": "array: layer = material_id; volume: w = (material_id + 0.5) / 256",
    "value": "linear = texel * scale + bias, per slice: (rgb_scale, rgb_bias) for RGB, (alpha_scale, alpha_bias) for A",
}

#: A material's name: a letter, then letters, digits, '-' or '_', at most 63 in all. It names the
#: material in shader code (e.g. ``separable_f_cos_NAME``) and in the manifest. Match it with
#: ``fullmatch``: Python's ``$`` also matches before a final line break ("abc\n"), JSON Schema's does not.
NAME_PATTERN = re.compile(r"^[A-Za-z][A-Za-z0-9_-]{0,62}$")


def material_constant(name: str) -> str:
    """The shader constant every include declares a material's ID by: ``MATERIAL_`` and the name in
    capitals, each character but a letter or digit as ``_`` (the manifest's ``constant``).

    >>> material_constant("gold-film")
    'MATERIAL_GOLD_FILM'
    """
    return "MATERIAL_" + re.sub(r"[^A-Z0-9]", "_", name.upper())


#: Smallest GGX roughness the renderer uses: keeps D's peak 1 / (pi alpha^2) finite in f32
#: and the highlight of a gloss-1 object at least a few texels of a 16-bit g-buffer wide.
SPECULAR_ALPHA_MIN = 0.002
#: The same lobe as a roughness r (alpha = r^2, Burley 2012; MaterialX's and Mitsuba's principled), rounded: 0.045.
SPECULAR_ROUGHNESS_MIN = round(SPECULAR_ALPHA_MIN**0.5, 3)

#: The specular lobe the slices are made for (manifest ``specular_lobe``; docs/atlas-format.md).
#: An engine needs it to shade with A correctly: A scales exactly this f_s cos.
SPECULAR_LOBE = {
    "name": "ggx-smith-height-correlated",
    "equation": "f_s cos = D(N.H) V(N.L, N.V) max(N.L, 0), scaled by A",
    "distribution": "D = alpha^2 / (pi ((N.H)^2 (alpha^2 - 1) + 1)^2)",
    "visibility": "V = 0.5 / (N.L sqrt((N.V)^2 (1 - alpha^2) + alpha^2) + N.V sqrt((N.L)^2 (1 - alpha^2) + alpha^2))",
    "roughness": f"alpha = max((1 - gloss)^2, {SPECULAR_ALPHA_MIN})",
}


def texel_centres(width: int = WIDTH, height: int = HEIGHT) -> tuple[np.ndarray, np.ndarray]:
    """N.L and N.V at the texel centres of one slice.

    N.L_i = -1 + 2 i / (W - 1) and N.V_j = j / (H - 1): both range ends lie on
    texel centres, so a texture lookup at N.L = +-1 or N.V = 0, 1 reads an
    unfiltered texel.
    """
    nl = -1.0 + 2.0 * np.arange(width, dtype=np.float64) / (width - 1)
    nv = np.arange(height, dtype=np.float64) / (height - 1)
    return nl, nv


def texel_grid(width: int = WIDTH, height: int = HEIGHT) -> tuple[np.ndarray, np.ndarray]:
    """(N.L, N.V) broadcast to ``(height, width)``; row j is N.V_j."""
    nl, nv = texel_centres(width, height)
    return np.meshgrid(nl, nv, indexing="xy")


def atlas_uv(n_dot_l, n_dot_v, width: int = WIDTH, height: int = HEIGHT):
    """Normalised texture coordinates of (N.L, N.V), exactly as the shader include computes them.

    u = (0.5 + (W-1) (N.L+1)/2) / W and v = (0.5 + (H-1) N.V) / H.
    """
    nl = np.clip(np.asarray(n_dot_l, dtype=np.float64), -1.0, 1.0)
    nv = np.clip(np.asarray(n_dot_v, dtype=np.float64), 0.0, 1.0)
    u = (0.5 + (width - 1) * (nl + 1.0) * 0.5) / width
    v = (0.5 + (height - 1) * nv) / height
    return u, v
