"""Shared fixtures: small synthetic images, the repository's sample images, and the `uwnr` binary
(for the tests that compare with the command line; they skip, visibly, when it is not built)."""

import os
import shutil
import subprocess
from pathlib import Path

import numpy as np
import pytest
from PIL import Image

ROOT = Path(__file__).resolve().parents[2]
SAMPLES = ROOT / "assets" / "samples"
SHARED_DATA = ROOT.parent / "shared" / "data"


def _find_cli():
    env = os.environ.get("UWNR_BIN")
    if env:
        return Path(env) if Path(env).is_file() else None
    for profile in ("release", "debug"):
        p = ROOT / "target" / profile / "uwnr"
        if p.is_file():
            return p
    found = shutil.which("uwnr")
    return Path(found) if found else None


@pytest.fixture(scope="session")
def cli():
    path = _find_cli()
    if path is None:
        pytest.skip("the uwnr binary is not built (cargo build -p uwnr-cli, or set UWNR_BIN)")
    return path


@pytest.fixture(scope="session")
def samples():
    if not SAMPLES.is_dir():
        pytest.skip(f"sample images not found at {SAMPLES}")
    return SAMPLES


def gradient(h, w, seed=0):
    """A smooth, textured clean-looking RGB image, uint8."""
    rng = np.random.default_rng(seed)
    y, x = np.mgrid[0:h, 0:w].astype(np.float32)
    base = np.stack(
        [0.5 + 0.4 * np.sin(x / 7.0 + seed), 0.5 + 0.4 * np.cos(y / 5.0), (x + y) / (h + w)],
        axis=2,
    )
    noise = rng.normal(0, 0.03, size=base.shape)
    return (np.clip(base + noise, 0, 1) * 255 + 0.5).astype(np.uint8)


def water(h, w, rgb=(30, 140, 120), seed=1):
    """A greenish, hazy 'underwater' reference, uint8."""
    rng = np.random.default_rng(seed)
    y = np.linspace(1.2, 0.6, h, dtype=np.float32)[:, None, None]
    img = np.array(rgb, np.float32)[None, None, :] * y + rng.normal(0, 4, size=(h, w, 3))
    return np.clip(img, 0, 255).astype(np.uint8)


@pytest.fixture(scope="session")
def network():
    import uwnr

    if not uwnr.HAS_BUNDLED_MODEL:
        pytest.skip("this build has no bundled model")
    return uwnr.Renderer()


def run_cli(cli, *args):
    """Runs the `uwnr` binary with `args`; fails the test on a non-zero exit."""
    proc = subprocess.run([str(cli), *map(str, args)], capture_output=True, text=True)
    assert proc.returncode == 0, proc.stderr
    return proc


def read_png(path):
    """An image file as an RGB uint8 array."""
    return np.asarray(Image.open(path).convert("RGB"))
