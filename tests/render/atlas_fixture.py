"""A small hand-made atlas for the renderer tests, and a numpy reference of the lighting.

The atlas is built from closed forms (not by the bake), so what the GPU must return
is known independently: each slice's 8-bit texels are decoded here with the sRGB
formula and filtered bilinearly with the contract's texel-centre mapping.
"""

from __future__ import annotations

import numpy as np

from atlasgen.bake.mips import build_array_mips
from atlasgen.contract import HEIGHT, LAYERS, WIDTH, atlas_uv, texel_grid
from atlasgen.io.manifest import Dimensions, Manifest, MaterialEntry
from atlasgen.models import get_model
from atlasgen.optics.quantize import dequantize_rgba, quantize_rgba
from atlasgen.render.atlas_texture import RenderAtlas
from atlasgen.shaders.include import render_include

LAMBERT, GLOSSY, TOON, MIPS, PLAIN = 0, 1, 2, 3, 4
#: Constant linear grey of each mip level of the ``mips`` slice (levels differ on purpose).
MIP_GREYS = np.array([0.9, 0.6, 0.35, 0.2, 0.1, 0.05, 0.02])
GLOSSY_SCALE = (2.0, 1.5)  # rgb, alpha: exercises the include's per-slice scale


def glossy_values(nl, nv):
    """A slice with colour, N.V dependence and a Fresnel-like specular scale (linear, pre-scale)."""
    rgb = np.maximum(nl, 0.0)[..., None] * np.array([1.6, 0.9, 0.3]) * (0.6 + 0.4 * nv)[..., None]
    alpha = 0.3 + 1.2 * (1.0 - nv) ** 5
    return np.concatenate([rgb, alpha[..., None]], -1)


def build_fixture_atlas() -> RenderAtlas:
    nl, nv = texel_grid()
    values = np.zeros((LAYERS, HEIGHT, WIDTH, 4))
    values[LAMBERT, ..., :3] = np.maximum(nl, 0.0)[..., None]
    values[GLOSSY] = glossy_values(nl, nv)
    toon = np.where(nl > 0.3, 0.9, 0.25) * np.where(nv > 0.2, 1.0, 0.4)
    values[TOON, ..., :3] = toon[..., None]
    values[PLAIN, ..., :3] = np.maximum(nl, 0.0)[..., None] * np.array([0.8, 0.7, 0.6])
    scales = np.ones((LAYERS, 2))
    scales[GLOSSY] = GLOSSY_SCALE
    stored = values / np.concatenate([np.repeat(scales[:, :1], 3, 1), scales[:, 1:]], 1)[:, None, None, :]
    float_levels = build_array_mips(np.clip(stored, 0.0, 1.0))
    for k, grey in enumerate(MIP_GREYS):
        float_levels[k][MIPS, ..., :3] = grey
        float_levels[k][MIPS, ..., 3] = 0.0
    levels = [quantize_rgba(lv, True) for lv in float_levels]
    entries = []
    for name, slot, outline in (("lambert", LAMBERT, False), ("glossy", GLOSSY, False), ("toon", TOON, True),
                                ("mips", MIPS, False), ("plain", PLAIN, False)):  # fmt: skip
        entries.append(MaterialEntry(
            name=name, id=slot, constant=f"MATERIAL_{name.upper()}", first_slice=slot, type="lambert",
            flags={"outline": outline}, scale=[scales[slot].tolist()], bias=[[0.0, 0.0]],
        ))  # fmt: skip
    manifest = Manifest(dimensions=Dimensions(width=WIDTH, height=HEIGHT, layers=LAYERS, mip_count=len(levels)),
                        encoding="srgb", dxgi_format=29, layout="array", materials=entries)  # fmt: skip
    include = render_include(manifest, scales, np.zeros((LAYERS, 2)), models=get_model)
    return RenderAtlas(levels, True, manifest, include, "fixture-atlas")


def decoded_slice(atlas: RenderAtlas, slot: int, level: int = 0) -> np.ndarray:
    """Linear RGBA of one slice as the sampler returns it, with the slice's scale applied."""
    rgba = dequantize_rgba(atlas.levels[level][slot], atlas.srgb)
    scale = atlas.manifest.by_slice(slot).scale[0]
    rgba[..., :3] *= scale[0]
    rgba[..., 3] *= scale[1]
    return rgba


def sample_bilinear(table: np.ndarray, n_dot_l, n_dot_v) -> np.ndarray:
    """Bilinear lookup with clamp-to-edge at the contract's (u, v); ``table`` is (H, W, C)."""
    h, w = table.shape[:2]
    u, v = atlas_uv(n_dot_l, n_dot_v, w, h)
    x = np.clip(u * w - 0.5, 0.0, w - 1.0)
    y = np.clip(v * h - 0.5, 0.0, h - 1.0)
    x0 = np.minimum(np.floor(x).astype(int), w - 2)
    y0 = np.minimum(np.floor(y).astype(int), h - 2)
    fx, fy = (x - x0)[..., None], (y - y0)[..., None]
    t = table
    return ((t[y0, x0] * (1 - fx) + t[y0, x0 + 1] * fx) * (1 - fy)
            + (t[y0 + 1, x0] * (1 - fx) + t[y0 + 1, x0 + 1] * fx) * fy)  # fmt: skip


def light_at(light, world: np.ndarray):
    """``(unit l, irradiance E)`` of a scene light at points ``world`` (..., 3): E = colour * I / d^2
    towards a point light, colour * E along a directional one.

    With a range r, written out here from docs/scenes.md (not taken from atlasgen.optics.falloff):
    E *= (1 - (d/r)^4)^2 for d < r, 0 beyond; a spot light scales E by 1 within its inner angle,
    (outer - theta) / (outer - inner) between the two, 0 beyond the outer one."""
    radiant = np.asarray(light.colour) * light.intensity
    if light.type in ("point", "spot"):
        d = np.asarray(light.position) - world
        d2 = np.sum(d * d, -1, keepdims=True)
        l = d / np.sqrt(d2)
        scale = np.ones_like(d2)
        if np.isfinite(light.range):
            dist = np.sqrt(d2)
            scale = np.where(dist < light.range, (1.0 - (dist / light.range) ** 4) ** 2, 0.0)
        if light.type == "spot":
            theta = np.degrees(np.arccos(np.clip(-np.sum(l * np.asarray(light.direction), -1, keepdims=True), -1, 1)))
            cone = np.clip((light.outer_angle - theta) / (light.outer_angle - light.inner_angle), 0.0, 1.0)
            scale = scale * cone
        return l, radiant * scale / d2
    return np.broadcast_to(-np.asarray(light.direction), world.shape), np.broadcast_to(radiant, world.shape)


def reference_radiance(atlas, scene, aovs, rays, specular: bool = True) -> np.ndarray:
    """The lighting equation evaluated in float64 numpy from the g-buffer read back.

    L = sum_lights E (albedo A.rgb / pi + A.a D V max(N.L, 0)), the GGX lobe written out
    here from docs/atlas-format.md (not taken from atlasgen.optics.specular):
    D = a^2 / (pi ((N.H)^2 (a^2 - 1) + 1)^2), V = 1 / (2 (N.L sqrt(N.V^2 (1 - a^2) + a^2) +
    N.V sqrt(N.L^2 (1 - a^2) + a^2))), a = max((1 - gloss)^2, 0.002), N.V clamped to [0, 1],
    E = I / d^2 (point) or E (directional), A bilinear at lod 0.
    """
    n = aovs["normal"].astype(np.float64)
    depth = aovs["depth"].astype(np.float64)
    ids = aovs["id"]
    albedo = aovs["albedo"].astype(np.float64)
    gloss = aovs["gloss"].astype(np.float64)
    covered = ids != 0xFFFF
    world = np.asarray(scene.camera.position) + rays * np.where(covered, depth, 0.0)[..., None]
    v = -rays / np.linalg.norm(rays, axis=-1, keepdims=True)
    n_dot_v = np.sum(n * v, -1)
    out = np.zeros(n.shape)
    a2 = np.maximum((1.0 - gloss) ** 2, 0.002) ** 2
    nv = np.clip(n_dot_v, 0.0, 1.0)
    for slot in np.unique(ids[covered]):
        table = decoded_slice(atlas, int(slot))
        mask = ids == slot
        for light in scene.lights:
            l, e = light_at(light, world)
            n_dot_l = np.sum(n * l, -1)
            a = sample_bilinear(table, n_dot_l, n_dot_v)
            h = l + v
            h = h / np.linalg.norm(h, axis=-1, keepdims=True)
            n_dot_h = np.sum(n * h, -1)
            nl = np.clip(n_dot_l, 0.0, 1.0)
            d = a2 / (np.pi * (n_dot_h**2 * (a2 - 1.0) + 1.0) ** 2)
            with np.errstate(divide="ignore", invalid="ignore"):  # V is infinite where N.L = N.V = 0: masked
                vis = 0.5 / (nl * np.sqrt(nv * nv * (1.0 - a2) + a2) + nv * np.sqrt(nl * nl * (1.0 - a2) + a2))
                spec = np.where((n_dot_l > 0) & (n_dot_h > 0), d * vis * nl, 0.0)
            contrib = e * (albedo * a[..., :3] / np.pi + (a[..., 3] * spec * specular)[..., None])
            out[mask] += contrib[mask]
    out[~covered] = scene.background
    return out


def interior(ids: np.ndarray, margin: int = 1) -> np.ndarray:
    """Covered pixels whose (2 margin + 1)^2 neighbourhood has one material only (no silhouettes)."""
    h, w = ids.shape
    pad = np.pad(ids, margin, mode="edge")
    same = np.ones_like(ids, dtype=bool)
    for dy in range(-margin, margin + 1):
        for dx in range(-margin, margin + 1):
            same &= pad[margin + dy : margin + dy + h, margin + dx : margin + dx + w] == ids
    return same & (ids != 0xFFFF)
