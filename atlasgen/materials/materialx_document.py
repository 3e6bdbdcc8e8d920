"""Reading MaterialX documents (``.mtlx``): every ``surfacematerial`` becomes one separable material
(:func:`atlasgen.materials.material.read_material_file` makes the :class:`~atlasgen.materials.material.Material` records).

Each material's surface shader must be one of :data:`~atlasgen.separable.materialx_oracle.SURFACE_MODELS`
with constant inputs. It becomes ``type = "separable"``, ``source = "materialx"``, whose BRDF is
MaterialX's own GLSL (:mod:`atlasgen.separable.materialx_oracle`), baked as
``representation = "auto"`` within :data:`DEFAULT_BUDGET` of :data:`ERROR_MEASURE` (the cheapest of
one LUT slice and K separable terms whose error against the oracle meets it; docs/materialx.md).

- Names come from the document (the ``surfacematerial`` node's name); the manifest's ``params``
  record ``materialx.document`` and ``materialx.material``.
- An input driven by a node, a node graph or an interface name is refused with one line naming
  it, unless ``flatten`` says what to use instead: ``"default"`` (the nodedef's default) or a
  ``{input: value}`` table (others still refused). What was flattened is recorded in
  ``materialx.flattened``.
- A constant input must be of its nodedef's type, parse whole, be finite, lie within the nodedef's
  ``uimin``..``uimax`` and need no colour-space or unit conversion; the shader node's nodedef must be
  the oracle's; elements of one parent must have unique names (MaterialX's reader keeps the
  first of two and drops the other silently), none empty, and no material may hide in a node
  graph; the document must pass MaterialX's own validation. Each is refused with one line otherwise.
- A lobe no slice can hold is refused, naming its input: an anisotropic one (the slice is indexed
  by N.L and N.V, not the azimuth) and a mirror (roughness 0, a delta lobe), each where its weight
  is above 0, as a separable material refuses a Mitsuba BSDF's anisotropy and delta lobes. A lobe
  sharper than :data:`ROUGHNESS_MIN` bakes, named in ``materialx.sharp_lobes`` and
  ``not_in_table``; the bake's error warning gives it as the cause.
- Inputs the table's equation has no room for (emission, opacity, transmission) are named in
  ``materialx.not_in_table``, never dropped silently: the oracle shades the reflection with
  emission 0 and opacity 1, the bake warns, and the report lists them.

MaterialX is imported inside functions (the ``materialx`` extra).
"""

from __future__ import annotations

import contextlib
import hashlib
import json
import math
import os
import re
from pathlib import Path
from xml.etree import ElementTree

from atlasgen.contract import SPECULAR_ALPHA_MIN, SPECULAR_ROUGHNESS_MIN
from atlasgen.errors import FieldError, InputError, MaterialError, shorten
from atlasgen.io.fields import FLOAT32_MAX, validate_params
from atlasgen.io.text import check_path_text, decode_utf8, read_input_bytes
from atlasgen.models import get_model
from atlasgen.models.materialx import EXPECTED_VALUES, check_input_value, shown_values
from atlasgen.separable.materialx_oracle import (
    SURFACE_MODELS,
    load_materialx_libraries,
    surface_defaults,
    surface_inputs,
    surface_nodedef,
    surface_ranges,
)

__all__ = ["DEFAULT_BUDGET", "ERROR_MEASURE", "SAMPLING_GRID", "NOT_IN_TABLE", "MATERIAL_NOT_IN_TABLE", "ROUGHNESS_MIN",
           "is_materialx_file", "read_materialx_document"]  # fmt: skip

#: What ``representation = "auto"`` judges a document's candidates by: the relative log RMS of f cos
#: against the oracle (:func:`atlasgen.separable.error.relative_log_errors`), which follows what the
#: validation scenes' display shows; the relative RMS is ruled by grazing peaks the display clips,
#: and ranked SVD terms, whose 8-bit noise fills a sharp lobe's dim tails, above NMF ones (docs/materialx.md).
ERROR_MEASURE = "relative_log_rms"
#: The :data:`ERROR_MEASURE` that ``representation = "auto"`` must meet.
DEFAULT_BUDGET = 0.04
#: The separable sampling grid the terms are fitted on: the 16-texel grid, which other separable
#: materials also try, never erred less on the shipped document, and each grid costs the oracle's
#: evaluations, so the bake tries only this one (both targets, f cos and f times a proxy, still).
SAMPLING_GRID = 32
#: Inputs that MaterialX's own shader graphs leave unused (glTF's and USD's ``occlusion``, USD's ``displacement``)
#: are named as well: otherwise a value given would vanish without a word.
_OCCLUSION = "occlusion (MaterialX's shader leaves it unused, and an occlusion map varies over a surface, which a slice does not)"
#: Per surface model: input -> (the value the oracle shades with, what the table cannot hold).
NOT_IN_TABLE = {
    "standard_surface": {"emission": (0.0, "emission"), "opacity": ((1.0, 1.0, 1.0), "opacity"),
                         "transmission": (None, "transmission (the reflection that remains is baked)")},
    "open_pbr_surface": {"emission_luminance": (0.0, "emission"), "geometry_opacity": (1.0, "opacity"),
                         "transmission_weight": (None, "transmission (the reflection that remains is baked)")},
    "gltf_pbr": {"emissive": ((0.0, 0.0, 0.0), "emission"), "alpha": (1.0, "opacity"),
                 "transmission": (None, "transmission (the reflection that remains is baked)"),
                 "occlusion": (1.0, _OCCLUSION)},
    "UsdPreviewSurface": {"emissiveColor": ((0.0, 0.0, 0.0), "emission"), "opacity": (1.0, "opacity"),
                          "displacement": (0.0, "displacement (it moves geometry, which a slice does not hold)"),
                          "occlusion": (1.0, _OCCLUSION),
                          "normal": ((0.0, 0.0, 1.0), "a tilted tangent-space normal (the response then varies with the "
                                     "azimuth, which a slice indexed by N.L and N.V does not hold; the geometry's own "
                                     "normal is baked)")},
}  # fmt: skip
#: Per surface model: (its thin-walled switch, its subsurface weight). A thin wall's subsurface is light passing
#: through the sheet (MaterialX's graphs shade it with a translucent BSDF), which a slice of N.L >= 0 cannot hold:
#: a white thin-walled sheet baked as a black ball, without a word.
_THIN_WALLED_SUBSURFACE = {"standard_surface": ("thin_walled", "subsurface"),
                           "open_pbr_surface": ("geometry_thin_walled", "subsurface_weight")}  # fmt: skip


def _gltf_opacity(value: dict) -> float:
    """The opacity glTF's graph shades with (``value``: input -> its value): 1 where ``alpha_mode`` is OPAQUE (0),
    1 or 0 as ``alpha`` reaches ``alpha_cutoff`` or not where it is MASK (1), ``alpha`` where it is BLEND (2).

    >>> _gltf_opacity({"alpha": 0.2, "alpha_mode": 0, "alpha_cutoff": 0.5}), _gltf_opacity({"alpha": 0.7, "alpha_mode": 1, "alpha_cutoff": 0.5})
    (1.0, 1.0)
    >>> _gltf_opacity({"alpha": 0.2, "alpha_mode": 1, "alpha_cutoff": 0.5}), _gltf_opacity({"alpha": 0.2, "alpha_mode": 2, "alpha_cutoff": 0.5})
    (0.0, 0.2)
    """
    if value["alpha_mode"] == 0:
        return 1.0
    if value["alpha_mode"] == 1:
        return 1.0 if value["alpha"] >= value["alpha_cutoff"] else 0.0
    return value["alpha"]


#: Per surface model: input -> the value the model's graph shades with, from every input's value, where that is
#: not the input's own: glTF's makes an OPAQUE material opaque whatever its alpha, so an alpha there was named as
#: lost opacity (and failed --strict).
_SHADED_VALUE = {"gltf_pbr": {"alpha": _gltf_opacity}}
#: A surfacematerial's inputs beside its surface shader: what each would change that the table cannot hold.
MATERIAL_NOT_IN_TABLE = {
    "backsurfaceshader": "a back face is shaded with the front surface's slice (the renderer flips its normal)",
    "displacementshader": "displacement moves geometry, which an atlas slice does not hold",
}
#: standard_surface's specular roughness shapes three lobes: the dielectric's (weight ``specular``), the
#: metal's (``metalness``) and the transmission's (``transmission``); any of them weighted shows it.
_SS_MAIN = ("specular", "metalness", "transmission")
#: Per surface model: (roughness input, the weight inputs of the lobes it shapes; none: always shown) of
#: each microfacet roughness.
_LOBES = {
    "standard_surface": (("specular_roughness", _SS_MAIN), ("coat_roughness", ("coat",))),
    "open_pbr_surface": (("specular_roughness", ("specular_weight",)), ("coat_roughness", ("coat_weight",))),
    "gltf_pbr": (("roughness", ()), ("clearcoat_roughness", ("clearcoat",))),
    "UsdPreviewSurface": (("roughness", ()), ("clearcoatRoughness", ("clearcoat",))),
}
#: Per surface model: (anisotropy input, the weight inputs of the lobes it shapes) of each that has one.
_ANISOTROPY = {
    "standard_surface": (("specular_anisotropy", _SS_MAIN), ("coat_anisotropy", ("coat",))),
    "open_pbr_surface": (("specular_roughness_anisotropy", ("specular_weight",)), ("coat_roughness_anisotropy", ("coat_weight",))),
    "gltf_pbr": (("anisotropy_strength", ()),),
    "UsdPreviewSurface": (),
}  # fmt: skip
#: The roughness of the renderer's sharpest lobe, alpha = roughness^2 = :data:`~atlasgen.contract.SPECULAR_ALPHA_MIN`.
#: A sharper lobe's peak falls between a slice's texels (the distribution's OpenPBR car paint has a coat of 0.02,
#: whose fit errs by 130 %); at roughness 0, a mirror, the fit's error estimate runs to 1e14 %.
ROUGHNESS_MIN = SPECULAR_ROUGHNESS_MIN
#: An include element's tag as ElementTree names it (MaterialX reads ``xi:include`` in this namespace).
XINCLUDE = "{http://www.w3.org/2001/XInclude}include"
#: MaterialX's reader takes an element for an include by its literal tag, ``xi:include``, whatever the
#: prefix is bound to; ElementTree by its namespace. Both must agree (see :func:`_check_include_tags`).
_INCLUDE_TAG = re.compile(r"<([A-Za-z_][\w.-]*:)?include(?=[\s/>])")
_COMMENT = re.compile(r"<!--.*?-->", re.S)
#: Bytes a document or a file it includes may have: a material library is kilobytes; a 60 MB one took
#: 340 MB to read, and a 6 GB one was read whole into memory.
MAX_DOCUMENT_BYTES = 16 << 20
_DOCUMENT_LIMIT = (MAX_DOCUMENT_BYTES, "a MaterialX document")


def is_materialx_file(path) -> bool:
    """Whether ``path`` names a MaterialX document (``.mtlx``)."""
    return str(path).lower().endswith(".mtlx")


def _plain(value):
    if isinstance(value, bool | int | float | str):
        return value
    if hasattr(value, "asTuple"):
        return [float(x) for x in value.asTuple()]
    return str(value)


def _driver(inp) -> str | None:
    """What drives an input other than a value: ``node 'tex'``, ``node graph 'ng'``, ``interface 'x'``."""
    for what, name in (("node", inp.getNodeName()), ("node graph", inp.getNodeGraphString()),
                       ("interface input", inp.getInterfaceName()), ("output", inp.getOutputString())):  # fmt: skip
        if name:
            return f"{what} {name!r}"
    return None


def _differs(value, neutral) -> bool:
    if isinstance(neutral, tuple):
        return any(abs(float(a) - float(b)) > 0.0 for a, b in zip(value, neutral, strict=False))
    return abs(float(value) - float(neutral)) > 0.0


def _lobe_alpha(category: str, inputs: dict, defaults: dict) -> float:
    """The narrowest microfacet lobe's GGX alpha = roughness^2 (MaterialX's mx_roughness_anisotropy), at least 1e-3."""
    alphas = []
    for rough, weights in _LOBES[category]:
        w = max((float(inputs.get(k, defaults.get(k, (None, 1.0))[1])) for k in weights), default=1.0)
        if w > 0.0 and rough in defaults:
            alphas.append(float(inputs.get(rough, defaults[rough][1])) ** 2)
    return max(min(alphas, default=0.25), 1e-3)


def read_materialx_document(path, flatten=None) -> list[dict]:
    """Every ``surfacematerial`` of a ``.mtlx`` document, in document order, as the fields of a
    :class:`~atlasgen.materials.material.Material`: ``name``, ``type``, ``params`` (validated),
    ``source``, ``content_hash`` (:func:`material_digest`), ``description``.

    ``flatten``: ``None`` (refuse driven inputs), ``"default"`` or ``{input: value}`` (see the module).

    Raises
    ------
    InputError
        The file is missing or unreadable.
    MaterialError
        Malformed XML, no material, a material whose shader is missing, unsupported or has a
        driven input, or a name atlasgen cannot use; one line naming the file and the field
        (``<material>.<input>``).
    """
    import MaterialX as mx

    path = Path(path)
    shown = path.as_posix()
    data = read_input_bytes(path, limit=_DOCUMENT_LIMIT)
    text = _decode(shown, data)
    # What the document includes is read here first: MaterialX's reader would wait forever on a named
    # pipe, and it drops an included element whose name is taken without a word.
    documents = [(shown, _parse_xml(shown, data))]
    _check_include_tags(shown, text, documents[0][1])
    included = _included_files(path, documents[0][1])
    documents += [(p.as_posix(), tree) for p, _, tree, _ in included]
    doc = mx.createDocument()
    try:
        mx.readFromXmlString(doc, text, mx.FileSearchPath(str(path.parent)), _include_options(mx, path, included))
    except MaterialError:
        raise
    except Exception as exc:  # noqa: BLE001 - MaterialX raises its own exception types
        first = str(exc).strip().splitlines()[0] if str(exc).strip() else type(exc).__name__
        raise MaterialError(shown, None, f"malformed MaterialX document: {first}") from None
    libraries = load_materialx_libraries()
    with _named_as_included(included):
        _refuse_duplicate_names(documents)
        _refuse_values_written_as_text(documents)
        _refuse_ignored_children(documents, doc)
        _refuse_namespaces(documents)
        _refuse_library_names(documents, doc, libraries)
        _refuse_library_implementations(documents, doc, libraries)
    doc.importLibrary(libraries)
    with _named_as_included(included):
        out = _read_materials(shown, path, documents, doc, included, flatten)
    # Last, so that the checks above name their own field: what MaterialX itself finds wrong (a connection
    # to an output the node does not have, say), which its generator would otherwise shade regardless.
    # An input with no value is read as the nodedef's default, as MaterialX's generator shades it.
    _, message = doc.validate()
    faults = [line.strip() for line in message.splitlines() if line.strip() and not line.strip().startswith(_NO_VALUE)]
    if faults:
        raise MaterialError(shown, None, f"expected a document MaterialX validates, got: {_validation_fault(faults[0])}")
    return out


def _read_materials(shown: str, path: Path, documents: list, doc, included: list, flatten) -> list[dict]:
    """Each ``surfacematerial`` of the read ``doc`` as :func:`read_materialx_document` returns it."""
    nodes = _material_nodes(documents, doc)
    if not nodes:
        raise MaterialError(shown, None, "expected at least one surfacematerial node, found none")
    model = get_model("separable")
    out = []
    for node in nodes:
        name = node.getName()
        connection = node.getInput("surfaceshader")
        shader = None if connection is None else connection.getConnectedNode()
        if shader is None:
            raise MaterialError(shown, f"{name}.surfaceshader", "expected a connected surface shader node, found none")
        category = shader.getCategory()
        if category not in SURFACE_MODELS:
            raise MaterialError(
                shown,
                f"{name}.surfaceshader",
                f"surface shader {category!r} is not supported; expected one of {', '.join(SURFACE_MODELS)}",
            )
        # The file that writes the shader's inputs: an included file's value was blamed on the including document.
        spec = _read_shader(_where(documents, shader.getName()), name, category, shader, flatten)
        spec["not_in_table"] += _material_not_in_table(node) + _variants_not_applied(doc, name)
        # The file's name, not the path as given: the manifest's ``source`` locates the file, and a
        # path as given made the manifest (and the content hash) depend on the working folder.
        spec["document"] = path.name
        raw = {"source": "materialx", "materialx": spec, "representation": "auto", "max_error": DEFAULT_BUDGET,
               "grid": SAMPLING_GRID}  # fmt: skip
        params = validate_params(model.params, raw, shown)
        model.check(params, shown)
        out.append({"name": name, "type": "separable", "params": params, "source": shown,
                    "content_hash": material_digest(name, params), "includes": tuple(p.as_posix() for p, _, _, _ in included),
                    "description": f"MaterialX {category} {name!r} from {path.name}"})  # fmt: skip
    return out


#: A line of ``Document.validate``'s report: what is wrong, then the element as XML (its attributes in order).
#: MaterialX writes the name unescaped, so a name holding a quote ends at the quote before the next attribute or the end.
_FAULT = re.compile(r'(?s)(?P<what>.*?):\s*<(?P<tag>[\w:]+)\s+name="(?P<name>.*?)"(?=\s+[\w:]+="|\s*/?>)')


def _validation_fault(line: str) -> str:
    """A line of MaterialX's validation as one short clause: what is wrong and the element's tag and name, not
    the element's XML, whose head alone fitted the line (``<input name="bas... (110 characters)``).

    >>> _validation_fault('Interface name not found in referenced declaration: <input name="base_color" type="color3" />')
    "Interface name not found in referenced declaration: input 'base_color'"
    >>> print(_validation_fault('Invalid element name: <surfacematerial name="mat"a" type="material">'))
    Invalid element name: surfacematerial 'mat"a'
    """
    match = _FAULT.match(line)
    return shorten(f"{match['what']}: {match['tag']} {match['name']!r}" if match else line, 160)


def _material_not_in_table(node) -> list[str]:
    """The surfacematerial's own inputs the table has no room for (:data:`MATERIAL_NOT_IN_TABLE`), each
    ``"input = what drives it: why"``, as the shader's are; any other input is named as unknown to atlasgen."""
    out = []
    for inp in node.getInputs():
        key = inp.getName()
        if key == "surfaceshader":
            continue
        driver = _driver(inp) or (repr(inp.getValueString()) if inp.getValueString() else None)
        if driver is not None:
            out.append(f"{key} = {driver}: {MATERIAL_NOT_IN_TABLE.get(key, 'an input of the material atlasgen does not bake')}")
    return out


def _variants_not_applied(doc, material: str) -> list[str]:
    """A clause for each variant a look assigns where it assigns ``material``: a look binds materials to geometry
    and may switch their inputs to a variant's values, which atlasgen, baking each material as its inputs give
    it (as MaterialX's generator shades it), does not apply; a bake that kept the material's own roughness where
    the look asked for another said nothing. A look that only binds geometry changes no slice, and is not named."""
    out = []
    for look in doc.getLooks():
        assigns = [a for a in look.getActiveMaterialAssigns() if a.getMaterial() == material]
        if not assigns:
            continue
        chosen = [(a.getName(), v) for a in assigns for v in a.getChildren() if v.getCategory() == "variantassign"]
        chosen += [(None, v) for v in look.getActiveVariantAssigns()]
        for assign, variant in chosen:
            where = f"look {look.getName()!r}" + (f", materialassign {assign!r}" if assign else "")
            out.append(f"variant {variant.getAttribute('variant')!r} of variantset {variant.getAttribute('variantset')!r} "
                       f"({where}): looks are not applied, the material's own inputs are baked")  # fmt: skip
    return out


def material_digest(name: str, params: dict) -> str:
    """SHA-256 of one material as read: its name and its validated parameters (the document's file
    name, its constant inputs, what was flattened, what the table cannot hold, the representation),
    as canonical JSON; the manifest's ``params`` hold the same, so anyone can check it.

    A material's bake is a function of these alone (the oracle shades the nodedef generated for its
    category with these inputs), so this is the cache's key and the manifest's ``content_hash``:
    editing one material of a document, or a file it includes, re-bakes the materials whose values
    changed, and the others keep their slices and their validation. No path enters it: the same
    document gives the same hashes wherever it lies and wherever atlasgen runs.

    >>> material_digest("gold", {"materialx": {"inputs": {"base": 1.0}}}) == material_digest("gold", {"materialx": {"inputs": {"base": 1.0}}})
    True
    >>> material_digest("gold", {"materialx": {"inputs": {"base": 1.0}}}) == material_digest("gold", {"materialx": {"inputs": {"base": 0.5}}})
    False
    """
    text = json.dumps({"name": name, "params": params}, sort_keys=True, allow_nan=False)
    return hashlib.sha256(text.encode()).hexdigest()


@contextlib.contextmanager
def _named_as_included(included: list):
    """Run the whole-document checks so that a refusal of an included file ends ``(included by FILE)``, as the
    refusals made while the file is read do (docs/materialx.md): a namespace in an included file named the file
    but not the document that led to it."""
    included_by = {found.as_posix(): includer for found, _, _, includer in included}
    try:
        yield
    except FieldError as exc:
        if exc.path not in included_by:
            raise
        raise type(exc)(exc.path, exc.field, f"{exc.expected} (included by {included_by[exc.path]})") from None


def _refuse_namespaces(documents) -> None:
    """Refuse a document (or an included one) with a ``namespace``: MaterialX qualifies its materials' names as
    ``ns:NAME``, which no atlas name can hold (:data:`~atlasgen.contract.NAME_PATTERN`), and its validation then
    failed on the standard library's own node graphs, a message about MaterialX's internals (``input 'in1'``)."""
    for shown, root in documents:
        namespace = root.get("namespace")
        if namespace is not None:
            shown_namespace = shorten(repr(namespace), 40)
            raise MaterialError(shown, "namespace", f"a document with a namespace ({shown_namespace}) is not read: "
                                "MaterialX qualifies its materials' names as 'namespace:NAME', which an atlas name "
                                "cannot hold; expected the document without its namespace attribute")  # fmt: skip


def _parse_xml(shown: str, data: bytes):
    """The XML tree of a document MaterialX read; expat refuses what MaterialX may not (an entity expansion, say)."""
    try:
        return ElementTree.fromstring(data)
    except ElementTree.ParseError as exc:
        raise MaterialError(shown, None, f"malformed MaterialX document: XML parse error ({exc})") from None


def _decode(shown: str, data: bytes) -> str:
    try:
        return decode_utf8(data)
    except UnicodeDecodeError:
        raise MaterialError(shown, None, "expected UTF-8 MaterialX XML") from None


def _check_include_tags(shown: str, text: str, root) -> None:
    """Refuse an include MaterialX and ElementTree would read differently: MaterialX takes ``<xi:include>``
    for one by its literal tag, so ``xi`` bound to another namespace included a file this reader never saw
    (its materials baked, its bytes in no cache key), and ``<foo:include>`` bound to XInclude the reverse."""
    tags = _INCLUDE_TAG.findall(_COMMENT.sub("", text))
    literal = sum(prefix == "xi:" for prefix in tags)
    namespaced = [e for e in root.iter() if isinstance(e.tag, str) and e.tag.rpartition("}")[2] == "include"]
    if any(prefix not in ("xi:", "") for prefix in tags) or literal != len(namespaced) or any(
            e.tag != XINCLUDE for e in namespaced):  # fmt: skip
        raise MaterialError(shown, "xi:include", "expected each include written <xi:include href=...> with "
                            f"xmlns:xi=\"{XINCLUDE[1:].partition('}')[0]}\", as MaterialX reads them")  # fmt: skip


def _find_include(href: str, folder: Path, document: Path) -> Path | None:
    """Where an ``href`` is looked up: beside the file that includes it, then beside the document; never the
    working folder or ``MATERIALX_SEARCH_PATH``, where MaterialX's own reader would look next."""
    return next((p for p in (folder / href, document.parent / href) if os.path.lexists(p)), None) if href else None


#: Deepest chain of includes MaterialX 1.39 reads (its reader's MAX_XINCLUDE_DEPTH: 256 nested includes read,
#: 257 refused with "Maximum XInclude depth exceeded").
MAX_INCLUDE_DEPTH = 256
#: Most inclusions one document may make in all, counting a file once per path that reaches it: MaterialX
#: reads a file anew at each, and 48 files of 150 bytes, each including the next two, ran for hours.
MAX_INCLUSIONS = 1024


def _included_files(path: Path, root) -> list:
    """``(path, bytes, tree, includer)`` of every file the document at ``path`` includes (``xi:include``, and what
    those include), each once, in document order (:func:`_find_include`), ``includer`` the file whose include
    reached it first, as shown. A cycle is left to MaterialX to refuse.

    The walk keeps its own stack: a chain of 1000 files ran out of Python's recursion (an internal error).

    Raises
    ------
    InputError
        An included path is a named pipe, a device, a folder, unreadable or over the size limit
        (:func:`read_input_bytes`).
    MaterialError
        An ``href`` is found nowhere, an included file is not UTF-8 XML, includes nest deeper than
        :data:`MAX_INCLUDE_DEPTH`, or MaterialX would read more than :data:`MAX_INCLUSIONS` of them.
    """
    out: list = []
    document = os.path.realpath(path)
    seen = {document}
    edges: dict = {document: []}  # each file's includes, by real path, one per xi:include element
    stack = [(path.as_posix(), path.parent, document, root.iter(XINCLUDE))]
    while stack:
        shown, folder, real_parent, elements = stack[-1]
        element = next(elements, None)
        if element is None:
            stack.pop()
            continue
        href = element.get("href") or ""
        found = _find_include(href, folder, path)
        if found is None:
            raise MaterialError(shown, "xi:include", f"expected a file beside it or beside the document, found "
                                f"none for href {href!r}")  # fmt: skip
        check_path_text(found)  # the depfile and the manifest's includes record it
        real = os.path.realpath(found)
        edges[real_parent].append(real)
        # A file that includes itself, or one that includes it: MaterialX said "XInclude cycle detected" and no more.
        back = next((entry[0] for entry in stack if entry[2] == real), None)
        if back is not None:
            back = "the document" if real == document else repr(back)
            raise MaterialError(shown, "xi:include", f"expected no include cycle, got href {href!r} leading back to {back}")
        if real in seen:
            continue
        if len(stack) > MAX_INCLUDE_DEPTH:
            raise MaterialError(shown, "xi:include", f"expected includes nested at most {MAX_INCLUDE_DEPTH} deep (as "
                                f"MaterialX reads them), got a deeper chain at href {href!r}")  # fmt: skip
        seen.add(real)
        # A refusal names the included file at fault, and the file whose xi:include led there.
        try:
            data = read_input_bytes(found, limit=_DOCUMENT_LIMIT)
            text = _decode(found.as_posix(), data)
            included = _parse_xml(found.as_posix(), data)
            _check_include_tags(found.as_posix(), text, included)
        except FieldError as exc:
            raise type(exc)(exc.path, exc.field, f"{exc.expected} (included by {shown})") from None
        except InputError as exc:
            raise InputError(f"{exc} (included by {shown})") from None
        out.append((found, data, included, shown))
        edges[real] = []
        stack.append((found.as_posix(), found.parent, real, included.iter(XINCLUDE)))
    inclusions = _count_inclusions(edges, document)
    if inclusions > MAX_INCLUSIONS:
        got = f"{inclusions}" if inclusions <= 10**6 else "over a million"
        raise MaterialError(path.as_posix(), "xi:include", f"expected at most {MAX_INCLUSIONS} inclusions in all (MaterialX "
                            f"reads a file again on every path that includes it), got {got}")  # fmt: skip
    return out


def _count_inclusions(edges: dict, start) -> int:
    """How many files MaterialX reads for the document ``start``: every path through ``edges`` (file -> the files
    its xi:include elements name); an edge back into a file still being counted (a cycle, which MaterialX
    refuses) counts once. Exact (Python's integers): 100 levels of a diamond count 2^101 - 2.

    >>> _count_inclusions({"d": ["a", "b"], "a": ["c"], "b": ["c"], "c": []}, "d")
    4
    """
    counted: dict = {}
    open_ = set()
    # Post-order without recursion: a file's count is 1 for each include plus what that file includes.
    stack = [(start, False)]
    while stack:
        node, children_done = stack.pop()
        if children_done:
            total = sum(1 + counted.get(child, 0) for child in edges.get(node, ()))
            counted[node] = total
            open_.discard(node)
            continue
        if node in counted or node in open_:
            continue
        open_.add(node)
        stack.append((node, True))
        stack.extend((child, False) for child in edges.get(node, ()) if child not in counted and child not in open_)
    return counted[start]


def _include_options(mx, path: Path, included: list):
    """MaterialX read options whose includes are the bytes :func:`_included_files` read and hashed, found as
    it found them: MaterialX's own reader opens each file again (a named pipe hangs it) and looks further
    (the working folder), so a document could bake a material no check or cache key saw."""
    by_path = {os.path.realpath(found): data for found, data, _, _ in included}

    def read_include(sub, filename, search_path, options) -> None:
        href = filename.asString()
        found = _find_include(href, Path(search_path.asString()), path)
        data = by_path.get(os.path.realpath(found)) if found is not None else None
        if data is None:  # not met: _included_files read every file an href reaches, and refused cycles first
            raise MaterialError(path.as_posix(), "xi:include", f"expected an include read with the document, got href "
                                f"{href!r}")  # fmt: skip
        mx.readFromXmlString(sub, decode_utf8(data), mx.FileSearchPath(str(found.parent)), options)

    options = mx.XmlReadOptions()
    options.readXIncludeFunction = read_include
    return options


#: The elements that give a node's input its value: ``<input>``, and a 1.37 document's ``<bindinput>`` and ``<parameter>``.
_VALUE_TAGS = ("input", "bindinput", "parameter")


def _refuse_values_written_as_text(documents: list) -> None:
    """Refuse an ``<input>`` whose value is written as its text (``<input name="roughness" type="float">0</input>``;
    ``documents``: ``(shown, tree)``): MaterialX reads only the ``value`` attribute, so the nodedef's default was
    baked in its place without a word, and a mirror written so passed the check that refuses one."""
    for shown, root in documents:
        for parent in root.iter():
            for child in parent:
                # A 1.37 document's <bindinput> and <parameter> become inputs as MaterialX reads it, their text dropped.
                if child.tag in _VALUE_TAGS and (child.text or "").strip() and child.get("value") is None:
                    raise MaterialError(shown, f"{parent.get('name')}.{child.get('name')}", "expected the value in a "
                                        f"value attribute (value=\"{child.text.strip()[:40]}\"), got it as the element's "
                                        "text, which MaterialX ignores")  # fmt: skip


def _refuse_ignored_children(documents: list, doc) -> None:
    """Refuse a child of a surface shader node that MaterialX did not read as an input (``documents``: ``(shown,
    tree)``; ``doc``: the document as read): a 1.39 document's ``<parameter name="specular_roughness" value="0">``
    is no input to MaterialX, so the nodedef's default was baked in its place without a word (a 1.37 document's
    becomes an input as it is read, and is baked)."""
    for shown, root in documents:
        for element in root:
            node = doc.getNode(element.get("name") or "") if element.tag in SURFACE_MODELS else None
            for child in element if node is not None else ():
                if child.tag not in ("input", "output") and node.getInput(child.get("name") or "") is None:
                    raise MaterialError(shown, f"{element.get('name')}.{child.get('name')}", f"expected an <input> "
                                        f"element, got <{shorten(child.tag, 40)}>, which MaterialX does not read as an "
                                        "input of the node")  # fmt: skip


def _refuse_duplicate_names(documents: list) -> None:
    """Refuse two elements of one parent with one name, and one name at the top of a document and of a file
    it includes (``documents``: ``(shown, tree)``, the document first): MaterialX's reader keeps the first and
    drops the other without a word, so a copied material block left unrenamed would vanish from the atlas."""
    top: dict = {}
    for shown, root in documents:
        for parent in root.iter():
            seen: dict = {}
            for child in parent:
                name = child.get("name")
                if name is None:
                    continue
                if not name:  # MaterialX names it itself (surfacematerial1), a name the document never gave
                    raise MaterialError(shown, f"<{child.tag}>", "expected a name, got an empty one")
                if child.tag == "surfacematerial" and parent is not root:
                    # MaterialX lists only a document's top-level materials: this one would vanish from the atlas.
                    raise MaterialError(shown, name, f"expected a surfacematerial at the top of the document, found "
                                        f"one inside <{parent.tag} name={parent.get('name')!r}>")  # fmt: skip
                if name in seen:
                    raise MaterialError(shown, name, f"expected unique names among the children of <{parent.tag}>, "
                                        f"found <{seen[name]}> and <{child.tag}> both named {name!r}")  # fmt: skip
                seen[name] = child.tag
        for child in root:
            name = child.get("name")
            if name is not None and top.setdefault(name, shown) != shown:
                raise MaterialError(documents[0][0], name, f"expected unique names in a document and the files it "
                                    f"includes, found {name!r} in both {top[name]} and {shown}")  # fmt: skip


#: A component of a MaterialX value string: what C's strtof reads whole (nan and inf are refused later, as
#: not finite). MaterialX's own parser reads a leading number and drops the rest: "1,2,3" for a float
#: baked 1, "0x1" baked 0, "0.5abc" baked 0.5.
#: ASCII only, as strtof reads in the C locale: Python's \d and \s also match other scripts' digits and
#: spaces, and "0.4" followed by an Arabic-Indic five passed the check and was baked as 0.4.
_NUMBER = re.compile(r"\s*[+-]?(?:(?:\d+\.?\d*|\.\d+)(?:[eE][+-]?\d+)?|(?i:nan|inf(?:inity)?))\s*", re.ASCII)
_INTEGER = re.compile(r"\s*[+-]?\d+\s*", re.ASCII)
_COMPONENTS = {"float": 1, "vector2": 2, "color3": 3, "vector3": 3, "color4": 4, "vector4": 4}
#: What ``Document.validate`` says of an input given neither a value nor a connection.
_NO_VALUE = "Node input binds no value or connection"
#: The colour space the oracle's values are in: MaterialX's default working space, linear Rec. 709.
_LINEAR = "lin_rec709"


def _value_parses(kind: str, text: str) -> bool:
    """Whether ``text`` is a whole value of ``kind``, every character read (see :data:`_NUMBER`).

    >>> _value_parses("float", "0.5"), _value_parses("float", "1,2,3"), _value_parses("color3", "1, 0.5, .2")
    (True, False, True)
    >>> _value_parses("integer", "1.5"), _value_parses("color3", "0.5, 0.5, 0.5,"), _value_parses("boolean", "true")
    (False, False, True)
    >>> _value_parses("float", "0.4\u0665"), _value_parses("integer", "\u0661"), _value_parses("float", "\u00a00.5")
    (False, False, False)
    """
    if kind == "integer":
        return _INTEGER.fullmatch(text) is not None
    if kind == "boolean":
        return text.strip() in ("true", "false")
    count = _COMPONENTS.get(kind)
    if count is None:
        return True
    parts = text.split(",")
    return len(parts) == count and all(_NUMBER.fullmatch(part) for part in parts)


def _beyond_float32(kind: str, text: str) -> bool:
    """Whether ``text`` is a whole value of ``kind`` with a finite component too large for a float32.

    >>> _beyond_float32("float", "1e300"), _beyond_float32("color3", "0.5, -1e40, 0"), _beyond_float32("float", "inf")
    (True, True, False)
    """
    if kind not in _COMPONENTS or not _value_parses(kind, text):
        return False
    numbers = [float(part) for part in text.split(",")]
    return all(math.isfinite(x) for x in numbers) and any(abs(x) > FLOAT32_MAX for x in numbers)


def _check_units(shown: str, field: str, inp, declared) -> None:
    """Refuse a colour space or unit the value would have to be converted from: the oracle is handed the
    value as written, where MaterialX's generator converts it (an sRGB 0.5 is 0.214 linear; a thickness in
    nanometres is 1000 times one in the nodedef's micrometres)."""
    space = inp.getActiveColorSpace() if inp.getType().startswith("color") else ""
    if space and space != _LINEAR:
        raise MaterialError(shown, field, f"expected a linear colour (colorspace {_LINEAR}), got colorspace {space!r}; "
                            "atlasgen bakes values as written, with no colour transform")  # fmt: skip
    unit, expected = inp.getUnit(), declared.getUnit() if declared is not None else ""
    if unit and unit != expected:
        raise MaterialError(shown, field, f"expected {'unit ' + repr(expected) if expected else 'no unit'} (the nodedef's), "
                            f"got unit {unit!r}; atlasgen bakes values as written, with no unit conversion")  # fmt: skip


#: Why an input its nodedef declares without a default is named rather than used.
_NO_DEFAULT = "the oracle shades with the geometry's own normal and tangent and no volume, so the slice holds no value of it"


def _constant(shown: str, field: str, inp, kind: str, limits):
    """A constant input's plain value, or None where it has none (the nodedef's default then applies);
    refused on one line where its type is not the nodedef's, or it does not parse, is not finite or
    lies outside the nodedef's limits."""
    given_kind = inp.getType()
    if given_kind != kind:
        raise MaterialError(shown, field, f"expected type {kind} (the nodedef's), got {given_kind!r}")
    text = inp.getValueString()
    if not text.strip():
        return None
    value = inp.getValue()
    if value is None or not _value_parses(kind, text):
        expected = EXPECTED_VALUES.get(kind, "a " + kind + " value")
        if _beyond_float32(kind, text):
            # MaterialX reads a float32, and 1e300 does not parse: it is finite, so "expected a finite number" misled.
            expected += f" within float32's range (at most {FLOAT32_MAX:g} in magnitude)"
        raise MaterialError(shown, field, f"expected {expected}, got {text!r}")
    return check_input_value(shown, field, kind, _plain(value), limits)


def _lobes_no_slice_holds(shown: str, material: str, category: str, inputs: dict, defaults: dict) -> list[str]:
    """One line for the first anisotropic or mirror lobe (roughness 0) of weight above 0 (:data:`_ANISOTROPY`),
    naming the input and whether its value is the nodedef's default; else a clause for each lobe of weight
    sharper than :data:`ROUGHNESS_MIN`, which bakes."""

    def value(key):
        return float(inputs[key] if key in inputs else defaults[key][1])

    def weighted(weights):
        """The first of the lobes' weights above 0 ("" where the lobe is always shown), or None if none is."""
        if not weights:
            return ""
        return next((k for k in weights if k in defaults and value(k) > 0.0), None)

    def where(weight):
        return f" where {weight} > 0" if weight else ""

    def given(key):
        return f"{value(key):g}" + ("" if key in inputs else " (the nodedef's default)")

    for key, weights in _ANISOTROPY[category]:
        weight = weighted(weights)
        if key in defaults and value(key) != 0.0 and weight is not None:
            raise MaterialError(shown, f"{material}.{key}", f"expected 0{where(weight)}, got {given(key)}: an anisotropic "
                                "lobe varies with the azimuth, which a slice indexed by N.L and N.V does not hold; "
                                "set it to 0 to bake the isotropic lobe")  # fmt: skip
    sharp = []
    for key, weights in _LOBES[category]:
        weight = weighted(weights)
        if key not in defaults or value(key) >= ROUGHNESS_MIN or weight is None:
            continue
        if value(key) <= 0.0:
            raise MaterialError(shown, f"{material}.{key}", f"expected above 0{where(weight)}, got {given(key)}: a mirror "
                                "(a delta lobe), which no slice holds; give it a roughness, at least "
                                f"{ROUGHNESS_MIN:g} for the renderer's sharpest lobe (alpha {SPECULAR_ALPHA_MIN:g})")  # fmt: skip
        sharp.append(f"{key} = {given(key)}: a lobe sharper than the renderer's sharpest (roughness {ROUGHNESS_MIN:g}, "
                     f"alpha {SPECULAR_ALPHA_MIN:g}), whose highlight falls between the slice's texels")  # fmt: skip
    return sharp


def _where(documents, name: str) -> str:
    """The file of ``documents`` (``(shown, tree)``, the document first) whose top-level element is named ``name``."""
    return next((shown for shown, tree in documents if any(c.get("name") == name for c in tree)), documents[0][0])


def _material_nodes(documents, doc) -> list:
    """The document's ``surfacematerial`` nodes, refusing what MaterialX takes for a material and cannot shade as one:
    ``getMaterialNodes`` returned every node of type ``material`` (``<SurfaceMaterial>``, ``<not_a_node>``, which
    have no nodedef), and a ``surfacematerial`` of another type was left out, so the only one in a document was
    refused as "found none"."""
    out = []
    for node in doc.getNodes():
        name, category, kind = node.getName(), node.getCategory(), node.getType()
        if category == "surfacematerial" and kind != "material":
            raise MaterialError(_where(documents, name), f"{name}.type", f"expected 'material', got {kind!r}")
        if kind == "material" and category != "surfacematerial":
            raise MaterialError(_where(documents, name), name, f"expected a surfacematerial node, got <{category}> "
                                "of type material, which atlasgen does not bake")  # fmt: skip
        if category == "surfacematerial":
            out.append(node)
    return out


def _refuse_library_implementations(documents, doc, libraries) -> None:
    """Refuse a node graph or an implementation of the document that implements a nodedef of MaterialX's standard
    libraries (its ``nodedef`` attribute): MaterialX's generator then shades the document's (an unlit graph, say)
    for every node of that nodedef, while the oracle shades the library's, and the bake differed without a word."""
    for element in doc.getChildren():
        nodedef = element.getAttribute("nodedef")
        if element.getCategory() in ("nodegraph", "implementation") and nodedef and libraries.getChild(nodedef) is not None:
            name = element.getName()
            raise MaterialError(_where(documents, name), f"{name}.nodedef", f"expected no implementation of the "
                                f"standard libraries' {nodedef} (MaterialX would shade the document's, and the oracle "
                                f"shades the library's), got <{element.getCategory()}> {name!r}")  # fmt: skip


def _refuse_library_names(documents, doc, libraries) -> None:
    """Refuse an element of the document (or a file it includes; ``documents``: ``(shown, tree)``, the document
    first) named as one of MaterialX's standard libraries: importing the libraries keeps the document's, so a
    nodedef ``ND_standard_surface_surfaceshader`` of its own gave the node other defaults in MaterialX, while the
    oracle shades the library's, and the bake differed from what MaterialX shows without a word."""
    for element in doc.getChildren():
        name = element.getName()
        if libraries.getChild(name) is not None:
            raise MaterialError(_where(documents, name), name, f"expected no element named as one of MaterialX's standard libraries' (they "
                                f"are loaded already, and the oracle shades theirs), got <{element.getCategory()}> {name!r}")  # fmt: skip


def _read_shader(shown: str, material: str, category: str, shader, flatten) -> dict:
    """The ``materialx`` table of one shader node: its constant inputs, what was flattened, what the table cannot hold."""
    defaults = surface_defaults(category)
    ranges = surface_ranges(category)
    declared = surface_inputs(category)
    # Inputs first: MaterialX finds no nodedef for a node with an unknown input or one of another type.
    for inp in shader.getInputs():
        key = inp.getName()
        if key not in declared:
            raise MaterialError(shown, f"{material}.{key}", f"unknown input of {category}; expected one of "
                                f"{', '.join(declared)}")  # fmt: skip
        if inp.getType() != declared[key]:
            raise MaterialError(shown, f"{material}.{key}", f"expected type {declared[key]} (the nodedef's), got "
                                f"{inp.getType()!r}")  # fmt: skip
    nodedef, expected = shader.getNodeDef(), surface_nodedef(category)
    if nodedef is None or nodedef.getName() != expected:
        # A nodedef, version or type attribute picks another nodedef (an older version's defaults, say), or none.
        got = repr(nodedef.getName()) if nodedef is not None else "none MaterialX can find"
        raise MaterialError(shown, f"{material}.surfaceshader", f"expected the nodedef the oracle shades, {expected}, "
                            f"got {got} (from the node's nodedef, version or type)")  # fmt: skip
    inputs, flattened, no_default = {}, {}, []
    for inp in shader.getInputs():
        key = inp.getName()
        if key not in defaults and inp.getValue() is None and _driver(inp) is None:
            continue  # a geometric input left at its default (normal, tangent)
        _check_units(shown, f"{material}.{key}", inp, nodedef.getActiveInput(key))
        driver = _driver(inp)
        if driver is not None:
            given = flatten.get(key) if isinstance(flatten, dict) else None
            if given is None and flatten != "default":
                raise MaterialError(
                    shown, f"{material}.{key}", f"driven by {driver}; expected a constant value (or bake it at its default: atlasgen bake --flatten default"
                    ")"
                )  # fmt: skip
            if given is not None and key in defaults:
                given = check_input_value(shown, f"{material}.{key}", defaults[key][0], given, ranges.get(key))
            value = given if given is not None else (defaults[key][1] if key in defaults else None)
            flattened[key] = {"driven_by": driver, "value": value}
            if value is not None:
                inputs[key] = value
            continue
        if key not in defaults:
            # Declared without a default (a geometric normal or tangent, glTF's attenuation distance): the
            # oracle shades the geometry's own frame and no volume, so a value given is named, not used.
            value = _constant(shown, f"{material}.{key}", inp, declared[key], ranges.get(key))
            if value is not None:
                no_default.append(f"{key} = {shown_values(value if isinstance(value, list) else [value])}: {_NO_DEFAULT}")
            continue
        value = _constant(shown, f"{material}.{key}", inp, defaults[key][0], ranges.get(key))
        if value is not None:
            inputs[key] = value
    sharp_lobes = _lobes_no_slice_holds(shown, material, category, inputs, defaults)
    oracle_inputs = dict(inputs)
    not_in_table = list(sharp_lobes) + no_default
    for key, (neutral, what) in NOT_IN_TABLE[category].items():
        value = inputs.get(key, defaults[key][1] if key in defaults else None)
        shaded = _SHADED_VALUE.get(category, {}).get(key)
        if shaded is not None and shaded({k: inputs.get(k, d[1]) for k, d in defaults.items()}) == neutral:
            continue
        reference = neutral if neutral is not None else 0.0
        if value is not None and _differs(value, reference if not isinstance(reference, tuple) else reference):
            shown_value = shown_values(value) if isinstance(value, list | tuple) else value  # as the no-default inputs'
            not_in_table.append(f"{key} = {shown_value}: {what}")
            if neutral is not None:
                oracle_inputs[key] = list(neutral) if isinstance(neutral, tuple) else neutral
    if category in _THIN_WALLED_SUBSURFACE:
        thin, weight = _THIN_WALLED_SUBSURFACE[category]
        value = inputs.get(weight, defaults[weight][1])
        if inputs.get(thin, defaults[thin][1]) and _differs(value, 0.0):
            not_in_table.append(f"{weight} = {value} with {thin} = true: light through the thin wall (translucency; "
                                "the reflection that remains is baked)")  # fmt: skip
    return {"document": shown, "material": material, "category": category, "inputs": inputs, "oracle_inputs": oracle_inputs,
            "flattened": flattened, "not_in_table": not_in_table, "sharp_lobes": sharp_lobes,
            "alpha": _lobe_alpha(category, inputs, defaults),
            "error_measure": ERROR_MEASURE}  # fmt: skip
