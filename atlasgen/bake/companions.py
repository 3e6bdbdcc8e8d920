"""The bytes a bake writes beside an atlas, made again from its manifest: what ``atlasgen info`` holds an include or
the separable side-car to before it calls it "this bake".

The includes' first line and the side-car's header record the manifest's SHA-256, which says which bake a file
came from, not that it is still what that bake wrote: an include whose material constant was edited (50u made 51u),
or cut in half, kept its first line and was reported as of this bake. Every byte of them follows from the manifest
(:func:`~atlasgen.shaders.include.render_include`, :func:`~atlasgen.shaders.include.render_include_data`), so the
files are compared with what it gives.
"""

from __future__ import annotations

from atlasgen.io.atlas import Atlas
from atlasgen.io.sidecar import stamp_sidecar
from atlasgen.models import get_model
from atlasgen.shaders.include import manifest_scale_bias, render_include, render_include_data, stamp_include

__all__ = ["expected_companions"]

#: The includes' suffixes by the language each is written in.
_LANGUAGES = {".wgsl": "wgsl", ".glsl": "glsl", ".hlsl": "hlsl"}


def expected_companions(atlas: Atlas) -> dict[str, bytes]:
    """``suffix -> bytes`` of each file :data:`atlasgen.io.atlas.COMPANIONS` names, as a bake of ``atlas``'s manifest
    writes it (the side-car only where a material is separable). The manifest must have passed
    :func:`~atlasgen.models.check_manifest_models`: its entries' models make the text."""
    manifest = atlas.manifest
    sha256 = bytes.fromhex(atlas.manifest_sha256)
    scales, biases = manifest_scale_bias(manifest)
    out = {suffix: stamp_include(render_include(manifest, scales, biases, lang, models=get_model), sha256).encode()
           for suffix, lang in _LANGUAGES.items()}  # fmt: skip
    data = render_include_data(manifest, models=get_model)
    if data:
        out[".separable.bin"] = stamp_sidecar(data, sha256)
    return out
