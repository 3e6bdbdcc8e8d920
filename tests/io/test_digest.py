"""Array digests: the same bytes of another type or shape hash apart."""

import doctest

import numpy as np

from atlasgen.io import digest
from atlasgen.io.digest import array_digest


def test_the_module_s_doctests_pass():
    result = doctest.testmod(digest)
    assert result.attempted > 0 and result.failed == 0


def test_type_shape_and_every_byte_count():
    a = np.arange(6, dtype=np.uint8)
    assert array_digest(a) != array_digest(a.astype(np.int8))
    assert array_digest(a) != array_digest(a.reshape(2, 3))
    b = a.copy()
    b[5] = 7
    assert array_digest(a) != array_digest(b)
    assert array_digest(a.reshape(2, 3).T) == array_digest(np.ascontiguousarray(a.reshape(2, 3).T))  # C order, not strides
