"""Stable slice allocation: explicit TOML ids first, then a library's manifest (``--ids-from``), then the
previous manifest, then the lowest free range."""

from __future__ import annotations

from pathlib import Path

from atlasgen.contract import LAYERS
from atlasgen.errors import MaterialError

__all__ = ["assign_slices"]


def _span(start, count):
    return range(start, start + count)


def assign_slices(requests: list[tuple], previous: dict[str, int] | None = None, layers: int = LAYERS,
                  pinned: tuple | None = None) -> dict[str, int]:  # fmt: skip
    """First slice of every material, keeping slices stable across re-bakes.

    Parameters
    ----------
    requests
        ``(name, slice_count, explicit_id_or_None, source_path)`` per material, in any order:
        new slices are handed out in name order.
    previous
        ``name -> first_slice`` from the previous manifest, if any.
    pinned
        ``(manifest_path, name -> first_slice)`` of another atlas whose IDs this one must share
        (``atlasgen bake --ids-from``): its slices yield only to explicit ids, and a material it names
        gets exactly its slice there or is refused; the previous manifest's materials move out of its way.

    A material with an explicit ``id`` gets exactly that slice; one that was in the
    previous manifest keeps its slice when it still fits there, unless its run grew into
    another's (that one keeps its slice); the rest take the lowest free run of slices.
    Two explicit ids that overlap are a conflict, and so is an explicit id that lands on a
    slice the previous manifest gave to a material still present (moving that one would
    silently change its ID in every scene).

    Raises
    ------
    MaterialError
        On a conflict, or when the materials need more slices than the atlas has.
    """
    previous = previous or {}
    # By name, not by bake order: the same materials get the same slices however they
    # were listed on the command line (names are unique: check_unique_names).
    requests = sorted(requests, key=lambda request: request[0])
    owner: dict[int, str] = {}
    first: dict[str, int] = {}
    sources = {name: src for name, _, _, src in requests}

    def claim(name, start, count, src, why):
        if start < 0 or start + count > layers:
            raise MaterialError(src, "id", f"expected slices {start}..{start + count - 1} to lie within 0..{layers - 1}")
        for s in _span(start, count):
            if s in owner:
                other = owner[s]
                raise MaterialError(
                    src, "id", f"slice {s} ({why}) conflicts with material {other!r} ({sources[other]}); expected a free slice"
                )
        for s in _span(start, count):
            owner[s] = name
        first[name] = start

    total = sum(count for _, count, _, _ in requests)
    if total > layers:
        src = requests[-1][3] if requests else "materials"
        raise MaterialError(src, None, f"the materials need {total} slices; expected at most {layers} (the atlas has {layers})")

    for name, count, explicit, src in requests:
        if explicit is not None:
            claim(name, explicit, count, src, "explicit id")
    explicit_names = {name for name, _, explicit, _ in requests if explicit is not None}
    if pinned is not None:
        _claim_pinned(requests, pinned, claim, owner, layers)
    # Where each material still present began in the previous manifest. A run that now reaches another's
    # first slice grew (the previous runs did not overlap): it moves, and the other keeps its ID. In name
    # order instead, a grown material took the next one's place and moved that one, though it had not
    # changed, and a scene atlas baked with its old ID went stale.
    homes = {previous[name]: name for name, _, explicit, _ in requests if explicit is None and name in previous}
    # The --ids-from manifest's IDs of materials this atlas lacks stay theirs: a material of this atlas alone taking
    # one (the library's red-plastic's 0, say) made one g-buffer ID two materials across the atlases, which --ids-from
    # exists to prevent. Earlier IDs here move out of their way, as out of the pinned materials' own.
    reserved = set(pinned[1].values()) if pinned is not None else set()
    for name, count, explicit, src in requests:
        if explicit is None and name in previous and name not in first:
            start = previous[name]
            if any(homes.get(s, name) != name for s in _span(start + 1, count - 1)) or reserved.intersection(_span(start, count)):
                continue
            taken = [s for s in _span(start, count) if s in owner]
            if start + count <= layers and not taken:
                claim(name, start, count, src, "previous manifest")
            elif taken and owner[taken[0]] in explicit_names:
                other = owner[taken[0]]
                raise MaterialError(
                    sources[other],
                    "id",
                    f"explicit id takes slice {taken[0]}, which the previous manifest gives to {name!r} ({src}); "
                    "expected a free slice (or delete the old manifest to re-number)",
                )
    # A material whose multi-slice run grew past its old place moves to the lowest free run; one over a reserved ID
    # only where no other run is left (the atlas's 256 slices shared with the library's absent materials).
    for name, count, _explicit, src in requests:
        if name in first:
            continue
        start = _lowest_run(owner, count, layers, reserved)
        if start is None:
            start = _lowest_run(owner, count, layers, set())
        if start is None:
            raise MaterialError(src, None, f"needs {count} consecutive free slices; expected a gap that large in the atlas")
        claim(name, start, count, src, "allocated")
    return first


def _lowest_run(owner: dict, count: int, layers: int, reserved: set) -> int | None:
    """The first slice of the lowest run of ``count`` slices none of which is owned or ``reserved``; None where there
    is none. (A run over another atlas's ID would make that ID read one of its slices.)"""
    for start in range(layers - count + 1):
        if not any(s in owner or s in reserved for s in _span(start, count)):
            return start
    return None


def _claim_pinned(requests, pinned, claim, owner, layers) -> None:
    """Give each material the ``pinned`` manifest names its slice there, after the explicit ids, or refuse it: a
    scene atlas baked ``--ids-from`` the library must not give a material another ID than the library's."""
    path, slots = pinned
    shown = Path(path).as_posix()
    for name, count, explicit, src in requests:
        if explicit is not None or name not in slots:
            continue
        start = slots[name]
        span = f"slices {start}..{start + count - 1}" if count > 1 else f"slice {start}"
        if start + count > layers:
            raise MaterialError(src, None, f"material {name!r} needs {span} where --ids-from {shown} puts it, beyond the "
                                           f"atlas's {layers}; expected the library's slices (re-bake {shown})")  # fmt: skip
        taken = [s for s in _span(start, count) if s in owner]
        if taken:
            raise MaterialError(src, None, f"material {name!r} needs {span} where --ids-from {shown} puts it, and slice "
                                           f"{taken[0]} holds {owner[taken[0]]!r}; expected the library's slices free "
                                           f"(re-bake {shown}, or change the explicit id)")  # fmt: skip
        claim(name, start, count, src, f"--ids-from {shown}")
