"""Reading a ``uwnr dataset`` folder: :class:`PairDataset` yields each pair's images and labels as
NumPy arrays, without torch; :func:`webdataset_urls` lists the folder's WebDataset shards.

The folder (``OUT``) is what ``uwnr dataset`` writes: ``OUT/manifest.jsonl`` with one JSON line
per pair (failed pairs have none), the images ``underwater/NAME_k.png`` and ``clean/NAME_k.png``,
optionally ``depth/NAME_k.png`` (16-bit grey) and ``lightfield/...``, the labels
``labels/NAME_k.json`` (COCO: ``{"image": {...}, "annotations": [...]}``, boxes ``[x, y, w, h]`` in
pixels) or ``labels/NAME_k.txt`` (YOLO: ``class cx cy w h`` or ``class x1 y1 ... xn yn``,
normalised by the pair's width and height), and ``masks/NAME_k.png`` (label values). Paths in the
manifest are relative to ``OUT``.

>>> ds = uwnr.PairDataset("out/")
>>> item = ds[0]          # {"id", "underwater", "clean", "boxes", "classes", ..., "record"}
>>> underwater, boxes = item["underwater"], item["boxes"]   # HxWx3 uint8, Nx4 xyxy pixels

A PyTorch ``Dataset`` needs nothing more: ``DataLoader(uwnr.PairDataset("out/"),
batch_size=None)`` works as it is (batches of boxes of varying counts need a ``collate_fn``, as for
any detection dataset).
"""

from __future__ import annotations

import json
import os
from typing import Any, Callable, Dict, Iterator, List, Optional, Sequence, Tuple, Union

import numpy as np

from . import _uwnr

#: What :class:`PairDataset` can load per pair, by the manifest field that names the file.
LOADABLE = ("underwater", "clean", "depth", "lightfield", "mask")
#: What it loads by default (each only when the pair's record has it).
DEFAULT_IMAGES = ("underwater", "clean", "depth", "mask")

_PNG_SIGNATURE = b"\x89PNG\r\n\x1a\n"


def _png_bit_depth(path: str) -> int:
    """The bit depth per sample in a PNG's header (8 for files that are not PNG)."""
    with open(path, "rb") as f:
        head = f.read(26)
    if len(head) < 26 or head[:8] != _PNG_SIGNATURE or head[12:16] != b"IHDR":
        return 8
    return head[24]


def _read_rgb(path: str) -> np.ndarray:
    """An image file as HxWx3 codes as stored: uint8 for 8-bit files, uint16 for 16-bit PNGs.
    uwnr's decoder gives ``code / max`` in float32, which maps back to the code exactly."""
    bits = _png_bit_depth(path)
    data, height, width = _uwnr.load_rgb(path)
    values = np.frombuffer(data, dtype=np.float32).reshape(height, width, 3)
    if bits == 16:
        return np.floor(values * np.float32(65535.0) + np.float32(0.5)).astype(np.uint16)
    return np.floor(values * np.float32(255.0) + np.float32(0.5)).astype(np.uint8)


def _read_depth(path: str) -> np.ndarray:
    """A depth PNG as HxW codes as stored (uint16 for 16-bit grey, uint8 for 8-bit)."""
    return np.ascontiguousarray(_read_rgb(path)[:, :, 0])


def _read_mask(path: str) -> np.ndarray:
    """A label PNG's values exactly: palette indices, 8- or 16-bit grey (HxW), or RGB(A) (HxWxC).
    Decoded with Pillow, which keeps palette indices."""
    try:
        from PIL import Image
    except ImportError:
        raise ImportError(
            f"reading the mask {path} needs Pillow (pip install pillow); or leave 'mask' out of "
            "PairDataset's images"
        ) from None
    with Image.open(path) as img:
        img.load()
        mode = img.mode
        arr = np.array(img)  # a copy: writable, as every array of an item
    if mode == "1":
        return arr.astype(np.uint8)
    if mode.startswith("I;16") or (mode == "I" and _png_bit_depth(path) == 16):
        return arr.astype(np.uint16)
    return arr


def _coco_labels(path: str) -> Tuple[np.ndarray, np.ndarray, List[Dict[str, Any]]]:
    with open(path, encoding="utf-8") as f:
        try:
            doc = json.load(f)
        except json.JSONDecodeError as e:
            raise ValueError(f"{path}: not valid JSON: {e}") from None
    if not isinstance(doc, dict) or not isinstance(doc.get("annotations"), list):
        raise ValueError(f"{path}: expected a COCO labels object with an 'annotations' list")
    annotations = doc["annotations"]
    boxes = np.zeros((len(annotations), 4), np.float32)
    classes = np.zeros(len(annotations), np.int64)
    for i, ann in enumerate(annotations):
        bbox = ann.get("bbox") if isinstance(ann, dict) else None
        if bbox is None or len(bbox) != 4 or "category_id" not in ann:
            raise ValueError(
                f"{path}: annotation {i} needs 'bbox' [x, y, w, h] and 'category_id', got {ann!r}"
            )
        x, y, w, h = (float(v) for v in bbox)
        boxes[i] = (x, y, x + w, y + h)
        classes[i] = int(ann["category_id"])
    return boxes, classes, annotations


def _yolo_labels(
    path: str, width: int, height: int
) -> Tuple[np.ndarray, np.ndarray, List[Dict[str, Any]]]:
    rows: List[Dict[str, Any]] = []
    boxes: List[Tuple[float, float, float, float]] = []
    with open(path, encoding="utf-8") as f:
        lines = f.read().splitlines()
    for number, line in enumerate(lines, start=1):
        fields = line.split()
        if not fields:
            continue
        try:
            cls = int(fields[0])
            values = [float(v) for v in fields[1:]]
        except ValueError:
            raise ValueError(f"{path}:{number}: not a YOLO line: {line!r}") from None
        if len(values) == 4:
            cx, cy, w, h = values
            rows.append({"class": cls, "box": values})
            boxes.append(
                (
                    (cx - w / 2) * width,
                    (cy - h / 2) * height,
                    (cx + w / 2) * width,
                    (cy + h / 2) * height,
                )
            )
        elif len(values) >= 6 and len(values) % 2 == 0:
            xs, ys = values[0::2], values[1::2]
            rows.append({"class": cls, "polygon": values})
            boxes.append((min(xs) * width, min(ys) * height, max(xs) * width, max(ys) * height))
        else:
            raise ValueError(
                f"{path}:{number}: a YOLO line is 'class cx cy w h' or 'class x1 y1 ... xn yn' "
                f"with n >= 3, got {len(fields)} fields"
            )
    box_array = np.array(boxes, np.float32).reshape(len(boxes), 4)
    classes = np.array([r["class"] for r in rows], np.int64)
    return box_array, classes, rows


class PairDataset:
    """The pairs of a ``uwnr dataset`` folder, as NumPy arrays and labels; no torch needed.

    :param folder: the dataset folder (``OUT``, holding ``manifest.jsonl``).
    :param images: what to load per pair, among ``LOADABLE``: ``"underwater"``, ``"clean"``,
        ``"depth"``, ``"lightfield"``, ``"mask"``; each only when the pair's record names it
        (``"underwater"`` and ``"clean"`` must be named). Default ``DEFAULT_IMAGES``.
    :param transform: a callable applied to each item (the dict below); its result is the item.

    An item is a dict:

    - ``"id"``: the pair's id (``NAME_k``); ``"record"``: its manifest line as a dict;
    - ``"underwater"``, ``"clean"`` (and ``"lightfield"``): HxWx3 uint8 arrays (uint16 for a
      16-bit PNG);
    - ``"depth"``: HxW, the codes as stored (uint16 for the 16-bit depth maps ``uwnr dataset``
      writes), when the record has a depth;
    - ``"mask"``: the label PNG's values exactly (palette indices or grey levels, HxW; HxWxC for
      RGB), never interpolated, when the record has a mask (read with Pillow);
    - ``"boxes"`` (float32 Nx4, ``[x1, y1, x2, y2]`` in pixels of the pair), ``"classes"`` (int64
      N: COCO ``category_id`` or YOLO class) and ``"annotations"`` (the COCO annotation dicts as
      written, or for YOLO one dict per line: ``{"class": c, "box": [cx, cy, w, h]}`` or
      ``{"class": c, "polygon": [x1, y1, ...]}``, normalised), when the record has labels. A YOLO
      polygon's box is the polygon's bounding box.

    Map-style: ``len(ds)``, ``ds[i]``, ``for item in ds``. A PyTorch ``Dataset`` wraps it in one
    line, or needs no wrapper at all::

        loader = torch.utils.data.DataLoader(uwnr.PairDataset("out/"), batch_size=None,
                                             shuffle=True, num_workers=2)

    Errors: ``FileNotFoundError`` for a missing folder, manifest or file a record names (the
    message names the file); ``ValueError`` for a manifest line or labels file that cannot be read
    (naming the file and line).
    """

    def __init__(
        self,
        folder: Union[str, os.PathLike],
        images: Sequence[str] = DEFAULT_IMAGES,
        transform: Optional[Callable[[Dict[str, Any]], Any]] = None,
    ) -> None:
        self.folder = os.fspath(folder)
        images = (images,) if isinstance(images, str) else tuple(images)
        for name in images:
            if name not in LOADABLE:
                raise ValueError(f"unknown image {name!r} (one of {', '.join(LOADABLE)})")
        self.images: Tuple[str, ...] = images
        self.transform = transform
        if not os.path.isdir(self.folder):
            raise FileNotFoundError(f"dataset folder {self.folder} does not exist")
        manifest = os.path.join(self.folder, "manifest.jsonl")
        if not os.path.isfile(manifest):
            raise FileNotFoundError(
                f"{manifest} does not exist: is {self.folder} a folder written by `uwnr dataset`?"
            )
        #: The manifest's records (one dict per pair), in file order.
        self.records: List[Dict[str, Any]] = []
        with open(manifest, encoding="utf-8") as f:
            for number, line in enumerate(f, start=1):
                if not line.strip():
                    continue
                try:
                    record = json.loads(line)
                except json.JSONDecodeError as e:
                    raise ValueError(f"{manifest}:{number}: not valid JSON: {e}") from None
                if not isinstance(record, dict):
                    raise ValueError(f"{manifest}:{number}: a record is a JSON object")
                missing = [k for k in ("id", "underwater", "clean") if k not in record]
                if missing:
                    raise ValueError(
                        f"{manifest}:{number}: a record needs 'id', 'underwater' and 'clean'; "
                        f"missing {', '.join(missing)}"
                    )
                self.records.append(record)

    def __len__(self) -> int:
        return len(self.records)

    def _path(self, record: Dict[str, Any], field: str) -> str:
        path = os.path.join(self.folder, record[field])
        if not os.path.isfile(path):
            raise FileNotFoundError(
                f"{path} does not exist (the {field} of pair {record['id']!r} in "
                f"{os.path.join(self.folder, 'manifest.jsonl')})"
            )
        return path

    def __getitem__(self, index: int) -> Any:
        """The item of pair ``index`` (negative indices count from the end)."""
        if not -len(self) <= index < len(self):
            raise IndexError(f"index {index} is out of range for {len(self)} pairs")
        record = self.records[index]
        item: Dict[str, Any] = {"id": record["id"]}
        for name in self.images:
            if not record.get(name):
                continue
            path = self._path(record, name)
            if name == "depth":
                item[name] = _read_depth(path)
            elif name == "mask":
                item[name] = _read_mask(path)
            else:
                item[name] = _read_rgb(path)
        if record.get("labels"):
            path = self._path(record, "labels")
            if path.endswith(".json"):
                boxes, classes, annotations = _coco_labels(path)
            elif path.endswith(".txt"):
                width, height = int(record["width"]), int(record["height"])
                boxes, classes, annotations = _yolo_labels(path, width, height)
            else:
                raise ValueError(f"{path}: labels are COCO (.json) or YOLO (.txt)")
            item["boxes"] = boxes
            item["classes"] = classes
            item["annotations"] = annotations
        item["record"] = record
        return self.transform(item) if self.transform is not None else item

    def __iter__(self) -> Iterator[Any]:
        for i in range(len(self)):
            yield self[i]

    def __repr__(self) -> str:
        return f"uwnr.PairDataset({self.folder!r}, pairs={len(self)}, images={self.images})"


def webdataset_urls(folder: Union[str, os.PathLike]) -> List[str]:
    """The paths of a dataset folder's WebDataset shards (``OUT/webdataset/*.tar``, from its
    ``index.json``), in order; pass them to ``webdataset.WebDataset``."""
    root = os.path.join(os.fspath(folder), "webdataset")
    index = os.path.join(root, "index.json")
    if not os.path.isfile(index):
        raise FileNotFoundError(
            f"{index} does not exist: was the dataset written with --format webdataset?"
        )
    with open(index, encoding="utf-8") as f:
        try:
            shards = json.load(f)["shards"]
        except (json.JSONDecodeError, KeyError, TypeError) as e:
            raise ValueError(
                f"{index}: expected {{'shards': [{{'file': ...}}, ...]}}: {e!r}"
            ) from None
    return [os.path.join(root, shard["file"]) for shard in shards]


def webdataset_decoder(key: str, data: bytes) -> Optional[np.ndarray]:
    """A WebDataset decoder handler that keeps label-mask values: ``*.mask.png`` members are
    decoded with Pillow as integer arrays exactly as stored (16-bit instance ids stay uint16,
    palette masks give their indices, grey masks uint8; RGB masks HxWx3), never scaled to
    ``rgb8``. Every other member is left to the next handler (``None``), so use it first::

        wds.WebDataset(urls).decode(uwnr.webdataset_decoder, "rgb8")
    """
    if not key.lower().endswith("mask.png"):
        return None
    import io

    from PIL import Image

    with Image.open(io.BytesIO(data)) as img:
        img.load()
        if img.mode in ("I;16", "I;16B", "I;16L", "I"):
            # Pillow reads 16-bit grey PNGs as I;16 or I (32-bit); the values are 16-bit.
            return np.asarray(img).astype(np.uint16)
        # "P" (palette indices), "L", "RGB", "RGBA", "LA": the stored values as they are.
        return np.asarray(img).copy()
