"""A Mitsuba 3 BSDF, given as a dict, evaluated vectorised with ``BSDF.eval`` in ``llvm_ad_rgb``.

Mitsuba and Dr.Jit are imported here only, inside functions: a LUT-only bake never loads them.
"""

from __future__ import annotations

import re

import numpy as np

from atlasgen.backend_messages import native_lines_of_a_failure_dropped
from atlasgen.contract import SPECULAR_ALPHA_MIN, SPECULAR_ROUGHNESS_MIN
from atlasgen.errors import BackendError, InputError, MaterialError, did_you_mean, shorten
from atlasgen.interrupts import deferred_interrupts
from atlasgen.io.fields import fits_float32, is_number, shown
from atlasgen.io.oiio import import_oiio
from atlasgen.io.text import read_input_bytes, special_file_kind

__all__ = [
    "VARIANT",
    "unheld_in_bsdf",
    "transmitting_field",
    "BSDF_PROPERTIES",
    "load_mitsuba_bsdf",
    "explain_mitsuba_error",
    "evaluate_mitsuba_f_cos",
    "bsdf_alpha",
    "transmitted_fractions",
    "delta_fractions",
    "bsdf_lobes",
    "describe_lobes",
    "TRANSMISSION_VIEWS",
]

VARIANT = "llvm_ad_rgb"

_IOR = ("int_ior", "ext_ior")
_ROUGH = ("distribution", "alpha", "alpha_u", "alpha_v", "sample_visible")
#: Mitsuba 3's BSDF plugins and their named properties (Mitsuba 3 docs, "Plugin reference: BSDFs");
#: used only to suggest a spelling when Mitsuba reports an unreferenced property. Nested BSDFs
#: (``twosided``, ``blendbsdf``, ``mask``, ...) take them under any key.
BSDF_PROPERTIES = {
    "diffuse": ("reflectance",),
    "conductor": ("material", "eta", "k", "specular_reflectance"),
    "roughconductor": ("material", "eta", "k", "specular_reflectance", *_ROUGH),
    "dielectric": (*_IOR, "specular_reflectance", "specular_transmittance"),
    "thindielectric": (*_IOR, "specular_reflectance", "specular_transmittance"),
    "roughdielectric": (*_IOR, "specular_reflectance", "specular_transmittance", *_ROUGH),
    "plastic": (*_IOR, "diffuse_reflectance", "specular_reflectance", "nonlinear"),
    "roughplastic": (
        *_IOR,
        "diffuse_reflectance",
        "specular_reflectance",
        "nonlinear",
        "distribution",
        "alpha",
        "sample_visible",
    ),  # fmt: skip
    "principled": (
        "base_color",
        "roughness",
        "anisotropic",
        "metallic",
        "spec_trans",
        "eta",
        "specular",
        "spec_tint",
        "sheen",
        "sheen_tint",
        "flatness",
        "clearcoat",
        "clearcoat_gloss",
    ),  # fmt: skip
    "principledthin": (
        "base_color",
        "roughness",
        "anisotropic",
        "spec_trans",
        "eta",
        "spec_tint",
        "sheen",
        "sheen_tint",
        "flatness",
        "diff_trans",
    ),  # fmt: skip
    "twosided": (),
    "blendbsdf": ("weight",),
    "mask": ("opacity",),
    "bumpmap": (),
    "normalmap": (),
    "null": (),
    "pplastic": (*_IOR, "diffuse_reflectance", "specular_reflectance", "alpha"),
    "hair": (
        "eumelanin",
        "pheomelanin",
        "sigma_a",
        "reflectance",
        "int_ior",
        "longitudinal_roughness",
        "azimuthal_roughness",
        "scale_tilt",
    ),  # fmt: skip
    "measured": ("filename",),
}
_COLOUR = 'expected {type = "rgb", value = [r, g, b]}, a spectrum or a number'
_PROPERTY_TYPES = {"vector": "a list", "string": "a string", "boolean": "true/false", "float": "a number",
                   "integer": "an integer"}  # fmt: skip


def _one_line(message) -> str:
    """Mitsuba's message on one line, without its source-file tags (``[parser.cpp:123]``)."""
    parts = (re.sub(r"\[[\w.]+(?::\d+)?\]\s*", "", part).strip(" -") for part in str(message).splitlines())
    return "; ".join(part for part in parts if part)


def _mitsuba():
    # A Ctrl-C during start-up is raised as KeyboardInterrupt once it is over, never as
    # the failure it would cause inside it (see atlasgen.interrupts).
    with deferred_interrupts():
        try:
            import mitsuba as mi
        except ImportError as exc:  # pragma: no cover - depends on the installation
            raise BackendError(f"Mitsuba 3 is not installed ({exc}); install the 'mitsuba' extra") from None
        if mi.variant() != VARIANT:
            try:
                mi.set_variant(VARIANT)
            except Exception as exc:  # pragma: no cover - depends on the installation
                raise BackendError(f"Mitsuba variant {VARIANT!r} is unavailable: {_one_line(exc)}") from None
    return mi


def _nodes(spec: dict, prefix: str):
    """``(mitsuba node name, dotted field, dict)`` for ``spec`` and every table nested in it;
    Mitsuba names a node by its key, and the top one ``root``."""
    yield "root", prefix, spec
    stack = [(prefix, spec)]
    while stack:
        where, node = stack.pop(0)
        for key, value in node.items():
            if isinstance(value, dict):
                yield key, f"{where}.{key}", value
                stack.append((f"{where}.{key}", value))


def unheld_in_bsdf(spec: dict, field: str = "bsdf") -> list[str]:
    """What of the BSDF table ``spec`` a slice does not hold though the bake takes it, one clause each, naming its
    dotted key: a rough lobe sharper than the renderer's sharpest (alpha below ``SPECULAR_ALPHA_MIN``), whose
    highlight falls between the fit's samples, so the fit's own figure never sees it; and a ``mask``'s opacity
    below 1, the light it lets through (no slice holds transmission: an object's opacity is the scene's).

    >>> unheld_in_bsdf({"type": "roughconductor", "alpha": 1e-4})[0].split(":")[0]
    'bsdf.alpha = 0.0001'
    >>> unheld_in_bsdf({"type": "mask", "opacity": 0.5, "material": {"type": "diffuse"}})[0].split(":")[0]
    'bsdf.opacity = 0.5'
    >>> unheld_in_bsdf({"type": "principled", "roughness": 0.0})[0].split(":")[0]
    'bsdf.roughness = 0'
    >>> unheld_in_bsdf({"type": "roughconductor", "alpha": {"type": "checkerboard"}})[0].split(":")[0]
    'bsdf.alpha = a texture'
    >>> unheld_in_bsdf({"type": "roughconductor", "alpha": 0.2})
    []
    """
    out = []
    for _, where, node in _nodes(spec, field):
        for key in ("alpha", "alpha_u", "alpha_v", "roughness"):
            value = node.get(key)
            limit = SPECULAR_ROUGHNESS_MIN if key == "roughness" else SPECULAR_ALPHA_MIN
            # 0 too: a GGX lobe of alpha 0 is a mirror, its spike baked as a scale of 1e5 that the fit never sees.
            if is_number(value) and 0.0 <= value < limit:
                out.append(f"{where}.{key} = {value:g}: a lobe sharper than the renderer's sharpest (alpha "
                           f"{SPECULAR_ALPHA_MIN:g}), whose highlight falls between the fit's samples")  # fmt: skip
            elif isinstance(value, dict):
                out.append(f"{where}.{key} = a texture: a lobe whose sharpness is read at uv (0.5, 0.5) and not checked "
                           f"against the renderer's sharpest (alpha {SPECULAR_ALPHA_MIN:g})")  # fmt: skip
        opacity = node.get("opacity", 0.5)
        if node.get("type") == "mask" and (not is_number(opacity) or opacity < 1.0):
            shown_opacity = f"{opacity:g}" if is_number(opacity) else "a texture"
            out.append(f"{where}.opacity = {shown_opacity}: the light a mask lets through, which no slice holds (an "
                       "object's opacity is the scene's)")  # fmt: skip
    return out


def _node(spec: dict, field: str, name: str | None) -> tuple[str, dict]:
    return next(((where, node) for key, where, node in _nodes(spec, field) if key == name), (field, spec))


def _toml(value) -> str:
    """``value`` as TOML writes it, lists too: ``[true, "0.5", [0.5]]``."""
    return f"[{', '.join(_toml(v) for v in value)}]" if isinstance(value, list) else _shown(value).replace("'", '"')


def _shown(value) -> str:
    return "true" if value is True else "false" if value is False else repr(value) if isinstance(value, str) else str(value)


def explain_mitsuba_error(message: str, spec: dict, field: str = "bsdf") -> tuple[str, str]:
    """The offending key (a dotted field under ``field``) and a one-line explanation of an
    error ``mi.load_dict(spec)`` raised.

    Mitsuba names the dict node (``At dictionary node "reflectance"``, ``root`` for the top)
    and, where it can, the property (``The property "alpha" has the wrong type``,
    ``unreferenced property ... "alhpa"``); both are looked up in ``spec``. Mitsuba's own text
    follows in parentheses, without its source-file tags, on one line.
    """
    text = "; ".join(part.strip(" -") for part in str(message).splitlines() if part.strip(" -"))
    plain = _one_line(message)
    node_name = re.search(r'dictionary node "([^"]+)"', text)
    where, node = _node(spec, field, node_name.group(1) if node_name else None)
    mitsuba = f"(Mitsuba: {plain})"
    if m := re.search(r'Plugin "([^"]+)" not found', text):
        return f"{where}.type", (f"expected a Mitsuba BSDF plugin such as {', '.join(sorted(BSDF_PROPERTIES)[:6])}, ..., "
                                 f"got {m.group(1)!r}{did_you_mean(m.group(1), BSDF_PROPERTIES)} {mitsuba}")  # fmt: skip
    if m := re.search(r'unreferenced propert\w+ in \w+ plugin of type "([^"]+)":;\s*\S+ "([^"]+)"', text):
        plugin, key = m.groups()
        known = BSDF_PROPERTIES.get(plugin, ())
        listed = f"one of {', '.join(known)}" if known else "a property it takes"
        return f"{where}.{key}", f"unknown property of a {plugin!r} BSDF; expected {listed}{did_you_mean(key, known)} {mitsuba}"
    if m := re.search(r'The property "([^"]+)" has the wrong type \(expected ([^,)]+)[^)]*, got (\w+)\)', text):
        key, expected, got = m.groups()
        value = _shown(node.get(key, got))
        if "color" in expected or "spectrum" in expected:
            return f"{where}.{key}", f"{_COLOUR}, got {value} {mitsuba}"
        return f"{where}.{key}", f"expected {_PROPERTY_TYPES.get(expected, expected)}, got {value} {mitsuba}"
    if m := re.search(r'\[(\w+)\] could not interpret "([^"]*)" as a color', text):
        key = m.group(1)
        where = next((w for k, w, _ in _nodes(spec, field) if k == key), f"{field}.{key}")
        return where, f'expected {{type = "rgb", value = [r, g, b]}} (three numbers), got value = {m.group(2)} {mitsuba}'
    # Otherwise the message quotes the bad value (an IOR name, a distribution): name its key.
    quoted = set(re.findall(r'"([^"]+)"', text))
    for w, n in [(where, node)] + [(w, n) for _, w, n in _nodes(spec, field)]:
        key = next((k for k, v in n.items() if isinstance(v, str) and k != "type" and v in quoted), None)
        if key is None and isinstance(n.get("material"), str) and f"/{n['material']}." in text:
            key = "material"  # a conductor's unknown material: Mitsuba quotes the file it looked for
        if key is not None:
            return f"{w}.{key}", f"Mitsuba rejected {_shown(n[key])} {mitsuba}"
    return where, f"Mitsuba rejected the BSDF {node.get('type')!r} {mitsuba}"


#: Microfacet roughness keys and the range a bake accepts for them (the ``alpha`` of the
#: analytic sources is (0, 4] too); Mitsuba itself takes any number, and a negative one
#: gives factors of 1e5 and more. ``roughness`` is the principled BSDF's, in [0, 1].
ROUGHNESS_RANGES = {"alpha": (0.0, 4.0), "alpha_u": (0.0, 4.0), "alpha_v": (0.0, 4.0), "roughness": (0.0, 1.0)}


#: Properties that hold a reflectance, transmittance or colour (Mitsuba 3 docs, "Plugin reference: BSDFs"),
#: and a conductor's complex index: physical values are >= 0, and a negative one is a sign error, not a look.
COLOUR_KEYS = ("reflectance", "diffuse_reflectance", "specular_reflectance", "specular_transmittance", "base_color",
               "eta", "k")  # fmt: skip
#: Properties that weigh two things against each other, in [0, 1]: ``blendbsdf``'s ``weight``, ``mask``'s
#: ``opacity`` and the principled BSDFs' lobe weights (Mitsuba 3 docs, "blendbsdf", "mask", "principled").
WEIGHT_KEYS = ("weight", "opacity", "metallic", "spec_trans", "spec_tint", "sheen", "sheen_tint", "flatness", "clearcoat",
               "clearcoat_gloss", "anisotropic", "diff_trans")  # fmt: skip
_CONDUCTORS = ("conductor", "roughconductor")


def _colour_numbers(value) -> list | None:
    """The numbers of a colour property (a number, ``{type = "rgb", value = [r, g, b]}``, or a
    ``{type = "spectrum"}`` of one value or ``[[wavelength, value], ...]``), or None for another form
    (a texture): Mitsuba reads those itself."""
    if is_number(value):
        return [value]
    if not isinstance(value, dict):
        return None
    inner = value.get("value")
    if value.get("type") == "rgb" and isinstance(inner, list):
        return [x for x in inner if is_number(x)]
    if value.get("type") == "uniform" and is_number(inner):
        return [inner]
    if value.get("type") == "spectrum":
        if is_number(inner):
            return [inner]
        if isinstance(inner, list):
            return [pair[1] for pair in inner if isinstance(pair, list) and len(pair) == 2 and is_number(pair[1])]
    return None  # a texture, or a spectrum file: _check_tables reads that, once


#: Bytes a spectrum file may have: a measured one is a few kB.
_SPECTRUM_BYTES = 1 << 20
#: A number as Mitsuba's spectrum files write it.
_SPECTRUM_NUMBER = re.compile(r"[+-]?(?:\d+\.?\d*|\.\d+)(?:[eE][+-]?\d+)?")


def read_spectrum_file(filename) -> list[list[float]]:
    """The ``[wavelength, value]`` pairs of a spectrum file, as Mitsuba's ``spectrum`` plugin reads one: a pair a
    line, ``#`` starting a comment; at least two, the wavelengths increasing.

    Mitsuba checks an inline spectrum's pairs but not a file's: an unsorted file, or one of one line, baked all
    black with exit 0, and a negative one passed the check of a negative reflectance.

    Raises
    ------
    InputError
        The file cannot be read (missing, a folder or a pipe, over 1 MB).
    ValueError
        A line that is not two numbers, fewer than two pairs, or wavelengths not increasing; the message says which.
    """
    text = read_input_bytes(filename, limit=(_SPECTRUM_BYTES, "a spectrum file")).decode("utf-8", errors="replace")
    pairs = []
    for number, line in enumerate(text.splitlines(), 1):
        words = line.split("#", 1)[0].split()
        if not words:
            continue
        if len(words) != 2 or not all(_SPECTRUM_NUMBER.fullmatch(w) for w in words):
            raise ValueError(f"line {number} is {shorten(repr(line.strip()))}; expected 'wavelength value', two numbers")
        pairs.append([float(w) for w in words])
    if len(pairs) < 2:
        raise ValueError(f"{len(pairs)} wavelength-value pairs; expected at least 2")
    for (a, _), (b, _) in zip(pairs, pairs[1:], strict=False):
        if not b > a:
            raise ValueError(f"wavelength {b:g} after {a:g}; expected the wavelengths increasing")
    return pairs


def _check_tables(spec: dict, path, field: str) -> None:
    """Refuse a colour table whose values are not numbers (a ``true`` read as 1, a string failed in nanobind with a
    second line), a spectrum file that Mitsuba would read as black (:func:`read_spectrum_file`), and a ``volume``
    texture without the volume it reads (Mitsuba crashed on it: SIGSEGV, no line at all)."""
    kind, value = spec.get("type"), spec.get("value")
    if kind == "rgb" and "value" in spec and not (is_number(value) or (
            isinstance(value, list) and len(value) == 3 and all(is_number(v) for v in value))):  # fmt: skip
        # As Mitsuba's own refusal of two numbers is explained (explain_mitsuba_error), naming the colour.
        raise MaterialError(
            path, field, f'expected {{type = "rgb", value = [r, g, b]}} (three numbers), got value = {_toml(value)}'
        )
    if kind == "spectrum" and "value" in spec and not (is_number(value) or (isinstance(value, list) and all(
            isinstance(p, list) and len(p) == 2 and all(is_number(x) for x in p) for p in value))):  # fmt: skip
        raise MaterialError(path, f"{field}.value", f"expected a number or [[wavelength, value], ...], pairs of numbers, "
                                                    f"got {_toml(value)}")  # fmt: skip
    if kind == "spectrum" and isinstance(spec.get("filename"), str):
        try:
            pairs = read_spectrum_file(spec["filename"])
        except InputError as exc:
            raise MaterialError(path, f"{field}.filename", f"expected a spectrum file Mitsuba reads: {exc}") from None
        except ValueError as exc:
            raise MaterialError(path, f"{field}.filename", f"{shorten(spec['filename'])}: {exc}") from None
        parent, _, key = field.rpartition(".")
        if key in COLOUR_KEYS:  # the colour this spectrum is, checked as its parent checks an inline one
            _refuse_negative(path, parent, key, [v for _, v in pairs], spec)
    if kind == "volume" and not isinstance(spec.get("volume"), dict):
        raise MaterialError(path, f"{field}.volume", f"expected the volume a volume texture reads (a table, e.g. "
                                                     f"{{type = \"constvolume\", value = 0.5}}), got {_shown(spec.get('volume'))}")  # fmt: skip


def _refuse_negative(path, field: str, key: str, numbers, value) -> None:
    """Refuse the colour ``key`` of the table at ``field`` where one of its ``numbers`` is negative."""
    if numbers and min(numbers) < 0.0:
        noun = "a complex index part" if key in ("eta", "k") else "a reflectance"
        raise MaterialError(path, f"{field}.{key}", f"expected {noun} >= 0 in every channel, got {shown(value)}")


def _check_meaningful(spec: dict, path, field: str) -> None:
    """Refuse what no material means: a negative colour (:data:`COLOUR_KEYS`), a weight outside [0, 1]
    (:data:`WEIGHT_KEYS`), a conductor with eta = k = 0 (its Fresnel term is 0/0: NaN in every sample)."""
    for key in COLOUR_KEYS:
        if key in spec:
            _refuse_negative(path, field, key, _colour_numbers(spec[key]), spec[key])
    for key in WEIGHT_KEYS:
        value = spec.get(key)
        if is_number(value) and not 0.0 <= value <= 1.0:
            raise MaterialError(path, f"{field}.{key}", f"expected a weight in [0, 1], got {shown(value)}")
    if spec.get("type") in _CONDUCTORS and "eta" in spec and "k" in spec:
        eta, k = _colour_numbers(spec["eta"]), _colour_numbers(spec["k"])
        if eta and k and not any(eta) and not any(k):
            raise MaterialError(path, f"{field}.eta", "expected eta or k > 0 for a conductor, got eta = k = 0 "
                                                      "(its Fresnel reflectance is 0/0)")  # fmt: skip


#: Most texels a ``bitmap`` texture may declare, 8192 x 8192: Mitsuba allocates what the file's header says, and
#: an 875 KB PNG declaring 30000 x 30000 crashed the bake (SIGSEGV: no line at all).
MAX_BITMAP_TEXELS = 8192 * 8192


class _Unopened(Exception):
    """OpenImageIO could not open a texture (it returns None, and keeps its message)."""


def _check_bitmap(spec: dict, path, field: str) -> None:
    """Refuse a ``bitmap`` texture whose header declares more than :data:`MAX_BITMAP_TEXELS`, read from the header
    alone (a file that does not open is left to Mitsuba, whose complaint names it)."""
    filename = spec.get("filename")
    if spec.get("type") != "bitmap" or not isinstance(filename, str) or special_file_kind(filename) is not None:
        return
    oiio = import_oiio()

    try:
        # A file libpng cannot read printed "libpng error: ... bad header" before Mitsuba's refusal, which says it too.
        with native_lines_of_a_failure_dropped():
            image = oiio.ImageInput.open(filename)
            if image is None:
                raise _Unopened
    except _Unopened:
        # Taken, or OpenImageIO prints it at exit ("exited with a pending error message"): three more lines after
        # Mitsuba's refusal, which names the file.
        oiio.geterror()
        return
    try:
        width, height = image.spec().width, image.spec().height
    finally:
        image.close()
    if width * height > MAX_BITMAP_TEXELS:
        raise MaterialError(path, f"{field}.filename", f"expected a texture of at most {MAX_BITMAP_TEXELS} texels, "
                            f"got {width} x {height} in {shorten(filename)}")  # fmt: skip


def _flattened(value):
    """The items of ``value``, nested lists opened (a spectrum's pairs); ``value`` itself where it is no list.

    >>> list(_flattened([[400.0, 0.5], [700.0, 0.25]])), list(_flattened(0.5))
    ([400.0, 0.5, 700.0, 0.25], [0.5])
    """
    if not isinstance(value, list):
        yield value
        return
    for item in value:
        yield from _flattened(item)


def _check_bsdf_values(spec: dict, path, field: str) -> None:
    """Every number of the (nested) BSDF table finite in float32, every roughness in range,
    every ``type`` a plugin name, every colour and weight meaningful (:func:`_check_meaningful`):
    one-line errors naming ``bsdf.key``."""
    plugin = spec.get("type")
    if not isinstance(plugin, str) or not plugin:
        raise MaterialError(path, f"{field}.type", f"expected a Mitsuba plugin name (a string), got {shown(plugin)}")
    _check_bitmap(spec, path, field)
    _check_tables(spec, path, field)
    for key, value in spec.items():
        where = f"{field}.{key}"
        if isinstance(value, dict):
            _check_bsdf_values(value, path, where)
            continue
        # Nested too: a spectrum's [[wavelength, value], ...] pairs hid a NaN until the bake's samples, 6 s later.
        for number in _flattened(value):
            if is_number(number) and not fits_float32(number):
                raise MaterialError(path, where, f"expected a finite float32 number, got {shown(value)}")
        if key == "id" and not isinstance(value, str):  # Mitsuba's own: "std::bad_cast", naming the table
            raise MaterialError(path, where, f"expected a name (Mitsuba's id of the table, a string), got {_shown(value)}")
        if key in ROUGHNESS_RANGES and not is_number(value):  # a texture table went on above
            raise MaterialError(path, where, f"expected a roughness (a number, or a texture table), got {_shown(value)}")
        if key in ROUGHNESS_RANGES and is_number(value):
            lo, hi = ROUGHNESS_RANGES[key]
            ok = (value > lo or (key == "roughness" and value == lo)) and value <= hi
            if not ok:
                bounds = f"in [{lo:g}, {hi:g}]" if key == "roughness" else f"> {lo:g} and <= {hi:g}"
                raise MaterialError(path, where, f"expected a roughness {bounds}, got {shown(value)}")
    _check_meaningful(spec, path, field)


#: Plugins whose lobe is smooth (a delta): ``BSDF.eval`` returns 0 for it (Mitsuba 3 docs, "BSDF.eval").
_DELTA_PLUGINS = ("plastic", "conductor", "dielectric", "thindielectric")


def _anisotropy_field(spec: dict, field: str) -> str:
    """The dotted key that makes ``spec`` anisotropic: ``alpha_v`` (or ``alpha_u``), a principled
    ``anisotropic``, else the table itself."""
    for _, where, node in _nodes(spec, field):
        if node.get("alpha_u") != node.get("alpha_v"):
            return f"{where}.alpha_v" if "alpha_v" in node else f"{where}.alpha_u"
        if node.get("anisotropic"):
            return f"{where}.anisotropic"
    return field


def _delta_field(spec: dict, field: str) -> tuple[str, str]:
    """The dotted ``type`` key of the first smooth (delta) plugin in ``spec``, and that plugin."""
    for _, where, node in _nodes(spec, field):
        if node.get("type") in _DELTA_PLUGINS:
            return f"{where}.type", str(node["type"])
    return f"{field}.type", str(spec.get("type"))


def transmitting_field(spec: dict, field: str = "bsdf") -> tuple[str, str] | None:
    """The dotted ``type`` key of the innermost BSDF table in ``spec`` that transmits light, and its plugin (a
    ``blendbsdf``'s ``roughdielectric``, not the blend); None where none does. Each table is loaded alone."""
    mi = _mitsuba()
    found = None
    for _, where, node in _nodes(spec, field):
        if not isinstance(node.get("type"), str):
            continue
        try:
            obj = mi.load_dict(dict(node))
        except Exception:  # a table Mitsuba loads only within its parent (or no BSDF): not this question's
            continue
        if isinstance(obj, mi.BSDF) and bsdf_lobes(obj, mi)["transmits"]:
            found = (f"{where}.type", node["type"])
    return found


def bsdf_lobes(bsdf, mi) -> dict:
    """``{"anisotropic": bool, "delta_components": int, "transmits": bool}`` of a loaded BSDF: Mitsuba's
    ``Anisotropic`` flag, how many of its components (``BSDF.flags(i)``) carry ``DeltaReflection``, and whether
    it transmits light beside reflecting it."""
    delta = sum(mi.has_flag(bsdf.flags(i), mi.BSDFFlags.DeltaReflection) for i in range(bsdf.component_count()))
    flags = bsdf.flags()
    # Mitsuba's Transmission mask includes Null: a thin dielectric's straight-through transmission is flagged Null
    # alone. With a reflection: the null BSDF (Null and no reflection) is refused apart, by load_mitsuba_bsdf.
    transmits = mi.has_flag(flags, mi.BSDFFlags.Transmission) and mi.has_flag(flags, mi.BSDFFlags.Reflection)
    return {"anisotropic": bool(mi.has_flag(flags, mi.BSDFFlags.Anisotropic)), "delta_components": int(delta),
            "transmits": bool(transmits)}  # fmt: skip


def load_mitsuba_bsdf(
    spec: dict,
    path,
    field: str = "bsdf",
    reflection_only: bool | None = None,
    anisotropic: bool | str | None = None,
    rough_only: bool | str | None = None,
):
    """Instantiate a Mitsuba BSDF from a dict (``mi.load_dict``).

    The table is checked first (numbers finite in float32, roughness in range, ``type``
    a name, colours >= 0, weights in [0, 1], no conductor with eta = k = 0); the BSDF must
    reflect light diffusely or glossily, since smooth (delta) lobes and the ``null`` BSDF
    evaluate to zero everywhere and leave nothing to factor.
    With ``reflection_only = False`` a BSDF that transmits light (``roughdielectric``,
    ``dielectric``, ``thindielectric``, ...) is refused, since a slice holds reflection
    only; ``True`` accepts it, ``None`` (the default) does not check.
    ``anisotropic`` and ``rough_only`` do the same for Mitsuba's ``Anisotropic`` flag (a slice
    of (N.L, N.V) cannot hold a response that turns with the azimuth) and for a component with
    ``DeltaReflection`` beside the rough ones (``BSDF.eval`` omits it, so the fit would drop it
    unseen): ``False`` refuses, ``True`` accepts, ``None`` does not check. A string in place of
    ``False`` refuses and names what to set instead (the model's consent field, or a remedy).

    Raises
    ------
    MaterialError
        The dict is not a BSDF Mitsuba accepts: one line naming the file and the
        offending key (``bsdf.reflectance``), what was expected, and Mitsuba's own
        complaint (:func:`explain_mitsuba_error`).
    BackendError
        Mitsuba or its ``llvm_ad_rgb`` variant is missing.
    """
    if not isinstance(spec, dict) or "type" not in spec:
        raise MaterialError(path, field, f"expected a Mitsuba BSDF table with a 'type' key, got {shown(spec)}")
    _check_bsdf_values(spec, path, field)
    mi = _mitsuba()
    try:
        with native_lines_of_a_failure_dropped():
            obj = mi.load_dict(dict(spec))
    except Exception as exc:
        raise MaterialError(path, *explain_mitsuba_error(str(exc), spec, field)) from None
    if not isinstance(obj, mi.BSDF):
        raise MaterialError(path, field, f"expected a Mitsuba BSDF plugin, got a {type(obj).__name__} ({spec.get('type')!r})")
    flags = obj.flags()
    lobes = bsdf_lobes(obj, mi)
    if reflection_only is False and lobes["transmits"]:
        raise MaterialError(path, f"{field}.type", f"a {spec['type']!r} BSDF transmits light, which a separable slice "
                                                   "cannot hold; set reflection_only = true to bake its reflection alone")  # fmt: skip
    if not (mi.has_flag(flags, mi.BSDFFlags.GlossyReflection) or mi.has_flag(flags, mi.BSDFFlags.DiffuseReflection)):
        raise MaterialError(path, f"{field}.type", f"expected a BSDF with a diffuse or glossy reflection, got {spec['type']!r}, "
                                                   "which has none (smooth and null lobes evaluate to zero)")  # fmt: skip
    if lobes["anisotropic"] and anisotropic is not None and anisotropic is not True:
        remedy = anisotropic if isinstance(anisotropic, str) else "set accept_anisotropy = true to bake it anyway"
        raise MaterialError(path, _anisotropy_field(spec, field), f"expected an isotropic BSDF: a {spec['type']!r} BSDF that "
                            f"turns with the azimuth cannot be held by an (N.L, N.V) slice; {remedy} "
                            "(its measured error is recorded and printed)")  # fmt: skip
    if lobes["delta_components"] and rough_only is not None and rough_only is not True:
        where, plugin = _delta_field(spec, field)
        remedy = rough_only if isinstance(rough_only, str) else "or set rough_only = true to bake its rough lobes alone"
        raise MaterialError(path, where, f"expected rough lobes only: a {plugin!r} BSDF has a smooth (delta) reflection, which "
                                         f"BSDF.eval omits and a slice cannot hold; use its rough form, {remedy} "
                                         "(the dropped fraction is recorded)")  # fmt: skip
    _check_evaluates(obj, spec, path, field)
    return obj


def _check_evaluates(obj, spec: dict, path, field: str) -> None:
    """Refuse a BSDF that loads but does not evaluate in the RGB variant: a ``blackbody`` spectrum loads and then
    raised "Not implemented for non-spectral modes" mid-bake, an internal error. One pair is evaluated here."""
    try:
        evaluate_mitsuba_f_cos(obj, np.array([[0.0, 0.6, 0.8]]), np.array([[0.0, -0.6, 0.8]]))
    except RuntimeError as exc:
        mitsuba = " ".join(str(exc).split())
        node = next((where for _, where, n in _nodes(spec, field) if n.get("type") == "blackbody"), None)
        if node is not None:
            raise MaterialError(path, node, f"expected a spectrum Mitsuba's RGB variant evaluates, got a blackbody, "
                                f"which needs a spectral one (Mitsuba: {mitsuba})") from None  # fmt: skip
        raise MaterialError(path, field, f"expected a BSDF Mitsuba's RGB variant evaluates (Mitsuba: {mitsuba})") from None


def describe_lobes(spec: dict) -> dict:
    """:func:`bsdf_lobes` of the BSDF dict ``spec`` (loaded unchecked: its material was checked when read)."""
    mi = _mitsuba()
    return bsdf_lobes(load_mitsuba_bsdf(spec, "<describe_lobes>"), mi)


def evaluate_mitsuba_f_cos(bsdf, l, v) -> np.ndarray:
    """f cos(theta_l) of a loaded Mitsuba BSDF for unit (l, v) in the local frame (n = +z).

    Mitsuba's ``si.wi`` is the direction towards the viewer and ``wo`` the one
    towards the light; ``BSDF.eval`` returns f cos(theta_wo), which is f cos(theta_l)
    here (Mitsuba 3 docs, "BSDF.eval"). One call evaluates every pair.
    """
    mi = _mitsuba()
    import drjit as dr

    l = np.ascontiguousarray(np.asarray(l, dtype=np.float32).reshape(-1, 3))
    v = np.ascontiguousarray(np.asarray(v, dtype=np.float32).reshape(-1, 3))
    count = l.shape[0]
    si = dr.zeros(mi.SurfaceInteraction3f, count)
    si.wi = mi.Vector3f(v[:, 0], v[:, 1], v[:, 2])
    si.sh_frame = mi.Frame3f(mi.Vector3f(0.0, 0.0, 1.0))
    si.uv = mi.Point2f(0.5, 0.5)
    value = bsdf.eval(mi.BSDFContext(), si, mi.Vector3f(l[:, 0], l[:, 1], l[:, 2]))
    out = np.asarray(value, dtype=np.float64)
    return out.T.reshape(count, 3)


def bsdf_alpha(spec: dict) -> float | None:
    """The smallest microfacet roughness in a (nested) Mitsuba BSDF dict: ``alpha``,
    ``alpha_u``/``alpha_v``, or the principled BSDFs' ``roughness`` r as alpha = r^2
    (Mitsuba 3 docs, "principled"). None when the dict gives none (the estimator then
    measures the lobe from f, :func:`atlasgen.separable.source.measure_lobe_alpha`)."""
    found = []
    for _, _, node in _nodes(spec, "bsdf"):
        for key in ("alpha", "alpha_u", "alpha_v"):
            if isinstance(node.get(key), (int, float)) and not isinstance(node.get(key), bool):
                found.append(float(node[key]))
        if node.get("type") in ("principled", "principledthin") and isinstance(node.get("roughness"), (int, float)):
            found.append(max(float(node["roughness"]) ** 2, 1e-3))
    return min(found) if found else None


#: View angles (degrees from the normal) at which :func:`transmitted_fractions` measures.
TRANSMISSION_VIEWS = (0.0, 30.0, 60.0, 80.0)
_TRANSMISSION_SAMPLES = 1 << 16
_TRANSMISSION_SEED = 7


def transmitted_fractions(spec: dict, views=TRANSMISSION_VIEWS, samples: int = _TRANSMISSION_SAMPLES) -> list[dict]:
    """The fraction of a BSDF's response that is transmitted, T / (R + T), at each view angle.

    R and T are the directional albedos of the reflected and transmitted halves, each the
    mean of Mitsuba's ``BSDF.sample`` weight (f cos / pdf) over the samples whose
    direction leaves on that side (Mitsuba 3 docs, "BSDF.sample"), averaged over RGB.
    ``samples`` stratified-by-seed uniform numbers per angle (numpy PCG64, fixed seed), so
    the figure is deterministic. Returns ``[{"view_deg", "fraction"}, ...]``.
    """
    return _sampled_fractions(spec, views, samples, lambda mi, bs: np.asarray(bs.wo.z, dtype=np.float64) < 0.0)


def delta_fractions(spec: dict, views=TRANSMISSION_VIEWS, samples: int = _TRANSMISSION_SAMPLES) -> list[dict]:
    """The fraction of a BSDF's response in its smooth (delta) lobes, the part ``BSDF.eval`` omits,
    at each view angle: D / (D + S), with D and S the directional albedos of the samples whose
    ``sampled_type`` has Mitsuba's ``Delta`` flag and of the rest, measured as
    :func:`transmitted_fractions` measures T / (R + T). Returns ``[{"view_deg", "fraction"}, ...]``.
    """
    return _sampled_fractions(spec, views, samples, lambda mi, bs: mi.has_flag(bs.sampled_type, mi.BSDFFlags.Delta).numpy())


def _sampled_fractions(spec: dict, views, samples: int, selected) -> list[dict]:
    """The share of ``BSDF.sample``'s weight over the samples ``selected(mi, bs)`` marks, per view angle."""
    mi = _mitsuba()
    import drjit as dr

    bsdf = load_mitsuba_bsdf(spec, "<sampled_fractions>")
    rng = np.random.default_rng(_TRANSMISSION_SEED)
    out = []
    for degrees in views:
        theta = np.radians(degrees)
        xi = rng.random((3, samples)).astype(np.float32)
        si = dr.zeros(mi.SurfaceInteraction3f, samples)
        si.wi = mi.Vector3f(np.full(samples, np.sin(theta), np.float32), np.zeros(samples, np.float32),
                            np.full(samples, np.cos(theta), np.float32))  # fmt: skip
        si.sh_frame = mi.Frame3f(mi.Vector3f(0.0, 0.0, 1.0))
        si.uv = mi.Point2f(0.5, 0.5)
        bs, weight = bsdf.sample(mi.BSDFContext(), si, mi.Float(xi[0]), mi.Point2f(xi[1], xi[2]))
        w = np.asarray(weight, dtype=np.float64).reshape(3, -1).mean(axis=0)
        w = np.where(np.isfinite(w), w, 0.0)
        chosen = np.asarray(selected(mi, bs), dtype=bool)
        total = float(np.sum(w))
        fraction = float(np.sum(w[chosen]) / total) if total > 0.0 else 0.0
        out.append({"view_deg": float(degrees), "fraction": float(f"{fraction:.4g}")})
    return out
