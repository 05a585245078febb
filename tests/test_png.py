"""The PNG encoder (util/png.py) against Pillow's decoder (every pixel back as written) and the
specification's chunk layout and CRC."""
import io
import struct

import numpy as np
import pytest
from PIL import Image

from rayvr.util.png import encode_png


def decode(pieces) -> np.ndarray:
    with Image.open(io.BytesIO(b"".join(pieces))) as im:
        im.load()
        return np.asarray(im)


@pytest.mark.parametrize("channels", [1, 3, 4])
@pytest.mark.parametrize("level", [0, 1, 6, 9])
def test_noise_decodes_exactly(channels, level):
    rng = np.random.default_rng(channels * 10 + level)
    image = rng.integers(0, 256, (37, 53, channels), dtype=np.uint8)
    back = decode(encode_png(image, level))
    assert back.shape == (37, 53) if channels == 1 else image.shape
    np.testing.assert_array_equal(back.reshape(image.shape), image)


def test_grey_2d_and_mode():
    image = np.arange(6 * 5, dtype=np.uint8).reshape(6, 5) * 8
    with Image.open(io.BytesIO(b"".join(encode_png(image)))) as im:
        assert im.mode == "L" and im.size == (5, 6)
        np.testing.assert_array_equal(np.asarray(im), image)


def test_modes_rgb_rgba():
    for channels, mode in ((3, "RGB"), (4, "RGBA")):
        with Image.open(io.BytesIO(b"".join(encode_png(np.zeros((2, 2, channels), np.uint8))))) as im:
            assert im.mode == mode


@pytest.mark.parametrize("shape", [(1, 1, 3), (1, 7, 3), (9, 1, 4), (1, 1)])
def test_one_pixel_wide_or_high(shape):
    image = np.random.default_rng(3).integers(0, 256, shape, dtype=np.uint8)
    np.testing.assert_array_equal(decode(encode_png(image)), image)


def test_wraparound_filter_on_steps():
    # left neighbour larger than the pixel: the Sub filter's uint8 difference wraps, and decodes back
    image = np.zeros((4, 6, 3), np.uint8)
    image[:, ::2] = 255
    image[:, 1::2] = 1
    np.testing.assert_array_equal(decode(encode_png(image)), image)


def test_same_pixels_as_pillow_file():
    rng = np.random.default_rng(5)
    image = (rng.random((40, 60, 3)) * 30 + np.linspace(0, 200, 60)[None, :, None]).astype(np.uint8)
    buf = io.BytesIO()
    Image.fromarray(image).save(buf, format="PNG")
    np.testing.assert_array_equal(decode(encode_png(image, 1)), decode([buf.getvalue()]))


def test_compression_level_shrinks_a_smooth_image():
    image = np.tile(np.arange(256, dtype=np.uint8)[None, :, None], (64, 1, 3))
    assert len(b"".join(encode_png(image, 9))) < len(b"".join(encode_png(image, 0)))


@pytest.mark.parametrize("bad", [np.zeros((2, 2, 3), np.float32), np.zeros((2, 2, 2), np.uint8),
                                 np.zeros((0, 2, 3), np.uint8), np.zeros(5, np.uint8)])
def test_bad_images_say_what(bad):
    with pytest.raises(ValueError, match="PNG encoding takes"):
        encode_png(bad)


def crc32_reference(data: bytes) -> int:
    """CRC-32 as the PNG specification defines it (reflected polynomial 0xEDB88320, initial and
    final XOR 0xFFFFFFFF), bit by bit: independent of zlib."""
    crc = 0xFFFFFFFF
    for byte in data:
        crc ^= byte
        for _ in range(8):
            crc = (crc >> 1) ^ (0xEDB88320 if crc & 1 else 0)
    return crc ^ 0xFFFFFFFF


@pytest.mark.parametrize("channels", [1, 3, 4])
def test_every_chunk_has_its_length_and_crc(channels):
    """Each chunk's length and CRC (over tag and data) by the specification: Pillow's reader does
    not check IEND's CRC, so an IEND with a wrong one would pass the decode tests."""
    img = np.random.default_rng(channels).integers(0, 256, (5, 7, channels), dtype=np.uint8)
    blob = b"".join(encode_png(img))
    assert blob[:8] == b"\x89PNG\r\n\x1a\n"
    at, tags = 8, []
    while at < len(blob):
        (length,), tag = struct.unpack(">I", blob[at:at + 4]), blob[at + 4:at + 8]
        data = blob[at + 8:at + 8 + length]
        (crc,) = struct.unpack(">I", blob[at + 8 + length:at + 12 + length])
        assert len(data) == length and crc == crc32_reference(tag + data), tag
        tags.append(tag)
        at += 12 + length
    assert at == len(blob) and tags[0] == b"IHDR" and tags[-1] == b"IEND" and b"IDAT" in tags
    assert blob[-12:] == b"\x00\x00\x00\x00IEND\xaeB`\x82"  # the one IEND every PNG ends with
