"""Renderers and augmentations in other processes: fork (after the parent rendered), spawn
(pickled), and a PyTorch DataLoader with two workers when torch is installed."""

import multiprocessing as mp
import pickle

import numpy as np
import pytest

import uwnr
from conftest import gradient, water

CLEAN, REF = gradient(40, 48), water(40, 40)
# A child that deadlocks (a thread pool inherited through fork) fails the test instead of
# hanging it.
TIMEOUT = 300


def _render_with(renderer):
    return renderer.render(CLEAN, REF)


def _augment_with(aug):
    return [aug(CLEAN) for _ in range(4)]


def test_a_forked_child_renders_after_the_parent_did(network):
    expected = network.render(CLEAN, REF)
    ctx = mp.get_context("fork")
    with ctx.Pool(2) as pool:
        outs = pool.map_async(_render_with, [network, network]).get(TIMEOUT)
    for out in outs:
        assert np.array_equal(out, expected)


def test_a_spawned_child_rebuilds_the_renderer_from_its_pickle(network):
    expected = network.render(CLEAN, REF)
    clone = pickle.loads(pickle.dumps(network))
    assert np.array_equal(clone.render(CLEAN, REF), expected)
    ctx = mp.get_context("spawn")
    with ctx.Pool(1) as pool:
        out = pool.apply_async(_render_with, (network,)).get(TIMEOUT)
    assert np.array_equal(out, expected)


def test_baseline_renderers_pickle_with_their_options():
    r = uwnr.Renderer(method="jerlov", seed=9, water_type="5C")
    clone = pickle.loads(pickle.dumps(r))
    assert np.array_equal(clone.render(CLEAN), r.render(CLEAN))
    assert clone.source == r.source


def test_an_augmentation_is_reproducible_in_a_spawned_worker():
    aug = uwnr.UnderwaterAugment([REF], methods=["jerlov", "reinhard"], p=1.0, seed=2)
    expected = _augment_with(pickle.loads(pickle.dumps(aug)))
    ctx = mp.get_context("spawn")
    with ctx.Pool(1) as pool:
        outs = pool.apply_async(_augment_with, (aug,)).get(TIMEOUT)
    for a, b in zip(outs, expected):
        assert np.array_equal(a, b)


class _Pairs:
    """A map-style dataset of (underwater, clean) pairs made on the fly."""

    def __init__(self, aug, n):
        self.aug, self.n = aug, n

    def __len__(self):
        return self.n

    def __getitem__(self, i):
        import torch

        clean = torch.from_numpy(gradient(32, 32, seed=i)).permute(2, 0, 1).float() / 255
        return self.aug(clean), clean


@pytest.mark.parametrize("start", ["fork", "spawn"])
def test_a_dataloader_with_two_workers(start, network):
    torch = pytest.importorskip("torch")
    network.render(CLEAN, REF)  # the parent's pool is running when the workers fork
    aug = uwnr.UnderwaterAugment([REF], methods=["uwnr", "jerlov"], p=1.0, seed=0)

    def load():
        torch.manual_seed(0)
        loader = torch.utils.data.DataLoader(
            _Pairs(aug, 8), batch_size=2, num_workers=2,
            multiprocessing_context=start, timeout=TIMEOUT,
        )
        return [u for u, _ in loader]

    first, second = load(), load()
    assert len(first) == 4 and first[0].shape == (2, 3, 32, 32)
    assert first[0].dtype == torch.float32
    for a, b in zip(first, second):
        assert torch.equal(a, b)
