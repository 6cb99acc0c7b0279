"""Bad input raises the exception that names the problem, never a crash."""

import struct

import numpy as np
import pytest

import uwnr
from conftest import gradient, water


CLEAN, REF = gradient(32, 32), water(32, 32)


@pytest.mark.parametrize(
    "bad, match",
    [
        (np.zeros(10, np.uint8), "HxW"),
        (np.zeros((2, 8, 8, 3), np.uint8), "HxW"),
        (np.zeros((8, 8, 2), np.uint8), "HxW"),
        (np.zeros((0, 8, 3), np.uint8), "empty"),
        (np.full((8, 8, 3), 1.5, np.float32), r"\[0, 1\]"),
        (np.full((8, 8, 3), -0.1, np.float64), r"\[0, 1\]"),
        (np.full((8, 8, 3), np.nan, np.float32), "NaN"),
        (np.zeros((8, 8, 3), np.int32), "dtype"),
        (np.zeros((8, 8, 3), np.complex64), "dtype"),
    ],
)
def test_bad_images_raise_value_error(network, bad, match):
    with pytest.raises(ValueError, match=match):
        network.render(bad, REF)
    with pytest.raises(ValueError, match=match):
        uwnr.Reference(bad)


def test_objects_that_are_not_images_raise_type_error(network):
    with pytest.raises(TypeError, match="NumPy array"):
        network.render([[1, 2, 3]], REF)
    with pytest.raises(TypeError):
        network.render(CLEAN, 42)


def test_missing_and_corrupt_files(network, tmp_path):
    with pytest.raises(FileNotFoundError, match="does not exist"):
        network.render(tmp_path / "nope.png", REF)
    broken = tmp_path / "broken.png"
    broken.write_bytes(b"\x89PNG\r\n\x1a\n" + b"\x00" * 20)
    with pytest.raises(ValueError, match="not a readable image"):
        network.render(broken, REF)
    truncated = tmp_path / "truncated.jpg"
    truncated.write_bytes(b"\xff\xd8\xff\xe0\x00\x10JFIF\x00")
    with pytest.raises(ValueError, match="truncated|not a readable"):
        uwnr.Reference(truncated)


def test_methods_that_need_a_reference(network):
    with pytest.raises(ValueError, match="needs a reference"):
        network.render(CLEAN)
    for method in ("uisa", "reinhard"):
        with pytest.raises(ValueError, match="needs a reference"):
            uwnr.Renderer(method=method).render(CLEAN)
    # Jerlov never needs one; Sea-thru samples its coefficients without one.
    uwnr.Renderer(method="jerlov").render(CLEAN)
    uwnr.Renderer(method="seathru").render(CLEAN)


def test_bad_options():
    with pytest.raises(ValueError, match="unknown method"):
        uwnr.Renderer(method="uwgan2")
    with pytest.raises(ValueError, match="water_typ"):
        uwnr.Renderer(method="jerlov", water_typ="3C")
    with pytest.raises(ValueError, match="12Z"):
        uwnr.Renderer(method="jerlov", water_type="12Z")
    with pytest.raises(ValueError, match="does not apply to method uwnr"):
        uwnr.Renderer(water_type="3C")
    with pytest.raises(ValueError, match="weights apply only"):
        uwnr.Renderer(method="reinhard", weights="x.safetensors")
    with pytest.raises(ValueError, match="device"):
        uwnr.Renderer(device="cuda")
    with pytest.raises(ValueError, match="tile"):
        uwnr.Renderer(tile=100)
    with pytest.raises(ValueError, match="seed"):
        uwnr.Renderer(seed=-1)
    with pytest.raises(ValueError, match="map"):
        uwnr.lightfield(REF, map="log")


def test_bad_weights(tmp_path):
    with pytest.raises(FileNotFoundError, match="does not exist"):
        uwnr.Renderer(weights=tmp_path / "missing.safetensors")
    junk = tmp_path / "junk.safetensors"
    junk.write_bytes(b"this is not a weights file at all")
    with pytest.raises(uwnr.Error):
        uwnr.Renderer(weights=junk)
    # A well-formed safetensors file whose tensors are not the generator's.
    header = b'{"w":{"dtype":"F32","shape":[2],"data_offsets":[0,8]}}'
    wrong = tmp_path / "wrong.safetensors"
    wrong.write_bytes(struct.pack("<Q", len(header)) + header + b"\x00" * 8)
    with pytest.raises(uwnr.Error, match="wrong.safetensors"):
        uwnr.Renderer(weights=wrong)
    assert issubclass(uwnr.Error, Exception)


def test_bad_depth(network):
    with pytest.raises(ValueError, match="depth"):
        network.render(CLEAN, REF, np.zeros((32, 32, 3), np.float32))
    with pytest.raises(ValueError, match=r"\[0, 1\]"):
        network.render(CLEAN, REF, np.full((32, 32), 2.0, np.float32))


def test_metrics_need_images_of_one_size():
    with pytest.raises(ValueError, match="differ in size"):
        uwnr.metrics.psnr(CLEAN, gradient(16, 16))
    with pytest.raises(ValueError):
        uwnr.metrics.ssim(gradient(5, 5), gradient(5, 5))
