"""Deferred translucency, as in Meshkin's "Fully Deferred Rendering Pipeline" (sec. 2).

After the opaque objects are lit, each translucent object, sorted back to front, is

1. drawn into the g-buffer *opaque*, with z-test and z-writes, over what is there;
   every pixel it wins gets stencil 1 (the stencil is cleared to 0 first);
2. lit by the same deferred lighting pass, restricted by the stencil to those pixels;
3. blended into the lit frame: frame = opacity * lit + (1 - opacity) * frame.

Only the nearest surface of each object reaches the g-buffer, so an object never
blends with itself: no intra-object sorting is needed, which is the talk's point.
"""

from __future__ import annotations

import numpy as np

from atlasgen.render.camera import camera_basis

__all__ = ["sort_back_to_front", "object_sort_key", "translucent_steps", "screen_rectangle"]


def object_sort_key(obj, centre, eye, forward) -> tuple:
    """Far to near by view depth of the bounding-box centre; ties broken by the object's
    own fields, never its position in the scene file, so listing order cannot matter."""
    depth = float(np.dot(np.asarray(centre) - eye, forward))
    return (-depth, obj.material, obj.translate, obj.rotate, obj.scale, obj.shape, obj.opacity, obj.albedo, obj.gloss,
            str(obj.file), obj.segments, obj.minor_radius)  # fmt: skip


def sort_back_to_front(objects, centres, camera) -> list[int]:
    """Indices into ``objects`` of the translucent ones, farthest first; none of opacity 0, which blends in nothing
    (drawn, an invisible toon object left its g-buffer layer's outline, and its ID in ``--aov id``)."""
    _, _, forward = camera_basis(camera)
    eye = np.asarray(camera.position, dtype=np.float64)
    chosen = [i for i, o in enumerate(objects) if o.translucent and o.opacity > 0.0]
    return sorted(chosen, key=lambda i: object_sort_key(objects[i], centres[i], eye, forward))


def screen_rectangle(corners_world: np.ndarray, view_proj: np.ndarray, width: int, height: int):
    """Pixel rectangle ``(x, y, w, h)`` covering the projected box corners, or ``None`` if off screen.

    A box reaching behind the camera (any corner with clip w <= 0) gets the full screen.
    """
    clip = np.c_[corners_world, np.ones(len(corners_world))] @ view_proj.T
    if (clip[:, 3] <= 1e-6).any():
        return (0, 0, width, height)
    ndc = clip[:, :2] / clip[:, 3:]
    x0 = int(np.floor((ndc[:, 0].min() + 1) / 2 * width)) - 1
    x1 = int(np.ceil((ndc[:, 0].max() + 1) / 2 * width)) + 1
    y0 = int(np.floor((1 - ndc[:, 1].max()) / 2 * height)) - 1
    y1 = int(np.ceil((1 - ndc[:, 1].min()) / 2 * height)) + 1
    x0, y0, x1, y1 = max(x0, 0), max(y0, 0), min(x1, width), min(y1, height)
    if x1 <= x0 or y1 <= y0:
        return None
    return (x0, y0, x1 - x0, y1 - y0)


def translucent_steps(gbuffer_pass, lighting_pass, gbuffer, hdr, frame_group, object_group, lighting_group, draw,
                      opacity, scissor=None, after=None, cull=None) -> list:  # fmt: skip
    """Steps 1-3 for one object, ``draw`` its ``(gpu_mesh, slot)``: a list of ``encode(encoder, timestamps)``
    calls, one per pass, in order, so the renderer can record, time or split them.

    ``scissor`` is the object's screen rectangle (:func:`screen_rectangle`); the lighting pass is
    skipped when it is empty. ``after(encoder, timestamps)`` (optional) runs between the g-buffer
    and lighting passes, e.g. to copy out the stencil; ``cull(encoder, timestamps)`` (optional)
    then rebuilds the light lists against the depths this object left in the g-buffer, so that its
    layer is lit with lists correct for its own depths.
    """

    def draw_step(encoder, timestamps=None):
        gbuffer_pass.encode(encoder, gbuffer, frame_group, object_group, [draw], clear=False, stencil_reference=1,
                            timestamps=timestamps)  # fmt: skip

    def light_step(encoder, timestamps=None):
        lighting_pass.encode(encoder, hdr, gbuffer, lighting_group, opacity=opacity, scissor=scissor, timestamps=timestamps)

    steps = [draw_step] + ([after] if after is not None else [])
    if scissor is None:
        return steps
    return steps + ([cull] if cull is not None else []) + [light_step]
