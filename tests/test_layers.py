"""The package's layers: imports point down only, and function-level imports are only for heavy backends.

The layer table and every allowed exception live here, in one place. A module may import
from its own layer or a lower one; the import graph at module level is acyclic; only the
optional heavy dependencies (:data:`LAZY_OK`) are imported inside functions, so that
``atlasgen --help`` and a LUT-only bake stay fast; the library never imports click nor calls
``sys.exit``.
"""

from __future__ import annotations

import ast
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]

#: Lowest first. A top-level module (``atlasgen/errors.py``) sits in layer "atlasgen".
LAYERS = ["atlasgen", "optics", "io", "separable", "shaders", "models",
          "materials", "bake", "render", "validate", "preview", "reports", "cli"]  # fmt: skip

#: Imported inside functions on purpose: each is heavy or optional (a GPU, a Mitsuba build,
#: a plotting stack), and a LUT-only bake or ``--help`` must not pay for it.
LAZY_OK = {
    "mitsuba",
    "drjit",
    "wgpu",
    "cffi",  # wgpu-py's foreign-function layer (atlasgen/render/ffi_types.py)
    "matplotlib",
    "flip_evaluator",
    "flip",
    "trimesh",
    "OpenImageIO",
    "PIL",
    "jinja2",
    "zstandard",
    "watchfiles",
    "MaterialX",  # the MaterialX importer and its oracle (atlasgen/separable/materialx_oracle.py)
    "moderngl",
}

#: (importing module, imported module) pairs allowed to break the rules above, with why.
EXCEPTIONS: dict[tuple[str, str], str] = {
    ("atlasgen.__main__", "atlasgen.cli.main"): "`python -m atlasgen` is the command line's entry point",
    ("atlasgen.separable.rebuild", "scipy.sparse"): "imported where a separable stencil is built: the renderer, so "
    "every `atlasgen preview` of a LUT material, imports this module, and SciPy's sparse matrices cost ~0.3 s to import",
    ("atlasgen.separable", "atlasgen.separable.rebuild"): "docs/separable.md's `from atlasgen.separable import "
    "evaluate_separable`, resolved on first use so that the package itself imports nothing (SciPy's sparse matrices)",
}


def _module_files():
    for path in sorted((ROOT / "atlasgen").rglob("*.py")):
        rel = path.relative_to(ROOT / "atlasgen").with_suffix("")
        yield "atlasgen." + ".".join(p for p in rel.parts if p != "__init__") if rel.parts != ("__init__",) else "atlasgen", path
    for path in sorted((ROOT / "cli").glob("*.py")):
        name = "atlasgen.cli" if path.stem == "__init__" else f"atlasgen.cli.{path.stem}"
        yield name, path


MODULES = dict(_module_files())


def layer_of(module: str) -> int:
    parts = module.split(".")
    if (
        len(parts) >= 2
        and parts[1] in LAYERS
        and (f"atlasgen.{parts[1]}" in MODULES and MODULES[f"atlasgen.{parts[1]}"].name == "__init__.py")
    ):
        return LAYERS.index(parts[1])
    return 0


def _imports(path: Path):
    """(imported module, line, at_module_level) for every import in ``path``."""
    tree = ast.parse(path.read_text(), str(path))
    top_level = {id(node) for node in tree.body}
    # An import under `if TYPE_CHECKING:` or try/except at module level still counts as module level.
    for node in tree.body:
        if isinstance(node, (ast.If, ast.Try)):
            top_level |= {id(n) for n in ast.walk(node)}
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            for alias in node.names:
                yield alias.name, node.lineno, id(node) in top_level
        elif isinstance(node, ast.ImportFrom) and node.module:
            assert node.level == 0, f"{path}:{node.lineno}: relative import; the package uses absolute imports"
            names = [f"{node.module}.{a.name}" for a in node.names]
            # `from atlasgen.x import y` imports module atlasgen.x.y when that is a module.
            targets = [n for n in names if n in MODULES] or [node.module]
            for t in targets:
                yield t, node.lineno, id(node) in top_level


GRAPH = {name: list(_imports(path)) for name, path in MODULES.items()}


def test_every_atlasgen_folder_is_in_the_layer_table():
    folders = {p.name for p in (ROOT / "atlasgen").iterdir() if (p / "__init__.py").exists()}
    assert folders <= set(LAYERS), f"add {sorted(folders - set(LAYERS))} to LAYERS"


@pytest.mark.parametrize("module", sorted(MODULES))
def test_imports_point_down(module):
    up = [
        f"{MODULES[module].relative_to(ROOT)}:{line}: {module} ({LAYERS[layer_of(module)]}) imports {target} ({LAYERS[layer_of(target)]})"
        for target, line, _ in GRAPH[module]
        if target.startswith("atlasgen") and layer_of(target) > layer_of(module) and (module, target) not in EXCEPTIONS
    ]
    assert not up, "\n".join(up)


@pytest.mark.parametrize("module", sorted(MODULES))
def test_function_level_imports_are_only_heavy_backends(module):
    lazy = [
        f"{MODULES[module].relative_to(ROOT)}:{line}: import of {target} inside a function"
        for target, line, top in GRAPH[module]
        if not top and target.split(".")[0] not in LAZY_OK and (module, target) not in EXCEPTIONS
    ]
    assert not lazy, "\n".join(lazy)


def test_the_module_level_import_graph_is_acyclic():
    edges = {m: {t for t, _, top in GRAPH[m] if top and t in MODULES and t != m} for m in MODULES}
    # Importing a package runs its __init__: an edge to atlasgen.x.y also reaches atlasgen.x.
    state: dict[str, int] = {}
    stack: list[str] = []

    def visit(m):
        state[m] = 1
        stack.append(m)
        for t in sorted(edges[m]):
            if state.get(t) == 1:
                cycle = stack[stack.index(t) :] + [t]
                pytest.fail("import cycle: " + " -> ".join(cycle))
            if t not in state:
                visit(t)
        stack.pop()
        state[m] = 2

    for m in sorted(MODULES):
        if m not in state:
            visit(m)


def test_the_library_never_imports_click_nor_exits():
    offenders = []
    for module, path in MODULES.items():
        if module.startswith("atlasgen.cli"):
            continue
        text = path.read_text()
        if any(t.split(".")[0] == "click" for t, _, _ in GRAPH[module]) or "sys.exit(" in text:
            offenders.append(str(path.relative_to(ROOT)))
    assert not offenders


def test_the_bake_cache_key_covers_every_layer_below_bake():
    # A change to any code a bake runs on re-bakes (atlasgen/bake/cache.py, the Makefile's BAKE_CODE):
    # a new layer below bake/ must join BAKE_RELEVANT, or its changes would be served stale slices.
    from atlasgen.bake.cache import bake_relevant_files

    package = ROOT / "atlasgen"
    below = [package / layer for layer in LAYERS[1 : LAYERS.index("bake")]]
    expected = {*package.glob("*.py"), *(p for folder in below for p in folder.rglob("*.py"))}
    missing = sorted(p.relative_to(ROOT).as_posix() for p in expected - set(bake_relevant_files()))
    assert not missing, f"add to BAKE_RELEVANT: {missing}"
