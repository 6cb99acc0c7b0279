#!/usr/bin/env python3
"""Times one UWNR training step in PyTorch on the CPU, the same step as
`cargo bench -p uwnr-train --bench train`: the full-width generator (the released
MHB-Unet, `model/FSU2.py`, written out from its description), the default loss of
`uwnr train` without VGG19 weights (0.6 L1 + 0.5 (1 - SSIM) + 0.5 dark channel + 0.5 the
paper's light-field term), backward, AdamW (lr 2e-4, weight decay 1e-6).

Usage: python3 tools/torch_train_bench.py [--threads 2] [--steps 5]
Prints the median step time and samples/s for batch 4 at 128x128 and batch 1 at 256x256.
"""

import argparse
import math
import statistics
import time

import torch
import torch.nn as nn
import torch.nn.functional as F


class SA(nn.Module):
    def __init__(self, c):
        super().__init__()
        self.spatial_pool = nn.Sequential(nn.Conv2d(c, c // 4, 1), nn.LeakyReLU(), nn.Conv2d(c // 4, 1, 1), nn.Sigmoid())

    def forward(self, x):
        return x * self.spatial_pool(x)


class CA(nn.Module):
    def __init__(self, c):
        super().__init__()
        self.pool = nn.AdaptiveAvgPool2d(1)
        self.channel_map = nn.Sequential(nn.Conv2d(c, c // 4, 1), nn.LeakyReLU(), nn.Conv2d(c // 4, c, 1), nn.Sigmoid())

    def forward(self, x):
        return x * self.channel_map(self.pool(x))


class BasicBlock(nn.Module):
    def __init__(self, c):
        super().__init__()
        self.conk3 = nn.Conv2d(c, c, 3, padding=1)
        self.conk1 = nn.Conv2d(c, c, 1)
        self.SA = SA(c)
        self.CA = CA(c)
        self.act = nn.LeakyReLU()

    def forward(self, x):
        y = self.act(self.conk1(x) + self.conk3(x) + x)
        return self.CA(self.SA(y)) + x


def down(cin, cout):
    return nn.Sequential(nn.Conv2d(cin, cout, 3, stride=2, padding=1), nn.ELU(), BasicBlock(cout))


def up(c):
    return nn.Sequential(nn.Conv2d(c, 2 * c, 3, padding=1), nn.ELU(), nn.PixelShuffle(2))


class Generator(nn.Module):
    def __init__(self, w=64):
        super().__init__()
        self.d1, self.d2, self.d3, self.d4 = down(7, w), down(w, 2 * w), down(2 * w, 4 * w), down(4 * w, 8 * w)
        self.u1, self.u2, self.u3, self.u4 = up(8 * w), up(4 * w), up(2 * w), up(w)
        self.out = nn.Sequential(nn.Conv2d(w // 2, 3, 3, padding=1), nn.Tanh())

    def forward(self, x):
        x2 = self.d1(x)
        x4 = self.d2(x2)
        x8 = self.d3(x4)
        x16 = self.d4(x8)
        y8 = self.u1(x16) + x8
        y4 = self.u2(y8) + x4
        y2 = self.u3(y4) + x2
        return self.out(self.u4(y2))


def gauss1d(sigma, radius):
    k = torch.tensor([math.exp(-(i * i) / (2 * sigma * sigma)) for i in range(-radius, radius + 1)])
    return k / k.sum()


def blur(x, sigma):
    c, h, w = x.shape[1], x.shape[2], x.shape[3]
    full = math.ceil(3 * sigma)
    rx, ry = min(full, w - 1), min(full, h - 1)
    kx, ky = gauss1d(sigma, rx), gauss1d(sigma, ry)
    y = F.conv2d(x, kx.view(1, 1, 1, -1).repeat(c, 1, 1, 1), padding=(0, rx), groups=c)
    y = F.conv2d(y, ky.view(1, 1, -1, 1).repeat(c, 1, 1, 1), padding=(ry, 0), groups=c)
    ones = torch.ones(1, 1, h, w)
    n = F.conv2d(F.conv2d(ones, kx.view(1, 1, 1, -1), padding=(0, rx)), ky.view(1, 1, -1, 1), padding=(ry, 0))
    return y / n


def light_field_map(x):
    s = F.avg_pool2d(x, 3)
    m = sum(blur(s, sg * (1 / 3) / 0.3) for sg in (15.0, 60.0, 90.0)) / 3
    l = m.clamp_min(1 / 255).log()
    b = l.shape[0]
    f = l.view(b, -1)
    lo, hi = f.min(1, keepdim=True)[0], f.max(1, keepdim=True)[0]
    return ((f - lo) / (hi - lo + 1e-6)).view_as(l)


def dark_channel(x, k=15):
    m = x[:, 1:].min(1, keepdim=True)[0]
    return -F.max_pool2d(-m, k, stride=1, padding=k // 2)


def ssim(x, y):
    c = x.shape[1]
    k = gauss1d(1.5, 5)
    kx, ky = k.view(1, 1, 1, -1).repeat(c, 1, 1, 1), k.view(1, 1, -1, 1).repeat(c, 1, 1, 1)

    def f(t):
        return F.conv2d(F.conv2d(t, kx, groups=c), ky, groups=c)

    mx, my = f(x), f(y)
    sxx, syy, sxy = f(x * x) - mx * mx, f(y * y) - my * my, f(x * y) - mx * my
    c1, c2 = 0.01**2, 0.03**2
    return (((2 * mx * my + c1) * (2 * sxy + c2)) / ((mx * mx + my * my + c1) * (sxx + syy + c2))).mean()


def loss_fn(out, tgt):
    rec = (out - tgt).abs().mean()
    per = 1 - ssim(out.clamp(0, 1), tgt)
    dc = (dark_channel(out) - dark_channel(tgt)).abs().mean()
    lf = (light_field_map(out) - light_field_map(tgt)).abs().mean()
    return 0.6 * rec + 0.5 * per + 0.5 * dc + 0.5 * lf


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--threads", type=int, default=2)
    ap.add_argument("--steps", type=int, default=5)
    args = ap.parse_args()
    torch.set_num_threads(args.threads)
    torch.manual_seed(0)
    net = Generator()
    for m in net.modules():
        if isinstance(m, nn.Conv2d):
            nn.init.normal_(m.weight, 0.0, 0.02)
    opt = torch.optim.AdamW(net.parameters(), lr=2e-4, betas=(0.9, 0.999), weight_decay=1e-6)
    print(f"torch {torch.__version__}, {args.threads} threads, params {sum(p.numel() for p in net.parameters())}")
    for b, s in [(4, 128), (1, 256)]:
        x = torch.rand(b, 7, s, s)
        y = torch.rand(b, 3, s, s)
        times = []
        for i in range(args.steps + 1):
            t = time.perf_counter()
            opt.zero_grad()
            loss = loss_fn(net(x), y)
            loss.backward()
            opt.step()
            if i > 0:  # the first step warms up
                times.append(time.perf_counter() - t)
        med = statistics.median(times)
        print(f"RESULT torch train_{b}x{s} median_s={med:.3f} samples_per_s={b / med:.2f} loss={loss.item():.4f}")


if __name__ == "__main__":
    main()
