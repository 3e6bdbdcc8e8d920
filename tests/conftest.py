"""Shared fixtures. Backend-gated fixtures skip cleanly where a backend is missing."""

from __future__ import annotations

import os
import textwrap
from pathlib import Path

import pytest
from hypothesis import settings

# No timed assertions (developers' guide): Hypothesis's per-example deadline is one, and it
# fails tests at random on a loaded machine.
settings.register_profile("atlasgen", deadline=None)
settings.load_profile("atlasgen")

# Hypothesis's per-example deadline is a timed assertion: on a loaded machine it fails
# tests whose results are right. Examples are bounded by their own size instead.
from hypothesis import settings  # noqa: E402

settings.register_profile("atlasgen", deadline=None)
settings.load_profile("atlasgen")

os.environ.setdefault("XDG_RUNTIME_DIR", "/tmp/atlasgen-xdg-%d" % os.getuid())
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
}


def pytest_collection_modifyitems(config, items):
    for item in items:
        for fixture, marker in FIXTURE_MARKERS.items():
            if fixture in getattr(item, "fixturenames", ()):
                item.add_marker(marker)


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
