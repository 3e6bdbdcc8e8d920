"""PNG and EXR files: written by atlasgen.io.images, read back by OpenImageIO and by a PNG reader of our own."""

from __future__ import annotations

import doctest
import os
import struct
import zlib
from pathlib import Path

import numpy as np
import pytest

from atlasgen.errors import OutputError
from atlasgen.io import images
from atlasgen.io.images import encode_exr, encode_png, openable_name, write_exr, write_png


def test_the_examples_in_the_docstrings_hold():
    result = doctest.testmod(images)
    assert result.attempted > 0 and result.failed == 0


def read(path):
    import OpenImageIO as oiio

    buf = oiio.ImageBuf(str(path))
    return buf.get_pixels(oiio.FLOAT if str(path).endswith(".exr") else oiio.UINT8), buf.spec()


def decode_png(data: bytes) -> np.ndarray:
    """8-bit, non-interlaced PNG to (h, w, c) codes (PNG spec, ISO/IEC 15948: chunks, zlib, per-row filters)."""
    assert data[:8] == b"\x89PNG\r\n\x1a\n"
    pos, idat, header = 8, b"", None
    while pos < len(data):
        (length,) = struct.unpack(">I", data[pos : pos + 4])
        kind, body = data[pos + 4 : pos + 8], data[pos + 8 : pos + 8 + length]
        assert zlib.crc32(kind + body) == struct.unpack(">I", data[pos + 8 + length : pos + 12 + length])[0]
        if kind == b"IHDR":
            header = struct.unpack(">IIBBBBB", body)
        elif kind == b"IDAT":
            idat += body
        pos += 12 + length
    w, h, depth, colour, _, _, interlace = header
    assert depth == 8 and interlace == 0
    c = {0: 1, 4: 2, 2: 3, 6: 4}[colour]
    raw = zlib.decompress(idat)
    out = np.zeros((h, w * c), dtype=np.int64)
    stride = w * c + 1
    for y in range(h):
        kind, row = raw[y * stride], np.frombuffer(raw[y * stride + 1 : (y + 1) * stride], np.uint8).astype(np.int64)
        up = out[y - 1] if y else np.zeros(w * c, np.int64)
        cur = np.zeros(w * c, np.int64)
        for x in range(w * c):
            left = cur[x - c] if x >= c else 0
            ul = up[x - c] if x >= c else 0
            if kind == 0:
                pred = 0
            elif kind == 1:
                pred = left
            elif kind == 2:
                pred = up[x]
            elif kind == 3:
                pred = (left + up[x]) // 2
            else:  # Paeth
                p = left + up[x] - ul
                pa, pb, pc = abs(p - left), abs(p - up[x]), abs(p - ul)
                pred = left if pa <= pb and pa <= pc else (up[x] if pb <= pc else ul)
            cur[x] = (row[x] + pred) & 0xFF
        out[y] = cur
    return out.reshape(h, w, c).astype(np.uint8)


@pytest.mark.parametrize("channels", [1, 3, 4])
def test_png_holds_the_codes_exactly(tmp_path, channels):
    codes = np.random.default_rng(channels).integers(0, 256, (9, 13, channels), dtype=np.uint8)
    write_png(tmp_path / "a.png", codes)
    data = (tmp_path / "a.png").read_bytes()
    np.testing.assert_array_equal(decode_png(data), codes)
    if channels != 4:  # OpenImageIO's reader premultiplies alpha unless told otherwise
        np.testing.assert_array_equal(read(tmp_path / "a.png")[0].reshape(codes.shape), codes)
    assert encode_png(codes) == data  # same codes, same bytes


def _zlib_level_class(data: bytes) -> int:
    """FLEVEL of the PNG's zlib stream (RFC 1950, sec. 2.2): 0 for levels 0-1, 1 for 2-5, 2 for 6, 3 for 7-9."""
    start = data.index(b"IDAT") + 4
    return data[start + 1] >> 6


@pytest.mark.parametrize("level, flevel", [(0, 0), (2, 1), (None, 2), (9, 3)])
def test_a_png_compression_level_changes_the_bytes_not_the_codes(level, flevel):
    y, x = np.mgrid[0:40, 0:60]
    codes = np.stack([x * 4, y * 6, (x * y) % 256], axis=-1).astype(np.uint8)
    data = encode_png(codes, compression=level)
    np.testing.assert_array_equal(decode_png(data), codes)
    assert _zlib_level_class(data) == flevel
    assert encode_png(codes, compression=level) == data  # same codes and level, same bytes
    if level is not None:
        assert len(encode_png(codes, compression=0)) >= len(data) >= len(encode_png(codes, compression=9))


@pytest.mark.parametrize("level", [-1, 10])
def test_a_png_compression_level_is_zlibs(level):
    with pytest.raises(ValueError, match="zlib level from 0 to 9"):
        encode_png(np.zeros((2, 2, 3), np.uint8), compression=level)


def test_png_takes_8_bit_codes_only():
    with pytest.raises(TypeError, match="8-bit codes"):
        encode_png(np.zeros((2, 2, 3)))
    with pytest.raises(TypeError, match="8-bit codes"):
        encode_png(np.zeros((2, 2, 5), np.uint8))


def test_exr_round_trips_linear_floats_with_their_channel_names(tmp_path):
    rng = np.random.default_rng(1)
    radiance = (rng.random((5, 7, 3)) * 40).astype(np.float32)
    radiance[0, 0] = (np.inf, 0.0, 1e-30)
    write_exr(tmp_path / "a.exr", radiance)
    pixels, spec = read(tmp_path / "a.exr")
    np.testing.assert_array_equal(pixels, radiance)
    assert list(spec.channelnames) == ["R", "G", "B"]
    assert spec.get_string_attribute("compression") == "zip"
    write_exr(tmp_path / "z.exr", radiance[..., :1], ("Z",))
    pixels, spec = read(tmp_path / "z.exr")
    assert list(spec.channelnames) == ["Z"]
    np.testing.assert_array_equal(pixels, radiance[..., :1])
    with pytest.raises(ValueError, match="channels"):
        encode_exr(radiance, ("R", "G"))


def test_writes_are_atomic_and_report_the_folder(tmp_path):
    (tmp_path / "blocker").write_text("")
    with pytest.raises(OutputError, match="cannot write output folder"):
        write_png(tmp_path / "blocker" / "a.png", np.zeros((1, 1, 3), np.uint8))
    assert sorted(p.name for p in tmp_path.iterdir()) == ["blocker"]


def test_an_image_is_encoded_beside_its_output_not_in_the_system_temp_folder(tmp_path, monkeypatch):
    """Issue 24: the EXR was encoded in the system temp folder, so a full temp folder failed a
    render whose output folder had room, and the message named the scratch file."""
    import tempfile

    from atlasgen.render.output import write_render

    monkeypatch.setattr(tempfile, "tempdir", str(tmp_path / "no-such-temp-folder"))
    out = tmp_path / "render" / "r.exr"
    write_render(out, np.full((4, 6, 3), 0.5, np.float32))
    assert sorted(p.name for p in out.parent.iterdir() if not p.name.endswith(".atlasgen")) == ["r.exr", "r.png"]
    assert read(out)[0].shape == (4, 6, 3)


@pytest.fixture
def full_folder(tmp_path):
    """A 64 KiB tmpfs, filled up (root only)."""
    import os
    import subprocess

    folder = tmp_path / "full"
    folder.mkdir()
    if os.geteuid() != 0 or subprocess.run(["mount", "-t", "tmpfs", "-o", "size=64k", "tmpfs", str(folder)],
                                           capture_output=True).returncode != 0:  # fmt: skip
        pytest.skip("mounting a small tmpfs needs root")
    try:
        yield folder
    finally:
        subprocess.run(["umount", str(folder)], check=True)


def test_a_full_disk_names_the_output_and_leaves_nothing(full_folder):
    from atlasgen.render.output import write_render

    out = full_folder / "r.exr"
    noise = np.random.default_rng(1).random((256, 256, 3), dtype=np.float32)
    with pytest.raises(OutputError) as refused:
        write_render(out, noise)
    message = str(refused.value)
    assert message.startswith(f"{out.as_posix()}: cannot write (") and "atlasgen.tmp" not in message, message
    assert "\n" not in message and list(full_folder.iterdir()) == []


def test_an_exr_cut_short_at_its_last_flush_is_refused_not_returned(tmp_path):
    """With the file size limit at 4 KiB, a 5 KB EXR's last chunk failed to write when the file was closed, which
    OpenImageIO does not report: the cut file came back (4096 bytes) and `render` committed it, exit 0. A child
    process sets the limit (Python ignores SIGXFSZ, so the write fails with EFBIG instead of killing it)."""
    import subprocess
    import sys
    import textwrap

    script = textwrap.dedent(f"""
        import resource
        import numpy as np
        from atlasgen.errors import OutputError
        from atlasgen.io.images import encode_exr
        pixels = np.broadcast_to(np.linspace(0, 1, 64, dtype=np.float32)[None, :, None], (200, 64, 3)).copy()
        assert 4096 < len(encode_exr(pixels)) < 8192  # the case: one chunk past the limit
        resource.setrlimit(resource.RLIMIT_FSIZE, (4096, 4096))
        try:
            data = encode_exr(pixels, near={str(tmp_path / "r.exr")!r})
        except OutputError as exc:
            print("refused:", exc)
        else:
            print("returned", len(data), "bytes")
    """)  # fmt: skip
    done = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True, timeout=120)
    assert done.returncode == 0, done.stderr
    assert done.stdout.strip() == (f"refused: {(tmp_path / 'r.exr').as_posix()}: cannot write (the file written does not "
                                   "read back: Some scanline chunks were missing or corrupted)")  # fmt: skip
    assert list(tmp_path.iterdir()) == []


def test_an_exr_beside_a_name_that_is_no_utf8_encodes_and_is_written(tmp_path):
    """encode_exr's scratch file goes beside its output, and OpenImageIO refused a folder named with byte 0xff
    (a TypeError: render -o $'\\xfd'.exr was an internal error). Such a scratch file goes to the temporary folder."""
    import os

    import OpenImageIO as oiio

    out = tmp_path / os.fsdecode(b"\xfdd") / os.fsdecode(b"r\xfd.exr")
    pixels = np.arange(4 * 6 * 3, dtype=np.float32).reshape(4, 6, 3)
    write_exr(out, pixels)
    ascii_copy = tmp_path / "copy.exr"
    ascii_copy.write_bytes(out.read_bytes())
    image = oiio.ImageInput.open(str(ascii_copy))
    np.testing.assert_array_equal(image.read_image(oiio.FLOAT), pixels)
    image.close()


def test_a_name_openimageio_cannot_take_leads_to_the_file_a_dotdot_after_a_link_reaches(tmp_path):
    """A name of no UTF-8 is opened through a link; abspath folded ``lnk/..`` as text, so the link led to the
    folder's twin beside the link (here: a file of other bytes), not to the file the path names."""
    name = os.fsdecode(b"sky\xff.exr")
    (tmp_path / "elsewhere" / "sub").mkdir(parents=True)
    (tmp_path / "elsewhere" / name).write_bytes(b"the file the path names")
    (tmp_path / name).write_bytes(b"its textual twin")
    (tmp_path / "lnk").symlink_to(tmp_path / "elsewhere" / "sub", target_is_directory=True)
    with openable_name(tmp_path / "lnk" / ".." / name) as opened:
        assert opened != str(tmp_path / "lnk" / ".." / name)  # not UTF-8: a link was made
        assert Path(opened).read_bytes() == b"the file the path names"


def test_a_scratch_folder_a_killed_run_left_in_the_temporary_folder_is_removed(tmp_path, monkeypatch):
    """encode_png without an output beside it writes in the system's temporary folder: a kill, or a Ctrl-C during the
    clean-up, left an atlasgen-image-<random> folder there for good. Named by its process now, the next encode removes
    a dead one's and leaves a running one's."""
    import subprocess
    import sys
    import tempfile

    monkeypatch.setattr(tempfile, "tempdir", str(tmp_path))
    dead = int(subprocess.run([sys.executable, "-c", "import os; print(os.getpid())"], capture_output=True, text=True).stdout)
    stale = tmp_path / f".atlasgen-image.{dead}.k3j4h5g6.atlasgen.tmp"
    (stale / "sub").mkdir(parents=True)
    (stale / "image.png").write_bytes(b"half a picture")
    live = tmp_path / f".atlasgen-image.{os.getpid()}.q1w2e3r4.atlasgen.tmp"
    live.mkdir()
    assert images.encode_png(np.zeros((2, 3, 3), np.uint8))[:8] == b"\x89PNG\r\n\x1a\n"
    assert sorted(p.name for p in tmp_path.iterdir()) == [live.name]
