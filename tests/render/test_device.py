"""Device creation: one place, a clear error when there is no adapter, errors collected."""

from __future__ import annotations

import logging

import pytest

from atlasgen.errors import BackendError
from atlasgen.render import device as device_module


@pytest.fixture
def wgpu():
    """wgpu with its native backend loaded: loading it replaces ``wgpu.gpu``, so a patch made before would be lost
    (these tests passed only after another test had loaded it)."""
    pytest.importorskip("wgpu.backends.wgpu_native")
    import wgpu

    return wgpu


def test_no_adapter_says_what_to_install(monkeypatch, wgpu):
    monkeypatch.setattr(wgpu.gpu, "request_adapter_sync", lambda **kwargs: None)
    with pytest.raises(BackendError) as info:
        device_module.create_device()
    message = str(info.value)
    assert "apt-get install mesa-vulkan-drivers" in message and "\n" not in message
    assert info.value.exit_code == 5


def test_adapter_failure_is_a_backend_error(monkeypatch, wgpu):

    def fail(**kwargs):
        raise RuntimeError("Request adapter failed: no backend")

    monkeypatch.setattr(wgpu.gpu, "request_adapter_sync", fail)
    with pytest.raises(BackendError, match="mesa-vulkan-drivers.*no backend"):
        device_module.create_device()


def test_a_ctrl_c_while_the_adapter_is_requested_is_one_keyboard_interrupt_after_it(monkeypatch, wgpu):
    """Raised inside wgpu-native's cffi callback, a Ctrl-C printed cffi's traceback and wgpu failed on an
    assertion (exit 1 or 5). Held, the request finishes, and the interrupt follows it as the command's 130."""
    import os
    import signal

    finished = []

    def interrupted(**kwargs):
        os.kill(os.getpid(), signal.SIGINT)  # Python raises it at the next instruction unless it is held
        finished.append(True)

    monkeypatch.setattr(wgpu.gpu, "request_adapter_sync", interrupted)
    with pytest.raises(KeyboardInterrupt):
        device_module.create_device()  # no adapter (None), so no device is made: the interrupt, not BackendError
    assert finished == [True]
    assert signal.getsignal(signal.SIGINT) is signal.default_int_handler


@pytest.mark.slow
def test_shared_device_collects_logged_errors(gpu_device):
    assert device_module.get_device() is gpu_device
    assert gpu_device.name and gpu_device.adapter.info["adapter_type"]
    gpu_device.take_errors()
    logging.getLogger("wgpu").error("Validation Error: something went wrong")
    assert gpu_device.take_errors() == ["Validation Error: something went wrong"]
    assert gpu_device.take_errors() == []


@pytest.mark.slow
def test_validation_errors_raise(gpu_device):
    import wgpu

    with pytest.raises(wgpu.GPUValidationError):
        gpu_device.device.create_shader_module(code="fn broken( {")
    gpu_device.take_errors()
