"""The underwater imaging field's image metrics, computed as ``uwnr eval`` computes them.

- :func:`psnr`: ``skimage.metrics.peak_signal_noise_ratio`` (8-bit data measured as ``u8 / 255``
  with data range 1, which equals skimage on the u8 arrays with ``data_range=255``);
- :func:`ssim`: ``skimage.metrics.structural_similarity(gaussian_weights=True, sigma=1.5,
  use_sample_covariance=False)``, mean over channels;
- :func:`uiqm`: Panetta et al. 2016 as coded in FUnIE-GAN's ``uqim_utils.py`` (10x10 tiles, RGB);
- :func:`uciqe`: Yang & Sowmya 2015 as coded in ``nevaluate.py`` (skimage Lab units).

``gray=True`` measures PSNR and SSIM on ITU-R BT.601 luma. Images are taken as
:class:`uwnr.Renderer` takes them (arrays, PIL images, torch tensors, paths; grey replicated,
alpha dropped); full-reference metrics need two images of the same size. Neither UIQM nor UCIQE
resizes: papers that follow the FUnIE-GAN or Shallow-UWnet scripts resize to 256x256 first.
"""

from __future__ import annotations

from typing import Any

from . import _convert, _uwnr

__all__ = ["psnr", "ssim", "uiqm", "uciqe"]


def _pixels(x: Any, what: str):
    if _convert.is_path(x):
        return _convert.rgb_pixels(_convert.load_path(x), what)
    arr, _ = _convert.to_array(x, what)
    return _convert.rgb_pixels(arr, what)


def _pair(a: Any, b: Any):
    pa, pb = _pixels(a, "first image"), _pixels(b, "second image")
    if pa[1:3] != pb[1:3]:
        raise ValueError(
            f"images differ in size: {pa[1]}x{pa[2]} and {pb[1]}x{pb[2]} (height x width)"
        )
    return pa, pb


def psnr(a: Any, b: Any, gray: bool = False) -> float:
    """Peak signal-to-noise ratio in dB (``inf`` for identical images)."""
    pa, pb = _pair(a, b)
    return _uwnr.metric("psnr", pa, pb, bool(gray))


def ssim(a: Any, b: Any, gray: bool = False) -> float:
    """Structural similarity (1 for identical images); images of at least 11x11 pixels."""
    pa, pb = _pair(a, b)
    return _uwnr.metric("ssim", pa, pb, bool(gray))


def uiqm(a: Any) -> float:
    """Underwater image quality measure (no reference)."""
    return _uwnr.metric("uiqm", _pixels(a, "image"), None, False)


def uciqe(a: Any) -> float:
    """Underwater colour image quality evaluation (no reference)."""
    return _uwnr.metric("uciqe", _pixels(a, "image"), None, False)
