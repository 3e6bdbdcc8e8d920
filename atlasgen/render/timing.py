"""GPU time per pass of a frame: timestamp queries where the device has them, fences otherwise.

A frame's passes carry labels (``gbuffer``, ``culling``, ``lighting``, ``translucency``, ``outlines``;
:meth:`atlasgen.render.renderer.Renderer.frame_steps`). With the ``timestamp-query`` feature each
pass writes a GPU timestamp at its start and end (WebGPU ``timestamp_writes``), and a label's time is
the sum of its passes' end - start. Without it, each pass is submitted alone and waited for, and its
wall time is counted: that includes the submission's overhead, so fenced figures are upper bounds.
"""

from __future__ import annotations

import time
from collections import defaultdict

import numpy as np

__all__ = ["TIMESTAMP_FEATURE", "PassTimer", "has_timestamps", "time_passes"]

#: The WebGPU feature that lets passes write GPU timestamps.
TIMESTAMP_FEATURE = "timestamp-query"


def has_timestamps(device) -> bool:
    """Whether ``device`` was created with :data:`TIMESTAMP_FEATURE`."""
    return TIMESTAMP_FEATURE in device.features


class PassTimer:
    """Timestamp writes for up to ``capacity`` passes of one submission, and their read-back."""

    def __init__(self, device, capacity: int = 64):
        import wgpu

        self.device = device
        self.capacity = capacity
        self.query_set = device.create_query_set(type="timestamp", count=2 * capacity)
        size = 16 * capacity
        self.resolved = device.create_buffer(size=size, usage=wgpu.BufferUsage.QUERY_RESOLVE | wgpu.BufferUsage.COPY_SRC)
        self.readable = device.create_buffer(size=size, usage=wgpu.BufferUsage.COPY_DST | wgpu.BufferUsage.MAP_READ)
        self.labels: list[str] = []

    def writes(self, label: str) -> dict:
        """The ``timestamp_writes`` of the next pass, counted under ``label``."""
        k = len(self.labels)
        if k >= self.capacity:
            raise ValueError(f"PassTimer holds {self.capacity} passes; a frame asked for more")
        self.labels.append(label)
        return {"query_set": self.query_set, "beginning_of_pass_write_index": 2 * k, "end_of_pass_write_index": 2 * k + 1}

    def resolve(self, encoder) -> None:
        """Record the copy of this frame's timestamps to a readable buffer (after its last pass)."""
        n = 2 * len(self.labels)
        if n:
            encoder.resolve_query_set(self.query_set, 0, n, self.resolved, 0)
            encoder.copy_buffer_to_buffer(self.resolved, 0, self.readable, 0, 8 * n)

    def read(self) -> dict[str, float]:
        """``{label: milliseconds}`` summed over the label's passes; forgets the labels for the next frame."""
        n = 2 * len(self.labels)
        out: dict[str, float] = defaultdict(float)
        if n:
            self.readable.map_sync("READ")
            ticks = np.frombuffer(self.readable.read_mapped(0, 8 * n), dtype=np.uint64).astype(np.int64).copy()
            self.readable.unmap()
            for k, label in enumerate(self.labels):
                # WebGPU timestamps are nanoseconds; an end before its start (a reset counter) counts 0.
                out[label] += max(int(ticks[2 * k + 1] - ticks[2 * k]), 0) / 1e6
        self.labels = []
        return dict(out)


def time_passes(
    renderer, frame, outlines: bool = True, method: str | None = None, timer: PassTimer | None = None
) -> tuple[dict, str]:
    """``({label: ms}, method)`` for one frame: ``method`` is ``"timestamps"`` or ``"fences"`` (by default the
    first where the device has timestamp queries). ``timer`` reuses a :class:`PassTimer` between frames."""
    method = method or ("timestamps" if has_timestamps(renderer.device) else "fences")
    steps = [s for s in renderer.frame_steps(frame, outlines) if s[0] is not None]
    if method == "timestamps":
        timer = timer or PassTimer(renderer.device, max(len(steps), 1))
        encoder = renderer.device.create_command_encoder()
        for label, encode in steps:
            encode(encoder, timer.writes(label))
        timer.resolve(encoder)
        renderer.submit([encoder.finish()])
        return timer.read(), method
    if method != "fences":
        raise ValueError(f"method must be 'timestamps' or 'fences', not {method!r}")
    out: dict[str, float] = defaultdict(float)
    for label, encode in steps:
        encoder = renderer.device.create_command_encoder()
        encode(encoder, None)
        t0 = time.perf_counter()
        renderer.submit([encoder.finish()])
        out[label] += (time.perf_counter() - t0) * 1000.0
    return dict(out), method
