"""UnderwaterAugment: probability, reproducibility, types and references."""

import numpy as np
import pytest
from PIL import Image

import uwnr
from conftest import gradient, water

X = gradient(40, 40)
REFS = [water(40, 40, rgb=(20, 90, 160), seed=3), water(40, 40, seed=4)]


def test_p_zero_returns_the_input_and_p_one_always_renders():
    never = uwnr.UnderwaterAugment(REFS, methods=["reinhard"], p=0.0)
    assert all(never(X) is X for _ in range(5))
    always = uwnr.UnderwaterAugment(REFS, methods=["reinhard"], p=1.0)
    for _ in range(5):
        out = always(X)
        assert out.shape == X.shape and not np.array_equal(out, X)


def test_the_same_seed_gives_the_same_stream_and_another_seed_another():
    def stream(seed):
        aug = uwnr.UnderwaterAugment(REFS, methods=["jerlov", "reinhard"], p=0.7, seed=seed)
        return [aug(X) for _ in range(8)]

    a, b, c = stream(1), stream(1), stream(2)
    assert all(np.array_equal(x, y) for x, y in zip(a, b))
    assert not all(np.array_equal(x, y) for x, y in zip(a, c))


def test_reseed_restarts_the_stream():
    aug = uwnr.UnderwaterAugment(REFS, methods=["jerlov"], p=1.0, seed=0)
    aug.reseed(77)
    first = [aug(X) for _ in range(3)]
    aug.reseed(77)
    assert all(np.array_equal(x, aug(X)) for x in first)


def test_methods_and_references_are_all_drawn():
    aug = uwnr.UnderwaterAugment(REFS, methods=["jerlov", "reinhard", "uisa"], p=1.0, seed=5)
    outs = {aug(X).tobytes() for _ in range(12)}
    assert len(outs) >= 6


def test_types_are_kept(network):
    aug = uwnr.UnderwaterAugment(REFS, methods=["uwnr"], p=1.0)
    assert aug(X).dtype == np.uint8
    f = aug(X.astype(np.float32) / 255)
    assert f.dtype == np.float32 and f.shape == X.shape
    pil = aug(Image.fromarray(X))
    assert isinstance(pil, Image.Image) and pil.size == (40, 40)


def test_torch_tensors_are_kept():
    torch = pytest.importorskip("torch")
    aug = uwnr.UnderwaterAugment(REFS, methods=["jerlov"], p=1.0)
    t = torch.from_numpy(X).permute(2, 0, 1).float() / 255
    out = aug(t)
    assert isinstance(out, torch.Tensor) and out.shape == t.shape and out.dtype == t.dtype
    u8 = aug(torch.from_numpy(X).permute(2, 0, 1).contiguous())
    assert u8.dtype == torch.uint8


def test_a_folder_of_references(tmp_path):
    for i, r in enumerate(REFS):
        Image.fromarray(r).save(tmp_path / f"r{i}.png")
    (tmp_path / "notes.txt").write_text("not an image")
    aug = uwnr.UnderwaterAugment(tmp_path, methods=["reinhard"], p=1.0)
    assert "references=2" in repr(aug)
    assert aug(X).shape == X.shape
    empty = tmp_path / "empty"
    empty.mkdir()
    with pytest.raises(ValueError, match="no images"):
        uwnr.UnderwaterAugment(empty)
    with pytest.raises(FileNotFoundError):
        uwnr.UnderwaterAugment(tmp_path / "missing")


def test_options_are_checked_when_the_augmentation_is_made():
    with pytest.raises(ValueError, match="unknown method"):
        uwnr.UnderwaterAugment(REFS, methods=["watergan"])
    with pytest.raises(ValueError, match="p must"):
        uwnr.UnderwaterAugment(REFS, p=1.5)
    with pytest.raises(ValueError, match="water_typ"):
        uwnr.UnderwaterAugment(REFS, methods=["jerlov"], method_options={"jerlov": {"water_typ": "3C"}})
    aug = uwnr.UnderwaterAugment(
        REFS, methods=["jerlov"], p=1.0, method_options={"jerlov": {"water_type": "9C"}}
    )
    assert aug(X).shape == X.shape


def test_a_given_depth_is_used():
    aug_near = uwnr.UnderwaterAugment(REFS, methods=["jerlov"], p=1.0, seed=1)
    aug_far = uwnr.UnderwaterAugment(REFS, methods=["jerlov"], p=1.0, seed=1)
    near = aug_near(X, depth=np.zeros((40, 40), np.float32))
    far = aug_far(X, depth=np.ones((40, 40), np.float32))
    assert np.abs(near.astype(float) - far).mean() > 5
