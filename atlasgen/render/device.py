"""The one place atlasgen makes a WebGPU adapter and device.

Everything GPU-side (the renderer, its tests, the benchmark) asks :func:`get_device`
for a :class:`GpuContext`, so adapter selection, the features the pipeline needs and
the collection of validation errors are decided exactly once.
"""

from __future__ import annotations

import logging
import os
import tempfile
from dataclasses import dataclass, field

from atlasgen.errors import BackendError
from atlasgen.interrupts import deferred_interrupts
from atlasgen.render.ffi_types import cached_declarations
from atlasgen.render.ffi_types import install as install_fast_types

__all__ = ["GpuContext", "get_device", "create_device", "INSTALL_HINT"]

#: What to install when no adapter is found (Debian/Ubuntu; lavapipe is Mesa's Vulkan on the CPU).
INSTALL_HINT = (
    "no WebGPU adapter found; install a Vulkan driver "
    "(Debian/Ubuntu: apt-get install mesa-vulkan-drivers for the lavapipe software GPU) "
    "and the Python package wgpu (pip install 'atlasgen[render]')"
)


class _ErrorCollector(logging.Handler):
    """Collects the errors wgpu-native reports through the ``wgpu`` logger.

    wgpu-py raises :class:`wgpu.GPUValidationError` from the call that caused an error
    when it can; errors that surface later (during submit, in a callback) are only
    logged. Collecting the log records lets tests assert that no error happened at all.
    """

    def __init__(self, errors: list):
        super().__init__(level=logging.ERROR)
        self.errors = errors

    def emit(self, record):
        self.errors.append(record.getMessage())


@dataclass
class GpuContext:
    """An adapter, its device and the validation errors the device reported so far."""

    adapter: object
    device: object
    errors: list = field(default_factory=list)

    @property
    def name(self) -> str:
        """Human-readable adapter name, e.g. ``llvmpipe (LLVM 15.0.6, 256 bits) (Vulkan, CPU)``."""
        info = self.adapter.info
        return f"{info.get('device', '?')} ({info.get('backend_type', '?')}, {info.get('adapter_type', '?')})"

    @property
    def is_software(self) -> bool:
        return self.adapter.info.get("adapter_type", "") == "CPU"

    def take_errors(self) -> list:
        """Return and forget the errors collected since the last call."""
        out = list(self.errors)
        self.errors.clear()
        return out


def _ensure_runtime_dir() -> None:
    # Mesa's Vulkan loader prints errors for every call without XDG_RUNTIME_DIR; a
    # private 0700 folder is what the XDG base-directory spec asks for.
    if os.environ.get("XDG_RUNTIME_DIR"):
        return
    path = os.path.join(tempfile.gettempdir(), f"atlasgen-xdg-{os.getuid()}")
    os.makedirs(path, mode=0o700, exist_ok=True)
    os.environ["XDG_RUNTIME_DIR"] = path


def create_device(power_preference: str = "high-performance") -> GpuContext:
    """Request an adapter and a device; raise :class:`BackendError` if there is none.

    The pipeline needs nothing beyond core WebGPU: stencil (``depth24plus-stencil8``),
    2D texture arrays with explicit per-level uploads, an ``r16uint`` render target
    and several colour attachments; ``timestamp-query`` is requested where the adapter has it.
    """
    _ensure_runtime_dir()
    try:
        with cached_declarations():  # the WebGPU header's parse, from the last process that made it
            import wgpu
            from wgpu.backends.wgpu_native._ffi import ffi
    except ImportError:
        raise BackendError(INSTALL_HINT) from None
    install_fast_types(ffi)
    # A Ctrl-C landing in wgpu-native's adapter or device callback is raised inside a cffi callback: cffi
    # prints it as "Exception ignored" with a traceback, and wgpu then fails on an assertion (exit 1 or 5).
    # Held until both are made, it is one KeyboardInterrupt here (atlasgen.interrupts).
    with deferred_interrupts():
        try:
            adapter = wgpu.gpu.request_adapter_sync(power_preference=power_preference)
        except Exception as exc:  # wgpu-native raises RuntimeError when no backend loads
            raise BackendError(f"{INSTALL_HINT} ({str(exc).splitlines()[0] if str(exc) else type(exc).__name__})") from None
        if adapter is None:
            raise BackendError(INSTALL_HINT)
        # Timestamp queries time the frame's passes (atlasgen.render.timing) where the adapter has them.
        features = [f for f in ("timestamp-query",) if f in adapter.features]
        device = adapter.request_device_sync(label="atlasgen", required_features=features)
    ctx = GpuContext(adapter, device)
    handler = _ErrorCollector(ctx.errors)
    logging.getLogger("wgpu").addHandler(handler)
    ctx._handler = handler
    return ctx


_shared: GpuContext | None = None


def get_device() -> GpuContext:
    """The process-wide context, created on first use (adapter creation takes ~1 s on lavapipe)."""
    global _shared
    if _shared is None:
        _shared = create_device()
    return _shared
