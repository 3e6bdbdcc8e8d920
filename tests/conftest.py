"""Shared fixtures. Backend-gated fixtures skip cleanly where a backend is missing."""

from __future__ import annotations

import json
import os
import textwrap
import time
from pathlib import Path

import pytest
from hypothesis import settings

# No timed assertions (developers' guide): Hypothesis's per-example deadline is one, and it
# fails tests at random on a loaded machine.
settings.register_profile("atlasgen", deadline=None)
settings.load_profile("atlasgen")

os.environ.setdefault("XDG_RUNTIME_DIR", f"/tmp/atlasgen-xdg-{os.getuid()}")
os.makedirs(os.environ["XDG_RUNTIME_DIR"], mode=0o700, exist_ok=True)


@pytest.fixture
def expect_rejected(write_material):
    """Write ``type = <model>`` plus ``body`` (or ``body`` alone when the type is None) to a
    TOML file and assert read_material rejects it.

    The message must be one line naming the file, the field (when given) and ``expected``.
    """

    def check(type_name: str, body: str, field: str | None, expected: str) -> str:
        from atlasgen.errors import MaterialError
        from atlasgen.materials.material import read_material

        path = write_material("bad", f'type = "{type_name}"\n{body}\n' if type_name else body)
        with pytest.raises(MaterialError) as info:
            read_material(path)
        message = str(info.value)
        assert "\n" not in message
        assert message.startswith(path.as_posix() + ": "), message
        if field is not None:
            assert f"field '{field}'" in message, message
        assert expected in message, message
        return message

    return check


@pytest.fixture(scope="session")
def separable_atlas(tmp_path_factory):
    """An sRGB atlas with separable materials (f_cos and f_proxy targets) and a Lambert LUT, on disk
    (for the separable maths' tests and for its shader code's, tests/shaders/test_separable.py)."""
    return _shared_bake(tmp_path_factory, "separable-atlas", SEPARABLE_ATLAS)


#: The materials of :func:`separable_atlas`.
SEPARABLE_ATLAS = {
    "lut": 'type = "lambert"\ncolour = [0.5, 0.5, 0.5]\n',
    "sharp": 'type = "separable"\nsource = "ggx"\nalpha = 0.05\nterms = 3\ntarget = "f_cos"\n',
    "plastic": 'type = "separable"\nsource = "ggx"\nalpha = 0.3\nfresnel = "exact"\ndiffuse = [0.4, 0.1, 0.05]\nterms = 2\ntarget = "f_proxy"\n',
    "phong": 'type = "separable"\nsource = "blinn_phong"\nexponent = 40.0\nspecular = [0.9, 0.6, 0.3]\nterms = 2\nparametrization = "in_out"\n',
}


def _shared_bake(tmp_path_factory, name: str, files: dict):
    """``(atlas.dds path, BakeResult)`` of ``files`` (``{stem: TOML text}``), baked once per test run
    for every xdist worker (:func:`shared_folder`); each worker reads the pickled result, so all of
    them test the same bake."""
    import pickle

    def build(folder):
        from atlasgen.bake.pipeline import bake_atlas, write_bake
        from atlasgen.materials.material import read_materials

        mats = folder / "materials"
        mats.mkdir()
        for stem, text in files.items():
            (mats / f"{stem}.toml").write_text(textwrap.dedent(text))
        result = bake_atlas(read_materials([mats]))
        write_bake(result, folder / "atlas.dds")
        (folder / "result.pickle").write_bytes(pickle.dumps(result))

    folder = shared_folder(tmp_path_factory, name, build)
    return folder / "atlas.dds", pickle.loads((folder / "result.pickle").read_bytes())


@pytest.fixture
def write_material(tmp_path):
    """Write a material TOML into ``tmp_path/materials`` and return its path."""
    folder = tmp_path / "materials"
    folder.mkdir(exist_ok=True)

    def write(name: str, text: str) -> Path:
        path = folder / f"{name}.toml"
        path.write_text(textwrap.dedent(text))
        return path

    return write


@pytest.fixture(scope="session")
def gpu_context():
    """The shared WebGPU context (lavapipe here); skips when wgpu or an adapter is missing.

    For session-scoped fixtures that render; tests request :func:`gpu_device`. Any test
    with this fixture in its closure is marked ``gpu`` and checked by :func:`gpu_device`
    (see :func:`pytest_collection_modifyitems` and :func:`_gpu_error_check`).
    """
    from atlasgen.errors import BackendError

    try:
        from atlasgen.render.device import get_device

        return get_device()
    except BackendError as exc:
        pytest.skip(str(exc))


def _assert_no_gpu_errors(context, when: str) -> None:
    errors = context.take_errors()
    assert not errors, f"the GPU device reported {len(errors)} error(s) {when}:\n" + "\n".join(errors)


@pytest.fixture
def gpu_device(gpu_context):
    """The shared WebGPU context, checked: the test errors if the device reported any error.

    The context collects every error wgpu reports (atlasgen/render/device.py: raised
    validation errors and the ones only logged, e.g. at submit). Errors found on the way
    in came from a session fixture or an earlier test; errors found on the way out, from
    this test.
    """
    _assert_no_gpu_errors(gpu_context, "before this test (in a session fixture or an earlier test)")
    yield gpu_context
    _assert_no_gpu_errors(gpu_context, "during this test")


@pytest.fixture(autouse=True)
def _gpu_error_check(request):
    """Every test that reaches the GPU through any fixture (a renderer, a validation run) gets
    :func:`gpu_device`'s check, whether or not it asks for the device itself."""
    if "gpu_context" in request.fixturenames:
        request.getfixturevalue("gpu_device")


#: Markers implied by a fixture anywhere in a test's fixture closure, so that a new test
#: using one of them is marked without saying so.
FIXTURE_MARKERS = {
    "gpu_context": "gpu",
    "mitsuba_llvm": "mitsuba",
    "mitsuba_rgb": "mitsuba",
    # Session fixtures that cost a second or more (2 cores): a Mitsuba and GPU run of every
    # test material; a bake of four separable materials; the renderer's pipelines.
    "validation_run": "slow",
    "separable_atlas": "slow",
    "renderer": "slow",
    # The shipped library's bake cache, filled once per test run for every xdist worker.
    "shipped_library_cache": "slow",
}


#: Session fixtures whose users run in one xdist worker (the group named here). Both are built once
#: per run for every worker (:func:`shared_folder`): a second worker would only wait for the first
#: to build them, while under a group it runs the rest of the suite meanwhile. (The renderer's
#: pipelines are not worth a group: tests/render took no less CPU with one, 2026-12-02.)
FIXTURE_GROUPS = {
    "validation_run": "validation-run",
    "shipped_library_cache": "shipped-library",
}

#: Fixture scopes that pytest-xdist would pay once per worker that runs a test of the module.
_MODULE_SCOPES = {"module", "class", "package"}


def _uses_a_module_fixture(item) -> bool:
    info = getattr(item, "_fixtureinfo", None)
    if info is None:
        return False
    return any(defs and defs[-1].scope in _MODULE_SCOPES for defs in info.name2fixturedefs.values())


@pytest.hookimpl(tryfirst=True)  # before xdist reads the groups (it suffixes node ids with them)
def pytest_collection_modifyitems(config, items):
    for item in items:
        for fixture, marker in FIXTURE_MARKERS.items():
            if fixture in getattr(item, "fixturenames", ()):
                item.add_marker(marker)
    if getattr(config.option, "loadgroup", False):  # set in xdist workers under --dist loadgroup
        _suffix_groups(items)
        _order_longest_first(items, getattr(config, "workerinput", {}).get(_DURATIONS_KEY) or {})


def _own_group(item) -> str | None:
    """The test's own ``xdist_group`` name(s), joined as pytest-xdist joins them, or None."""
    names = sorted({str(m.args[0] if m.args else m.kwargs.get("name", "default")) for m in item.iter_markers("xdist_group")})
    return "_".join(names) if names else None


def _fixture_group(item) -> str | None:
    return next((g for fixture, g in FIXTURE_GROUPS.items() if fixture in getattr(item, "fixturenames", ())), None)


def _suffix_groups(items) -> None:
    """Give each test of a group the node id ``<id>@<group>`` that ``--dist loadgroup`` schedules by.

    A test's group: its own ``xdist_group``, taken whole into a :data:`FIXTURE_GROUPS` group where
    one of its tests uses that fixture (tests/test_install.py's wheel and the library's bake cache);
    else the group of a :data:`FIXTURE_GROUPS` fixture it uses; else, where it uses a module-scoped
    fixture (a bake, a Mitsuba run, a browser), its module, so that the fixture is set up in one
    worker once. pytest-xdist 3.8 marks a group by setting ``item._nodeid``, which pytest 9 no
    longer reads (a node's id is ``item._id``): without this every group would be split across
    the workers and its shared fixtures paid in each. xdist's own pass runs after this hook
    (tryfirst) and sets the attribute pytest ignores."""
    from _pytest.nodeid import NodeId

    merged: dict = {}
    for item in items:
        own, fixture = _own_group(item), _fixture_group(item)
        if own is not None and fixture is not None:
            merged.setdefault(own, fixture)
    for item in items:
        own = _own_group(item)
        if own is not None:
            group = merged.get(own, own)
        else:
            group = _fixture_group(item) or (item.nodeid.split("::")[0] if _uses_a_module_fixture(item) else None)
        if group is not None and "@" not in item.nodeid:
            # The suffix goes into the last name, outside any [params], so that the id's string
            # rebuilt from its parts (the controller's report) is the same string.
            *names, last = item._id.names
            params = "" if item._id.params is None else f"[{item._id.params}]"
            item._id = NodeId(path=item._id.path, names=(*names, f"{last}{params}@{group}"))


# ---- xdist scheduling: the longest work first ------------------------------------------------
#: Where the last runs' seconds per test (setup, call and teardown) are kept (.pytest_cache).
_DURATIONS_KEY = "atlasgen/durations"
#: The same seconds as one full run measured them, kept in the repository, for a run that has no
#: .pytest_cache of its own (a fresh clone, CI): without them the work is handed out in collection
#: order, and a long group can start last. ``ATLASGEN_WRITE_DURATIONS=1 make test`` rewrites it.
_SHIPPED_DURATIONS = Path(__file__).resolve().parent / "durations.json"
_durations: dict = {}


def _base_id(nodeid: str) -> str:
    return nodeid.split("@", 1)[0]


def _order_longest_first(items, durations: dict) -> None:
    """Order the work units (an xdist group, or a test alone) by how long they took last time,
    longest first, then by size; ties keep the collection order. With --no-loadscope-reorder
    (pyproject.toml) xdist hands them out in this order, so a long test does not start last and
    leave the other core idle. A unit's tests keep their order, and a group goes to one worker at
    once, so a module's fixtures are still set up once; only tests alone (function-scoped
    fixtures only) move. A fresh clone, with no .pytest_cache, orders by the timings kept in
    tests/durations.json; a test none of them knows counts as 0 s."""
    units: dict = {}
    for item in items:
        key = item.nodeid.rsplit("@", 1)[1] if "@" in item.nodeid else item.nodeid
        units.setdefault(key, []).append(item)

    def cost(unit):
        return -sum(float(durations.get(_base_id(i.nodeid), 0.0)) for i in unit), -len(unit)

    items[:] = [item for unit in sorted(units.values(), key=cost) for item in unit]


try:  # pytest-xdist's hook (the controller's): every worker orders by the same timings
    import xdist  # noqa: F401

    def pytest_configure_node(node):
        cache = getattr(node.config, "cache", None)
        shipped = json.loads(_SHIPPED_DURATIONS.read_text()) if _SHIPPED_DURATIONS.exists() else {}
        node.workerinput[_DURATIONS_KEY] = {**shipped, **(cache.get(_DURATIONS_KEY, {}) if cache is not None else {})}

except ImportError:
    pass


def pytest_runtest_logreport(report):
    # In the controller every worker's reports arrive here too; a worker's are its own.
    _durations[_base_id(report.nodeid)] = _durations.get(_base_id(report.nodeid), 0.0) + report.duration


def pytest_sessionfinish(session):
    cache = getattr(session.config, "cache", None)
    if cache is None or hasattr(session.config, "workerinput") or not _durations:
        return
    measured = {k: round(v, 3) for k, v in _durations.items()}
    cache.set(_DURATIONS_KEY, {**cache.get(_DURATIONS_KEY, {}), **measured})
    if os.environ.get("ATLASGEN_WRITE_DURATIONS") == "1":
        # Tests under a tenth of a second hardly move the order: they are left out (0 s).
        kept = {k: round(v, 1) for k, v in sorted(measured.items()) if v >= 0.1}
        _SHIPPED_DURATIONS.write_text(json.dumps(kept, indent=0) + "\n")


ROOT = Path(__file__).resolve().parents[1]


def shared_folder(tmp_path_factory, name: str, build) -> Path:
    """A folder that ``build(folder)`` fills once per test run, shared by pytest-xdist's workers.

    The first process to arrive builds it under a lock; the others wait for it and reuse it. A
    build that raises leaves no folder, so the next test to ask tries again.
    """
    import fcntl
    import shutil

    root = tmp_path_factory.getbasetemp()
    if os.environ.get("PYTEST_XDIST_WORKER"):
        root = root.parent  # the run's base, shared by every worker's own basetemp
    folder, done = root / f"shared-{name}", root / f"shared-{name}.done"
    with open(root / f"shared-{name}.lock", "w") as lock:
        fcntl.flock(lock, fcntl.LOCK_EX)
        if not done.exists():
            shutil.rmtree(folder, ignore_errors=True)
            folder.mkdir()
            try:
                build(folder)
            except BaseException:
                shutil.rmtree(folder, ignore_errors=True)
                raise
            done.touch()
    return folder


@pytest.fixture(scope="session")
def shipped_library_cache(tmp_path_factory, mitsuba_llvm):
    """The bake cache (``atlasgen bake --cache``) of the shipped library, physics fits included.

    Baking the library costs a minute of CPU, most of it the fits from physics; every test that
    bakes the whole library (the goldens, the containers, the installed wheel) assembles it from
    this cache, as ``make atlas`` does. The cache's own correctness (a cached bake is the bake)
    is tests/test_cache.py's.
    """
    from atlasgen.bake.workers import fill_cache
    from atlasgen.materials.material import read_materials

    return shared_folder(
        tmp_path_factory, "library-cache", lambda folder: fill_cache(folder, read_materials([ROOT / "materials"]))
    )


@pytest.fixture(scope="session")
def mitsuba_llvm():
    """Mitsuba 3 set to its ``llvm_ad_rgb`` variant; skips when Mitsuba or the variant is missing.

    (Separable BRDFs, issue 3: Mitsuba BSDFs are evaluated in this variant only.)
    """
    try:
        import mitsuba as mi

        mi.set_variant("llvm_ad_rgb")
    except Exception as exc:  # ImportError, or the variant/LLVM is unavailable
        pytest.skip(f"Mitsuba 3 llvm_ad_rgb is unavailable: {exc}")
    return mi


# ---- the fast loop's CPU budget --------------------------------------------------------------
#: The `slow` marker's definition (pyproject.toml): a test over this many CPU seconds (its setup,
#: call and teardown, time.process_time, every thread of the process) is marked slow, or uses a
#: fixture in FIXTURE_MARKERS that makes it so. Fixtures scoped wider than a function are paid
#: once per process and are not charged to the test that happens to come first, except that one
#: costing more than the budget must itself be listed as slow.
SLOW_CPU_BUDGET_S = 2.0
#: Backend start-up (importing Mitsuba and setting its variant, opening the WebGPU device) is paid
#: by whichever test reaches it first in each process: never charged to a test.
_STARTUP_FIXTURES = {"gpu_context", "mitsuba_llvm", "mitsuba_rgb"}
#: ATLASGEN_CPU_GUARD=0 turns the guard off (a profiler or debugger inflates every test);
#: ATLASGEN_CPU_REPORT=FILE appends "nodeid<TAB>cpu seconds" for every test, to find them.
_GUARD = os.environ.get("ATLASGEN_CPU_GUARD", "1") != "0"
_REPORT = os.environ.get("ATLASGEN_CPU_REPORT")


#: Imported before the first test when the guard is on, so that no test is charged for being the
#: first in its process to import one (matplotlib alone costs most of a budget).
_HEAVY_IMPORTS = ("matplotlib", "matplotlib.pyplot", "scipy.optimize", "scipy.integrate", "scipy.interpolate",
                  "scipy.stats", "trimesh", "OpenImageIO", "jinja2", "zstandard", "wgpu", "PIL.Image")  # fmt: skip


def _is_xdist_controller(config) -> bool:
    """True in the process that only hands tests to xdist workers and runs none itself."""
    return not hasattr(config, "workerinput") and getattr(config.option, "dist", "no") != "no"


def pytest_configure(config):
    # The controller runs no test, so paying its imports would only delay the workers' start.
    if not _GUARD or _is_xdist_controller(config):
        return
    import importlib

    os.environ.setdefault("MPLBACKEND", "Agg")
    for name in _HEAVY_IMPORTS:
        try:
            importlib.import_module(name)
        except ImportError:  # an optional backend that is not installed: its tests skip
            pass


@pytest.hookimpl(hookwrapper=True)
def pytest_fixture_setup(fixturedef, request):
    if fixturedef.scope == "function":
        yield
        return
    start = time.process_time()
    yield
    spent = time.process_time() - start
    target = getattr(request, "_pyfuncitem", None)  # the test whose set-up this is
    if target is not None:
        target._atlasgen_wide_fixtures = getattr(target, "_atlasgen_wide_fixtures", 0.0) + spent
        if fixturedef.argname not in _STARTUP_FIXTURES and spent > SLOW_CPU_BUDGET_S:
            target._atlasgen_costly_fixtures = [*getattr(target, "_atlasgen_costly_fixtures", []), (fixturedef.argname, spent)]


@pytest.hookimpl(hookwrapper=True)
def pytest_runtest_protocol(item, nextitem):
    item._atlasgen_cpu_start = time.process_time()
    yield


@pytest.hookimpl(hookwrapper=True)
def pytest_runtest_makereport(item, call):
    outcome = yield
    if call.when != "teardown":
        return
    spent = time.process_time() - item._atlasgen_cpu_start - getattr(item, "_atlasgen_wide_fixtures", 0.0)
    if _REPORT:
        with open(_REPORT, "a", encoding="utf-8") as log:
            log.write(f"{item.nodeid}\t{spent:.3f}\t{getattr(item, '_atlasgen_wide_fixtures', 0.0):.3f}\n")
    report = outcome.get_result()
    if not _GUARD or item.get_closest_marker("slow") is not None or report.failed:
        return
    problems = []
    if spent > SLOW_CPU_BUDGET_S:
        problems.append(f"it used {spent:.2f} s of CPU")
    problems += [
        f"its fixture {name!r} used {cost:.2f} s of CPU" for name, cost in getattr(item, "_atlasgen_costly_fixtures", [])
    ]
    if problems:
        report.outcome = "failed"
        report.longrepr = (
            f"{item.nodeid} is not marked slow, but {'; '.join(problems)}, over the fast loop's budget of "
            f"{SLOW_CPU_BUDGET_S} s (tests/conftest.py SLOW_CPU_BUDGET_S): mark it @pytest.mark.slow, "
            "or list the fixture in FIXTURE_MARKERS"
        )
