"""Reading environment images: OpenEXR and Radiance HDR, RGB(A), and a one-line refusal for each bad file."""

import numpy as np
import pytest

from atlasgen.errors import FieldError, InputError, SceneError
from atlasgen.io.environment_file import read_environment_file
from atlasgen.io.images import write_exr

RNG = np.random.default_rng(2)


def _hdr(path, pixels):
    import OpenImageIO as oiio

    out = oiio.ImageOutput.create(str(path))
    assert out.open(str(path), oiio.ImageSpec(pixels.shape[1], pixels.shape[0], pixels.shape[2], oiio.FLOAT))
    out.write_image(np.ascontiguousarray(pixels, dtype=np.float32))
    out.close()


def test_an_exr_reads_as_its_radiance(tmp_path):
    pixels = RNG.random((8, 16, 3)).astype(np.float32) * 100.0
    write_exr(tmp_path / "sky.exr", pixels)
    got = read_environment_file(tmp_path / "sky.exr")
    assert got.dtype == np.float32 and got.shape == (8, 16, 3)
    np.testing.assert_array_equal(got, pixels)


def test_rgba_drops_alpha_and_hdr_reads_too(tmp_path):
    pixels = RNG.random((4, 8, 4)).astype(np.float32)
    write_exr(tmp_path / "a.exr", pixels, channel_names=("R", "G", "B", "A"))
    np.testing.assert_array_equal(read_environment_file(tmp_path / "a.exr"), pixels[..., :3])
    _hdr(tmp_path / "b.hdr", pixels[..., :3] * 10.0)
    np.testing.assert_allclose(
        read_environment_file(tmp_path / "b.hdr"), pixels[..., :3] * 10.0, atol=0.07
    )  # RGBE: 8-bit mantissas, one exponent per texel


def _bad(tmp_path, name, pixels=None, channels=("R", "G", "B"), raw=None):
    path = tmp_path / name
    if raw is not None:
        path.write_bytes(raw)
    elif pixels is not None:
        write_exr(path, pixels, channel_names=channels)
    return path


@pytest.mark.parametrize(
    "name, make, words",
    [
        ("sky.png", dict(raw=b"\x89PNG"), "expected an OpenEXR (.exr) or Radiance HDR (.hdr) environment image, got 'sky.png'"),
        ("junk.exr", dict(raw=b"not an image"), "expected an OpenEXR or Radiance HDR image ("),
        ("grey.exr", dict(pixels=np.ones((4, 8, 1), np.float32), channels=("Y",)), "expected RGB or RGBA channels, got Y"),
        ("wide.exr", dict(pixels=np.ones((4, 12, 3), np.float32)), "twice as wide as high, got 12x4"),
        ("tiny.exr", dict(pixels=np.ones((2, 4, 3), np.float32)), "expected at least 8x4 texels, got 4x2"),
        ("nan.exr", dict(pixels=np.where(np.arange(96).reshape(4, 8, 3) == 50, np.nan, 1.0).astype(np.float32)),
         "expected finite radiance, got NaN or infinity in 1 texels, the first at row 2, column 0"),
        ("inf.exr", dict(pixels=np.full((4, 8, 3), np.inf, np.float32)), "NaN or infinity in 32 texels, the first at row 0"),
        ("neg.exr", dict(pixels=np.where(np.arange(96).reshape(4, 8, 3) == 95, -1.0, 1.0).astype(np.float32)),
         "expected non-negative radiance, got negative values in 1 texels, the first at row 3, column 7"),
    ],
)  # fmt: skip
def test_each_bad_file_is_one_line_naming_it(tmp_path, name, make, words):
    path = _bad(tmp_path, name, **make)
    with pytest.raises(SceneError) as info:
        read_environment_file(path, SceneError)
    message = str(info.value)
    assert message.startswith(f"{path.as_posix()}: ") and "\n" not in message and words in message, message


def test_a_deep_exr_is_refused_not_read_as_zeros(tmp_path):
    """A hostile sweep: a deep copy of a constant sky read most texels as 0 (a darker render, exit 0), or was refused
    for a different NaN count each run."""
    import OpenImageIO as oiio

    flat = oiio.ImageBuf(oiio.ImageSpec(16, 8, 3, oiio.FLOAT))
    oiio.ImageBufAlgo.fill(flat, (0.5, 0.5, 0.5))
    path = tmp_path / "deep.exr"
    assert oiio.ImageBufAlgo.deepen(flat).write(str(path))
    with pytest.raises(SceneError) as info:
        read_environment_file(path, SceneError)
    assert str(info.value) == f"{path.as_posix()}: expected a flat image, got a deep OpenEXR (samples per pixel)"


def test_a_missing_file_is_an_input_error(tmp_path):
    with pytest.raises(InputError, match="no such environment image"):
        read_environment_file(tmp_path / "gone.exr")
    with pytest.raises(FieldError):  # the default error class
        read_environment_file(_bad(tmp_path, "junk.hdr", raw=b"#?RADIANCE\nbroken"))


def test_a_named_pipe_is_refused_before_it_is_opened(tmp_path):
    import os

    os.mkfifo(tmp_path / "sky.exr")
    with pytest.raises(SceneError, match="sky.exr: expected an OpenEXR or Radiance HDR image, got a named pipe"):
        read_environment_file(tmp_path / "sky.exr", SceneError)


def test_an_image_larger_than_the_limit_is_refused_before_its_pixels_are_read(tmp_path, monkeypatch):
    """A 3 MB EXR can declare 32768x16384 texels: the read ended in MemoryError (exit 1). The limit is
    lowered here so that a small file stands for one over it."""
    import atlasgen.io.environment_file as module

    monkeypatch.setattr(module, "MAX_ENVIRONMENT_HEIGHT", 4)
    path = _bad(tmp_path, "big.exr", pixels=np.ones((8, 16, 3), np.float32))
    with pytest.raises(SceneError) as info:
        read_environment_file(path, SceneError)
    assert str(info.value) == f"{path.as_posix()}: expected at most 8x4 texels (downsample it first), got 16x8"
    assert read_environment_file(_bad(tmp_path, "ok.exr", np.ones((4, 8, 3), np.float32))).shape == (4, 8, 3)  # at it


def test_a_file_whose_name_is_no_utf8_reads_as_any_other(tmp_path):
    """OpenImageIO's Python names must be UTF-8: a sky in a folder named with byte 0xff was an internal error."""
    import os

    folder = tmp_path / os.fsdecode(b"\xffd")
    folder.mkdir()
    pixels = np.linspace(0.1, 2.0, 8 * 16 * 3, dtype=np.float32).reshape(8, 16, 3)
    write_exr(tmp_path / "sky.exr", pixels)
    (tmp_path / "sky.exr").rename(folder / "sky.exr")
    np.testing.assert_array_equal(read_environment_file(folder / "sky.exr"), pixels)


def _oiio_exr(path, base_type, pixels):
    import OpenImageIO as oiio

    out = oiio.ImageOutput.create(str(path))
    out.open(str(path), oiio.ImageSpec(pixels.shape[1], pixels.shape[0], pixels.shape[2], base_type))
    out.write_image(pixels)
    out.close()
    return path


def test_integer_channels_are_refused_not_read_as_a_fraction_of_their_range(tmp_path):
    """OpenImageIO reads a uint EXR's 50 as 50 / (2^32 - 1): the sky rendered black, exit 0."""
    path = _oiio_exr(tmp_path / "ids.exr", "uint", np.full((4, 8, 3), 50, np.uint32))
    with pytest.raises(SceneError) as info:
        read_environment_file(path, SceneError)
    assert str(info.value) == f"{path.as_posix()}: expected half or float colour channels, got uint, uint, uint"
    half = _oiio_exr(tmp_path / "half.exr", "half", np.full((4, 8, 3), 50, np.float32))
    np.testing.assert_array_equal(read_environment_file(half), 50.0)


def test_a_header_whose_error_quotes_bytes_that_are_no_utf8_is_one_line(tmp_path):
    """Byte 0xff where an attribute's name ends: OpenImageIO's message quotes it, and its binding's
    UTF-8 decoding of that message raised UnicodeDecodeError, an internal error (exit 1)."""
    good = _bad(tmp_path, "sky.exr", np.full((4, 8, 3), 0.5, np.float32))
    data = bytearray(good.read_bytes())
    data[data.index(b"channels\0") + 8] = 0xFF
    path = _bad(tmp_path, "bad.exr", raw=bytes(data))
    with pytest.raises(SceneError) as info:
        read_environment_file(path, SceneError)
    message = str(info.value)
    assert message.startswith(f"{path.as_posix()}: expected an OpenEXR or Radiance HDR image (") and "\n" not in message
