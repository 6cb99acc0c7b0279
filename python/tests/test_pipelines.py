"""UnderwaterAugment inside the pipelines detection and segmentation training uses: torchvision
transforms.v2 (image plus tv_tensors boxes and masks) and Albumentations (an image-only transform
in a Compose with bbox_params). Rendering keeps the geometry, so the labels must come out exactly
as they went in, and flips after the render must move them as the library always does. Each group
skips, with its reason, when its library is not installed."""

import importlib
import pickle
import subprocess
import sys

import numpy as np
import pytest
from PIL import Image

import uwnr

H, W = 48, 64
# Boxes in pixels, [x1, y1, x2, y2] (pascal_voc / torchvision XYXY).
BOXES = [[2.0, 3.0, 30.0, 40.0], [20.5, 10.0, 60.0, 47.0]]
LABELS = [3, 7]


@pytest.fixture(scope="module")
def refs(samples):
    return [samples / "ref-blue.jpg", samples / "ref-green.png"]


@pytest.fixture(scope="module")
def clean(samples):
    """A real photo at a small size, HxWx3 uint8."""
    with Image.open(samples / "clean-room.jpg") as img:
        return np.asarray(img.convert("RGB").resize((W, H), Image.BILINEAR))


def a_mask():
    m = np.zeros((H, W), np.uint8)
    m[3:40, 2:30] = 1
    m[10:47, 21:60] = 2
    return m


def method_params():
    # A fast baseline, and the network (skipped, visibly, in builds without the bundled model).
    return ["reinhard", "uwnr"]


def needs_model(method, request):
    if method == "uwnr":
        request.getfixturevalue("network")


def test_import_uwnr_imports_neither_torch_nor_albumentations():
    code = (
        "import sys, uwnr\n"
        "bad = [m for m in ('torch', 'torchvision', 'albumentations') if m in sys.modules]\n"
        "assert not bad, bad\n"
    )
    subprocess.run([sys.executable, "-c", code], check=True)


# ---- torchvision transforms.v2 -------------------------------------------------------------


@pytest.fixture(scope="module")
def tv():
    torch = pytest.importorskip("torch", reason="torch is not installed")
    pytest.importorskip("torchvision", reason="torchvision is not installed")
    from torchvision import tv_tensors
    from torchvision.transforms import v2

    return torch, tv_tensors, v2


def tv_sample(tv, clean):
    torch, tv_tensors, _ = tv
    image = tv_tensors.Image(torch.from_numpy(clean.copy()).permute(2, 0, 1).contiguous())
    target = {
        "boxes": tv_tensors.BoundingBoxes(BOXES, format="XYXY", canvas_size=(H, W)),
        "masks": tv_tensors.Mask(torch.from_numpy(a_mask())),
        "labels": torch.tensor(LABELS),
    }
    return image, target


@pytest.mark.parametrize("method", method_params())
def test_v2_compose_renders_the_image_and_passes_labels_through(tv, refs, clean, method, request):
    needs_model(method, request)
    torch, tv_tensors, v2 = tv
    image, target = tv_sample(tv, clean)
    pipeline = v2.Compose([uwnr.UnderwaterAugment(refs, methods=[method], p=1.0, seed=0)])
    out_image, out_target = pipeline(image, target)
    assert type(out_image) is tv_tensors.Image
    assert out_image.shape == image.shape and out_image.dtype == image.dtype
    assert (out_image != image).float().mean() > 0.5
    assert out_target.keys() == target.keys()
    for key in target:
        assert out_target[key] is target[key]
    assert torch.equal(out_target["boxes"], torch.tensor(BOXES))


def test_v2_flip_after_the_render_moves_the_labels_as_usual(tv, refs, clean):
    torch, tv_tensors, v2 = tv
    image, target = tv_sample(tv, clean)
    aug = uwnr.UnderwaterAugment(refs, methods=["jerlov", "reinhard"], p=1.0, seed=1)
    out_image, out_target = v2.Compose([aug, v2.RandomHorizontalFlip(p=1.0)])(image, target)
    _, flipped = v2.RandomHorizontalFlip(p=1.0)(image, target)
    assert type(out_target["boxes"]) is tv_tensors.BoundingBoxes
    assert torch.equal(out_target["boxes"], flipped["boxes"])
    assert torch.equal(out_target["boxes"][0], torch.tensor([W - 30.0, 3.0, W - 2.0, 40.0]))
    assert torch.equal(out_target["masks"], target["masks"].flip(-1))
    assert out_target["labels"] is target["labels"]
    # The render is flipped too: flipping it back gives the same image as rendering alone.
    aug.reseed(5)
    alone = aug(image)
    aug.reseed(5)
    out_image, _ = v2.Compose([aug, v2.RandomHorizontalFlip(p=1.0)])(image, target)
    assert torch.equal(out_image.flip(-1), alone)


def test_v2_tuples_of_image_boxes_and_mask_with_a_plain_float_tensor(tv, refs, clean):
    torch, tv_tensors, v2 = tv
    _, target = tv_sample(tv, clean)
    image = torch.from_numpy(clean.copy()).permute(2, 0, 1).float() / 255
    boxes, mask = target["boxes"], target["masks"]
    aug = uwnr.UnderwaterAugment(refs, methods=["reinhard"], p=1.0)
    out = v2.Compose([aug])(image, boxes, mask)
    assert isinstance(out, tuple) and len(out) == 3
    assert type(out[0]) is torch.Tensor and out[0].dtype == torch.float32
    assert out[0].shape == image.shape and not torch.equal(out[0], image)
    assert out[1] is boxes and out[2] is mask
    # One tuple argument, as a Dataset returning (image, target) gives it to Compose.
    out = v2.Compose([aug])((image, target))
    assert isinstance(out, tuple) and out[1]["boxes"] is boxes and not torch.equal(out[0], image)


def test_v2_dict_samples_pil_images_and_arrays(tv, refs, clean):
    torch, tv_tensors, v2 = tv
    _, target = tv_sample(tv, clean)
    aug = uwnr.UnderwaterAugment(refs, methods=["reinhard"], p=1.0)
    # With a PIL image in the sample, a plain label tensor is not taken for the image.
    labels = torch.tensor(LABELS)
    sample = {"image": Image.fromarray(clean), "labels": labels, "boxes": target["boxes"]}
    out = v2.Compose([aug])(sample)
    assert isinstance(out["image"], Image.Image) and out["image"].size == (W, H)
    assert out["labels"] is labels and out["boxes"] is target["boxes"]
    assert not np.array_equal(np.asarray(out["image"]), clean)
    # An HxWx3 array is the image when the sample holds no tensor image.
    out = aug(clean, target["boxes"])
    assert out[0].shape == clean.shape and out[0].dtype == np.uint8 and out[1] is target["boxes"]


def test_v2_p_zero_returns_the_sample_itself_and_one_image_stays_an_image(tv, refs, clean):
    torch, tv_tensors, v2 = tv
    image, target = tv_sample(tv, clean)
    never = uwnr.UnderwaterAugment(refs, methods=["reinhard"], p=0.0)
    out = v2.Compose([never])(image, target)
    assert out[0] is image and out[1] is target
    always = uwnr.UnderwaterAugment(refs, methods=["reinhard"], p=1.0)
    alone = v2.Compose([always])(image)
    assert type(alone) is tv_tensors.Image and alone.shape == image.shape


def test_v2_samples_without_an_image_or_with_a_video_are_refused(tv, refs, clean):
    torch, tv_tensors, v2 = tv
    _, target = tv_sample(tv, clean)
    aug = uwnr.UnderwaterAugment(refs, methods=["reinhard"], p=0.0)
    with pytest.raises(TypeError, match="no image"):
        aug(target["boxes"], target["masks"])
    video = tv_tensors.Video(torch.zeros(2, 3, H, W, dtype=torch.uint8))
    with pytest.raises(TypeError, match="videos"):
        aug(video, target)


# ---- Albumentations -----------------------------------------------------------------------


@pytest.fixture(scope="module")
def A():
    return pytest.importorskip("albumentations", reason="albumentations is not installed")


@pytest.fixture(scope="module")
def AlbuAugment(A):
    from uwnr.albumentations import UnderwaterAugment

    return UnderwaterAugment


def coco_boxes():
    return [[x1, y1, x2 - x1, y2 - y1] for x1, y1, x2, y2 in BOXES]


@pytest.mark.parametrize("fmt", ["pascal_voc", "coco"])
@pytest.mark.parametrize("method", method_params())
@pytest.mark.filterwarnings("ignore:Got processor for bboxes, but no transform to process it")
def test_albumentations_compose_keeps_boxes_and_masks(
    A, AlbuAugment, refs, clean, fmt, method, request
):
    needs_model(method, request)
    boxes = BOXES if fmt == "pascal_voc" else coco_boxes()
    params = dict(bbox_params=A.BboxParams(format=fmt, label_fields=["labels"]), seed=0)
    uw = AlbuAugment(refs, methods=[method], p=1.0)
    out = A.Compose([uw], **params)(image=clean, mask=a_mask(), bboxes=boxes, labels=LABELS)
    # Albumentations round-trips boxes through normalised floats; the render adds nothing to that.
    plain = A.Compose([A.NoOp()], **params)(image=clean, mask=a_mask(), bboxes=boxes, labels=LABELS)
    np.testing.assert_array_equal(out["bboxes"], plain["bboxes"])
    np.testing.assert_allclose(out["bboxes"], boxes, atol=1e-4)
    assert list(out["labels"]) == LABELS
    np.testing.assert_array_equal(out["mask"], a_mask())
    assert out["image"].shape == clean.shape and out["image"].dtype == np.uint8
    assert (out["image"] != clean).mean() > 0.5


def test_albumentations_flip_after_the_render_moves_the_boxes_as_usual(A, AlbuAugment, refs, clean):
    params = dict(bbox_params=A.BboxParams(format="pascal_voc", label_fields=["labels"]), seed=0)
    uw = AlbuAugment(refs, methods=["jerlov", "reinhard"], p=1.0, render_seed=2)
    out = A.Compose([uw, A.HorizontalFlip(p=1.0)], **params)(
        image=clean, mask=a_mask(), bboxes=BOXES, labels=LABELS
    )
    flipped = A.Compose([A.HorizontalFlip(p=1.0)], **params)(
        image=clean, mask=a_mask(), bboxes=BOXES, labels=LABELS
    )
    np.testing.assert_array_equal(out["bboxes"], flipped["bboxes"])
    np.testing.assert_allclose(out["bboxes"][0], [W - 30.0, 3.0, W - 2.0, 40.0], atol=1e-4)
    np.testing.assert_array_equal(out["mask"], a_mask()[:, ::-1])
    assert not np.array_equal(out["image"], flipped["image"])


def test_albumentations_p_is_drawn_by_albumentations(A, AlbuAugment, refs, clean):
    never = AlbuAugment(refs, methods=["reinhard"], p=0.0)
    assert np.array_equal(A.Compose([never])(image=clean)["image"], clean)
    always = AlbuAugment(refs, methods=["reinhard"], p=1.0)
    assert always.augment.p == 1.0
    assert not np.array_equal(A.Compose([always])(image=clean)["image"], clean)


def test_albumentations_transform_pickles_and_describes_itself(A, AlbuAugment, refs, clean):
    def make():
        return AlbuAugment(refs, methods=["jerlov", "reinhard"], p=1.0, render_seed=9)

    uw = make()
    copy = pickle.loads(pickle.dumps(uw))
    assert copy.augment._renderers == {}  # rebuilt on first use, as in a spawned worker
    assert np.array_equal(copy(image=clean)["image"], make()(image=clean)["image"])
    names = uw.get_transform_init_args_names()
    assert set(names) == {
        "references",
        "methods",
        "render_seed",
        "weights",
        "method_options",
        "device",
    }
    d = A.to_dict(uw)["transform"]
    assert d["p"] == 1.0 and d["render_seed"] == 9 and d["methods"] == ["jerlov", "reinhard"]
    assert "render_seed=9" in repr(uw)


def test_the_albumentations_module_says_what_to_install(monkeypatch):
    monkeypatch.setitem(sys.modules, "albumentations", None)  # as if it were not installed
    monkeypatch.delitem(sys.modules, "uwnr.albumentations", raising=False)
    with pytest.raises(ImportError, match="pip install albumentations"):
        importlib.import_module("uwnr.albumentations")
