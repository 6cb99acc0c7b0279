"""Underwater augmentation for training loops: each call renders its input as an underwater
image, with probability ``p``, in the style of a reference and with a method drawn at random.

Randomness and seeds. Every draw (whether to apply, which method, which reference, the seed of the
method's own random parameters) comes from the augmentation's own NumPy generator, never from the
global NumPy, Python or torch generators. The generator is made in the process that first calls
the augmentation, from:

- ``SeedSequence([seed])`` in a process that is not a PyTorch DataLoader worker;
- ``SeedSequence([seed, info.seed])`` in a DataLoader worker, where ``info =
  torch.utils.data.get_worker_info()``. PyTorch gives each worker ``info.seed = base_seed +
  worker_id`` and draws ``base_seed`` from torch's generator once per epoch (per DataLoader
  iterator), so each worker draws its own stream, epochs differ, and a run is reproducible when
  the program calls ``torch.manual_seed`` (or passes a ``generator`` to the DataLoader).

A ``worker_init_fn`` is not needed. If you use one to set your own seeds, call
:meth:`UnderwaterAugment.reseed` in it to choose the augmentation's stream explicitly (for
example ``aug.reseed(1000 * epoch + worker_id)``); an explicit reseed wins over the rule above.

Work done once per process and kept: the renderers (the network's weights load on first use of
``"uwnr"``) and each reference's decoded image and light field map. The object pickles without
them (DataLoader workers started with ``spawn`` rebuild them on first use) and is safe to fork.
"""

from __future__ import annotations

import copy
import os
import sys
from typing import Any, Dict, List, Optional, Sequence, Tuple, Union

import numpy as np

from . import METHODS, Reference, Renderer, _convert

#: File extensions read from a references folder (as the command line reads them).
IMAGE_EXTENSIONS = (".png", ".jpg", ".jpeg", ".bmp", ".tif", ".tiff", ".webp")


def _list_references(references: Any) -> List[Any]:
    if isinstance(references, (str, os.PathLike)):
        path = os.fspath(references)
        if os.path.isdir(path):
            files = sorted(
                os.path.join(path, name)
                for name in os.listdir(path)
                if name.lower().endswith(IMAGE_EXTENSIONS)
            )
            if not files:
                raise ValueError(f"references folder {path} holds no images")
            return files
        if os.path.isfile(path):
            return [path]
        raise FileNotFoundError(f"references {path} does not exist")
    items = list(references)
    if not items:
        raise ValueError("references is empty")
    return items


def _torch_worker_seed() -> Optional[int]:
    """The DataLoader worker's seed when called in a worker, else ``None``. torch is looked up
    only if the program has imported it."""
    torch = sys.modules.get("torch")
    if torch is None:
        return None
    try:
        info = torch.utils.data.get_worker_info()
    except AttributeError:
        return None
    return None if info is None else int(info.seed)


def _tv_tensors() -> Any:
    """torchvision's ``tv_tensors`` module if the program has imported it, else ``None``: a
    tv_tensor can only exist once it has been imported, so uwnr never imports it itself."""
    return sys.modules.get("torchvision.tv_tensors")


def _flatten(x: Any, out: List[Any]) -> None:
    """The leaves of a sample, depth first, in the order of torch's ``tree_flatten``: tuples
    (named tuples too), lists and dicts (in key order) are containers, anything else a leaf."""
    if isinstance(x, (tuple, list)):
        for item in x:
            _flatten(item, out)
    elif isinstance(x, dict):
        for item in x.values():
            _flatten(item, out)
    else:
        out.append(x)


def _unflatten(x: Any, leaves: List[Any]) -> Tuple[Any, List[Any]]:
    """``x``'s structure rebuilt around ``leaves`` (as :func:`_flatten` listed them); returns the
    rebuilt sample and the leaves left over."""
    if isinstance(x, (tuple, list)):
        items = []
        for item in x:
            new, leaves = _unflatten(item, leaves)
            items.append(new)
        if isinstance(x, list):
            return items, leaves
        if hasattr(x, "_fields"):  # a named tuple
            return type(x)(*items), leaves
        return tuple(items), leaves
    if isinstance(x, dict):
        out = copy.copy(x)  # keeps the dict's type (OrderedDict, defaultdict, ...)
        for key, item in x.items():
            out[key], leaves = _unflatten(item, leaves)
        return out, leaves
    return leaves[0], leaves[1:]


def _image_slots(leaves: List[Any]) -> List[int]:
    """Which leaves of a sample are images to render, as torchvision v2 decides: every
    ``tv_tensors.Image`` and PIL image; without one, the first plain tensor (a tensor that is no
    tv_tensor); without any tensor, the first NumPy array (torchvision never transforms arrays, so
    this is uwnr's own rule). Boxes, masks, labels and everything else are passed through."""
    tv = _tv_tensors()
    torch = sys.modules.get("torch")
    explicit = []
    for i, leaf in enumerate(leaves):
        if tv is not None and isinstance(leaf, tv.Video):
            raise TypeError(
                "UnderwaterAugment renders images, not videos: render a tv_tensors.Video's "
                "frames one by one"
            )
        if (tv is not None and isinstance(leaf, tv.Image)) or _convert._is_pil(leaf):
            explicit.append(i)
    if explicit:
        return explicit
    if torch is not None:
        for i, leaf in enumerate(leaves):
            is_tv_tensor = tv is not None and isinstance(leaf, tv.TVTensor)
            if isinstance(leaf, torch.Tensor) and not is_tv_tensor:
                return [i]
    for i, leaf in enumerate(leaves):
        if isinstance(leaf, np.ndarray):
            return [i]
    kinds = ", ".join(sorted({type(leaf).__name__ for leaf in leaves})) or "nothing"
    raise TypeError(
        "UnderwaterAugment found no image in the sample (a tv_tensors.Image, a PIL image, a "
        f"tensor or a NumPy array); it holds {kinds}"
    )


def _render_keeping_type(
    renderer: Renderer, x: Any, reference: Optional[Reference], depth: Any, seed: int
) -> Any:
    """``renderer.render`` that also keeps a ``tv_tensors.Image`` a ``tv_tensors.Image``."""
    out = renderer.render(x, reference, depth, seed=seed)
    tv = _tv_tensors()
    if tv is not None and isinstance(x, tv.TVTensor):
        return tv.wrap(out, like=x)
    return out


class UnderwaterAugment:
    """An augmentation that renders its input underwater with probability ``p``.

    :param references: a folder of real underwater images, one image path, or a sequence of
        images (paths, arrays, PIL images, :class:`uwnr.Reference`).
    :param methods: the methods to draw from, uniformly (any of ``uwnr.METHODS``: ``"uwnr"``,
        ``"uwgan"``, ``"jerlov"``, ``"uisa"``, ``"seathru"``, ``"reinhard"``, ``"haze"``; those
        whose ``Renderer.reference_use`` is ``"ignored"`` are given no reference).
    :param p: probability of rendering; otherwise the input is returned unchanged.
    :param seed: the base of the augmentation's random stream (see the module docs).
    :param weights: UWNR weights for ``"uwnr"`` (``None``: the bundled model).
    :param method_options: per-method options, e.g. ``{"jerlov": {"water_type": "3C"}}``.
    :param device: the network's compute device.

    ``aug(x)`` takes and returns the same kind: a PIL image gives a PIL image, a NumPy array an
    array of the same dtype, a torch CHW tensor a tensor of the same dtype and device.
    ``aug(x, depth=d)`` uses a depth map (HxW in [0, 1], bright = far) instead of the built-in
    prior.

    Samples with labels. Called as a step of ``torchvision.transforms.v2.Compose``, on
    ``(image, target)``, ``(image, boxes, mask)``, a tuple or a dict, the augmentation renders
    the sample's image and returns the same structure with every other object (``BoundingBoxes``,
    ``Mask``, label tensors, dicts of them) the very same object: rendering keeps the geometry, so
    every label stays true. The image is what torchvision v2 takes as the image: every
    ``tv_tensors.Image`` and PIL image in the sample; without one, the first plain tensor (CHW);
    without any tensor, the first NumPy array (HxWxC). A ``tv_tensors.Image`` comes back a
    ``tv_tensors.Image``. When the draw says not to render, the sample itself is returned. torch
    and torchvision are never imported by uwnr: they are looked up only when the sample holds
    their objects.

    >>> from torchvision import tv_tensors
    >>> from torchvision.transforms import v2
    >>> pipeline = v2.Compose([uwnr.UnderwaterAugment("refs/", p=0.5), v2.RandomHorizontalFlip()])
    >>> image, target = pipeline(tv_tensors.Image(img), {"boxes": boxes, "labels": labels})

    For Albumentations use :class:`uwnr.albumentations.UnderwaterAugment`.
    """

    def __init__(
        self,
        references: Union[str, os.PathLike, Sequence[Any]],
        methods: Union[str, Sequence[str]] = ("uwnr",),
        p: float = 0.5,
        seed: int = 0,
        weights: Optional[Union[str, os.PathLike]] = None,
        method_options: Optional[Dict[str, Dict[str, Any]]] = None,
        device: Optional[str] = None,
    ) -> None:
        methods = [methods] if isinstance(methods, str) else list(methods)
        if not methods:
            raise ValueError("methods is empty")
        for m in methods:
            if m not in METHODS:
                raise ValueError(f"unknown method {m!r} (one of {', '.join(METHODS)})")
        if not 0.0 <= float(p) <= 1.0:
            raise ValueError(f"p must lie in [0, 1], got {p}")
        if not isinstance(seed, (int, np.integer)) or seed < 0:
            raise ValueError(f"seed must be a non-negative integer, got {seed!r}")
        method_options = dict(method_options or {})
        for name in method_options:
            if name not in methods:
                raise ValueError(f"method_options names {name!r}, which is not in methods")
        self.methods = methods
        self.p = float(p)
        self.seed = int(seed)
        self.weights = None if weights is None else os.fspath(weights)
        self.method_options = method_options
        self.device = device
        self._references = _list_references(references)
        # Fail now, not in a worker, on options a method does not take or weights that do not
        # load: build every renderer once here.
        self._renderers: Dict[str, Renderer] = {m: self._make_renderer(m) for m in methods}
        self._cache: Dict[int, Reference] = {}
        self._explicit_seed: Optional[int] = None
        self._rng: Optional[np.random.Generator] = None
        self._rng_key: Optional[tuple] = None

    def _make_renderer(self, method: str) -> Renderer:
        options = self.method_options.get(method, {})
        weights = self.weights if method == "uwnr" else None
        return Renderer(weights=weights, method=method, device=self.device, **options)

    def reseed(self, seed: int) -> None:
        """Restarts the random stream from ``seed`` (in this process), e.g. in a DataLoader's
        ``worker_init_fn``."""
        self._explicit_seed = int(seed)
        self._rng = None

    def _generator(self) -> np.random.Generator:
        if self._explicit_seed is not None:
            key = ("explicit", os.getpid(), self._explicit_seed)
            entropy = [self._explicit_seed]
        else:
            worker = _torch_worker_seed()
            key = ("auto", os.getpid(), worker)
            entropy = [self.seed] if worker is None else [self.seed, worker]
        if self._rng is None or self._rng_key != key:
            self._rng = np.random.Generator(np.random.PCG64(np.random.SeedSequence(entropy)))
            self._rng_key = key
        return self._rng

    def _reference(self, i: int) -> Reference:
        ref = self._cache.get(i)
        if ref is None:
            item = self._references[i]
            ref = item if isinstance(item, Reference) else Reference(item)
            self._cache[i] = ref
        return ref

    def __call__(self, *inputs: Any, depth: Any = None) -> Any:
        """Renders the image of a sample with probability ``p``.

        ``aug(x)`` with one image (array, PIL image, torch CHW tensor, path) returns the render in
        ``x``'s kind. ``aug(image, target)``, ``aug((image, target))`` or ``aug({"image": ...,
        ...})`` render the sample's image (found as described in the class docs) and return the
        same structure, every other object in it the same object, untouched; this is how
        ``torchvision.transforms.v2.Compose`` calls a transform. ``depth`` (keyword only) replaces
        the built-in depth prior for the image.
        """
        if not inputs:
            raise TypeError("UnderwaterAugment() takes an image or a sample, got nothing")
        sample = inputs if len(inputs) > 1 else inputs[0]
        structured = len(inputs) > 1 or isinstance(sample, (tuple, list, dict))
        rng = self._generator()
        # Every call takes the same four draws, so whether a call renders does not shift the
        # stream of later calls.
        apply = rng.random() < self.p
        method = self.methods[int(rng.integers(len(self.methods)))]
        ref_index = int(rng.integers(len(self._references)))
        render_seed = int(rng.integers(0, 2**63))
        if structured:
            # Checked before the draw takes effect, so a sample the augmentation cannot read fails
            # on the first call whatever p is.
            leaves: List[Any] = []
            _flatten(sample, leaves)
            slots = _image_slots(leaves)
        if not apply:
            return sample
        renderer = self._renderers.get(method)
        if renderer is None:
            renderer = self._renderers[method] = self._make_renderer(method)
        # A method that reads no reference is not given one (nor made to decode it).
        reads = renderer.reference_use != "ignored"
        reference = self._reference(ref_index) if reads else None
        if not structured:
            return _render_keeping_type(renderer, sample, reference, depth, render_seed)
        # Every image of one sample is rendered with the same draws.
        for i in slots:
            leaves[i] = _render_keeping_type(renderer, leaves[i], reference, depth, render_seed)
        out, rest = _unflatten(sample, leaves)
        assert not rest
        return out

    def __getstate__(self) -> Dict[str, Any]:
        state = self.__dict__.copy()
        state["_renderers"] = {}
        state["_cache"] = {}
        state["_rng"] = None
        state["_rng_key"] = None
        return state

    def __setstate__(self, state: Dict[str, Any]) -> None:
        self.__dict__.update(state)

    def __repr__(self) -> str:
        return (
            f"uwnr.UnderwaterAugment(methods={self.methods}, p={self.p}, seed={self.seed}, "
            f"references={len(self._references)})"
        )
