"""uwnr.PairDataset on dataset folders written by hand to the layout `uwnr dataset` writes
(manifest.jsonl, underwater/, clean/, depth/, masks/, labels/ in COCO or YOLO form): exact pixels,
exact mask values, boxes converted to xyxy pixels, errors that name the file."""

import json
import tarfile

import numpy as np
import pytest
from PIL import Image

import uwnr

W, H = 48, 32
# COCO boxes [x, y, w, h] in pixels, and the xyxy they must become.
COCO_BOXES = [[4.0, 6.0, 10.0, 8.0], [20.5, 1.0, 7.0, 9.5]]
COCO_XYXY = [[4.0, 6.0, 14.0, 14.0], [20.5, 1.0, 27.5, 10.5]]
CATEGORIES = [3, 1]
# YOLO: a box line (cx, cy, w, h normalised) and a polygon line (x, y pairs normalised).
YOLO_TEXT = "2 0.25 0.5 0.125 0.25\n0 0.5 0.25 0.75 0.25 0.625 0.75\n"
YOLO_XYXY = [[9.0, 12.0, 15.0, 20.0], [24.0, 8.0, 36.0, 24.0]]


def rgb(seed):
    return np.random.default_rng(seed).integers(0, 256, (H, W, 3), dtype=np.uint8)


def palette_mask():
    m = np.zeros((H, W), np.uint8)
    m[6:14, 4:14] = 1
    m[1:11, 20:28] = 7  # a value far from its neighbours: interpolation would show
    return m


def write_palette_png(path, values):
    """A palette PNG whose indices are ``values`` (its colours are unrelated to the indices)."""
    img = Image.new("P", (values.shape[1], values.shape[0]))
    img.putpalette([(37 * i) % 256 for i in range(768)])
    img.putdata(values.ravel().tolist())
    img.save(path)


def make_folder(root, labels="coco", names=("scene_0", "scene_1")):
    """A dataset folder to the `uwnr dataset` contract; returns the arrays written, by pair id."""
    for sub in ("underwater", "clean", "depth", "masks", "labels"):
        (root / sub).mkdir(parents=True, exist_ok=True)
    written = {}
    lines = []
    for index, name in enumerate(names):
        under, clean = rgb(2 * index), rgb(2 * index + 1)
        depth = (np.arange(H * W, dtype=np.uint32).reshape(H, W) * 41 + 1000 * index).astype(
            np.uint16
        )
        Image.fromarray(under).save(root / "underwater" / f"{name}.png")
        Image.fromarray(clean).save(root / "clean" / f"{name}.png")
        Image.fromarray(depth).save(root / "depth" / f"{name}.png")
        write_palette_png(root / "masks" / f"{name}.png", palette_mask())
        record = {
            "id": name,
            "index": index,
            "clean_source": f"photos/{name[:-2]}.jpg",
            "reference_source": "refs/a.jpg",
            "method": "uwnr",
            "params": {"scene_scale": 4.0},
            "seed": 7,
            "width": W,
            "height": H,
            "underwater": f"underwater/{name}.png",
            "clean": f"clean/{name}.png",
            "depth": f"depth/{name}.png",
            "mask": f"masks/{name}.png",
        }
        if labels == "coco":
            annotations = []
            if index == 0:
                annotations = [
                    {
                        "id": i + 1,
                        "image_id": 1,
                        "category_id": c,
                        "bbox": b,
                        "area": b[2] * b[3],
                        "iscrowd": 0,
                        "segmentation": [[b[0], b[1], b[0] + b[2], b[1], b[0], b[1] + b[3]]],
                    }
                    for i, (c, b) in enumerate(zip(CATEGORIES, COCO_BOXES))
                ]
                annotations[1]["segmentation"] = {"size": [H, W], "counts": "abc"}
            doc = {
                "image": {
                    "id": index + 1,
                    "file_name": record["underwater"],
                    "width": W,
                    "height": H,
                    "clean_file_name": record["clean"],
                    "source_id": 100,
                },
                "annotations": annotations,
            }
            (root / "labels" / f"{name}.json").write_text(json.dumps(doc))
            record["labels"] = f"labels/{name}.json"
        elif labels == "yolo":
            (root / "labels" / f"{name}.txt").write_text(YOLO_TEXT if index == 0 else "")
            record["labels"] = f"labels/{name}.txt"
        lines.append(json.dumps(record))
        written[name] = dict(underwater=under, clean=clean, depth=depth, record=record)
    (root / "manifest.jsonl").write_text("\n".join(lines) + "\n")
    return written


def test_coco_items_hold_exact_pixels_and_xyxy_boxes(tmp_path):
    written = make_folder(tmp_path, "coco")
    ds = uwnr.PairDataset(tmp_path)
    assert len(ds) == 2
    item = ds[0]
    assert item["id"] == "scene_0"
    assert item["record"] == written["scene_0"]["record"]
    for key in ("underwater", "clean"):
        assert item[key].shape == (H, W, 3) and item[key].dtype == np.uint8
        np.testing.assert_array_equal(item[key], written["scene_0"][key])
    assert item["depth"].dtype == np.uint16
    np.testing.assert_array_equal(item["depth"], written["scene_0"]["depth"])
    assert item["mask"].shape == (H, W) and item["mask"].dtype == np.uint8
    np.testing.assert_array_equal(item["mask"], palette_mask())  # indices, not colours
    assert item["boxes"].dtype == np.float32 and item["classes"].dtype == np.int64
    np.testing.assert_array_equal(item["boxes"], np.array(COCO_XYXY, np.float32))
    np.testing.assert_array_equal(item["classes"], CATEGORIES)
    labels = json.loads((tmp_path / "labels" / "scene_0.json").read_text())
    assert item["annotations"] == labels["annotations"]
    # A pair with no objects has empty boxes of the right shape.
    arrays = [v for v in item.values() if isinstance(v, np.ndarray)]
    assert len(arrays) == 6 and all(a.flags.writeable for a in arrays)
    empty = ds[1]
    assert empty["boxes"].shape == (0, 4) and empty["classes"].shape == (0,)
    assert empty["annotations"] == []


def test_yolo_boxes_and_polygons_become_xyxy_pixels(tmp_path):
    make_folder(tmp_path, "yolo")
    item = uwnr.PairDataset(tmp_path)[0]
    np.testing.assert_allclose(item["boxes"], YOLO_XYXY, atol=1e-5)
    np.testing.assert_array_equal(item["classes"], [2, 0])
    assert item["annotations"][0] == {"class": 2, "box": [0.25, 0.5, 0.125, 0.25]}
    assert item["annotations"][1]["class"] == 0 and len(item["annotations"][1]["polygon"]) == 6
    empty = uwnr.PairDataset(tmp_path)[1]
    assert empty["boxes"].shape == (0, 4) and empty["classes"].dtype == np.int64


def test_a_pair_without_labels_has_no_label_keys(tmp_path):
    make_folder(tmp_path, labels=None)
    item = uwnr.PairDataset(tmp_path)[0]
    assert "boxes" not in item and "annotations" not in item
    assert {"id", "underwater", "clean", "depth", "mask", "record"} <= item.keys()


@pytest.mark.parametrize("kind", ["grey8", "grey16", "rgb"])
def test_mask_values_are_read_exactly(tmp_path, kind):
    make_folder(tmp_path, "coco", names=("scene_0",))
    base = palette_mask()
    if kind == "grey8":
        values = base * 30
        Image.fromarray(values).save(tmp_path / "masks" / "scene_0.png")
    elif kind == "grey16":
        values = base.astype(np.uint16) * 9000 + 1
        Image.fromarray(values).save(tmp_path / "masks" / "scene_0.png")
    else:
        values = np.stack([base, base * 2, 255 - base], axis=2).astype(np.uint8)
        Image.fromarray(values).save(tmp_path / "masks" / "scene_0.png")
    mask = uwnr.PairDataset(tmp_path)[0]["mask"]
    assert mask.dtype == values.dtype
    np.testing.assert_array_equal(mask, values)


def test_images_chooses_what_is_loaded_and_transform_applies(tmp_path):
    make_folder(tmp_path, "coco")
    only = uwnr.PairDataset(tmp_path, images=("underwater",))[0]
    assert "underwater" in only and not {"clean", "depth", "mask"} & only.keys()
    assert "boxes" in only
    with pytest.raises(ValueError, match="unknown image"):
        uwnr.PairDataset(tmp_path, images=("segmentation",))
    ds = uwnr.PairDataset(tmp_path, transform=lambda item: (item["underwater"], item["boxes"]))
    image, boxes = ds[0]
    assert image.shape == (H, W, 3) and boxes.shape == (2, 4)


def test_len_indexing_and_iteration(tmp_path):
    make_folder(tmp_path, "coco", names=("a_0", "a_1", "b_0"))
    ds = uwnr.PairDataset(tmp_path, images=())
    assert len(ds) == 3
    assert [item["id"] for item in ds] == ["a_0", "a_1", "b_0"]
    assert ds[-1]["id"] == "b_0"
    with pytest.raises(IndexError):
        ds[3]
    assert "pairs=3" in repr(ds)


def test_missing_pairs_blank_lines_and_bad_lines(tmp_path):
    make_folder(tmp_path, "coco")
    manifest = tmp_path / "manifest.jsonl"
    # A failed pair has no line: only the lines present are pairs.
    first = manifest.read_text().splitlines()[0]
    manifest.write_text(first + "\n\n")
    assert len(uwnr.PairDataset(tmp_path)) == 1
    manifest.write_text(first + "\n{not json\n")
    with pytest.raises(ValueError, match=r"manifest.jsonl:2"):
        uwnr.PairDataset(tmp_path)
    manifest.write_text('{"id": "x_0"}\n')
    with pytest.raises(ValueError, match="missing underwater, clean"):
        uwnr.PairDataset(tmp_path)


def test_errors_name_the_missing_file(tmp_path):
    with pytest.raises(FileNotFoundError, match="does not exist"):
        uwnr.PairDataset(tmp_path / "nowhere")
    with pytest.raises(FileNotFoundError, match="manifest.jsonl"):
        uwnr.PairDataset(tmp_path)
    make_folder(tmp_path, "coco")
    (tmp_path / "clean" / "scene_1.png").unlink()
    (tmp_path / "labels" / "scene_0.json").unlink()
    ds = uwnr.PairDataset(tmp_path)
    with pytest.raises(FileNotFoundError, match=r"clean[/\\]scene_1\.png"):
        ds[1]
    with pytest.raises(FileNotFoundError, match=r"labels[/\\]scene_0\.json"):
        ds[0]
    (tmp_path / "labels" / "scene_1.json").write_text('{"annotations": [{"bbox": [1, 2]}]}')
    with pytest.raises(ValueError, match=r"scene_1\.json: annotation 0"):
        uwnr.PairDataset(tmp_path, images=())[1]


def test_a_yolo_line_of_the_wrong_length_names_the_line(tmp_path):
    make_folder(tmp_path, "yolo")
    (tmp_path / "labels" / "scene_0.txt").write_text("1 0.5 0.5 0.1 0.1\n3 0.1 0.2 0.3\n")
    with pytest.raises(ValueError, match=r"scene_0\.txt:2"):
        uwnr.PairDataset(tmp_path)[0]


def test_masks_without_pillow_say_what_to_install(tmp_path, monkeypatch):
    make_folder(tmp_path, "coco")
    monkeypatch.setitem(__import__("sys").modules, "PIL", None)
    ds = uwnr.PairDataset(tmp_path)
    with pytest.raises(ImportError, match="pip install pillow"):
        ds[0]
    # Everything else is read by uwnr's own decoder.
    item = uwnr.PairDataset(tmp_path, images=("underwater", "clean", "depth"))[0]
    assert item["depth"].dtype == np.uint16


def test_a_dataloader_takes_the_reader_as_it_is(tmp_path):
    torch = pytest.importorskip("torch", reason="torch is not installed")
    written = make_folder(tmp_path, "coco")
    loader = torch.utils.data.DataLoader(uwnr.PairDataset(tmp_path), batch_size=None)
    items = list(loader)
    assert len(items) == 2
    first = items[0]
    assert isinstance(first["underwater"], torch.Tensor) and first["underwater"].shape == (H, W, 3)
    assert torch.equal(first["underwater"], torch.from_numpy(written["scene_0"]["underwater"]))
    assert torch.equal(first["boxes"], torch.tensor(COCO_XYXY))
    assert first["id"] == "scene_0"


def test_webdataset_urls_lists_the_shards(tmp_path):
    written = make_folder(tmp_path, "coco", names=("scene_0",))
    shards = tmp_path / "webdataset"
    shards.mkdir()
    record = written["scene_0"]["record"]
    key = f"{record['index']:08d}-{record['id'].replace('.', '_')}"
    with tarfile.open(shards / "uwnr-000000.tar", "w") as tar:
        for suffix, path in [
            ("underwater.png", "underwater/scene_0.png"),
            ("clean.png", "clean/scene_0.png"),
            ("labels.json", "labels/scene_0.json"),
        ]:
            tar.add(tmp_path / path, arcname=f"{key}.{suffix}")
        (tmp_path / "line.json").write_text(json.dumps(record))
        tar.add(tmp_path / "line.json", arcname=f"{key}.json")
    index = {
        "shards": [{"file": "uwnr-000000.tar", "pairs": 1, "bytes": 0}],
        "pairs": 1,
        "pattern": "uwnr-{000000..000000}.tar",
    }
    (shards / "index.json").write_text(json.dumps(index))
    urls = uwnr.webdataset_urls(tmp_path)
    assert urls == [str(shards / "uwnr-000000.tar")]
    with pytest.raises(FileNotFoundError, match="--format webdataset"):
        uwnr.webdataset_urls(tmp_path / "underwater")
    wds = pytest.importorskip("webdataset", reason="webdataset is not installed")
    samples = list(wds.WebDataset(urls, shardshuffle=False).decode("rgb8"))
    assert len(samples) == 1 and samples[0]["__key__"] == key
    np.testing.assert_array_equal(samples[0]["underwater.png"], written["scene_0"]["underwater"])
    assert samples[0]["json"]["id"] == "scene_0"
