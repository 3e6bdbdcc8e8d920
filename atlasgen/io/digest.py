"""SHA-256 of arrays, for files that record what they hold: a cache entry checked before it is used, a report
that records what it measured."""

from __future__ import annotations

import hashlib

import numpy as np

__all__ = ["update_with_array", "array_digest"]


def update_with_array(digest, array) -> None:
    """Feed ``digest`` (a :mod:`hashlib` object) an array's dtype, shape and C-order bytes, so that arrays of the
    same bytes but another type or shape hash apart."""
    a = np.ascontiguousarray(array)
    digest.update(f"{a.dtype.str}{list(a.shape)}".encode())
    digest.update(a.tobytes())


def array_digest(array) -> str:
    """The hex SHA-256 of one array (:func:`update_with_array`).

    >>> array_digest(np.zeros(2, np.uint8)) == array_digest(np.zeros(2, np.uint8))
    True
    >>> array_digest(np.zeros(2, np.uint8)) == array_digest(np.zeros((1, 2), np.uint8))
    False
    """
    digest = hashlib.sha256()
    update_with_array(digest, array)
    return digest.hexdigest()
