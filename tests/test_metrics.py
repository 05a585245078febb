import math

import numpy as np
import pytest

from rayvr.quality import metrics as M


def _image(h=48, w=64, seed=0):
    """A smooth uint8 test image (gradients plus a few blobs) with headroom for +/- offsets."""
    rng = np.random.default_rng(seed)
    y, x = np.mgrid[0:h, 0:w] / max(h, w)
    img = np.stack([x, y, 0.5 * (x + y)], axis=2)
    for _ in range(4):
        cy, cx = rng.uniform(0, 1, 2)
        img += 0.3 * np.exp(-((x - cx) ** 2 + (y - cy) ** 2) / 0.01)[..., None]
    return np.clip(20 + 200 * img / img.max(), 0, 255).astype(np.uint8)


def test_identical_images():
    a = _image()
    assert M.psnr(a, a) == math.inf
    assert M.ssim(a, a) == pytest.approx(1.0, abs=1e-6)
    lin = np.random.default_rng(1).random((16, 16, 3))
    assert M.psnr(lin, lin) == math.inf


def test_identical_images_flip():
    pytest.importorskip("flip_evaluator")
    a = _image()
    assert M.flip(a, a) == 0.0
    c = M.compare(a, a, mask=np.ones(a.shape[:2], bool))
    assert c["flip"] == 0.0 and c["flip_mask"] == 0.0 and c["psnr"] == math.inf


@pytest.mark.parametrize("k", [1, 3, 10])
def test_uniform_offset_psnr(k):
    a = _image()
    b = a + np.uint8(k)  # no overflow: _image stays in [20, 220]
    # MSE = (k/255)^2 exactly, so PSNR = 20 log10(255 / k).
    assert M.psnr(a, b) == pytest.approx(20 * math.log10(255 / k), abs=1e-9)


def test_float_input_is_linear():
    lin = np.random.default_rng(2).random((8, 8, 3))
    enc = M.srgb_encode(lin)
    # Linear floats are encoded before comparing, so they match their uint8 sRGB encoding.
    u8 = np.round(enc * 255).astype(np.uint8)
    assert M.psnr(u8, lin) > 50
    # float_encoding="srgb" (for both images) skips the encoding step.
    assert M.psnr(u8, enc, float_encoding="srgb") > 50
    assert M.psnr(u8, lin, float_encoding="srgb") < 30
    # sRGB transfer function anchors: 0, 1 and mid-grey (0.2140 linear ~ 0.5 encoded).
    assert M.srgb_encode(np.array([0.0, 1.0, 0.21404])) == pytest.approx([0, 1, 0.5], abs=1e-4)
    # Out-of-range linear values are clipped (LDR): 2.0 behaves like 1.0.
    assert M.psnr(np.full((4, 4, 3), 2.0), np.ones((4, 4, 3))) == math.inf


def test_mask_selects_pixels():
    a = _image()
    b = a.copy()
    b[:, :32] = a[:, :32] + np.uint8(5)  # only the left half differs
    left = np.zeros(a.shape[:2], bool)
    left[:, :32] = True
    assert M.psnr(a, b, mask=left) == pytest.approx(20 * math.log10(255 / 5))
    assert M.psnr(a, b, mask=~left) == math.inf
    # Half the pixels: MSE halves, PSNR gains 10 log10(2) dB.
    assert M.psnr(a, b) == pytest.approx(20 * math.log10(255 / 5) + 10 * math.log10(2))
    # SSIM far from the edit is exactly 1; a full mask equals the unmasked value.
    right = np.zeros_like(left)
    right[:, 48:] = True
    assert M.ssim(a, b, mask=right) == pytest.approx(1.0, abs=1e-6)
    assert M.ssim(a, b, mask=np.ones_like(left)) == M.ssim(a, b)
    assert M.ssim(a, b, mask=left) < M.ssim(a, b)


def test_mask_flip():
    pytest.importorskip("flip_evaluator")
    a = _image()
    b = a.copy()
    b[:, :32] = 255 - a[:, :32]
    left = np.zeros(a.shape[:2], bool)
    left[:, :32] = True
    far = np.zeros_like(left)
    far[:, 56:] = True  # beyond FLIP's filter reach at the default ppd
    c = M.compare(a, b, mask=left)
    assert c["mask_pixels"] == left.sum()
    assert c["flip_mask"] > c["flip"] > 0
    assert M.flip(a, b, mask=far) < 1e-3
    # Mean over the whole image is the coverage-weighted mean of the two halves.
    whole = M.flip(a, b)
    assert whole == pytest.approx(0.5 * M.flip(a, b, mask=left) + 0.5 * M.flip(a, b, mask=~left))


def test_flip_ppd():
    pytest.importorskip("flip_evaluator")
    a = _image()
    b = np.clip(a.astype(int) + np.random.default_rng(3).integers(-30, 30, a.shape), 0, 255).astype(np.uint8)
    # Fewer pixels per degree = each pixel subtends more angle = noise is more visible.
    assert M.flip(a, b, ppd=10) > M.flip(a, b, ppd=67)


def test_ppd_for_headset():
    assert M.ppd_for_headset(100, 2000) == pytest.approx(20.0)
    assert M.DEFAULT_PPD == pytest.approx(1440 / 108)
    # A pinhole image is sparser (per degree) in its centre than on average.
    assert M.ppd_for_headset(90, 1000, at="center") == pytest.approx(500 / 1 * math.pi / 180)
    assert M.ppd_for_headset(90, 1000, at="center") < M.ppd_for_headset(90, 1000)
    with pytest.raises(ValueError):
        M.ppd_for_headset(0, 100)
    with pytest.raises(ValueError):
        M.ppd_for_headset(90, 100, at="edge")


def test_ssim_agrees_with_skimage():
    metrics = pytest.importorskip("skimage.metrics")
    rng = np.random.default_rng(4)
    a = _image(60, 80).astype(np.float64) / 255
    b = np.clip(a + rng.normal(0, 0.04, a.shape), 0, 1)
    kw = dict(channel_axis=-1, data_range=1.0, gaussian_weights=True, sigma=1.5,
              use_sample_covariance=False)
    cropped, full = metrics.structural_similarity(a, b, full=True, **kw)
    ours = M.ssim(a, b, float_encoding="srgb")
    # Same map (skimage's 'reflect' is numpy's 'symmetric'); skimage's scalar drops a 5 px border.
    assert ours == pytest.approx(full.mean(), abs=1e-5)
    assert ours == pytest.approx(cropped, abs=1e-2)
    assert M.ssim(a, b, mask=np.ones(a.shape[:2], bool), float_encoding="srgb") == ours


def test_ssim_tiny_and_constant_images():
    z = np.zeros((3, 2, 3), np.uint8)
    assert M.ssim(z, z) == pytest.approx(1.0)
    assert 0 <= M.ssim(z, z + np.uint8(40)) < 1


def test_validation():
    a = _image(8, 8)
    with pytest.raises(ValueError, match="shape mismatch"):
        M.psnr(a, _image(8, 9))
    with pytest.raises(ValueError, match="HxWx3"):
        M.psnr(a[..., 0], a[..., 0])
    with pytest.raises(TypeError, match="dtype"):
        M.psnr(a.astype(np.int32), a.astype(np.int32))
    bad = np.zeros((8, 8, 3))
    bad[1, 1, 1] = np.nan
    with pytest.raises(ValueError, match="NaN"):
        M.ssim(np.zeros((8, 8, 3)), bad)
    with pytest.raises(ValueError, match="mask shape"):
        M.psnr(a, a, mask=np.ones((4, 4), bool))
    with pytest.raises(TypeError, match="boolean"):
        M.psnr(a, a, mask=np.ones((8, 8)))
    with pytest.raises(ValueError, match="no pixels"):
        M.psnr(a, a, mask=np.zeros((8, 8), bool))
    with pytest.raises(ValueError, match="unknown metrics"):
        M.compare(a, a, metrics=("psnr", "lpips"))


def test_flip_missing_names_extra(monkeypatch):
    import sys

    monkeypatch.setitem(sys.modules, "flip_evaluator", None)  # importing it fails, as where it is not installed
    a = _image(8, 8)
    with pytest.raises(ImportError, match=r"rayvr\[bench\]"):
        M.flip(a, a)
    # PSNR/SSIM need nothing beyond numpy.
    assert M.compare(a, a, metrics=("psnr", "ssim"))["psnr"] == math.inf
