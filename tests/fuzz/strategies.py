"""Hypothesis strategies for the fuzz suite: material and scene TOML, damaged DDS files and
output-path combinations, plus the checks every example must pass.

Values are drawn from a mix of plausible ones (inside each schema's bounds, so that
examples reach the bake and the renderer) and adversarial ones (the float32 edges, NaN,
infinities, 400-digit integers, wrong types), then written as TOML by a small writer;
some texts are then cut or corrupted to reach the parser's errors.
"""

from __future__ import annotations

import hashlib
import json
import math
import os
import re
import struct
from pathlib import Path

from hypothesis import HealthCheck, event, settings
from hypothesis import strategies as st

from atlasgen.errors import EXIT_CODES, EXIT_INTERNAL
from tests.toml_text import toml_document

__all__ = [
    "FUZZ",
    "DOCUMENTED",
    "material_toml",
    "scene_toml",
    "dds_damage",
    "damage_dds",
    "tree_hash",
    "check_result",
    "check_finite_bake",
]

# ---- profiles ------------------------------------------------------------------------------
# "ci" (the default) keeps the whole suite well under two minutes and draws the same
# examples every run; "fuzz" (``make fuzz``) draws many more, at random, for as long as it takes.
# The GPU error check (tests/conftest.py gpu_device) is function-scoped on purpose: it checks
# the device before and after the whole test, every example included.
_SUPPRESSED = [HealthCheck.too_slow, HealthCheck.data_too_large, HealthCheck.filter_too_much,
               HealthCheck.function_scoped_fixture]  # fmt: skip
settings.register_profile("ci", max_examples=30, deadline=None, derandomize=True, database=None,
                          suppress_health_check=_SUPPRESSED)  # fmt: skip
settings.register_profile("fuzz", max_examples=2000, deadline=None, suppress_health_check=_SUPPRESSED)
#: The profile the fuzz tests run under: ATLASGEN_FUZZ_PROFILE, else "ci".
FUZZ = settings.get_profile(os.environ.get("ATLASGEN_FUZZ_PROFILE", "ci"))

#: Exit statuses a command may end with on any input; 1 (an internal error) is a bug.
DOCUMENTED = {code for code, _ in EXIT_CODES} - {EXIT_INTERNAL}

# ---- values --------------------------------------------------------------------------------
FLOAT32_MAX = struct.unpack("<f", b"\xff\xff\x7f\x7f")[0]
EDGE_FLOATS = (0.0, -0.0, 1e-45, 5e-324, 1e-300, 1e-38, 0.5, 1.0, -1.0, 1e30, 1e38, FLOAT32_MAX, 3.5e38, 1e39,
               1e300, 1.7976931348623157e308, math.nan, math.inf, -math.inf)  # fmt: skip
EDGE_INTS = (0, 1, -1, 3, 255, 256, 2**31 - 1, 2**31, 2**32 + 1, 2**63, 10**400, -(10**400))

edge_numbers = st.one_of(st.sampled_from(EDGE_FLOATS), st.sampled_from(EDGE_INTS))
any_number = st.one_of(edge_numbers, st.floats(allow_nan=True, allow_infinity=True), st.integers(-(2**70), 2**70))
scalars = st.one_of(any_number, st.booleans(), st.text(max_size=12))
weird = st.recursive(scalars, lambda inner: st.one_of(st.lists(inner, max_size=4),
                                                      st.dictionaries(st.text(max_size=6), inner, max_size=3)),
                     max_leaves=8)  # fmt: skip


def _number_in(lo, hi, integer=False):
    lo = -1e6 if lo is None else lo
    hi = 1e6 if hi is None else hi
    if integer:
        return st.integers(int(math.ceil(lo)), int(math.floor(hi)))
    return st.floats(lo, hi)


def value_for(param, clean=False):
    """A value for one model parameter: plausible when ``clean``, else sometimes adversarial."""
    kind = param.kind
    if kind in ("float", "int"):
        plausible = _number_in(param.lo, param.hi, integer=kind == "int")
    elif kind == "bool":
        plausible = st.booleans()
    elif kind == "colour":
        plausible = st.one_of(st.lists(st.floats(0.0, 1.0), min_size=3, max_size=3),
                              st.from_regex(r"#[0-9a-fA-F]{6}", fullmatch=True))  # fmt: skip
    elif kind == "choice":
        plausible = st.sampled_from(param.choices)
    elif kind == "float_list":
        plausible = st.lists(_number_in(param.lo, param.hi), min_size=1, max_size=4)
    elif kind == "colour_list":
        plausible = st.lists(st.lists(st.floats(0.0, 1.0), min_size=3, max_size=3), min_size=1, max_size=4)
    else:  # "table": a Mitsuba BSDF
        plausible = mitsuba_bsdfs(clean)
    return plausible if clean else st.one_of(plausible, plausible, plausible, edge_numbers, weird)


def mitsuba_bsdfs(clean=False):
    if clean:
        return st.fixed_dictionaries({"type": st.sampled_from(["roughconductor", "roughplastic", "diffuse"])},
                                     optional={"alpha": st.floats(0.05, 1.0)})  # fmt: skip
    plugins = st.sampled_from(["roughconductor", "roughplastic", "diffuse", "null", "dielectric", "plastic",
                               "principled", "twosided", "nosuch"])  # fmt: skip
    alpha = st.one_of(st.floats(0.05, 1.0), edge_numbers)
    return st.fixed_dictionaries({"type": st.one_of(plugins, weird)},
                                 optional={"alpha": alpha, "roughness": alpha, "alpha_u": alpha})  # fmt: skip


@st.composite
def damaged_text(draw, text: str, clean=False) -> bytes:
    """``text`` as UTF-8: whole when ``clean``, else sometimes cut, spliced with bytes, or not UTF-8."""
    data = text.encode("utf-8", "surrogatepass")
    how = "whole" if clean else draw(st.sampled_from(["whole"] * 6 + ["cut", "splice", "latin1"]))
    if how == "cut":
        return data[: draw(st.integers(0, len(data)))]
    if how == "splice":
        at = draw(st.integers(0, len(data)))
        return data[:at] + draw(st.binary(max_size=8)) + data[at:]
    if how == "latin1":
        return data + b"# \xe9\xff\n"
    return data


# ---- materials -----------------------------------------------------------------------------
COMMON = {
    "rgb_scale": st.one_of(st.just("auto"), st.floats(0.5, 8.0), edge_numbers, weird),
    "alpha_scale": st.one_of(st.just("auto"), st.floats(0.5, 8.0), edge_numbers, weird),
    "error_budget": st.one_of(st.floats(0.005, 0.2), edge_numbers, weird),
    "id": st.one_of(st.integers(0, 255), edge_numbers, weird),
    "name": st.one_of(st.from_regex(r"[A-Za-z][A-Za-z0-9_-]{0,10}", fullmatch=True), st.text(max_size=70), weird),
    "description": st.one_of(st.text(max_size=20), weird),
}
COMMON_CLEAN = {
    "rgb_scale": st.one_of(st.just("auto"), st.floats(0.5, 8.0)),
    "alpha_scale": st.one_of(st.just("auto"), st.floats(0.5, 8.0)),
    "error_budget": st.floats(0.01, 0.2),
    "description": st.text(max_size=20),
}


@st.composite
def material_toml(draw, types) -> bytes:
    """One material file's bytes; ``types`` are the model types to draw from (plus junk).

    Half the examples are clean (plausible values only, so that they reach the bake);
    the rest mix in adversarial values, unknown keys and damaged text.
    """
    from atlasgen.models import MODEL_TYPES, get_model

    clean = draw(st.booleans())
    types = st.sampled_from(types)
    type_name = draw(types if clean else st.one_of(types, types, types, weird))
    data = {"type": type_name}
    if isinstance(type_name, str) and type_name in MODEL_TYPES:
        for param in get_model(type_name).params:
            if draw(st.integers(0, 2)) == 0:
                data[param.name] = draw(value_for(param, clean))
        if type_name == "separable" and data.get("source") == "mitsuba" and "bsdf" not in data:
            data["bsdf"] = draw(mitsuba_bsdfs(clean))
        if type_name == "separable":
            if clean:  # what the model refuses in combination
                if data.get("terms") is not None:
                    data.pop("max_error", None)
                if data.get("source") != "mitsuba":
                    data.pop("bsdf", None)
            data.setdefault("grid", 8)  # keeps the bakes quick
    for key, strategy in COMMON.items():
        if key in ("id", "name") and clean:
            continue  # two materials of an example could collide
        if draw(st.integers(0, 5)) == 0:
            data[key] = draw(COMMON_CLEAN[key] if clean else strategy)
    if not clean and draw(st.integers(0, 9)) == 0:
        data[draw(st.text(min_size=1, max_size=8))] = draw(weird)
    return draw(damaged_text(toml_document(data), clean))


# ---- scenes --------------------------------------------------------------------------------
def _vec(clean, lo=-10.0, hi=10.0):
    plausible = st.lists(st.floats(lo, hi), min_size=3, max_size=3)
    return plausible if clean else st.one_of(plausible, plausible, st.lists(edge_numbers, min_size=3, max_size=3), weird)


def _num(clean, lo, hi):
    plausible = st.floats(lo, hi)
    return plausible if clean else st.one_of(plausible, plausible, edge_numbers, weird)


def _optional(draw, table, fields, rarity):
    for key, strategy in fields:
        if draw(st.integers(0, rarity)) == 0:
            table[key] = draw(strategy)


@st.composite
def scene_toml(draw, materials=("clay", "gloss"), mesh_files=("mesh.obj",)) -> bytes:
    """A scene file's bytes: small images (renders stay quick); half the examples clean, the
    rest with adversarial numbers, wrong types and damaged text anywhere."""
    clean = draw(st.booleans())
    camera = {"position": draw(st.one_of(st.just([0.0, 1.0, 5.0]), _vec(clean))),
              "target": draw(st.one_of(st.just([0.0, 0.0, 0.0]), _vec(clean)))}  # fmt: skip
    _optional(draw, camera, [("up", _vec(clean)), ("fov", _num(clean, 1, 170)), ("near", _num(clean, 0.001, 1)),
                             ("far", _num(clean, 10, 1e4))], 3)  # fmt: skip
    size = st.integers(1, 24) if clean else st.one_of(st.integers(1, 24), st.integers(1, 24), edge_numbers, weird)
    image = {"width": draw(size), "height": draw(size)}
    _optional(draw, image, [("background", _vec(clean, 0.0, 1.0))], 2)
    render = {}
    _optional(draw, render, [("mip_bias", _num(clean, -16, 16)), ("mip_distance", _num(clean, 0.1, 100)),
                             ("outline_colour", _vec(clean, 0.0, 1.0)), ("outline_depth", _num(clean, 0.001, 1)),
                             ("outline_normal_degrees", _num(clean, 1, 180)), ("exposure", _num(clean, 0.01, 10))], 4)  # fmt: skip
    lights = []
    for _ in range(draw(st.integers(0, 3))):
        kind = draw(
            st.sampled_from(["point", "directional"]) if clean else st.one_of(st.sampled_from(["point", "directional"]), weird)
        )
        light = {"type": kind, "intensity": draw(_num(clean, 0, 100))}
        key = ("position" if kind == "point" else "direction") if clean else draw(st.sampled_from(["position", "direction"]))
        light[key] = draw(_vec(clean))
        _optional(draw, light, [("colour", _vec(clean, 0.0, 1.0))], 2)
        lights.append(light)
    objects = []
    for _ in range(draw(st.integers(0, 3))):
        shapes = st.sampled_from(["sphere", "plane", "box", "torus", "mesh"])
        shape = draw(shapes if clean else st.one_of(shapes, weird))
        obj = {
            "shape": shape,
            "material": draw(st.sampled_from(materials) if clean else st.one_of(st.sampled_from(materials), weird)),
        }
        if shape == "mesh":
            obj["file"] = draw(
                st.sampled_from(mesh_files) if clean else st.one_of(st.sampled_from(mesh_files), st.text(max_size=10))
            )
        segments = st.integers(3, 32) if clean else st.one_of(st.integers(3, 32), edge_numbers, weird)
        # A clean scene gives tessellation only to the shapes that have it (others refuse it).
        tessellation = [("segments", segments)] if not clean or shape in ("sphere", "torus") else []
        tessellation += [("minor_radius", _num(clean, 0.01, 1))] if not clean or shape == "torus" else []
        _optional(draw, obj, [("translate", _vec(clean)), ("rotate", _vec(clean, -360, 360)), ("scale", _vec(clean, 0.1, 3)),
                              ("albedo", _vec(clean, 0.0, 1.0)), ("gloss", _num(clean, 0, 1)), ("opacity", _num(clean, 0, 1)),
                              *tessellation], 4)  # fmt: skip
        objects.append(obj)
    data = {"camera": camera, "image": image}
    if render:
        data["render"] = render
    if lights:
        data["lights"] = lights
    if objects:
        data["objects"] = objects
    if not clean and draw(st.integers(0, 14)) == 0:
        del data["camera"]
    return draw(damaged_text(toml_document(data), clean))


# ---- DDS -----------------------------------------------------------------------------------
#: Byte offsets of the DDS size fields (DirectXTex DDS.h, after the 4-byte magic).
DDS_FIELDS = {"size": 4, "flags": 8, "height": 12, "width": 16, "depth": 24, "mipMapCount": 28, "caps2": 112,
              "dxgiFormat": 128, "dimension": 132, "arraySize": 140}  # fmt: skip


#: Header values worth trying: small, the atlas's own, flag bits, the uint32 extremes.
HEADER_VALUES = (0, 1, 2, 3, 4, 7, 8, 9, 28, 29, 64, 256, 0x20000, 0x200000, 0x7FFFFFFF, 0xFFFFFFFF)

dds_damage = st.lists(
    st.one_of(
        st.tuples(st.just("field"), st.sampled_from(sorted(DDS_FIELDS)),
                  st.one_of(st.sampled_from(HEADER_VALUES), st.integers(0, 2**32 - 1))),
        st.tuples(st.just("byte"), st.integers(0, 199), st.integers(0, 255)),
        st.tuples(st.just("truncate"), st.integers(0, 2**20)),
        st.tuples(st.just("append"), st.binary(min_size=1, max_size=64)),
    ),
    min_size=1, max_size=3,
)  # fmt: skip
"""Ways to damage a DDS: set a header field, change a byte, cut it, add bytes (see :func:`damage_dds`)."""


def damage_dds(data: bytes, damage) -> bytes:
    """``data`` with the operations drawn from :data:`dds_damage` applied in turn."""
    out = bytearray(data)
    for op, *args in damage:
        if op == "field" and len(out) >= DDS_FIELDS[args[0]] + 4:
            struct.pack_into("<I", out, DDS_FIELDS[args[0]], args[1])
        elif op == "byte" and args[0] < len(out):
            out[args[0]] = args[1]
        elif op == "truncate":
            del out[args[0] :]
        elif op == "append":
            out += args[0]
    return bytes(out)


# ---- checks --------------------------------------------------------------------------------
def tree_hash(root: Path) -> dict:
    """Path -> content hash (or "dir") of everything under ``root``."""
    return {p.relative_to(root).as_posix(): hashlib.sha256(p.read_bytes()).hexdigest() if p.is_file() else "dir"
            for p in sorted(Path(root).rglob("*"))}  # fmt: skip


def check_result(result, allowed=DOCUMENTED, max_lines: int = 1) -> None:
    """A documented exit status other than an internal error, at most ``max_lines`` on
    stderr, and never a traceback."""
    event(f"exit {result.exit_code}")  # pytest --hypothesis-show-statistics: how far the examples got
    assert result.exit_code in allowed, (result.exit_code, result.stderr, result.exception)
    assert "Traceback" not in result.stderr and "Traceback" not in result.stdout, result.stderr
    assert len(result.stderr.splitlines()) <= max_lines, result.stderr


def _refuse_constant(name):
    raise AssertionError(f"non-finite number {name} in a manifest")


def check_finite_bake(dds_path: Path) -> None:
    """A bake's outputs read back, and every number in them is finite."""
    from atlasgen.io.dds import read_dds

    read_dds(dds_path)
    manifest = json.loads(dds_path.with_suffix(".json").read_text(), parse_constant=_refuse_constant)
    for entry in manifest["materials"]:
        for key in ("scale", "bias", "factor_scale", "factor_bias"):
            if key in entry:
                flat = json.dumps(entry[key])
                assert "NaN" not in flat and "Infinity" not in flat, (entry["name"], key)
    include = dds_path.with_suffix(".wgsl").read_text()
    assert not re.search(r"\b(nan|inf)\b", include, re.IGNORECASE), "non-finite constant in the include"
