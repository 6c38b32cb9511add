"""The learned detector's network: a tiny CenterNet-style encoder-decoder with stride-4 heads (torch).

Output channels at 1/4 resolution (see ``coastforge.detection.learned`` for the decoding):
``0..2`` class centre heatmaps (boat, vehicle, buoy; sigmoid), ``3..4`` sub-cell centre offset (cells),
``5..6`` log(length/4), log(width/4) in working pixels, ``7..8`` (cos 2θ, sin 2θ) of the long axis,
``9..10`` (cos θ, sin θ) of the front (θ = yaw, scene convention). The exported ONNX graph also emits
the heatmap's 3x3 local maxima so that the peak search is part of the model.
"""

from __future__ import annotations

N_CLASSES = 3
N_OUT = N_CLASSES + 8


def build_model(width: int = 16):
    """The network (a few hundred thousand parameters); torch is imported here, not at module import."""
    import torch
    from torch import nn
    import torch.nn.functional as F

    def cbr(cin, cout, stride=1, k=3):
        return nn.Sequential(nn.Conv2d(cin, cout, k, stride, k // 2, bias=False), nn.BatchNorm2d(cout),
                             nn.ReLU(inplace=True))

    class Res(nn.Module):
        def __init__(self, c, dil=1):
            super().__init__()
            self.a = nn.Sequential(nn.Conv2d(c, c, 3, 1, dil, dilation=dil, bias=False), nn.BatchNorm2d(c),
                                   nn.ReLU(inplace=True))
            self.b = nn.Sequential(nn.Conv2d(c, c, 3, 1, 1, bias=False), nn.BatchNorm2d(c))

        def forward(self, x):
            return F.relu(x + self.b(self.a(x)))

    w = width

    class Net(nn.Module):
        def __init__(self):
            super().__init__()
            self.s2 = cbr(3, w // 2, 2)                                               # 1/2
            self.s4 = nn.Sequential(cbr(w // 2, w, 2), Res(w))                         # 1/4
            self.s8 = nn.Sequential(cbr(w, 2 * w, 2), Res(2 * w))                      # 1/8
            self.s16 = nn.Sequential(cbr(2 * w, 3 * w, 2), Res(3 * w), Res(3 * w, 2))  # 1/16
            self.s32 = nn.Sequential(cbr(3 * w, 4 * w, 2), Res(4 * w, 2))              # 1/32: long boats
            self.l16 = nn.Conv2d(4 * w, 3 * w, 1)
            self.l8 = nn.Conv2d(3 * w, 2 * w, 1)
            self.l4 = nn.Conv2d(2 * w, w, 1)
            self.f16 = cbr(3 * w, 3 * w)
            self.f8 = cbr(2 * w, 2 * w)
            self.f4 = cbr(w, w)
            self.head = nn.Sequential(cbr(w, w), nn.Conv2d(w, N_OUT, 1))
            with torch.no_grad():  # CenterNet prior: few centres
                self.head[-1].bias[:N_CLASSES].fill_(-2.19)

        def forward(self, x):
            x4 = self.s4(self.s2(x))
            x8 = self.s8(x4)
            x16 = self.s16(x8)
            x32 = self.s32(x16)
            y = self.f16(x16 + F.interpolate(self.l16(x32), size=x16.shape[-2:], mode="nearest"))
            y = self.f8(x8 + F.interpolate(self.l8(y), size=x8.shape[-2:], mode="nearest"))
            y = self.f4(x4 + F.interpolate(self.l4(y), size=x4.shape[-2:], mode="nearest"))
            return self.head(y)

    return Net()


def export_wrapper(net):
    """The network as exported: input RGB uint8-range float (1,3,H,W) → (heat, peaks, regression)."""
    import torch
    from torch import nn
    import torch.nn.functional as F

    class Export(nn.Module):
        def __init__(self):
            super().__init__()
            self.net = net

        def forward(self, x):
            y = self.net(x / 255.0)
            heat = torch.sigmoid(y[:, :N_CLASSES])
            peaks = heat * (F.max_pool2d(heat, 3, 1, 1) == heat).float()
            return heat, peaks, y[:, N_CLASSES:]

    return Export()
