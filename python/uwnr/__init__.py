"""uwnr: underwater image rendering for Python.

Renders clean photos as underwater images in the style of real underwater references with the
UWNR network (Ye et al., "Underwater Light Field Retention: Neural Rendering for Underwater
Imaging", CVPR Workshops 2022; the bundled model ships inside the package), or with the physical
and statistical baselines it is compared with (Jerlov water types, UISA, Sea-thru, Reinhard), and
scores images with the field's metrics. The computations are the ``uwnr`` command line's own
(Rust, through a native module): for the same inputs ``Renderer().render`` gives the pixels
``uwnr render`` writes.

>>> import numpy as np, uwnr
>>> r = uwnr.Renderer()                                # the bundled model
>>> clean = np.full((64, 96, 3), 128, np.uint8)
>>> ref = np.zeros((64, 64, 3), np.uint8); ref[..., 1:] = 120
>>> out = r.render(clean, ref)                         # uint8 in, uint8 out
>>> out.shape, out.dtype
((64, 96, 3), dtype('uint8'))

Images are NumPy arrays (HxWx3, HxWx4 with alpha dropped, or HxW grey; uint8, uint16 or float in
[0, 1]), PIL images, torch CHW tensors or file paths; results come back in the same kind (file
paths give uint8 arrays). Depth maps are HxW in [0, 1] with bright = far; without one the built-in
prior is used, as on the command line.

For training data: :class:`UnderwaterAugment` (also a step of torchvision's ``transforms.v2``
pipelines, labels passing through; :mod:`uwnr.albumentations` for Albumentations) and
:class:`PairDataset`, a torch-free reader of the folders ``uwnr dataset`` writes.

Errors: ``ValueError`` for shapes, dtypes, value ranges and options; ``TypeError`` for objects
that are not images; ``FileNotFoundError`` for missing files; :class:`uwnr.Error` for weights,
model and rendering problems.
"""

from __future__ import annotations

import json
import os
from typing import Any, Dict, Iterable, List, Optional, Sequence, Union

import numpy as np

from . import _convert, _uwnr
from ._uwnr import Error

__version__: str = _uwnr.__version__

#: The methods a :class:`Renderer` can use.
METHODS = tuple(_uwnr.METHODS)
#: The light field normalisations: the paper's min-max map, the fixed-range map, or the
#: fixed-range map's mean over the frame (brightness without layout).
LIGHT_FIELD_MAPS = ("paper", "absolute", "global")
#: What can run the network in this build, the default first: "engine" (uwnr's own CPU
#: inference engine), "flex" (burn's CPU backend), "tch" in builds with libtorch.
DEVICES = tuple(_uwnr.DEVICES)
#: Whether this build carries the bundled model (``Renderer()`` with no weights).
HAS_BUNDLED_MODEL: bool = bool(_uwnr.BUNDLED_MODEL)
#: Whether this build carries the bundled UWGAN generator (``Renderer(method="uwgan")``).
HAS_BUNDLED_GAN: bool = bool(_uwnr.BUNDLED_GAN)

# Tiling defaults, as on the command line: images above one megapixel render in overlapping
# 1024-pixel tiles whose blend keeps the output equal to a whole-image render.
_MAX_WHOLE_PIXELS = 1024 * 1024
_TILE = 1024
_OVERLAP = 192


class Reference:
    """A real underwater image used as the style reference, decoded once, with its light field
    maps computed on first use and kept. Pass it to :meth:`Renderer.render` instead of an array
    when the same reference styles many images.

    :param image: array, PIL image, torch CHW tensor or file path.
    """

    def __init__(self, image: Any) -> None:
        arr = _convert.load_path(image) if _convert.is_path(image) else _convert.to_array(
            image, "reference"
        )[0]
        self._native = _uwnr.NativeReference(_convert.rgb_pixels(arr, "reference"))

    @property
    def width(self) -> int:
        return self._native.width

    @property
    def height(self) -> int:
        return self._native.height

    @property
    def image(self) -> np.ndarray:
        """The decoded reference, HxWx3 float32 in [0, 1]."""
        data = self._native.pixels()
        return _convert.image_from_bytes(data, self.height, self.width, "float32")

    def light_field(self, map: str = "absolute") -> np.ndarray:
        """The 256x256x3 light field map (float32 in [0, 1]) the network sees for this reference:
        multi-scale log luminance, normalised as ``map`` says (``"paper"``: min-max, as the
        released code; ``"absolute"``: fixed range, as the bundled model; ``"global"``: the
        absolute map's mean over the frame, channel by channel)."""
        if map not in LIGHT_FIELD_MAPS:
            raise ValueError(f"unknown light field map {map!r} (one of {', '.join(LIGHT_FIELD_MAPS)})")
        data = self._native.light_field(map)
        return _convert.image_from_bytes(data, 256, 256, "float32")

    def __reduce__(self):
        # The decoded pixels travel; the light field maps are recomputed where it is unpickled.
        return (Reference, (self.image,))

    def __repr__(self) -> str:
        return f"uwnr.Reference({self.width}x{self.height})"


ImageLike = Any
ReferenceLike = Union[Reference, Any]


def _reference(x: Optional[ReferenceLike]) -> Optional[Reference]:
    if x is None or isinstance(x, Reference):
        return x
    return Reference(x)


def _clean(x: ImageLike):
    """A clean image as native pixels, with how to return the result."""
    if _convert.is_path(x):
        arr = _convert.load_path(x)
        return _convert.rgb_pixels(arr, "clean image"), _convert.Kind("numpy", np.dtype(np.uint8))
    arr, kind = _convert.to_array(x, "clean image")
    return _convert.rgb_pixels(arr, "clean image"), kind


#: What ``depth_unit`` may say of a depth map: uwnr's absolute [0, 1]; relative (only
#: differences within the image act); metres; millimetres.
DEPTH_UNITS = ("absolute", "relative", "m", "mm")


def _depth(x: Any, unit: str = "absolute"):
    """The depth map as native pixels, and the unit the native module reads it in."""
    if not isinstance(unit, str) or unit not in DEPTH_UNITS:
        raise ValueError(f"depth_unit must be one of {', '.join(DEPTH_UNITS)}, got {unit!r}")
    if _convert.is_path(x):
        raise TypeError("depth: pass the map as an array (read the file with PIL or imageio)")
    if x is None:
        return None, "absolute"
    if unit in ("m", "mm"):
        return _convert.metric_depth_pixels(x, 1000.0 if unit == "mm" else 1.0), "m"
    return _convert.depth_pixels(x), unit


class Renderer:
    """Renders clean images as underwater images.

    :param weights: UWNR weights (safetensors with the authors' key names, or the authors'
        PyTorch checkpoint), or for ``method="uwgan"`` a GAN generator (``generator.safetensors``
        of a ``uwnr gan train`` run); ``None`` for the bundled model. Only for those two methods.
    :param method: ``"uwnr"`` (the network), ``"uwgan"`` (the UWGAN-style GAN baseline, which
        reads no reference), a baseline: ``"jerlov"``, ``"uisa"``, ``"seathru"``,
        ``"reinhard"``, or ``"haze"`` (plain haze ``I = J t + B (1 - t)`` with ``veil``, ``beta``
        and ``depth_scale_m``, a control); ``METHODS`` lists them.
    :param seed: the run seed; a render's random parameters (baselines, and the GAN's water code)
        come from it and the item's index, as in ``uwnr render``.
    :param device: what runs the network: ``"engine"`` (the default and the only choice: uwnr's
        CPU inference engine; the package renders without a training framework).
    :param max_whole_pixels, tile, overlap: tiling of large images, as on the command line.
    :param method_options: a baseline's parameters by name, as in its JSON config, e.g.
        ``water_type="3C"`` for Jerlov, ``space="lab"`` and ``match_std=False`` for Reinhard,
        ``coefficients={"mode": "given", "beta_d": [...], ...}`` for Sea-thru; for ``uwnr``,
        ``precision`` (``"f32"``, or ``"bf16"`` products on the engine: faster on CPUs with
        AVX512_BF16, up to one 8-bit level off), ``scene_scale`` (the metres a relative depth
        map spans: a number, default 4, or ``[min, max]`` drawn per image) and ``prior_trust`` (how far the built-in prior's depth
        differences act, 0 to 1; default 0.075, which keeps self-reconstruction fidelity; ``uwnr
        dataset`` uses 1). An option the method does not have is a ``ValueError``.

    The model loads once; a renderer is safe to share between threads (the GIL is released while
    it renders), to pickle (it is re-created, and the weights reloaded, where it is unpickled) and
    to use in forked processes such as DataLoader workers.
    """

    def __init__(
        self,
        weights: Optional[Union[str, os.PathLike]] = None,
        method: str = "uwnr",
        seed: int = 0,
        device: Optional[str] = None,
        max_whole_pixels: int = _MAX_WHOLE_PIXELS,
        tile: int = _TILE,
        overlap: int = _OVERLAP,
        **method_options: Any,
    ) -> None:
        if not isinstance(method, str):
            raise TypeError(f"method must be a string, got {type(method).__name__}")
        if not isinstance(seed, (int, np.integer)) or isinstance(seed, bool) or seed < 0:
            raise ValueError(f"seed must be a non-negative integer, got {seed!r}")
        if seed >= 2**64:
            raise ValueError(f"seed must be below 2**64, got {seed}")
        device = device if device is not None else DEVICES[0]
        if device not in DEVICES:
            raise ValueError(f"unknown device {device!r} (this build has {', '.join(DEVICES)})")
        if weights is not None:
            weights = os.fspath(weights)
        try:
            options_json = json.dumps(method_options)
        except TypeError as e:
            raise ValueError(f"method options must be JSON-like values: {e}") from None
        self._config: Dict[str, Any] = dict(
            weights=weights,
            method=method,
            seed=int(seed),
            device=device,
            max_whole_pixels=int(max_whole_pixels),
            tile=int(tile),
            overlap=int(overlap),
            **method_options,
        )
        self._native = _uwnr.NativeRenderer(
            method,
            weights,
            options_json,
            int(seed),
            device,
            int(max_whole_pixels),
            int(tile),
            int(overlap),
        )

    @property
    def method(self) -> str:
        """The method's name."""
        return self._native.method

    @property
    def seed(self) -> int:
        return self._native.seed

    @property
    def source(self) -> str:
        """Where the weights came from (``"bundled model"`` or the path), or the baseline's
        parameters as JSON."""
        return self._native.source

    @property
    def reference_use(self) -> str:
        """What a render does with a reference: ``"ignored"`` (uwgan, jerlov, haze, Sea-thru with
        sampled or given coefficients), ``"optional"`` (Sea-thru by default: fitted to the
        reference when there is one) or ``"required"``."""
        return self._native.reference_use

    @property
    def light_field_map(self) -> Optional[str]:
        """The light field map the network's weights read (``None`` for baselines)."""
        return self._native.light_field_map

    def render(
        self,
        clean: ImageLike,
        reference: Optional[ReferenceLike] = None,
        depth: Any = None,
        *,
        depth_unit: str = "absolute",
        seed: Optional[int] = None,
        index: int = 0,
    ) -> Any:
        """Renders ``clean`` in the style of ``reference`` at ``clean``'s own size.

        :param clean: the clean image (array, PIL image, torch CHW tensor or path).
        :param reference: a real underwater image or a :class:`Reference`; needed by ``uwnr``,
            ``uisa`` and ``reinhard``, used by ``seathru`` (coefficients fitted from it), ignored
            by ``jerlov``.
        :param depth: HxW depth map in [0, 1], bright = far (resized to the image if its size
            differs), read as absolute depth: 0 at the camera, 1 far away, so with the bundled
            model a constant 1 renders the scene far off in the reference's water; ``None`` for
            the built-in prior, a relative map (only depth differences within the image act).
        :param depth_unit: how ``depth`` is read: ``"absolute"`` (above), ``"relative"`` (a
            map normalised per image, such as a monocular network's: only differences within
            the image act, over the renderer's ``scene_scale``), ``"m"`` or ``"mm"`` (measured
            distances, e.g. NYU-v2's uint16 millimetres; holes as 0 or NaN are filled): the
            scene's metres go into the water's attenuation, the reference's subject taken to be
            3 m away. A depth map is trusted fully; the built-in prior ``prior_trust``.
        :param seed, index: the draw of the random parameters: ``item_seed(seed, index)``, with
            ``seed`` defaulting to the renderer's; ``uwnr render`` draws item ``i`` of a batch
            with index ``i``.
        :returns: the render, in the type and dtype of ``clean`` (uint8 stays uint8; float stays
            float, in [0, 1]).
        """
        pixels, kind = _clean(clean)
        ref = _reference(reference)
        depth_pixels, unit = _depth(depth, depth_unit)
        out = self._native.render(
            pixels,
            None if ref is None else ref._native,
            depth_pixels,
            unit,
            None if seed is None else int(seed),
            int(index),
        )
        arr = _convert.image_from_bytes(out, pixels[1], pixels[2], pixels[4])
        return _convert.restore(arr, kind)

    def render_batch(
        self,
        cleans: Sequence[ImageLike],
        references: Union[ReferenceLike, Sequence[Optional[ReferenceLike]], None] = None,
        depths: Optional[Sequence[Any]] = None,
        *,
        depth_unit: str = "absolute",
        seed: Optional[int] = None,
    ) -> List[Any]:
        """Renders many images in parallel (the GIL is released). ``references`` is one
        reference for all, or one per image (cycled when shorter, as ``uwnr render``'s default
        pairing); item ``i`` draws its parameters with index ``i``."""
        cleans = list(cleans)
        if not cleans:
            return []
        if references is None or isinstance(references, Reference) or not isinstance(
            references, (list, tuple)
        ):
            refs = [_reference(references)]
        else:
            refs = [_reference(r) for r in references]
            if not refs:
                raise ValueError("references is an empty sequence")
        if depths is not None:
            depths = list(depths)
            if len(depths) != len(cleans):
                raise ValueError(f"{len(depths)} depth maps for {len(cleans)} clean images")
        items = []
        kinds = []
        for i, clean in enumerate(cleans):
            pixels, kind = _clean(clean)
            ref = refs[i % len(refs)]
            depth, _ = _depth(depths[i] if depths is not None else None, depth_unit)
            items.append((pixels, None if ref is None else ref._native, depth))
            kinds.append(kind)
        # Every map given shares depth_unit; millimetres arrive in metres.
        native_unit = "m" if depth_unit in ("m", "mm") else depth_unit
        outs = self._native.render_batch(items, native_unit, None if seed is None else int(seed))
        return [
            _convert.restore(
                _convert.image_from_bytes(out, item[0][1], item[0][2], item[0][4]), kind
            )
            for out, item, kind in zip(outs, items, kinds)
        ]

    def __reduce__(self):
        return (_rebuild_renderer, (self._config,))

    def __repr__(self) -> str:
        return f"uwnr.Renderer(method={self.method!r}, source={self.source!r}, seed={self.seed})"


def _rebuild_renderer(config: Dict[str, Any]) -> Renderer:
    return Renderer(**config)


def lightfield(reference: ReferenceLike, map: str = "absolute") -> np.ndarray:
    """The 256x256x3 light field map (float32 in [0, 1]) of a real underwater image: what the
    network sees of a reference (``uwnr lightfield``). ``map="absolute"`` is the bundled model's
    normalisation, ``"paper"`` the released code's."""
    return _reference(reference).light_field(map)


def depth(clean: ImageLike) -> np.ndarray:
    """The built-in depth prior of an image (HxW float32 in [0, 1], bright = far), the depth
    ``Renderer.render`` uses when none is given."""
    pixels, _ = _clean(clean)
    data = _uwnr.builtin_depth(pixels)
    return np.frombuffer(data, dtype=np.float32).reshape(pixels[1], pixels[2]).copy()


from . import metrics  # noqa: E402
from .augment import UnderwaterAugment  # noqa: E402
from .dataset import PairDataset, webdataset_decoder, webdataset_urls  # noqa: E402

__all__ = [
    "DEVICES",
    "Error",
    "HAS_BUNDLED_MODEL",
    "HAS_BUNDLED_GAN",
    "LIGHT_FIELD_MAPS",
    "METHODS",
    "PairDataset",
    "Reference",
    "Renderer",
    "UnderwaterAugment",
    "depth",
    "lightfield",
    "metrics",
    "webdataset_decoder",
    "webdataset_urls",
]
