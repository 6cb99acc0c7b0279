#!/usr/bin/env python3
"""Reference values for uwnr-core's light-field map and the ops it is built from.

Computes, with the real Pillow and OpenCV 4.x:
  * the UWNR released code's `MutiScaleLuminanceEstimation` (myutils/dcp.py) at render time
    (reference -> torchvision Resize([256, 256]) on the PIL image, i.e. PIL BILINEAR -> the
    procedure) and on images at their own size (as in training);
  * PIL `Image.resize(..., BILINEAR)`, `cv2.resize(..., INTER_LINEAR)` with fx/fy and with dsize,
    and `cv2.GaussianBlur(img, (0, 0), sigma)` on uint8 images, individually;
  * `np.log10` of every uint8 value (NumPy evaluates it in float16).

Writes PNG fixtures and JSON manifests to crates/render/uwnr-core/tests/fixtures/{lightfield,ops}/.
Run from the workspace root:

    pip install "opencv-python-headless<5" "pillow<13" numpy
    python3 tools/lightfield_reference.py

Pillow 13 changed `resize` for some size combinations (when one side grows and the other
shrinks it no longer always runs the horizontal pass first), so the fixtures are made with
Pillow 12, whose `ImagingResampleInner` (horizontal pass, then vertical) matches the Pillow the
authors used. To keep another Pillow installed, put 12.x aside and point PYTHONPATH at it:

    pip install --target /tmp/pillow12 "pillow<13"
    PYTHONPATH=/tmp/pillow12 python3 tools/lightfield_reference.py

Sources under ../shared/data are optional: when the folder is absent only the bundled samples
(assets/samples) are used. Paths in the manifests are relative to the workspace root.
"""

import json
import sys
from pathlib import Path

import cv2
import numpy as np
import PIL
from PIL import Image

ROOT = Path(__file__).resolve().parent.parent
FIXTURES = ROOT / "crates" / "render" / "uwnr-core" / "tests" / "fixtures"
SHARED = ROOT.parent / "shared" / "data"
SAMPLES = ROOT / "assets" / "samples"

# Released code constants (myutils/dcp.py, test script).
SIGMA_LIST = [15, 60, 90]
SCALE = 0.3
REFERENCE_SIZE = 256
NUMBER_OF_SHARED_REFERENCES = 12
NUMBER_OF_SHARED_UNDERWATER = 4


def muti_scale_luminance_estimation(img):
    """The released function, verbatim except `np.float` (removed from NumPy) -> `np.float64`."""
    sigma_list = SIGMA_LIST
    w, h, c = img.shape
    img = cv2.resize(img, dsize=None, fx=SCALE, fy=SCALE)
    Luminance = np.ones_like(img).astype(np.float64)
    for sigma in sigma_list:
        L1 = np.log10(cv2.GaussianBlur(img, (0, 0), sigma))
        L1 = np.clip(L1, 0, 255)
        Luminance = Luminance + L1
    Luminance = Luminance / 3
    L = (Luminance - np.min(Luminance)) / (np.max(Luminance) - np.min(Luminance) + 0.0001)
    L = np.uint8(L * 255)
    L = cv2.resize(L, dsize=(h, w))
    return L


def load_rgb(path):
    with Image.open(path) as im:
        return im.convert("RGB")


def render_time_map(path):
    """torchvision Resize([256, 256]) on the PIL image is `img.resize((256, 256), BILINEAR)`."""
    pil = load_rgb(path).resize((REFERENCE_SIZE, REFERENCE_SIZE), Image.BILINEAR)
    return muti_scale_luminance_estimation(np.asarray(pil))


def save_png(path, array):
    path.parent.mkdir(parents=True, exist_ok=True)
    Image.fromarray(np.ascontiguousarray(array)).save(path, optimize=True)


def rel(path):
    """Path relative to the workspace root, with `../shared` for the shared data."""
    path = Path(path).resolve()
    try:
        return path.relative_to(ROOT).as_posix()
    except ValueError:
        return "../" + path.relative_to(ROOT.parent).as_posix()


def spread(items, count):
    """`count` items evenly spaced through a sorted list (deterministic)."""
    items = sorted(items)
    if len(items) <= count:
        return items
    step = len(items) / count
    return [items[int(i * step)] for i in range(count)]


def across_folders(files, count):
    """`count` files spread over the folders holding them (every folder first, then the first
    folders again), evenly spaced within each folder."""
    folders = {}
    for f in files:
        folders.setdefault(f.parent, []).append(f)
    keys = sorted(folders)
    picked = []
    for i, key in enumerate(keys):
        n = count // len(keys) + (1 if i < count % len(keys) else 0)
        picked += spread(folders[key], n)
    return picked


def shared_sources():
    if not SHARED.is_dir():
        print(f"note: {SHARED} absent, only bundled samples are used", file=sys.stderr)
        return []
    exts = {".png", ".jpg", ".jpeg"}
    refs = [p for p in (SHARED / "references").rglob("*") if p.suffix.lower() in exts]
    under = [
        p
        for p in (SHARED / "paired").glob("*/underwater/*")
        if p.suffix.lower() in exts
    ]
    return across_folders(refs, NUMBER_OF_SHARED_REFERENCES) + across_folders(
        under, NUMBER_OF_SHARED_UNDERWATER
    )


def fixture_name(path):
    r = rel(path).replace("../shared/data/", "shared-").replace("assets/samples/", "sample-")
    return Path(r.replace("/", "-")).stem


def lightfield_fixtures():
    out_dir = FIXTURES / "lightfield"
    entries = []
    bundled = sorted(SAMPLES.glob("ref-*")) + sorted(SAMPLES.glob("clean-*.jpg"))
    for path in bundled + shared_sources():
        name = fixture_name(path) + ".png"
        save_png(out_dir / name, render_time_map(path))
        entries.append({"kind": "render", "source": rel(path), "expected": name})
    # The procedure at the image's own size (training applies it to 256x256 crops; other sizes
    # check the dsize=(h, w) bookkeeping of the released code).
    for path in [SAMPLES / "ref-blue.jpg", SAMPLES / "clean-statues.jpg", SAMPLES / "ref-green.png"]:
        name = "raw-" + fixture_name(path) + ".png"
        save_png(out_dir / name, muti_scale_luminance_estimation(np.asarray(load_rgb(path))))
        entries.append({"kind": "raw", "source": rel(path), "expected": name})
    return entries


def ops_fixtures():
    out_dir = FIXTURES / "ops"
    rng = np.random.default_rng(20220619)
    inputs = {
        "noise-61x47.png": rng.integers(0, 256, (47, 61, 3), dtype=np.uint8),
        "noise-64x48.png": rng.integers(0, 256, (48, 64, 3), dtype=np.uint8),
        "ref-green-77.png": cv2.resize(np.asarray(load_rgb(SAMPLES / "ref-green.png")), None, fx=SCALE, fy=SCALE),
    }
    for name, array in inputs.items():
        save_png(out_dir / name, array)
    ref_green = "assets/samples/ref-green.png"

    def source(name):
        return ref_green if name == ref_green else name

    def read(name):
        if name == ref_green:
            return np.asarray(load_rgb(ROOT / ref_green))
        return inputs[name]

    cases = []

    def add(op, inp, params, result):
        out = f"{op}-{Path(inp).stem}-" + "-".join(str(v) for v in params.values()) + ".png"
        save_png(out_dir / out, result)
        cases.append({"op": op, "input": source(inp), "params": params, "expected": out})

    for inp, (w, h) in [
        ("noise-61x47.png", (130, 90)),
        ("noise-61x47.png", (20, 33)),
        ("noise-61x47.png", (61, 20)),
        (ref_green, (77, 100)),
        (ref_green, (300, 200)),
    ]:
        pil = Image.fromarray(read(inp)).resize((w, h), Image.BILINEAR)
        add("pil_bilinear", inp, {"width": w, "height": h}, np.asarray(pil))
    for inp, f in [(ref_green, 0.3), ("noise-61x47.png", 0.3), ("noise-61x47.png", 0.5), ("noise-64x48.png", 0.5)]:
        add("cv_linear_scale", inp, {"fx": f, "fy": f}, cv2.resize(read(inp), None, fx=f, fy=f))
    for inp, (w, h) in [
        ("ref-green-77.png", (256, 256)),
        ("noise-61x47.png", (150, 100)),
        ("noise-61x47.png", (30, 23)),
        ("noise-64x48.png", (32, 24)),
        ("noise-64x48.png", (64, 17)),
    ]:
        add("cv_linear", inp, {"width": w, "height": h}, cv2.resize(read(inp), dsize=(w, h)))
    for inp, sigma in [
        ("ref-green-77.png", 15),
        ("ref-green-77.png", 60),
        ("ref-green-77.png", 90),
        ("ref-green-77.png", 2.5),
        ("noise-61x47.png", 15),
        ("noise-61x47.png", 90),
        ("noise-64x48.png", 1.2),
    ]:
        add("cv_gaussian", inp, {"sigma": sigma}, cv2.GaussianBlur(read(inp), (0, 0), sigma))
    return cases


def main():
    versions = {"numpy": np.__version__, "opencv": cv2.__version__, "pillow": PIL.__version__}
    if not cv2.__version__.startswith("4."):
        sys.exit(f"OpenCV {cv2.__version__}: the released code used 4.x; pip install 'opencv-python-headless<5'")
    if int(PIL.__version__.split(".")[0]) >= 13:
        sys.exit(f"Pillow {PIL.__version__}: use Pillow < 13 (see the module docstring)")
    log10 = np.clip(np.log10(np.arange(256, dtype=np.uint8)), 0, 255)
    assert log10.dtype == np.float16, log10.dtype
    manifest = {
        "generator": "tools/lightfield_reference.py",
        "versions": versions,
        "log10_u8": [float(v) for v in log10.astype(np.float64)],
        "maps": lightfield_fixtures(),
    }
    (FIXTURES / "lightfield" / "manifest.json").write_text(json.dumps(manifest, indent=1) + "\n")
    ops = {"generator": "tools/lightfield_reference.py", "versions": versions, "cases": ops_fixtures()}
    (FIXTURES / "ops" / "manifest.json").write_text(json.dumps(ops, indent=1) + "\n")
    print(f"versions: {versions}")
    print(f"{len(manifest['maps'])} light-field maps, {len(ops['cases'])} op cases")


if __name__ == "__main__":
    with np.errstate(divide="ignore"):
        main()
