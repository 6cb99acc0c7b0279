"""Underwater rendering as an Albumentations transform: :class:`UnderwaterAugment`, an
``ImageOnlyTransform``, so boxes, masks and keypoints pass through a ``Compose`` untouched
(rendering keeps the geometry, so every label stays true for the underwater image).

>>> import albumentations as A
>>> from uwnr.albumentations import UnderwaterAugment
>>> pipeline = A.Compose(
...     [UnderwaterAugment("refs/", methods=["uwnr", "jerlov"], p=0.5), A.HorizontalFlip()],
...     bbox_params=A.BboxParams(format="pascal_voc", label_fields=["labels"]),
... )
>>> out = pipeline(image=image, bboxes=boxes, labels=labels)

Randomness: whether the transform applies is Albumentations' draw (``p``, from the ``Compose``'s
generators, ``seed=`` on ``A.Compose``); what a render looks like (method, reference, the method's
parameters) is drawn by uwnr's own generator, seeded by ``render_seed=`` here and by the DataLoader
worker as :mod:`uwnr.augment` describes. Needs ``pip install albumentations``.
"""

from __future__ import annotations

import os
from typing import Any, Dict, Optional, Sequence, Tuple, Union

import numpy as np

try:
    from albumentations import ImageOnlyTransform
except ImportError as e:  # pragma: no cover - depends on what is installed
    raise ImportError(
        "uwnr.albumentations needs the albumentations package (pip install albumentations); "
        "uwnr.UnderwaterAugment works without it"
    ) from e

from . import augment


class UnderwaterAugment(ImageOnlyTransform):
    """Renders the image underwater (an Albumentations image-only transform).

    :param references, methods, weights, method_options, device: as
        :class:`uwnr.UnderwaterAugment`.
    :param render_seed: the base of uwnr's random stream (``seed`` of
        :class:`uwnr.UnderwaterAugment`; ``seed`` is Albumentations' own attribute).
    :param p: the probability that Albumentations applies the transform.

    Images are HxWx3 uint8 or float32 in [0, 1] (Albumentations' conventions); the result has the
    input's dtype and size. The transform pickles (for DataLoader workers) without its renderers,
    which are rebuilt on first use.
    """

    def __init__(
        self,
        references: Union[str, os.PathLike, Sequence[Any]],
        methods: Union[str, Sequence[str]] = ("uwnr",),
        render_seed: int = 0,
        weights: Optional[Union[str, os.PathLike]] = None,
        method_options: Optional[Dict[str, Dict[str, Any]]] = None,
        device: Optional[str] = None,
        p: float = 0.5,
    ) -> None:
        super().__init__(p=p)
        # Albumentations draws whether to apply; uwnr's augmentation always renders when called.
        self.augment = augment.UnderwaterAugment(
            references,
            methods=methods,
            p=1.0,
            seed=render_seed,
            weights=weights,
            method_options=method_options,
            device=device,
        )
        self.references = references
        self.methods = self.augment.methods
        self.render_seed = self.augment.seed
        self.weights = self.augment.weights
        self.method_options = self.augment.method_options
        self.device = device

    def apply(self, img: np.ndarray, **params: Any) -> np.ndarray:
        """The render of ``img`` (HxWxC array), same dtype and size."""
        return self.augment(img)

    def reseed(self, seed: int) -> None:
        """Restarts uwnr's random stream from ``seed``, as :meth:`uwnr.UnderwaterAugment.reseed`."""
        self.augment.reseed(seed)

    def get_transform_init_args_names(self) -> Tuple[str, ...]:
        """The ``__init__`` arguments other than ``p`` (Albumentations' ``to_dict`` and repr)."""
        return ("references", "methods", "render_seed", "weights", "method_options", "device")
