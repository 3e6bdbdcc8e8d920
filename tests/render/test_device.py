"""Device creation: one place, a clear error when there is no adapter, errors collected."""

from __future__ import annotations

import logging

import pytest

from atlasgen.errors import BackendError
from atlasgen.render import device as device_module


def test_no_adapter_says_what_to_install(monkeypatch):
    wgpu = pytest.importorskip("wgpu")
    monkeypatch.setattr(wgpu.gpu, "request_adapter_sync", lambda **kwargs: None)
    with pytest.raises(BackendError) as info:
        device_module.create_device()
    message = str(info.value)
    assert "apt-get install mesa-vulkan-drivers" in message and "\n" not in message
    assert info.value.exit_code == 5


def test_adapter_failure_is_a_backend_error(monkeypatch):
    wgpu = pytest.importorskip("wgpu")

    def fail(**kwargs):
        raise RuntimeError("Request adapter failed: no backend")

    monkeypatch.setattr(wgpu.gpu, "request_adapter_sync", fail)
    with pytest.raises(BackendError, match="mesa-vulkan-drivers.*no backend"):
        device_module.create_device()


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
