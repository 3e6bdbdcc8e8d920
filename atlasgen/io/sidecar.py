"""The separable side-car ``X.separable.bin``: its header, and the manifest hash it records.

The header is the magic ``ASEP``, then little-endian u32 file version, row count and digest
length (32), then the SHA-256 of the manifest written with it; the table's float32 rows follow
(:func:`atlasgen.shaders.separable.separable_table_bytes`, docs/engine-integration.md).
"""

from __future__ import annotations

import struct

__all__ = ["SIDECAR_MAGIC", "SIDECAR_FILE_VERSION", "SIDECAR_HEADER_SIZE", "stamp_sidecar", "sidecar_manifest_sha256"]

SIDECAR_MAGIC = b"ASEP"
SIDECAR_FILE_VERSION = 2  # 2: the manifest's SHA-256 in the header (1: a 16-byte header)
SIDECAR_HEADER_SIZE = 48


def stamp_sidecar(data: bytes, manifest_sha256: bytes) -> bytes:
    """``data`` (:func:`separable_table_bytes`) recording ``manifest_sha256`` (32 bytes) in its header."""
    if len(manifest_sha256) != 32 or data[:4] != SIDECAR_MAGIC:
        raise ValueError("expected a separable side-car and a 32-byte SHA-256")
    return data[:16] + manifest_sha256 + data[SIDECAR_HEADER_SIZE:]


def sidecar_manifest_sha256(data: bytes) -> str | None:
    """The manifest SHA-256 (hex) a side-car's header records; ``None`` if it is not a version-2 side-car."""
    if len(data) < SIDECAR_HEADER_SIZE or data[:4] != SIDECAR_MAGIC:
        return None
    version, _rows, length = struct.unpack_from("<3I", data, 4)
    return data[16:48].hex() if version == SIDECAR_FILE_VERSION and length == 32 else None
