"""Conversions between the image types users hold (NumPy arrays, PIL images, torch tensors,
file paths) and the interleaved bytes the native module takes, and back to the caller's type.

Conventions (the same as the ``uwnr`` command line):

- 8-bit codes map to ``code / 255``, 16-bit to ``code / 65535``; floats must lie in [0, 1];
- HxW grey is replicated to RGB, an alpha channel is dropped;
- a uint8 result is rounded half up, ``floor(v * 255 + 0.5)``, as the PNG writer does.
"""

from __future__ import annotations

import os
from dataclasses import dataclass
from typing import Any, Optional, Tuple

import numpy as np

from . import _uwnr

#: Pixels as the native module takes them: (bytes, height, width, channels, dtype name).
Pixels = Tuple[bytes, int, int, int, str]

_FLOAT_DTYPES = (np.float16, np.float32, np.float64)


@dataclass(frozen=True)
class Kind:
    """How an input was given, so the result can be returned the same way."""

    container: str  # "numpy", "pil" or "torch"
    dtype: Any = None  # NumPy dtype of a NumPy input, torch dtype of a tensor
    device: Any = None  # torch device
    channels_first: bool = False


def _is_pil(x: Any) -> bool:
    return type(x).__module__.startswith("PIL.") and hasattr(x, "mode") and hasattr(x, "size")


def _is_torch(x: Any) -> bool:
    return type(x).__module__.startswith("torch") and hasattr(x, "detach") and hasattr(x, "dim")


def is_path(x: Any) -> bool:
    return isinstance(x, (str, os.PathLike))


def load_path(path: Any) -> np.ndarray:
    """Decodes an image file with uwnr's decoder (EXIF orientation, 16-bit, alpha dropped) into
    an HxWx3 float32 array in [0, 1]."""
    path = os.fspath(path)
    if not os.path.exists(path):
        raise FileNotFoundError(f"image file {path} does not exist")
    data, height, width = _uwnr.load_rgb(path)
    return np.frombuffer(data, dtype=np.float32).reshape(height, width, 3)


def _from_pil(img: Any) -> np.ndarray:
    if img.mode in ("RGB", "L"):
        return np.asarray(img)
    if img.mode in ("I;16", "I;16B", "I;16L"):
        return np.asarray(img).astype(np.uint16)
    if img.mode in ("F",):
        return np.asarray(img, dtype=np.float32)
    if img.mode == "I":
        raise ValueError("32-bit integer PIL images are not supported: convert to 'RGB' or 'I;16'")
    return np.asarray(img.convert("RGB"))


def to_array(x: Any, what: str = "image") -> Tuple[np.ndarray, Kind]:
    """``x`` as an HxWxC NumPy array (C in 1, 3, 4) and how it was given."""
    if _is_pil(x):
        return _from_pil(x), Kind("pil")
    if _is_torch(x):
        t = x.detach()
        if t.dim() != 3:
            raise ValueError(
                f"{what}: a torch tensor must be CHW (3 dimensions), got shape {tuple(t.shape)}"
            )
        arr = t.cpu().numpy()
        if arr.shape[0] not in (1, 3, 4):
            raise ValueError(
                f"{what}: a torch tensor must be CHW with 1, 3 or 4 channels, got shape "
                f"{tuple(t.shape)}"
            )
        return np.transpose(arr, (1, 2, 0)), Kind("torch", t.dtype, t.device, True)
    if isinstance(x, np.ndarray):
        return x, Kind("numpy", x.dtype)
    raise TypeError(
        f"{what}: expected a NumPy array, a PIL image, a torch tensor or a file path, "
        f"got {type(x).__name__}"
    )


def _unit_float(arr: np.ndarray, what: str) -> np.ndarray:
    """An integer or float array as float32 in [0, 1], checking a float array's range."""
    if arr.dtype == np.uint8:
        return arr
    if arr.dtype == np.uint16:
        return (arr.astype(np.float32) / np.float32(65535.0)).astype(np.float32)
    if arr.dtype in _FLOAT_DTYPES:
        f = arr.astype(np.float32, copy=False)
        if f.size and not np.isfinite(f).all():
            raise ValueError(f"{what}: contains NaN or infinite values")
        if f.size and (f.min() < 0.0 or f.max() > 1.0):
            raise ValueError(
                f"{what}: float values must lie in [0, 1], got min {float(f.min()):.4g} and "
                f"max {float(f.max()):.4g} (divide 8-bit data by 255, or pass it as uint8)"
            )
        return f
    raise ValueError(
        f"{what}: dtype {arr.dtype} is not supported (uint8, uint16, float16, float32, float64)"
    )


def rgb_pixels(arr: np.ndarray, what: str = "image") -> Pixels:
    """An HxW, HxWx1, HxWx3 or HxWx4 array as RGB pixels for the native module."""
    if arr.ndim == 2:
        arr = arr[:, :, None]
    if arr.ndim != 3 or arr.shape[2] not in (1, 3, 4):
        raise ValueError(
            f"{what}: expected an HxW, HxWx1, HxWx3 or HxWx4 image, got shape {arr.shape}"
        )
    if arr.shape[0] == 0 or arr.shape[1] == 0:
        raise ValueError(f"{what}: image is empty, shape {arr.shape}")
    values = _unit_float(arr, what)
    if values.shape[2] == 1:
        values = np.repeat(values, 3, axis=2)
    elif values.shape[2] == 4:
        values = values[:, :, :3]
    values = np.ascontiguousarray(values)
    height, width = values.shape[:2]
    dtype = "uint8" if values.dtype == np.uint8 else "float32"
    return (values.tobytes(), height, width, 3, dtype)


def _depth_array(depth: Any) -> np.ndarray:
    """A depth map as an HxW array, checked."""
    arr, _ = to_array(depth, "depth")
    if arr.ndim == 3 and arr.shape[2] == 1:
        arr = arr[:, :, 0]
    if arr.ndim != 2:
        raise ValueError(f"depth: expected an HxW map, got shape {arr.shape}")
    if arr.shape[0] == 0 or arr.shape[1] == 0:
        raise ValueError(f"depth: map is empty, shape {arr.shape}")
    return arr


def depth_pixels(depth: Any) -> Optional[Pixels]:
    """A depth map (HxW or HxWx1; float in [0, 1], uint8 or uint16; bright = far) as 1-channel
    float32 pixels, or ``None``."""
    if depth is None:
        return None
    arr = _depth_array(depth)
    values = _unit_float(arr, "depth")
    if values.dtype == np.uint8:
        values = values.astype(np.float32) / np.float32(255.0)
    values = np.ascontiguousarray(values, dtype=np.float32)
    return (values.tobytes(), values.shape[0], values.shape[1], 1, "float32")


def metric_depth_pixels(depth: Any, per_metre: float) -> Pixels:
    """A depth map in metres (``per_metre`` = 1) or millimetres (1000), HxW or HxWx1, any
    non-negative numbers (holes as 0 or NaN), as 1-channel float32 metres."""
    arr = _depth_array(depth)
    if arr.dtype.kind not in "uif":
        raise ValueError(f"depth: dtype {arr.dtype} is not a number type")
    values = arr.astype(np.float32) / np.float32(per_metre)
    values = np.where(np.isfinite(values), values, np.float32(0.0)).astype(np.float32)
    if values.min() < 0.0:
        raise ValueError(f"depth: distances must not be negative, got {float(values.min()):.4g}")
    if not (values > 0.0).any():
        raise ValueError("depth: holds no measured value (every value is 0 or not finite)")
    values = np.ascontiguousarray(values)
    return (values.tobytes(), values.shape[0], values.shape[1], 1, "float32")


def image_from_bytes(data: bytes, height: int, width: int, dtype: str) -> np.ndarray:
    """The native module's interleaved RGB result as an HxWx3 array."""
    np_dtype = np.uint8 if dtype == "uint8" else np.float32
    return np.frombuffer(data, dtype=np_dtype).reshape(height, width, 3).copy()


def restore(out: np.ndarray, kind: Kind) -> Any:
    """A rendered HxWx3 array (uint8 or float32) returned in the type the input came in."""
    if kind.container == "pil":
        from PIL import Image

        if out.dtype != np.uint8:
            out = _quantise(out)
        return Image.fromarray(out, mode="RGB") if _pil_takes_mode() else Image.fromarray(out)
    if kind.container == "torch":
        import torch

        arr = out
        if kind.dtype == torch.uint8:
            arr = out if out.dtype == np.uint8 else _quantise(out)
        elif out.dtype == np.uint8:
            arr = out.astype(np.float32) / np.float32(255.0)
        tensor = torch.from_numpy(np.ascontiguousarray(np.transpose(arr, (2, 0, 1))))
        return tensor.to(device=kind.device, dtype=kind.dtype)
    dtype = kind.dtype
    if out.dtype == dtype:
        return out
    if dtype == np.uint8:
        return _quantise(out)
    if dtype == np.uint16:
        return np.floor(out.astype(np.float64) * 65535.0 + 0.5).clip(0, 65535).astype(np.uint16)
    return out.astype(dtype)


def _quantise(values: np.ndarray) -> np.ndarray:
    return np.floor(values.astype(np.float32) * np.float32(255.0) + np.float32(0.5)).clip(
        0, 255
    ).astype(np.uint8)


def _pil_takes_mode() -> bool:
    # Pillow 11 deprecates the mode argument of fromarray; an HxWx3 uint8 array is RGB anyway.
    try:
        import PIL

        major = int(PIL.__version__.split(".")[0])
    except (ImportError, ValueError):
        return False
    return major < 11
