#!/usr/bin/env python3
"""Reference outputs of Shallow-UWnet in PyTorch, for crates/train/uwnr-enhance's parity test.

The architecture is written here from the paper's description (Naik et al. 2021) with the
released module names, so the state-dict keys are the released ones: `input.weight`,
`blocks.i.conv.weight` (conv3x3 w -> w, applied twice, Dropout2d(0.2) after each),
`blocks.i.conv1.weight` (conv3x3 w -> w-3, then the raw image is concatenated back),
`output.weight`; no biases.

Writes, at width 16 with 3 blocks and seeded random weights:
- crates/train/uwnr-enhance/tests/fixtures/parity_w16.safetensors: the weights;
- crates/train/uwnr-enhance/tests/fixtures/parity_w16.pth: the same as a PyTorch state dict;
- crates/train/uwnr-enhance/tests/fixtures/parity_w16_io.safetensors: `input` (1x3x24x40) and
  `output` (eval mode, computed in float64).
Also prints the parameter count of the paper's network (width 64).

Run from the repository root: `python3 tools/shallow_uwnet_parity.py` (needs torch, safetensors).
"""

from pathlib import Path

import torch
import torch.nn as nn
from safetensors.torch import save_file

SEED = 20210202
WIDTH = 16
BLOCKS = 3
INPUT_SHAPE = (1, 3, 24, 40)
OUT = Path("crates/train/uwnr-enhance/tests/fixtures")


class Block(nn.Module):
    def __init__(self, w):
        super().__init__()
        self.conv = nn.Conv2d(w, w, 3, padding=1, bias=False)
        self.conv1 = nn.Conv2d(w, w - 3, 3, padding=1, bias=False)
        self.drop = nn.Dropout2d(0.2)

    def forward(self, x, image):
        a = torch.relu(self.drop(self.conv(x)))
        a = torch.relu(self.drop(self.conv(a)))
        a = torch.relu(self.conv1(a))
        return torch.cat([a, image], 1)


class ShallowUWnet(nn.Module):
    def __init__(self, w=64, blocks=3):
        super().__init__()
        self.input = nn.Conv2d(3, w, 3, padding=1, bias=False)
        self.blocks = nn.ModuleList([Block(w) for _ in range(blocks)])
        self.output = nn.Conv2d(w, 3, 3, padding=1, bias=False)

    def forward(self, image):
        x = torch.relu(self.input(image))
        for b in self.blocks:
            x = b(x, image)
        return self.output(x)


def main():
    full = ShallowUWnet()
    print("parameters (width 64, 3 blocks):", sum(p.numel() for p in full.parameters()))
    torch.manual_seed(SEED)
    net = ShallowUWnet(WIDTH, BLOCKS).eval()
    state = {k: v.contiguous() for k, v in net.state_dict().items()}
    x = torch.rand(INPUT_SHAPE)
    with torch.no_grad():
        y = net.double()(x.double()).float()
    OUT.mkdir(parents=True, exist_ok=True)
    meta = {"uwnr.enhance.config": f'{{"width":{WIDTH},"blocks":{BLOCKS},"dropout":0.2}}',
            "uwnr.source": "tools/shallow_uwnet_parity.py, random weights"}
    save_file(state, OUT / "parity_w16.safetensors", metadata=meta)
    torch.save(state, OUT / "parity_w16.pth")
    save_file({"input": x.contiguous(), "output": y.contiguous()}, OUT / "parity_w16_io.safetensors")
    print("wrote", OUT)


if __name__ == "__main__":
    main()
