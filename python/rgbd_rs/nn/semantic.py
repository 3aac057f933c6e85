"""The semantic-labeling ConvNet of thesis §4.6 (Fig. 4.3).

Input: the 9 cues of eq. 4.2 per pixel (R, G, B, HHA, fitting error f, principal curvatures c1,
c2; :func:`rgbd_rs.segmentation.cues.semantic_cues`), at 320 x 240 in the thesis. Layers:

1. local contrast normalisation of each input channel on its own (:class:`_LocalContrastNorm`,
   the formula of :func:`rgbd_rs.shapes.views.local_contrast_normalize`);
2. three blocks of three 7 x 7 convolutions ("same" zero padding), each followed by tanh except
   the very last one; 90, 128 and 256 filters; the first convolution is grouped by input
   channel (9 groups: the 10 filters of group i see channel i only); a 2 x 2 max-pool ends
   blocks 1 and 2, so the output has 1/4 of the input's resolution (80 x 60 at 320 x 240);
3. a pixel-wise linear classifier without bias (a 1 x 1 convolution, 256 x 14 weights) whose
   softmax gives each output pixel's class PDF.

:meth:`SemanticNet.forward` returns the logits at 1/4 resolution; :func:`class_probabilities`
turns them into PDFs at any size (softmax over the classes, the ignored class removed, then
bilinear upsampling: a convex combination of PDFs is a PDF, so every pixel sums to 1).

Choices the thesis leaves open (stated here and with every result):

- ``width`` scales every layer (thesis 256 = the last block's filters): blocks of
  ``9 * round(10 * width / 256)``, ``round(128 * width / 256)`` and ``width`` filters (the first
  block stays a multiple of the 9 input channels). The thesis' full size is ``width=256``.
- LCN window: 15 x 15 at 320 pixels of width (the Farabet/Couprie window, METHOD_NOTES §8 [R];
  the thesis gives none), scaled with the input width (:func:`lcn_window`) and stored with the
  network.
- "Same" zero padding, so the output is exactly 1/4 of an input whose sides are multiples of 4
  (the thesis does not say how borders are handled).
- Glorot (Xavier) initialisation of every convolution and of the classifier (tanh gain), zero
  biases: the usual choice for tanh. (A zero or small classifier starts at uniform PDFs and
  avoids a loss spike in the first epochs on NYUv2 frames, but learns 2-3x slower: two tiny
  frames reached 40-45 % class accuracy in 60 epochs instead of 80 %.)
- Class ``ignore_index`` (0 = unlabeled in NYUv2's 13-class labels) keeps its row of the
  classifier (the thesis' 256 x 14 shape) but is never a target: training ignores its pixels and
  its probability is fixed at 0 (its logit masked before the softmax) in training and inference
  alike, so the PDFs sum to 1 over the 13 real classes and the class index is the label value.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

import torch
from torch import nn
from torch.nn import functional as F

from rgbd_rs import _validate
from rgbd_rs.errors import InvalidArgumentError, ShapeMismatchError

__all__ = [
    "ARCH",
    "CUE_NAMES",
    "N_CUES",
    "SemanticNet",
    "class_probabilities",
    "lcn_window",
]

#: Name stored in checkpoints; a checkpoint of another architecture is refused.
ARCH = "semantic-convnet/1"
#: The input channels of eq. 4.2, in order.
CUE_NAMES = ("R", "G", "B", "hha_disparity", "hha_height", "hha_angle", "fit_error", "c1", "c2")
N_CUES = len(CUE_NAMES)
#: Filters of the three blocks (§4.6: 90, 128, 256) and the thesis width (the last block's).
THESIS_FILTERS = (90, 128, 256)
THESIS_WIDTH = 256
#: Convolutions per block, kernel side and pooling (§4.6, Fig. 4.3).
CONVS_PER_BLOCK = 3
KERNEL = 7
POOL = 2
#: Output resolution / input resolution (two 2 x 2 max-pools).
DOWNSAMPLE = POOL * POOL
#: The thesis' classes: 13 NYUv2 classes plus unknown (§4.6: 256 x 14 classifier).
THESIS_CLASSES = 14
#: The thesis' input size, width x height (§4.6).
THESIS_INPUT_SIZE = (320, 240)
#: LCN window at 320 pixels of width (Farabet/Couprie, METHOD_NOTES §8 [R]; not in the thesis).
LCN_WINDOW_AT_320 = 15
#: LCN floor of the local standard deviation (Torch7's threshold, as the shape views).
LCN_EPS = 1e-4
#: Smallest input side: two pools must leave at least one pixel.
MIN_SIDE = DOWNSAMPLE


def lcn_window(width: int) -> int:
    """The LCN window for inputs ``width`` pixels wide: ``15 * width / 320`` rounded half up to an
    odd integer, at least 3 (320 -> 15, 160 -> 9, 640 -> 31)."""
    w = _validate.integer("width", width, minimum=1)
    k = int(LCN_WINDOW_AT_320 * w / THESIS_INPUT_SIZE[0] + 0.5)
    return max(3, k if k % 2 else k + 1)


def _block_filters(width: int) -> tuple[int, int, int]:
    """Filters of the three blocks for ``width`` (the last block's filters; 256 -> 90, 128,
    256). The first block is a multiple of the 9 cue channels (its first layer is grouped)."""
    w = _validate.integer("width", width, minimum=1, maximum=4096)
    per_channel = max(1, int(THESIS_FILTERS[0] / N_CUES * w / THESIS_WIDTH + 0.5))
    second = max(1, int(THESIS_FILTERS[1] * w / THESIS_WIDTH + 0.5))
    return N_CUES * per_channel, second, w


class _LocalContrastNorm(nn.Module):
    """Local contrast normalisation of each channel on its own (no parameters): with ``B`` the
    mean over the ``window x window`` box of the pixels inside the image,
    ``v = x - B(x)``, ``sigma = sqrt(B(v^2))``, ``y = v / max(sigma, mean(sigma), eps)`` (the
    mean over each map). Same values as :func:`rgbd_rs.shapes.views.local_contrast_normalize`."""

    def __init__(self, window: int, eps: float = LCN_EPS) -> None:
        super().__init__()
        self.window = _validate.integer("window", window, minimum=1, maximum=1023)
        if self.window % 2 == 0:
            raise InvalidArgumentError(f"window: got {window}, expected an odd number of pixels")
        self.eps = _validate.real("eps", eps, positive=True)

    def _box(self, x: torch.Tensor) -> torch.Tensor:
        k = self.window
        return F.avg_pool2d(x, k, stride=1, padding=k // 2, count_include_pad=False)

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        """``N x C x H x W`` -> the same shape, each map normalised."""
        v = x - self._box(x)
        sigma = self._box(v * v).clamp_min(0).sqrt()
        floor = sigma.mean(dim=(-2, -1), keepdim=True).clamp_min(self.eps)
        return v / torch.maximum(sigma, floor)


#: The largest convolution kernel side :class:`_GroupedConv` takes.
MAX_KERNEL = 31


class _GroupedConv(nn.Module):
    """A convolution whose ``out_channels`` filters are split into ``groups`` groups, group i
    seeing input channel group i only: the weights of ``nn.Conv2d(..., groups=groups)``
    (``out x in/groups x k x k``), run as one dense convolution with the block-diagonal weight
    they span (torch's grouped convolution is ~10x slower on CPU than a dense one)."""

    def __init__(self, in_channels: int, out_channels: int, kernel: int, groups: int) -> None:
        super().__init__()
        in_channels = _validate.integer("in_channels", in_channels, minimum=1)
        out_channels = _validate.integer("out_channels", out_channels, minimum=1)
        kernel = _validate.integer("kernel", kernel, minimum=1, maximum=MAX_KERNEL)
        groups = _validate.integer("groups", groups, minimum=1)
        if in_channels % groups or out_channels % groups:
            raise InvalidArgumentError(
                f"groups: got {groups}, expected a divisor of {in_channels} and {out_channels}"
            )
        self.in_channels, self.out_channels, self.groups = in_channels, out_channels, groups
        self.kernel_size = (kernel, kernel)
        per_in = in_channels // groups
        self.weight = nn.Parameter(torch.empty(out_channels, per_in, kernel, kernel))
        self.bias = nn.Parameter(torch.zeros(out_channels))
        group_of_out = torch.arange(out_channels) // (out_channels // groups)
        group_of_in = torch.arange(in_channels) // per_in
        mask = (group_of_out[:, None] == group_of_in[None, :]).to(torch.float32)
        slot = torch.arange(in_channels) % per_in  # which of a group's inputs each channel is
        self.register_buffer("mask", mask, persistent=False)
        self.register_buffer("slot", slot, persistent=False)

    def dense_weight(self) -> torch.Tensor:
        """``out x in x k x k``: zero outside each filter's group."""
        w = self.weight.index_select(1, self.slot)  # type: ignore[arg-type]
        w = w * self.mask[:, :, None, None]  # type: ignore[index]
        return w.contiguous(memory_format=torch.channels_last)

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        pad = self.kernel_size[0] // 2
        return F.conv2d(x, self.dense_weight(), self.bias, padding=pad)


def _conv(c_in: int, c_out: int, groups: int = 1) -> nn.Module:
    if groups > 1:
        return _GroupedConv(c_in, c_out, KERNEL, groups)
    return nn.Conv2d(c_in, c_out, KERNEL, padding=KERNEL // 2)


class SemanticNet(nn.Module):
    """Fig. 4.3's ConvNet: ``N x 9 x H x W`` cues -> ``N x n_classes x H/4 x W/4`` logits.

    ``n_classes`` (14 in the thesis: NYUv2's 13 classes and unlabeled/unknown as class 0),
    ``width`` (the last block's filters, 256 in the thesis; see :func:`_block_filters`),
    ``lcn_window`` (odd pixels; default :func:`lcn_window` of the thesis' 320-pixel width).
    """

    def __init__(
        self,
        n_classes: int = THESIS_CLASSES,
        *,
        width: int = THESIS_WIDTH,
        lcn_window: int = LCN_WINDOW_AT_320,
    ) -> None:
        super().__init__()
        self.n_classes = _validate.integer("n_classes", n_classes, minimum=2, maximum=10_000)
        self.width = _validate.integer("width", width, minimum=1, maximum=4096)
        self.lcn_window = _validate.integer("lcn_window", lcn_window, minimum=1, maximum=1023)
        if self.lcn_window % 2 == 0:
            raise InvalidArgumentError(
                f"lcn_window: got {lcn_window}, expected an odd number of pixels"
            )
        self.filters = _block_filters(self.width)
        self.lcn = _LocalContrastNorm(self.lcn_window)
        layers: list[nn.Module] = []
        c = N_CUES
        for b, f in enumerate(self.filters):
            for k in range(CONVS_PER_BLOCK):
                first = b == 0 and k == 0
                layers.append(_conv(c, f, groups=N_CUES if first else 1))
                c = f
                last = b == len(self.filters) - 1 and k == CONVS_PER_BLOCK - 1
                if not last:  # no activation after the last convolution (§4.6)
                    layers.append(nn.Tanh())
            if b < len(self.filters) - 1:
                layers.append(nn.MaxPool2d(POOL))
        self.features = nn.Sequential(*layers)
        self.classifier = nn.Conv2d(c, self.n_classes, 1, bias=False)
        for m in self.modules():
            if isinstance(m, (nn.Conv2d, _GroupedConv)):
                nn.init.xavier_uniform_(m.weight, gain=nn.init.calculate_gain("tanh"))
                if m.bias is not None:
                    nn.init.zeros_(m.bias)
        # Channels-last convolutions: ~2x faster on CPU (oneDNN); same values, same state_dict.
        self.to(memory_format=torch.channels_last)

    def arch_config(self) -> dict[str, Any]:
        """The constructor arguments (what checkpoints store to rebuild the network)."""
        return {"n_classes": self.n_classes, "width": self.width, "lcn_window": self.lcn_window}

    @classmethod
    def from_config(cls, config: Mapping[str, Any]) -> SemanticNet:
        """Inverse of :meth:`arch_config`; missing or unknown keys raise naming them."""
        keys = {"n_classes", "width", "lcn_window"}
        if not isinstance(config, Mapping) or set(config) != keys:
            got = sorted(config) if isinstance(config, Mapping) else type(config).__name__
            raise InvalidArgumentError(f"arch_config: got {got}, expected keys {sorted(keys)}")
        return cls(config["n_classes"], width=config["width"], lcn_window=config["lcn_window"])

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        """Logits ``N x n_classes x floor(H/4) x floor(W/4)`` of ``N x 9 x H x W`` cues."""
        if not isinstance(x, torch.Tensor) or x.ndim != 4 or x.shape[1] != N_CUES:
            got = tuple(x.shape) if isinstance(x, torch.Tensor) else type(x).__name__
            raise ShapeMismatchError(f"x: got {got}, expected (N, {N_CUES}, H, W) cues")
        if x.dtype != torch.float32:
            raise InvalidArgumentError(f"x: got dtype {x.dtype}, expected torch.float32 cues")
        if min(x.shape[-2:]) < MIN_SIDE:
            raise ShapeMismatchError(
                f"x: got {x.shape[-2]} x {x.shape[-1]} pixels, expected sides >= {MIN_SIDE}"
            )
        x = self.lcn(x).contiguous(memory_format=torch.channels_last)
        return self.classifier(self.features(x))  # type: ignore[no-any-return]


def class_probabilities(
    logits: torch.Tensor,
    size: tuple[int, int] | None = None,
    *,
    ignore_index: int | None = 0,
) -> torch.Tensor:
    """Per-pixel class PDFs ``N x C x H x W`` of ``N x C x h x w`` logits: softmax over the
    classes with class ``ignore_index`` (None: none) at probability 0, then bilinearly upsampled
    to ``size`` = (height, width) when given (half-pixel centres, ``align_corners=False``).
    Every pixel's PDF sums to 1 (bilinear weights are convex)."""
    if not isinstance(logits, torch.Tensor) or logits.ndim != 4:
        got = tuple(logits.shape) if isinstance(logits, torch.Tensor) else type(logits).__name__
        raise ShapeMismatchError(f"logits: got {got}, expected (N, C, h, w)")
    if not logits.is_floating_point():
        raise InvalidArgumentError(f"logits: got dtype {logits.dtype}, expected floating point")
    c = int(logits.shape[1])
    if ignore_index is not None:
        ignore_index = _validate.integer("ignore_index", ignore_index, maximum=c - 1)
        if c < 3:
            raise ShapeMismatchError(
                f"logits: got {c} classes with one ignored, expected at least 3"
            )
        mask = torch.zeros(c, dtype=logits.dtype, device=logits.device)
        mask[ignore_index] = float("-inf")
        logits = logits + mask.view(1, c, 1, 1)
    p = torch.softmax(logits, dim=1)
    if size is not None:
        if not isinstance(size, (tuple, list)) or len(size) != 2:
            raise InvalidArgumentError(f"size: got {size!r}, expected (height, width)")
        h = _validate.integer("size[0]", size[0], minimum=1, maximum=_validate.MAX_SIDE)
        w = _validate.integer("size[1]", size[1], minimum=1, maximum=_validate.MAX_SIDE)
        if (h, w) != tuple(p.shape[-2:]):  # channels-last: the H x W x C view is contiguous
            p = p.contiguous(memory_format=torch.channels_last)
            p = F.interpolate(p, size=(h, w), mode="bilinear", align_corners=False)
    return p
