"""The GAN baseline (method "uwgan"): the command line's pixels, seeds, no reference, errors."""

import numpy as np
import pytest
from PIL import Image

import uwnr
from conftest import gradient, read_png, run_cli, water


@pytest.fixture(scope="module")
def gan():
    if not uwnr.HAS_BUNDLED_GAN:
        pytest.skip("this build has no bundled UWGAN generator")
    return uwnr.Renderer(method="uwgan", seed=7)


def test_renders_as_the_cli_writes(cli, gan, tmp_path):
    cleans = [gradient(40, 56, seed=s) for s in range(3)]
    src = tmp_path / "cleans"
    src.mkdir()
    for i, c in enumerate(cleans):
        Image.fromarray(c).save(src / f"c{i}.png")
    out = tmp_path / "out"
    run_cli(cli, "render", src, "--method", "uwgan", "--seed", 7, "--output", out)
    for i, g in enumerate(gan.render_batch(cleans)):
        assert np.array_equal(g, read_png(out / f"c{i}.png")), i


def test_seeds_choose_the_water_and_references_are_not_read(gan):
    clean = gradient(48, 64)
    a = gan.render(clean)
    assert a.shape == clean.shape and a.dtype == np.uint8
    assert np.array_equal(a, gan.render(clean))
    assert np.array_equal(a, gan.render(clean, water(30, 30)))
    assert not np.array_equal(a, gan.render(clean, seed=8))
    assert not np.array_equal(a, gan.render(clean, index=1))
    assert gan.method == "uwgan" and gan.source == "bundled UWGAN model"
    assert gan.light_field_map is None


def test_depth_changes_the_render(gan):
    clean = gradient(48, 64)
    near = gan.render(clean, depth=np.zeros((48, 64), np.float32))
    far = gan.render(clean, depth=np.ones((48, 64), np.float32))
    assert np.abs(near.astype(float) - far).mean() > 1.0


def test_bad_options_and_weights_are_refused(tmp_path):
    with pytest.raises(ValueError, match="does not apply to method uwgan"):
        uwnr.Renderer(method="uwgan", water_type="3C")
    with pytest.raises(FileNotFoundError):
        uwnr.Renderer(method="uwgan", weights=tmp_path / "missing.safetensors")
    bad = tmp_path / "bad.safetensors"
    bad.write_bytes(b"not safetensors")
    with pytest.raises(uwnr.Error):
        uwnr.Renderer(method="uwgan", weights=bad)
