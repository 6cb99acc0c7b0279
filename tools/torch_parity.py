#!/usr/bin/env python3
"""Reference outputs of the UWNR generator (MHB-Unet) in PyTorch, for crates/render/uwnr-model's
parity tests.

The architecture is written here from the method description (UWNR, Ye et al., CVPR-W 2022,
and the released model/FSU2.py layout), with the released module names so the state-dict keys
are the authors': `in_conv_down1.mpconv.0.weight`, `...mpconv.2.SA.spatial_pool.0.weight`, ...

Writes, at width 8 with seeded random weights (scaled up from the N(0, 0.02) training init so
that activations are far from zero and the tanh is neither flat nor saturated):

- crates/render/uwnr-model/tests/fixtures/parity_w8.safetensors: the weights (f16, to keep the file
  small; the reference is computed from the same f16-rounded values), with the config and
  provenance in the safetensors metadata;
- crates/render/uwnr-model/tests/fixtures/parity_w8_ckpt.pth: the same weights as the authors'
  training checkpoint, `torch.save({'G1': {'module.' + k: v}, 'optimizer_weightG1': ...})`;
- crates/render/uwnr-model/tests/fixtures/parity_w8_io.safetensors: `input` (1x7x32x48),
  `output` (1x3x32x48, computed in float64) and `mean.K` (the pooled channel-attention input
  of encoder block K).

Also checks the parameter count of the full-width network.

Run from the repository root: `python3 tools/torch_parity.py` (needs torch, safetensors).
"""

import argparse
import json
from pathlib import Path

import torch
import torch.nn as nn
from safetensors.torch import save_file

SEED = 20220619
WIDTH = 8
INPUT_SHAPE = (1, 7, 32, 48)
# Conv weights ~ N(0, (WEIGHT_GAIN / sqrt(fan_in))^2), biases ~ U(-BIAS_RANGE, BIAS_RANGE).
WEIGHT_GAIN = 0.8
BIAS_RANGE = 0.3
# Released network: parameters without / with the four unused InstanceNorm2d(c/2, affine).
PAPER_PARAMS_USED = 11_569_271
PAPER_PARAMS_ALL = 11_570_231


class SpatialAttention(nn.Module):
    """t * sigmoid(conv1x1(LeakyReLU(conv1x1(t)))), c -> c/4 -> 1."""

    def __init__(self, c):
        super().__init__()
        self.spatial_pool = nn.Sequential(
            nn.Conv2d(c, c // 4, 1), nn.LeakyReLU(), nn.Conv2d(c // 4, 1, 1), nn.Sigmoid()
        )

    def forward(self, t):
        return t * self.spatial_pool(t)


class ChannelAttention(nn.Module):
    """t * sigmoid(conv1x1(LeakyReLU(conv1x1(mean_hw(t))))), c -> c/4 -> c."""

    def __init__(self, c):
        super().__init__()
        self.channel_map = nn.Sequential(
            nn.Conv2d(c, c // 4, 1), nn.LeakyReLU(), nn.Conv2d(c // 4, c, 1), nn.Sigmoid()
        )
        self.last_mean = None

    def forward(self, t):
        self.last_mean = t.mean(dim=(2, 3), keepdim=True)
        return t * self.channel_map(self.last_mean)


class BasicBlock(nn.Module):
    """CA(SA(LeakyReLU(conv1x1(x) + conv3x3(x) + x))) + x; owns an unused InstanceNorm."""

    def __init__(self, c):
        super().__init__()
        self.conk3 = nn.Conv2d(c, c, 3, padding=1)
        self.conk1 = nn.Conv2d(c, c, 1)
        self.SA = SpatialAttention(c)
        self.CA = ChannelAttention(c)
        self.norm = nn.InstanceNorm2d(c // 2, affine=True)  # never called

    def forward(self, x):
        y = nn.functional.leaky_relu(self.conk1(x) + self.conk3(x) + x, 0.01)
        return self.CA(self.SA(y)) + x


class Down(nn.Module):
    def __init__(self, cin, cout):
        super().__init__()
        self.mpconv = nn.Sequential(
            nn.Conv2d(cin, cout, 3, stride=2, padding=1), nn.ELU(), BasicBlock(cout)
        )

    def forward(self, x):
        return self.mpconv(x)


class Up(nn.Module):
    def __init__(self, c):
        super().__init__()
        self.up = nn.Sequential(nn.Conv2d(c, 2 * c, 3, padding=1), nn.ELU(), nn.PixelShuffle(2))

    def forward(self, x):
        return self.up(x)


class Generator(nn.Module):
    def __init__(self, width=64, cin=7, cout=3):
        super().__init__()
        c = width
        self.in_conv_down1 = Down(cin, c)
        self.down2 = Down(c, 2 * c)
        self.down3 = Down(2 * c, 4 * c)
        self.down4 = Down(4 * c, 8 * c)
        self.up1 = Up(8 * c)
        self.up2 = Up(4 * c)
        self.up3 = Up(2 * c)
        self.up4 = Up(c)
        self.out = nn.Sequential(nn.Conv2d(c // 2, cout, 3, padding=1), nn.Tanh())

    def blocks(self):
        return [d.mpconv[2] for d in (self.in_conv_down1, self.down2, self.down3, self.down4)]

    def forward(self, x):
        x2 = self.in_conv_down1(x)
        x4 = self.down2(x2)
        x8 = self.down3(x4)
        x16 = self.down4(x8)
        y8 = self.up1(x16) + x8
        y4 = self.up2(y8) + x4
        y2 = self.up3(y4) + x2
        return self.out(self.up4(y2))


def randomize(model, gen):
    with torch.no_grad():
        for m in model.modules():
            if isinstance(m, nn.Conv2d):
                fan_in = m.in_channels * m.kernel_size[0] * m.kernel_size[1]
                std = WEIGHT_GAIN / fan_in**0.5
                m.weight.copy_(torch.randn(m.weight.shape, generator=gen) * std)
                m.bias.copy_((torch.rand(m.bias.shape, generator=gen) * 2 - 1) * BIAS_RANGE)
            elif isinstance(m, nn.InstanceNorm2d):
                # Unused by the forward; random so a loader that used them would be caught.
                m.weight.copy_(torch.randn(m.weight.shape, generator=gen))
                m.bias.copy_(torch.randn(m.bias.shape, generator=gen))
        # Round to f16 so the f16 fixture holds exactly the weights the reference used.
        for p in model.parameters():
            p.copy_(p.half().float())


def main():
    root = Path(__file__).resolve().parent.parent
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--out-dir", type=Path, default=root / "crates/render/uwnr-model/tests/fixtures")
    args = ap.parse_args()
    args.out_dir.mkdir(parents=True, exist_ok=True)

    full = Generator(64)
    n_all = sum(p.numel() for p in full.parameters())
    n_used = sum(p.numel() for n, p in full.named_parameters() if ".norm." not in n)
    print(f"full-width parameters: {n_all:,} with the unused norms, {n_used:,} without")
    assert (n_all, n_used) == (PAPER_PARAMS_ALL, PAPER_PARAMS_USED), (n_all, n_used)

    gen = torch.Generator().manual_seed(SEED)
    model = Generator(WIDTH).eval()
    randomize(model, gen)
    x = torch.rand(INPUT_SHAPE, generator=gen)

    with torch.no_grad():
        y32 = model(x)
        model64 = model.double()
        y = model64(x.double())
        means = [b.CA.last_mean.float().contiguous() for b in model64.blocks()]
        model.float()
    print(
        f"output: mean {y.mean():.4f} std {y.std():.4f} min {y.min():.4f} max {y.max():.4f}; "
        f"torch f32 vs f64 max abs {(y32.double() - y).abs().max():.2e}"
    )
    for k, m in enumerate(means):
        print(f"block {k} CA mean: shape {tuple(m.shape)}, range [{m.min():.3f}, {m.max():.3f}]")

    state = {k: v.detach().clone().contiguous() for k, v in model.state_dict().items()}
    config = {"in_channels": 7, "out_channels": 3, "base_width": WIDTH}
    meta = {
        "uwnr.config": json.dumps(config),
        "uwnr.source": f"tools/torch_parity.py seed {SEED}: random weights for parity tests",
    }
    save_file({k: v.half() for k, v in state.items()}, args.out_dir / "parity_w8.safetensors", meta)

    opt = torch.optim.AdamW(model.parameters(), lr=2e-4, betas=(0.9, 0.999), weight_decay=1e-6)
    torch.save(
        {"G1": {"module." + k: v for k, v in state.items()}, "optimizer_weightG1": opt.state_dict()},
        args.out_dir / "parity_w8_ckpt.pth",
    )

    io = {"input": x.contiguous(), "output": y.float().contiguous()}
    io.update({f"mean.{k}": m for k, m in enumerate(means)})
    save_file(io, args.out_dir / "parity_w8_io.safetensors", {"uwnr.source": "tools/torch_parity.py"})
    for name in ("parity_w8.safetensors", "parity_w8_ckpt.pth", "parity_w8_io.safetensors"):
        print(f"wrote {name}: {(args.out_dir / name).stat().st_size:,} bytes")


if __name__ == "__main__":
    main()
