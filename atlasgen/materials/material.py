"""Reading material definitions from TOML files into validated :class:`Material` records."""

from __future__ import annotations

import hashlib
import os
from dataclasses import dataclass, field
from pathlib import Path, PurePath

from atlasgen.contract import NAME_PATTERN, material_constant
from atlasgen.errors import InputError, MaterialError, SceneError, did_you_mean
from atlasgen.io.fields import Param, check_keys, validate_params
from atlasgen.io.fields import shown as short
from atlasgen.io.referenced_files import map_files, real_folder_path, referenced_files
from atlasgen.io.text import MISSING, check_path_text, decode_utf8, parse_toml, path_kind, read_input_bytes
from atlasgen.materials.materialx_document import is_materialx_file, read_materialx_document
from atlasgen.materials.scene import read_scene
from atlasgen.models import get_model, model_types
from atlasgen.models.physical_fit import FIT_GLOSS, check_physical_fit

__all__ = [
    "Material",
    "read_material",
    "read_materials",
    "read_material_file",
    "find_material_files",
    "check_unique_names",
    "is_material_file_name",
    "select_scene_materials",
    "COMMON_KEYS",
    "MAX_MATERIAL_BYTES",
]


#: Keys every material file may carry besides its model's parameters.
COMMON_KEYS = ("name", "type", "id", "description", "rgb_scale", "alpha_scale", "error_budget", "from", "fit_gloss",
               "nonfinite_tolerance", "validate")  # fmt: skip
#: Keys of a material's ``[validate]`` table: its look goal against its physical reference
#: (``atlasgen validate``; the defaults are atlasgen.validate.run's GOAL_LOOK_PSNR_DB and GOAL_LOOK_FLIP).
VALIDATE_KEYS = ("psnr_db", "flip")
#: Values of ``from``: the model's closed form, or a fit to its physical reference
#: (:mod:`atlasgen.models.physical_fit`).
FIT_SOURCES = ("model", "physical")


@dataclass
class Material:
    """One validated material definition."""

    name: str
    type: str
    params: dict
    source: str  # path as given, POSIX separators
    content_hash: str  # sha256 of the file's bytes (and of the files it includes)
    id: int | None = None
    description: str = ""
    rgb_scale: object = "auto"
    alpha_scale: object = "auto"
    error_budget: float | None = None
    fit_from: str = "model"  # the file's ``from``
    fit_gloss: float | None = None  # with from = "physical": the renderer gloss the slice is fitted for
    #: Non-finite (NaN, inf) samples of the source the bake may replace by 0, with a warning; more are an error.
    nonfinite_tolerance: int = 0
    #: The ``[validate]`` table: a look goal of the material's own (``psnr_db``, ``flip``), or None for the defaults.
    look_goal: dict | None = None
    extra: dict = field(default_factory=dict)
    #: The files the definition includes (a MaterialX document's ``xi:include``), POSIX: a rebuild depends on them.
    includes: tuple[str, ...] = ()

    @property
    def model(self):
        return get_model(self.type)

    @property
    def slice_count(self) -> int:
        return self.model.slice_count(self.params)

    @property
    def constant_name(self) -> str:
        """Shader-constant spelling of the name, e.g. ``gold-film`` -> ``MATERIAL_GOLD_FILM`` (:func:`~atlasgen.contract.material_constant`)."""
        return material_constant(self.name)


#: The keys every material file may have besides its model's, checked by the one field validator.
_ID = Param("id", None, "int", 0, 255, doc="slice index")
#: Numbers > 0 that stay finite and > 0 in float32 (the include's constants).
_POSITIVE = Param("", None, "float", 0.0, lo_open=True)
_FIT_GLOSS = Param("fit_gloss", FIT_GLOSS, "float", 0.0, 1.0, doc="renderer gloss a from = 'physical' slice is fitted for")
_SCALE = Param("", "auto", "float", 0.0, lo_open=True, alternative="auto")
#: A material file is a few hundred bytes (a toon threshold list a few kB); a 6 GB one was read whole.
#: The largest material file read (a MaterialX document's own limit is the same).
MAX_MATERIAL_BYTES = 16 << 20
_MATERIAL_LIMIT = (MAX_MATERIAL_BYTES, "a material file")
_NONFINITE = Param("nonfinite_tolerance", 0, "int", 0, doc="non-finite source samples the bake may replace by 0")
_LOOK_PSNR = Param(
    "validate.psnr_db", None, "float", 0.0, lo_open=True, doc="look goal: least PSNR (dB) against the physical reference"
)
_LOOK_FLIP = Param("validate.flip", None, "float", 0.0, 1.0, doc="look goal: most mean FLIP against the physical reference")


def _look_goal(raw, path) -> dict | None:
    """The ``[validate]`` table, checked: ``{"psnr_db": x, "flip": y}`` with the keys it sets, or None.

    >>> _look_goal({"validate": {"psnr_db": 28}}, "m.toml")
    {'psnr_db': 28.0}
    >>> _look_goal({}, "m.toml") is None
    True
    """
    table = raw.get("validate")
    if table is None:
        return None
    if not isinstance(table, dict):
        raise MaterialError(path, "validate", f"expected a table with {' and/or '.join(VALIDATE_KEYS)}, got {short(table)}")
    unknown = sorted(set(table) - set(VALIDATE_KEYS))
    if unknown:
        raise MaterialError(path, f"validate.{unknown[0]}", f"unknown key; expected one of {', '.join(VALIDATE_KEYS)}")
    params = {"psnr_db": _LOOK_PSNR, "flip": _LOOK_FLIP}
    return {k: float(params[k].coerce(table[k], path, name=f"validate.{k}")) for k in VALIDATE_KEYS if k in table}


def _scale_field(raw, key, path):
    return _SCALE.coerce(raw.get(key, "auto"), path, name=key)


def read_material(path) -> Material:
    """Parse and validate one material file.

    Raises
    ------
    InputError
        The file is missing or unreadable.
    MaterialError
        Malformed TOML, an unknown type or key, or a parameter out of range; the
        message names the file, the field and what was expected.
    """
    path = Path(path)
    shown = path.as_posix()
    data = read_input_bytes(path, limit=_MATERIAL_LIMIT)
    try:
        text = decode_utf8(data)
    except UnicodeDecodeError:
        raise MaterialError(shown, None, "expected UTF-8 TOML text") from None
    raw = parse_toml(text, shown, MaterialError)

    type_name = raw.get("type")
    known = model_types()
    if type_name is None:
        raise MaterialError(shown, "type", "missing; expected one of " + ", ".join(known))
    if not isinstance(type_name, str) or type_name not in known:
        hint = did_you_mean(type_name, known) if isinstance(type_name, str) else ""
        raise MaterialError(shown, "type", f"unknown model {short(type_name)}{hint}; expected one of " + ", ".join(known))

    name = raw.get("name", path.stem)
    if not isinstance(name, str) or not NAME_PATTERN.fullmatch(name):
        raise MaterialError(shown, "name", f"expected a letter then letters, digits, '-' or '_' (at most 63), got {short(name)}")

    material_id = raw.get("id")
    if material_id is not None:
        material_id = _ID.coerce(material_id, shown)

    description = raw.get("description", "")
    if not isinstance(description, str):
        raise MaterialError(shown, "description", f"expected a string, got {short(description)}")

    error_budget = raw.get("error_budget")
    if error_budget is not None:
        error_budget = _POSITIVE.coerce(error_budget, shown, name="error_budget")

    model = get_model(type_name)
    # Every key a material file may hold, in the refusal's list too: it named the model's parameters alone ("expected
    # one of: colour" for a lambert file whose name, id and description were taken).
    check_keys(raw, {p.name for p in model.params} | set(COMMON_KEYS), shown)
    model_raw = {k: v for k, v in raw.items() if k not in COMMON_KEYS}
    params = validate_params(model.params, model_raw, shown)
    params, files = _resolve_files(params, path, shown)
    model.check(params, shown)
    for key, when in model.unused_fields(params).items():
        if key in model_raw:
            raise MaterialError(shown, key, f"only read {when}; expected no {key} (its value would be dropped)")
    if error_budget is not None:
        params = model.apply_budget(params, float(error_budget), shown)
    fit_from = raw.get("from", "model")
    if fit_from not in FIT_SOURCES:
        raise MaterialError(shown, "from", f"expected one of {', '.join(repr(s) for s in FIT_SOURCES)}, got {short(fit_from)}")
    if fit_from == "physical":
        if error_budget is not None:
            raise MaterialError(
                shown, "error_budget", "expected no error budget with from = 'physical' (a fitted slice has no supersampling)"
            )
        check_physical_fit(model, params, shown)
        fit_gloss = float(_FIT_GLOSS.coerce(raw.get("fit_gloss", FIT_GLOSS), shown))
    elif "fit_gloss" in raw:
        raise MaterialError(
            shown, "fit_gloss", "expected no fit_gloss without from = 'physical' (it is the gloss a physical fit is made for)"
        )
    else:
        fit_gloss = None
    return Material(
        name=name,
        type=type_name,
        params=params,
        source=shown,
        content_hash=_content_hash(data, files),
        id=material_id,
        description=description,
        rgb_scale=_scale_field(raw, "rgb_scale", shown),
        alpha_scale=_scale_field(raw, "alpha_scale", shown),
        error_budget=None if error_budget is None else float(error_budget),
        fit_from=fit_from,
        fit_gloss=fit_gloss,
        nonfinite_tolerance=int(_NONFINITE.coerce(raw.get("nonfinite_tolerance", 0), shown)),
        look_goal=_look_goal(raw, shown),
        includes=tuple(Path(resolved).as_posix() for _, resolved in files),
    )


def _resolve_files(params: dict, path: Path, shown: str) -> tuple[dict, list[tuple[str, str]]]:
    """``params`` with each file they name (:func:`~atlasgen.io.referenced_files.referenced_files`) absolute, a relative
    name taken from the material file's folder, and ``(name as given, absolute path)`` of each: a name that is no
    file is refused on one line naming its field (Mitsuba read it from the working folder, so another folder baked
    another file, or printed OpenImageIO's complaints on stdout)."""
    found = referenced_files(params)
    resolved: dict[str, str] = {}
    for where, name in found:
        target = Path(name) if Path(name).is_absolute() else path.parent / name
        kind = path_kind(target)
        if kind is not None:
            what = "no such file" if kind == MISSING else kind
            raise MaterialError(shown, where, f"expected a file (a relative name is from the material file's folder), "
                                f"got {short(name)}: {target.as_posix()}: {what}")  # fmt: skip
        # The file the system found: abspath would fold a "link/.." textually, and name another file than the one checked.
        resolved[name] = os.path.realpath(target)
    return map_files(params, lambda name: resolved.get(name, name)), [(name, resolved[name]) for _, name in found]


def _content_hash(data: bytes, files: list[tuple[str, str]]) -> str:
    """SHA-256 of the material file's bytes, then of each file it names (its name as given and its bytes' SHA-256): a
    changed data file is another material, which the bake's cache and the manifest's hash must see."""
    digest = hashlib.sha256(data)
    for name, resolved in files:
        with open(resolved, "rb") as handle:
            digest.update(b"\0" + name.encode("utf-8") + b"\0" + hashlib.file_digest(handle, "sha256").digest())
    return digest.hexdigest()


def read_material_file(path, materialx_flatten=None) -> list[Material]:
    """The materials of one file: a TOML material file's one, or every ``surfacematerial`` of a
    MaterialX document (``.mtlx``, :mod:`atlasgen.materials.materialx_document`; ``materialx_flatten``
    says what driven inputs become)."""
    check_path_text(path)
    if not is_materialx_file(path):
        return [read_material(path)]
    out = []
    for fields in read_materialx_document(path, materialx_flatten):
        if not NAME_PATTERN.fullmatch(fields["name"]):
            raise MaterialError(fields["source"], fields["name"],
                                "expected a material name of a letter then letters, digits, '-' or '_' (at most 63)")  # fmt: skip
        out.append(Material(**fields))
    return out


def is_material_file_name(name: str) -> bool:
    """Whether a folder's entry called ``name`` is one of its material files: ``*.toml`` or ``*.mtlx``, not
    hidden. Hidden names are editors' (Emacs's lock link ``.#clay.toml``, which points nowhere) and are
    what make's ``$(wildcard materials/*.toml)`` leaves out too.

    >>> [is_material_file_name(n) for n in ("clay.toml", "lib.mtlx", ".#clay.toml", "clay.toml~")]
    [True, True, False, False]
    """
    return not name.startswith(".") and name.endswith((".toml", ".mtlx"))


def find_material_files(paths) -> list[Path]:
    """Expand files and folders (their material files, :func:`is_material_file_name`, sorted, non-recursive)
    into a file list.

    Sorting makes the bake order, and so the atlas, independent of the file system. A file named twice is kept once,
    where it is first named.
    """
    files: list[Path] = []
    for p in paths:
        p = Path(p)
        if p.is_dir():
            entries = sorted(p.iterdir(), key=lambda f: f.name)
            # A folder's material files are found by their lower-case extension, as make's materials/*.toml finds
            # them: one spelt otherwise was left out without a word, though named on its own it bakes.
            for f in entries:
                if not is_material_file_name(f.name) and is_material_file_name(f.name.lower()):
                    ext = f.suffix.lower()
                    raise InputError(f"{f.as_posix()}: expected a material file's extension in lower case ({ext}), "
                                     f"as a folder's material files are found; rename it")  # fmt: skip
            files.extend(f for f in entries if is_material_file_name(f.name))
        elif (kind := path_kind(p)) is None:
            files.append(p)
        elif kind == MISSING:
            raise InputError(f"{p.as_posix()}: no such file or folder")
        else:
            raise InputError(f"{p.as_posix()}: expected a material file or a folder, got {kind}")
    # A file named twice (``bake m ./m/``, ``bake m/a.toml m``) is read once: it was refused as two materials of one
    # name "also in" itself. Two names of one file (a link) stay two files, as their materials' names may differ. Named
    # by where the system finds it: ``link/../m/a.toml`` is another folder's file than ``m/a.toml``, which abspath
    # took for the same, keeping whichever came first.
    seen: set[str] = set()
    unique = []
    for f in files:
        key = real_folder_path(f)
        if key not in seen:
            seen.add(key)
            unique.append(f)
    return unique


def read_materials(paths, materialx_flatten=None) -> list[Material]:
    """Read every material under ``paths`` (a MaterialX document gives each of its materials); duplicate names are an error."""
    return check_unique_names([m for f in find_material_files(paths) for m in read_material_file(f, materialx_flatten)])


def check_unique_names(materials: list[Material]) -> list[Material]:
    """Reject two materials whose names (or shader constants) collide, naming where the second's name is written:
    a MaterialX material's element, a TOML file's ``name`` field, or its file name where it has none."""
    seen: dict[str, Material] = {}
    for m in materials:
        key = m.constant_name
        if key in seen:
            other = seen[key]
            field, written = _name_field(m)
            if other.name == m.name:
                raise MaterialError(m.source, field, f"duplicate material name {m.name!r} (also in {other.source}); "
                                    f"expected a name no other material has ({written})")  # fmt: skip
            raise MaterialError(m.source, field, f"duplicate material name {m.name!r}: {other.name!r} (in {other.source}) "
                                f"is the same shader constant {key}; expected names that differ in more than case or "
                                f"'-' against '_' ({written})")  # fmt: skip
        seen[key] = m
    return materials


def _name_field(m: Material) -> tuple[str, str]:
    """The field a refusal of ``m``'s name names, and where that name is written."""
    if is_materialx_file(m.source):
        return m.name, "the surfacematerial's name in the document"
    if PurePath(m.source).stem != m.name:
        return "name", "the file's name field"
    return "name", "the file's name field, or the file's own name where it has none"


def select_scene_materials(materials: list[Material], scene_path) -> list[Material]:
    """Only the materials ``scene_path`` references, in library order.

    Raises
    ------
    SceneError
        The scene names a material the library does not have (the message lists them).
    """
    scene = read_scene(scene_path)
    wanted = {obj.material for obj in scene.objects}
    by_name = {m.name: m for m in materials}
    for index, obj in enumerate(scene.objects):
        if obj.material not in by_name:
            known = ", ".join(sorted(by_name)) or "none"
            raise SceneError(
                Path(scene_path).as_posix(),
                f"objects[{index}].material",
                f"unknown material {obj.material!r}{did_you_mean(obj.material, by_name)}; known: {known}",
            )
    return [m for m in materials if m.name in wanted]
