"""Rendering: the same pixels as the command line, every method, dtypes, shapes and threads."""

import subprocess
from concurrent.futures import ThreadPoolExecutor

import numpy as np
import pytest
from PIL import Image

import uwnr
from conftest import gradient, read_png, run_cli, water


@pytest.fixture(scope="module")
def pngs(tmp_path_factory):
    d = tmp_path_factory.mktemp("inputs")
    clean, ref = gradient(72, 104), water(60, 80)
    Image.fromarray(clean).save(d / "clean.png")
    Image.fromarray(ref).save(d / "ref.png")
    return d, clean, ref


def test_uint8_arrays_render_as_the_cli_writes(cli, network, pngs, tmp_path):
    d, clean, ref = pngs
    out = tmp_path / "out.png"
    run_cli(cli, "render", d / "clean.png", "--reference", d / "ref.png", "--output", out)
    expected = read_png(out)
    got = network.render(clean, ref)
    assert got.dtype == np.uint8 and got.shape == expected.shape
    assert np.array_equal(got, expected), np.abs(got.astype(int) - expected).max()


def test_file_paths_render_as_the_cli_writes(cli, network, samples, tmp_path):
    out = tmp_path / "statues.png"
    clean, ref = samples / "clean-statues.jpg", samples / "ref-blue.jpg"
    run_cli(cli, "render", clean, "--reference", ref, "--output", out)
    got = network.render(clean, ref)
    assert np.array_equal(got, read_png(out))


@pytest.mark.parametrize("method", ["jerlov", "uisa", "seathru", "reinhard", "haze"])
def test_baselines_render_as_the_cli_writes(cli, pngs, tmp_path, method):
    d, clean, ref = pngs
    out = tmp_path / f"{method}.png"
    run_cli(
        cli, "render", d / "clean.png", "--reference", d / "ref.png", "--output", out,
        "--method", method, "--seed", 11,
    )
    got = uwnr.Renderer(method=method, seed=11).render(clean, ref)
    assert np.array_equal(got, read_png(out))


def test_bf16_is_refused_where_no_network_runs_as_the_cli_refuses_it(cli, network, pngs, tmp_path):
    # The bundled model runs no network (its correction is none): bf16 products would do nothing.
    d, clean, ref = pngs
    out = tmp_path / "bf16.png"
    proc = subprocess.run(
        [str(cli), "render", d / "clean.png", "--reference", d / "ref.png", "--output", out,
         "--precision", "bf16"], capture_output=True, text=True)
    assert proc.returncode != 0 and "runs none" in proc.stderr, proc.stderr
    assert not out.exists()
    with pytest.raises(ValueError, match="runs none"):
        uwnr.Renderer(precision="bf16")
    with pytest.raises(ValueError, match="f64"):
        uwnr.Renderer(precision="f64")
    with pytest.raises(ValueError, match="unknown device 'flex'"):
        uwnr.Renderer(precision="bf16", device="flex")


def test_reference_use_comes_from_the_method():
    assert uwnr.Renderer(method="jerlov").reference_use == "ignored"
    assert uwnr.Renderer(method="haze").reference_use == "ignored"
    assert uwnr.Renderer(method="reinhard").reference_use == "required"
    assert uwnr.Renderer(method="seathru").reference_use == "optional"
    sampled = uwnr.Renderer(method="seathru", coefficients={"mode": "sampled"})
    assert sampled.reference_use == "ignored"


def test_a_batch_draws_item_i_as_the_cli_does(cli, pngs, tmp_path):
    d, _, ref = pngs
    cleans = [gradient(40, 56, seed=s) for s in range(3)]
    src = tmp_path / "cleans"
    src.mkdir()
    for i, c in enumerate(cleans):
        Image.fromarray(c).save(src / f"c{i}.png")
    out = tmp_path / "out"
    run_cli(cli, "render", src, "--reference", d / "ref.png", "--output", out,
            "--method", "jerlov", "--seed", 5)
    got = uwnr.Renderer(method="jerlov", seed=5).render_batch(cleans, ref)
    for i, g in enumerate(got):
        assert np.array_equal(g, read_png(out / f"c{i}.png")), i


def test_lightfield_is_the_map_the_cli_writes(cli, pngs, tmp_path):
    d, _, ref = pngs
    for m in uwnr.LIGHT_FIELD_MAPS:
        out = tmp_path / f"lf-{m}.png"
        run_cli(cli, "lightfield", d / "ref.png", "--output", out, "--map", m)
        lf = uwnr.lightfield(ref, map=m)
        assert lf.shape == (256, 256, 3) and lf.dtype == np.float32
        assert np.array_equal(np.floor(lf * 255 + 0.5).astype(np.uint8), read_png(out))


def test_the_bundled_model_reproduces_the_golden_render(network, samples):
    golden = samples.parent / "golden" / "statues-blue.png"
    got = network.render(samples / "clean-statues.jpg", samples / "ref-blue.jpg")
    diff = np.abs(got.astype(int) - read_png(golden))
    assert diff.max() <= 3 and diff.mean() <= 0.1


@pytest.mark.parametrize("method", uwnr.METHODS)
def test_every_method_renders_a_changed_image_of_the_same_size(network, method):
    if method == "uwgan" and not uwnr.HAS_BUNDLED_GAN:
        pytest.skip("this build has no bundled UWGAN generator")
    clean, ref = gradient(48, 64), water(50, 50)
    r = network if method == "uwnr" else uwnr.Renderer(method=method, seed=3)
    out = r.render(clean, ref)
    assert out.shape == clean.shape and out.dtype == np.uint8
    assert np.abs(out.astype(float) - clean).mean() > 2.0
    assert r.method == method


def test_float_inputs_give_float_outputs_matching_uint8(network):
    clean, ref = gradient(48, 48), water(48, 48)
    u8 = network.render(clean, ref)
    f32 = network.render(clean.astype(np.float32) / 255, ref)
    assert f32.dtype == np.float32 and 0 <= f32.min() and f32.max() <= 1
    assert np.array_equal(np.floor(f32 * 255 + 0.5).astype(np.uint8), u8)
    f64 = network.render(clean.astype(np.float64) / 255, ref)
    assert f64.dtype == np.float64
    u16 = network.render(clean.astype(np.uint16) * 257, ref)
    assert u16.dtype == np.uint16
    assert np.abs(u16 / 257.0 - u8).max() <= 1.0


def test_grey_and_rgba_inputs(network):
    clean, ref = gradient(40, 40), water(40, 40)
    grey = clean[:, :, 1]
    out = network.render(grey, ref)
    assert out.shape == (40, 40, 3)
    assert np.array_equal(out, network.render(np.repeat(grey[:, :, None], 3, axis=2), ref))
    rgba = np.concatenate([clean, np.full((40, 40, 1), 7, np.uint8)], axis=2)
    assert np.array_equal(network.render(rgba, ref), network.render(clean, ref))


@pytest.mark.parametrize("shape", [(17, 23), (33, 80), (1, 5)])
def test_any_size_renders_at_its_own_size(network, shape):
    clean = gradient(*shape)
    out = network.render(clean, water(30, 30))
    assert out.shape == clean.shape


def test_pil_in_pil_out(network):
    clean = Image.fromarray(gradient(40, 60))
    out = network.render(clean, Image.fromarray(water(40, 40)))
    assert isinstance(out, Image.Image) and out.size == clean.size and out.mode == "RGB"


def test_a_reference_object_equals_the_array_it_holds(network):
    clean, ref = gradient(40, 40), water(64, 48)
    r = uwnr.Reference(ref)
    assert (r.width, r.height) == (48, 64)
    assert np.array_equal(network.render(clean, r), network.render(clean, ref))
    assert np.array_equal(r.light_field("absolute"), uwnr.lightfield(ref))
    flat = r.light_field("global")
    assert flat.shape == (256, 256, 3)
    assert np.all(flat == flat[0, 0]), "one value per channel"
    assert np.allclose(flat[0, 0], r.light_field("absolute").mean(axis=(0, 1)), atol=3 / 255)


def test_depth_maps_are_used_and_resized(network):
    clean, ref = gradient(40, 40), water(40, 40)
    jerlov = uwnr.Renderer(method="jerlov", seed=1, water_type="3C")
    near = jerlov.render(clean, None, np.zeros((40, 40), np.float32))
    far = jerlov.render(clean, None, np.ones((40, 40), np.float32))
    assert np.abs(near.astype(float) - far).mean() > 10
    small = jerlov.render(clean, None, np.ones((10, 10), np.float32))
    assert np.array_equal(small, far)
    assert network.render(clean, ref, np.full((40, 40), 128, np.uint8)).shape == clean.shape
    prior = uwnr.depth(clean)
    assert prior.shape == (40, 40) and prior.dtype == np.float32
    assert np.array_equal(jerlov.render(clean, None, prior), jerlov.render(clean))


def test_metric_depth_renders_as_the_cli_does(cli, network, pngs, tmp_path):
    d, clean, ref = pngs
    h, w = clean.shape[:2]
    # 16-bit millimetres, 1 m at the bottom to 6 m at the top, with a hole.
    mm = np.tile(np.linspace(6000, 1000, h, dtype=np.float64)[:, None], (1, w)).astype(np.uint16)
    mm[0, 0] = 0
    Image.fromarray(mm).save(d / "mm.png")
    out = tmp_path / "out.png"
    run_cli(
        cli, "render", d / "clean.png", "--reference", d / "ref.png",
        "--depth", d / "mm.png", "--depth-unit", "mm", "--output", out,
    )
    got = network.render(clean, ref, mm, depth_unit="mm")
    assert np.abs(got.astype(int) - read_png(out)).max() <= 1
    # Metres are millimetres / 1000.
    metres = network.render(clean, ref, mm.astype(np.float32) / 1000, depth_unit="m")
    assert np.abs(metres.astype(int) - got).max() <= 1


def test_depth_units_change_the_render_as_water_would(network):
    clean, ref = gradient(64, 64), water(64, 64)
    ramp = np.tile(np.linspace(1, 0, 64, dtype=np.float32)[:, None], (1, 64))
    relative = network.render(clean, ref, ramp, depth_unit="relative")
    flipped = network.render(clean, ref, ramp[::-1].copy(), depth_unit="relative")
    assert relative.shape == clean.shape

    def contrast(img, rows):
        return float(img[rows].astype(float).std(axis=(0, 1)).mean())

    # Trusted: the same rows keep less contrast when they are far (top of `ramp`) than when
    # they are near (top of the flipped ramp), and the other way round at the bottom.
    top, bottom = slice(0, 16), slice(48, 64)
    assert contrast(relative, top) < contrast(flipped, top)
    assert contrast(relative, bottom) > contrast(flipped, bottom)
    # A whole scene farther than the reference's 3 m keeps less contrast than one nearer.
    near = network.render(clean, ref, np.full((64, 64), 1.0, np.float32), depth_unit="m")
    far = network.render(clean, ref, np.full((64, 64), 8.0, np.float32), depth_unit="m")
    assert contrast(far, slice(None)) < contrast(near, slice(None))
    with pytest.raises(ValueError, match="depth_unit"):
        network.render(clean, ref, ramp, depth_unit="furlongs")
    with pytest.raises(ValueError, match="no measured"):
        network.render(clean, ref, np.zeros((64, 64), np.float32), depth_unit="m")
    with pytest.raises(ValueError, match="negative"):
        network.render(clean, ref, -ramp, depth_unit="m")
    with pytest.raises(ValueError, match="scene scale"):
        uwnr.Renderer(scene_scale=-1)
    with pytest.raises(ValueError, match="option"):
        uwnr.Renderer(depth_scale=3)


def test_seeds_draw_the_baselines_parameters():
    clean = gradient(32, 32)
    r = uwnr.Renderer(method="jerlov", seed=4)
    a, b = r.render(clean), r.render(clean)
    assert np.array_equal(a, b)
    assert not np.array_equal(a, r.render(clean, seed=5))
    assert not np.array_equal(a, r.render(clean, index=1))
    assert np.array_equal(r.render(clean, index=1), uwnr.Renderer(method="jerlov", seed=4).render_batch([clean, clean])[1])


def test_method_options_reach_the_baseline():
    clean, ref = gradient(32, 32), water(32, 32)
    full = uwnr.Renderer(method="reinhard").render(clean, ref)
    mean_only = uwnr.Renderer(method="reinhard", match_std=False).render(clean, ref)
    assert not np.array_equal(full, mean_only)
    given = uwnr.Renderer(
        method="seathru",
        coefficients={"mode": "given", "beta_d": [0.4, 0.1, 0.05], "beta_b": [0.4, 0.1, 0.05],
                      "b_inf": [0.05, 0.3, 0.4]},
    )
    assert given.render(clean).shape == clean.shape


def test_a_balance_following_the_water_renders_as_the_cli_does(cli, pngs, tmp_path):
    d, clean, ref = pngs
    config = tmp_path / "follow.json"
    config.write_text('{"method": "uwnr", "balance_water_share": 0.325}')
    out = tmp_path / "follow.png"
    run_cli(cli, "render", d / "clean.png", "--reference", d / "ref.png", "--output", out,
            "--method-config", config)
    follows = uwnr.Renderer(method="uwnr", balance_water_share=0.325)
    got = follows.render(clean, ref)
    assert np.array_equal(got, read_png(out))
    assert not np.array_equal(got, uwnr.Renderer(method="uwnr").render(clean, ref))
    # A reference object keeps its chromaticity: the second render is the first.
    r = uwnr.Reference(ref)
    assert np.array_equal(follows.render(clean, r), got)
    assert np.array_equal(follows.render(clean, r), got)


def test_render_batch_equals_single_renders(network):
    cleans = [gradient(32, 40, seed=s) for s in range(4)]
    refs = [water(32, 32, seed=s) for s in range(2)]
    batch = network.render_batch(cleans, refs)
    for i, out in enumerate(batch):
        # Item i draws its particles from item i's seed, as a single render of index i does.
        assert np.array_equal(out, network.render(cleans[i], refs[i % 2], index=i))
    assert network.render_batch([]) == []


def test_one_renderer_shared_by_threads(network):
    clean, ref = gradient(48, 48), water(48, 48)
    expected = network.render(clean, ref)
    with ThreadPoolExecutor(4) as pool:
        outs = list(pool.map(lambda _: network.render(clean, ref), range(8)))
    for out in outs:
        assert np.array_equal(out, expected)


def test_properties(network):
    assert network.source == "bundled model"
    assert network.light_field_map == "absolute"
    assert uwnr.Renderer(method="jerlov").light_field_map is None
    assert "jerlov" in repr(uwnr.Renderer(method="jerlov"))


def test_the_package_renders_on_the_engine_only(network):
    # The package is the render wing: no training framework, so no burn device. The engine's
    # parity with burn's module is checked in the Rust tests of the training wing (uwnr-train).
    assert uwnr.DEVICES == ("engine",)
    clean, ref = gradient(40, 56), water(40, 40)
    engine = uwnr.Renderer(device="engine")
    assert np.array_equal(engine.render(clean, ref), network.render(clean, ref))
    with pytest.raises(ValueError, match="unknown device 'flex'"):
        uwnr.Renderer(device="flex")
