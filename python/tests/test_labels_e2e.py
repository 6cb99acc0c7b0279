"""Labelled datasets end to end: `uwnr dataset --coco/--masks/--yolo --format webdataset` written
by the command line, then read by the libraries people use (pycocotools, webdataset) and by
`uwnr.PairDataset`. Each test skips, visibly, when its library or the binary is absent."""

import json
import subprocess

import numpy as np
import pytest
from PIL import Image, ImageDraw

import uwnr
from conftest import gradient

# Two clean images and their objects: (name, width, height, [(category, polygon)]).
IMAGES = [
    ("harbour", 120, 80, [(1, [20, 10, 60, 12, 64, 50, 24, 56]), (2, [70, 40, 110, 30, 116, 76, 76, 70])]),
    ("reef", 90, 90, [(1, [5, 5, 40, 8, 35, 45, 8, 40]), (2, [50, 50, 85, 52, 80, 85, 55, 88])]),
]


def _polygon_mask(w, h, poly):
    img = Image.new("L", (w, h), 0)
    ImageDraw.Draw(img).polygon(poly, fill=1)
    return np.asarray(img, dtype=np.uint8)


@pytest.fixture(scope="module")
def labelled(tmp_path_factory):
    """A clean folder, references, a COCO file (polygons, plus one compressed-RLE object per
    image: the second) and instance masks (value = object number) of the same objects."""
    mask_api = pytest.importorskip("pycocotools.mask", reason="pycocotools is not installed")
    root = tmp_path_factory.mktemp("labelled")
    clean, refs, masks = root / "clean", root / "refs", root / "masks"
    for d in (clean, refs, masks):
        d.mkdir()
    images, annotations = [], []
    for n, (name, w, h, objects) in enumerate(IMAGES):
        Image.fromarray(gradient(h, w, seed=n)).save(clean / f"{name}.png")
        instance = np.zeros((h, w), np.uint8)
        images.append({"id": 10 + n, "file_name": f"{name}.png", "width": w, "height": h})
        for k, (cat, poly) in enumerate(objects):
            m = _polygon_mask(w, h, poly)
            instance[m > 0] = k + 1
            ann = {"id": 100 * (n + 1) + k, "image_id": 10 + n, "category_id": cat, "iscrowd": 0}
            if k == 1:
                rle = mask_api.encode(np.asfortranarray(m))
                ann["segmentation"] = {"size": rle["size"], "counts": rle["counts"].decode()}
                ann["bbox"] = [float(v) for v in mask_api.toBbox(rle)]
                ann["area"] = float(mask_api.area(rle))
            else:
                xs, ys = poly[0::2], poly[1::2]
                ann["segmentation"] = [poly]
                ann["bbox"] = [min(xs), min(ys), max(xs) - min(xs), max(ys) - min(ys)]
                ann["area"] = float(m.sum())
            annotations.append(ann)
        Image.fromarray(instance).save(masks / f"{name}.png")
    for j, rgb in enumerate([(20, 120, 130), (30, 140, 90)]):
        Image.fromarray(np.full((40, 50, 3), rgb, np.uint8)).save(refs / f"r{j}.png")
    coco = root / "instances.json"
    categories = [{"id": 1, "name": "fish"}, {"id": 2, "name": "rock"}]
    coco.write_text(json.dumps({"images": images, "annotations": annotations, "categories": categories}))
    return {"clean": clean, "refs": refs, "masks": masks, "coco": coco, "root": root}


@pytest.fixture(scope="module")
def made(labelled, request):
    """The dataset made from `labelled` at 64x48 (a crop for both images), 2 renders each, with
    WebDataset shards."""
    cli = request.getfixturevalue("cli")
    out = labelled["root"] / "out"
    cmd = [
        str(cli), "dataset", "--clean", str(labelled["clean"]), "--references", str(labelled["refs"]),
        "--coco", str(labelled["coco"]), "--masks", str(labelled["masks"]), "--method", "reinhard",
        "-k", "2", "--size", "64x48", "--format", "webdataset", "--no-gallery", "-o", str(out),
    ]
    done = subprocess.run(cmd, capture_output=True, text=True)
    assert done.returncode == 0, done.stderr
    return out


def test_pycocotools_reads_the_file_and_masks_match(made):
    coco_mod = pytest.importorskip("pycocotools.coco", reason="pycocotools is not installed")
    coco = coco_mod.COCO(str(made / "coco.json"))
    assert len(coco.getImgIds()) == 4
    assert sorted(c["name"] for c in coco.loadCats(coco.getCatIds())) == ["fish", "rock"]
    checked_rle = checked_poly = 0
    for img in coco.loadImgs(coco.getImgIds()):
        assert (img["width"], img["height"]) == (64, 48)
        pair = img["file_name"].split("/")[-1][: -len(".png")]
        written = np.asarray(Image.open(made / "masks" / f"{pair}.png"))
        assert written.shape == (48, 64)
        for ann in coco.loadAnns(coco.getAnnIds(imgIds=img["id"])):
            k = ann["category_id"] - 1  # object k of each image has category k + 1
            m = coco.annToMask(ann)
            assert m.shape == (48, 64)
            expected = written == k + 1
            if isinstance(ann["segmentation"], dict):
                # RLE resized with the mask's own nearest-neighbour rule: identical.
                assert isinstance(ann["segmentation"]["counts"], str)
                np.testing.assert_array_equal(m.astype(bool), expected)
                assert ann["area"] == expected.sum()
                checked_rle += 1
            else:
                # A scaled polygon rasterised again against the resized mask: the same shape.
                iou = (m.astype(bool) & expected).sum() / (m.astype(bool) | expected).sum()
                assert iou > 0.8, (pair, ann["id"], iou)
                checked_poly += 1
            x, y, w, h = ann["bbox"]
            ys, xs = np.nonzero(expected)
            assert abs(x - xs.min()) <= 1.5 and abs(x + w - xs.max() - 1) <= 1.5, (ann["bbox"], pair)
            assert abs(y - ys.min()) <= 1.5 and abs(y + h - ys.max() - 1) <= 1.5, (ann["bbox"], pair)
    assert checked_rle >= 2 and checked_poly >= 2


def test_webdataset_reads_the_shards(made):
    wds = pytest.importorskip("webdataset", reason="webdataset is not installed")
    urls = uwnr.webdataset_urls(made)
    samples = list(wds.WebDataset(urls, shardshuffle=False, empty_check=False))
    assert len(samples) == 4
    manifest = [json.loads(line) for line in (made / "manifest.jsonl").read_text().splitlines()]
    for sample, record in zip(samples, manifest):
        assert json.loads(sample["json"]) == record
        assert sample["underwater.png"] == (made / record["underwater"]).read_bytes()
        assert sample["clean.png"] == (made / record["clean"]).read_bytes()
        assert sample["mask.png"] == (made / record["mask"]).read_bytes()
        assert json.loads(sample["labels.json"]) == json.loads((made / record["labels"]).read_text())
    # Decoded as images by the library's own handlers.
    decoded = next(iter(wds.WebDataset(urls, shardshuffle=False, empty_check=False).decode("rgb8")))
    assert decoded["underwater.png"].shape == (48, 64, 3)


def test_pair_dataset_gives_the_coco_boxes(made):
    ds = uwnr.PairDataset(made)
    assert len(ds) == 4
    coco = json.loads((made / "coco.json").read_text())
    for item in ds:
        image = next(i for i in coco["images"] if i["file_name"] == item["record"]["underwater"])
        anns = [a for a in coco["annotations"] if a["image_id"] == image["id"]]
        xyxy = np.array([[x, y, x + w, y + h] for x, y, w, h in (a["bbox"] for a in anns)], np.float32)
        np.testing.assert_allclose(item["boxes"], xyxy.reshape(-1, 4))
        assert item["underwater"].shape == (48, 64, 3) and item["mask"].shape == (48, 64)


def test_yolo_labels_through_the_cli(labelled, cli, tmp_path):
    """YOLO files made from the same objects: written per pair, renormalised after the crop, and
    their boxes land where the masks say."""
    yolo = tmp_path / "yolo"
    yolo.mkdir()
    for name, w, h, objects in IMAGES:
        lines = []
        for cat, poly in objects:
            xs, ys = poly[0::2], poly[1::2]
            cx, cy = (min(xs) + max(xs)) / 2 / w, (min(ys) + max(ys)) / 2 / h
            lines.append(f"{cat - 1} {cx} {cy} {(max(xs) - min(xs)) / w} {(max(ys) - min(ys)) / h}")
        (yolo / f"{name}.txt").write_text("\n".join(lines) + "\n")
    out = tmp_path / "out"
    cmd = [
        str(cli), "dataset", "--clean", str(labelled["clean"]), "--references", str(labelled["refs"]),
        "--yolo", str(yolo), "--masks", str(labelled["masks"]), "--method", "reinhard",
        "--size", "64x48", "--no-gallery", "-o", str(out),
    ]
    done = subprocess.run(cmd, capture_output=True, text=True)
    assert done.returncode == 0, done.stderr
    for item in uwnr.PairDataset(out):
        assert item["boxes"].shape[1] == 4 and len(item["boxes"]) >= 1
        for box, cls in zip(item["boxes"], item["classes"]):
            cx, cy = int((box[0] + box[2]) / 2), int((box[1] + box[3]) / 2)
            assert 0 <= cx < 64 and 0 <= cy < 48
        assert (out / item["record"]["labels"]).suffix == ".txt"


def test_readme_example_with_the_bundled_samples(samples, cli, tmp_path):
    """The labelled example of docs/datasets.md ("Labels: COCO, YOLO, masks"): the bundled COCO file
    of the sample images, rendered, then loaded with pycocotools."""
    coco_mod = pytest.importorskip("pycocotools.coco", reason="pycocotools is not installed")
    out = tmp_path / "samples-coco"
    cmd = [
        str(cli), "dataset", "--clean", str(samples / "clean-statues.jpg"), str(samples / "clean-room.jpg"),
        "--references", str(samples / "ref-blue.jpg"), str(samples / "ref-green.png"),
        "--coco", str(samples / "coco" / "instances.json"), "--method", "reinhard", "-k", "2",
        "--size", "320x240", "--format", "webdataset", "-o", str(out),
    ]
    done = subprocess.run(cmd, capture_output=True, text=True)
    assert done.returncode == 0, done.stderr
    coco = coco_mod.COCO(str(out / "coco.json"))
    img = coco.loadImgs(coco.getImgIds())[0]
    anns = coco.loadAnns(coco.getAnnIds(imgIds=img["id"]))
    mask = coco.annToMask(anns[0])
    assert mask.shape == (240, 320) and mask.sum() > 0
    assert len(coco.getImgIds()) == 4


def test_webdataset_decoder_keeps_16_bit_mask_values(cli, tmp_path):
    """16-bit instance masks written as WebDataset shards come back with their values through
    `uwnr.webdataset_decoder` (``.decode("rgb8")`` alone would turn them into {0, 255})."""
    wds = pytest.importorskip("webdataset", reason="webdataset is not installed")
    from conftest import gradient, water

    clean, refs, masks = tmp_path / "clean", tmp_path / "refs", tmp_path / "masks"
    for d in (clean, refs, masks):
        d.mkdir()
    Image.fromarray(gradient(48, 64)).save(clean / "a.png")
    Image.fromarray(water(40, 40)).save(refs / "r.png")
    ids = np.zeros((48, 64), np.uint16)
    ids[5:20, 5:30] = 300
    ids[25:45, 30:60] = 65535
    Image.fromarray(ids.astype(np.int32)).convert("I;16").save(masks / "a.png")
    assert np.array_equal(np.asarray(Image.open(masks / "a.png")).astype(np.uint16), ids)
    out = tmp_path / "out"
    cmd = [
        str(cli), "dataset", "--clean", str(clean), "--references", str(refs),
        "--masks", str(masks), "--method", "reinhard", "--format", "webdataset",
        "--no-gallery", "-o", str(out),
    ]
    done = subprocess.run(cmd, capture_output=True, text=True)
    assert done.returncode == 0, done.stderr
    urls = uwnr.webdataset_urls(out)
    sample = next(iter(wds.WebDataset(urls, shardshuffle=False, empty_check=False).decode(
        uwnr.webdataset_decoder, "rgb8")))
    mask = sample["mask.png"]
    assert mask.dtype == np.uint16 and mask.shape == (48, 64)
    assert set(np.unique(mask).tolist()) == {0, 300, 65535}
    assert np.array_equal(mask, ids)
    # Other members still go to the next handler.
    assert sample["underwater.png"].shape == (48, 64, 3)
