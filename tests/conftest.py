"""Shared fixtures. Backend-gated fixtures skip cleanly where a backend is missing."""

from __future__ import annotations

import os
import textwrap
from pathlib import Path

import pytest

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
def gpu_device():
    """The shared WebGPU context (lavapipe here); skips when wgpu or an adapter is missing.

    Tests using it should end with ``assert gpu_device.take_errors() == []``-style
    checks (see ``tests/render``): the context collects every validation error the
    device reports.
    """
    from atlasgen.errors import BackendError

    try:
        from atlasgen.render.device import get_device

        return get_device()
    except BackendError as exc:
        pytest.skip(str(exc))


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
