"""The learned segmenter's network: a small U-Net (≈0.4 M parameters) whose decoder stops at half
resolution (terrain borders do not need more at the working GSD); logits are upsampled x2 bilinearly.

torch is a training-time dependency only: this module is imported by ``seg_train`` alone; inference
runs the exported ONNX graph with onnxruntime (``coastforge.segmentation.learned``).
"""

from __future__ import annotations


ARCHS = ("unet4", "unet5")


def build_segmenter(n_classes: int = 8, width: int = 16, arch: str = "unet4"):
    """The network (torch.nn.Module): input (N, 3, H, W) float in [-0.5, 0.5], H and W multiples of 16
    ("unet4") or 32 ("unet5"); output logits (N, n_classes, H, W).

    "unet5" adds a fifth, 1/32 stage with dilated convolutions: a receptive field of ~400 px (~120 m at the
    working GSD) instead of ~150, so a dark lawn is judged with the fairways, houses and paths around it."""
    import torch
    from torch import nn
    import torch.nn.functional as F

    def cbr(cin, cout, stride=1, dil=1):
        return nn.Sequential(nn.Conv2d(cin, cout, 3, stride, padding=dil, dilation=dil, bias=False),
                             nn.BatchNorm2d(cout), nn.ReLU(inplace=True))

    w = width
    c1, c2, c3, c4, c5 = int(1.5 * w), int(2.5 * w), 4 * w, 6 * w, 8 * w
    deep = arch == "unet5"
    if arch not in ARCHS:
        raise ValueError(f"arch {arch!r}: one of {ARCHS}")

    class SegNet(nn.Module):
        def __init__(self):
            super().__init__()
            self.stem = nn.Sequential(cbr(3, c1, 2), cbr(c1, c1), cbr(c1, c1))  # 1/2 (no full-res layer: speed)
            self.e2 = nn.Sequential(cbr(c1, c2, 2), cbr(c2, c2))  # 1/4
            self.e3 = nn.Sequential(cbr(c2, c3, 2), cbr(c3, c3))  # 1/8
            self.e4 = nn.Sequential(cbr(c3, c4, 2), cbr(c4, c4, dil=2))  # 1/16, wide context
            if deep:
                self.e5 = nn.Sequential(cbr(c4, c5, 2), cbr(c5, c5, dil=2), cbr(c5, c5, dil=4))  # 1/32
                self.d4 = cbr(c5 + c4, c4)
            self.d3 = cbr(c4 + c3, c3)
            self.d2 = cbr(c3 + c2, c2)
            self.d1 = cbr(c2 + c1, 2 * w)
            self.head = nn.Conv2d(2 * w, n_classes, 1)

        def forward(self, x):
            e1 = self.stem(x)
            e2 = self.e2(e1)
            e3 = self.e3(e2)
            e4 = self.e4(e3)
            up = lambda t, ref: F.interpolate(t, size=ref.shape[-2:], mode="bilinear", align_corners=False)  # noqa: E731
            if deep:
                e4 = self.d4(torch.cat([up(self.e5(e4), e4), e4], 1))
            d = self.d3(torch.cat([up(e4, e3), e3], 1))
            d = self.d2(torch.cat([up(d, e2), e2], 1))
            d = self.d1(torch.cat([up(d, e1), e1], 1))
            return F.interpolate(self.head(d), size=x.shape[-2:], mode="bilinear", align_corners=False)

    return SegNet()
