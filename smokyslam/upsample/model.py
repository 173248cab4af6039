"""The networks: a small U-Net generator, a PatchGAN discriminator, fixed line detectors.

milliMap up-samples with pix2pixHD (about 180M parameters); RadarHD with a 17.5M-parameter
U-Net. This U-Net is far smaller (about 0.8M parameters: 12 base channels, depth 4, at most
128 channels) so that it trains in an hour and infers a 512x512 map in a fraction of a
second on 2 CPU cores.

It is built to be shift-equivariant, so maps of any size can be up-sampled in one pass and
tiles agree where they overlap: no normalisation layer (a statistic over the whole image
would make each cell depend on the map's extent), average-pool down-sampling (a box filter,
less aliasing than max-pool or strided convolution) and bilinear up-sampling. An unknown
cell is encoded as zeros (``upsample/encoding.py``), so the convolutions' zero padding reads
as unknown space beyond the map.

Input: (B, 2, H, W), channel 0 = +1 occupied / -1 free / 0 unknown, channel 1 = known.
Output: (B, 1, H, W) logits of the dense map's value, sigmoid = 1 occupied, 0 free, 0.5
unknown (the error index's scale), with H and W multiples of ``2**depth``.
"""

from __future__ import annotations

import torch
from torch import nn
from torch.nn import functional

IN_CHANNELS = 2


def _block(c_in: int, c_out: int, convs: int) -> nn.Sequential:
    layers: list[nn.Module] = []
    for i in range(convs):
        layers += [nn.Conv2d(c_in if i == 0 else c_out, c_out, 3, padding=1), nn.LeakyReLU(0.1)]
    return nn.Sequential(*layers)


class UNetGenerator(nn.Module):
    """U-Net: ``depth`` halvings, channels doubling from ``base_channels`` up to
    ``max_channels``, skip links; one convolution per block at full resolution (where it
    costs most), two below."""

    def __init__(self, base_channels: int, depth: int, max_channels: int) -> None:
        super().__init__()
        self.depth = depth
        widths = [min(base_channels * 2**level, max_channels) for level in range(depth + 1)]
        self.down = nn.ModuleList(
            [_block(IN_CHANNELS, widths[0], 1)]
            + [_block(widths[i], widths[i + 1], 2) for i in range(depth)]
        )
        self.up = nn.ModuleList(
            [
                _block(widths[i + 1] + widths[i], widths[i], 1 if i == 0 else 2)
                for i in reversed(range(depth))
            ]
        )
        self.head = nn.Conv2d(widths[0], 1, 1)

    @property
    def stride(self) -> int:
        """Input sides must be multiples of this."""
        return 2**self.depth

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        skips = []
        for level, block in enumerate(self.down):
            if level:
                x = functional.avg_pool2d(x, 2)
            x = block(x)
            skips.append(x)
        for block, skip in zip(self.up, reversed(skips[:-1]), strict=True):
            x = functional.interpolate(x, scale_factor=2.0, mode="bilinear", align_corners=False)
            x = block(torch.cat([x, skip], dim=1))
        return self.head(x)


class PatchDiscriminator(nn.Module):
    """PatchGAN (pix2pix): real/fake logits per overlapping patch of (input, map) pairs."""

    def __init__(self, base_channels: int = 32) -> None:
        super().__init__()
        c = base_channels
        self.net = nn.Sequential(
            nn.Conv2d(IN_CHANNELS + 1, c, 4, stride=2, padding=1),
            nn.LeakyReLU(0.2),
            nn.Conv2d(c, 2 * c, 4, stride=2, padding=1),
            nn.LeakyReLU(0.2),
            nn.Conv2d(2 * c, 4 * c, 4, stride=2, padding=1),
            nn.LeakyReLU(0.2),
            nn.Conv2d(4 * c, 4 * c, 4, padding=1),
            nn.LeakyReLU(0.2),
            nn.Conv2d(4 * c, 1, 4, padding=1),
        )

    def forward(self, inputs: torch.Tensor, value: torch.Tensor) -> torch.Tensor:
        return self.net(torch.cat([inputs, value], dim=1))


def line_kernels() -> torch.Tensor:
    """(4, 1, 3, 3) fixed line detectors: horizontal, vertical and the two diagonals
    (milliMap's map prior); each sums to zero, so flat regions respond with nothing."""
    horizontal = torch.tensor([[-1.0, -1.0, -1.0], [2.0, 2.0, 2.0], [-1.0, -1.0, -1.0]])
    diagonal = torch.tensor([[2.0, -1.0, -1.0], [-1.0, 2.0, -1.0], [-1.0, -1.0, 2.0]])
    kernels = [horizontal, horizontal.T, diagonal, diagonal.flip(1)]
    return (torch.stack(kernels) / 6.0).unsqueeze(1)


def line_responses(value: torch.Tensor, kernels: torch.Tensor) -> torch.Tensor:
    """(B, 4, H, W) responses of the line detectors on a (B, 1, H, W) map value image."""
    return functional.conv2d(value, kernels, padding=1)


def parameter_count(model: nn.Module) -> int:
    return sum(p.numel() for p in model.parameters())
