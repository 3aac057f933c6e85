"""The ToF + stereo confidence ConvNet of thesis §3.6 (Fig. 3.3).

Six convolutions, ReLU after all but the last, ``width`` filters (128 in the thesis) in the first
five and 2 in the last, 5x5 then 3x3, no pooling. The input is padded by 7 pixels by replicating
its border (2 for the 5x5 layer + 5 x 1 for the 3x3 ones) and every convolution is "valid", so the
output has exactly the input's size and no layer sees zero padding. Output channel 0 is the ToF
confidence P_T, channel 1 the stereo confidence P_S; training regresses them with an MSE loss
(§3.7) and :func:`predict` clamps them to [0, 1].
"""

from __future__ import annotations

import contextlib
from collections.abc import Iterator
from pathlib import Path
from typing import Any, Literal, cast

import numpy as np
import numpy.typing as npt
import torch
from torch import nn
from torch.nn import functional as F

from rgbd_rs import _validate
from rgbd_rs.errors import InvalidArgumentError, RgbdError, ShapeMismatchError

#: Name stored in checkpoints; a checkpoint of another architecture is refused.
ARCH = "confidence-convnet/1"
#: Channels in and out.
IN_CHANNELS = 4
OUT_CHANNELS = 2
#: Replicate padding that makes the output the input's size: (5 - 1)/2 + 5 * (3 - 1)/2.
PAD = 7


def _check_input(x: object, min_side: int) -> None:
    if not (
        isinstance(x, torch.Tensor)
        and x.ndim == 4
        and x.shape[1] == IN_CHANNELS
        and min(x.shape[2:]) >= min_side
    ):
        shape = tuple(x.shape) if isinstance(x, torch.Tensor) else type(x).__name__
        raise ShapeMismatchError(
            f"x: got shape {shape}, expected (N, {IN_CHANNELS}, H, W) with H, W >= {min_side}"
        )
    if x.dtype != torch.float32:
        raise InvalidArgumentError(f"x: got dtype {x.dtype}, expected torch.float32 clues")


class ConfidenceNet(nn.Module):
    """Fig. 3.3's network; ``width`` filters in the five hidden layers."""

    def __init__(self, width: int = 128) -> None:
        super().__init__()
        w = _validate.integer("width", width, minimum=1, maximum=4096)
        self.width = w
        layers: list[nn.Module] = [nn.Conv2d(IN_CHANNELS, w, 5)]
        layers += [nn.Conv2d(w, w, 3) for _ in range(4)]
        layers.append(nn.Conv2d(w, OUT_CHANNELS, 3))
        self.layers = nn.ModuleList(layers)
        for conv in self.layers:
            assert isinstance(conv, nn.Conv2d)
            nn.init.xavier_uniform_(conv.weight)  # §3.7: Xavier initialisation
            assert conv.bias is not None
            nn.init.zeros_(conv.bias)

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        """``N x 4 x H x W`` normalised clues -> ``N x 2 x H x W`` (P_T, P_S), unclamped."""
        _check_input(x, 1)
        return self.body(F.pad(x, (PAD, PAD, PAD, PAD), mode="replicate"))

    def body(self, x: torch.Tensor) -> torch.Tensor:
        """The six convolutions on an input already padded by :data:`PAD` pixels (the output is
        ``2 * PAD`` smaller in each direction)."""
        _check_input(x, 2 * PAD + 1)
        y = x
        for i, conv in enumerate(self.layers):
            y = conv(y)
            if i < len(self.layers) - 1:
                y = F.relu(y)
        return y


#: :func:`predict`'s arithmetic: ``"float32"`` (on CUDA too: TF32 is switched off);
#: ``"bfloat16"`` (convolutions in bfloat16 with float32 accumulation, ~2x faster where the CPU
#: has native bfloat16 instructions; the confidences move by < 0.01); ``"auto"``: bfloat16 where
#: the CPU has them, else float32.
PRECISIONS = ("auto", "float32", "bfloat16")
Precision = Literal["auto", "float32", "bfloat16"]
#: What :class:`ConfidenceEstimator` (and so :func:`~rgbd_rs.fusion.fuse`) uses by default.
DEFAULT_PRECISION: Precision = "auto"


def _native_bfloat16() -> bool:
    """Whether this CPU runs bfloat16 convolutions natively (AVX-512 BF16 or AMX)."""
    # Not torch.ops.mkldnn._is_mkldnn_bf16_supported(): that is true on every AVX-512 CPU, where
    # oneDNN emulates bfloat16 (slower than float32) unless AVX512_BF16 or AMX is there.
    checks = ("_is_avx512_bf16_supported", "_is_amx_tile_supported")
    try:
        return any(bool(getattr(torch.cpu, name, lambda: False)()) for name in checks)
    except RuntimeError:
        return False


def _resolve_precision(precision: str, device: str = "cpu") -> Literal["float32", "bfloat16"]:
    """``precision`` validated, ``"auto"`` resolved for this CPU (see :data:`PRECISIONS`; float32
    on any other ``device``)."""
    p = _validate.choice("precision", precision, PRECISIONS)
    if p == "auto":
        return "bfloat16" if device == "cpu" and _native_bfloat16() else "float32"
    return cast(Literal["float32", "bfloat16"], p)


def predict(
    net: ConfidenceNet,
    inputs: npt.ArrayLike,
    *,
    tile: int | None = None,
    precision: Precision = "float32",
) -> tuple[npt.NDArray[np.float32], npt.NDArray[np.float32]]:
    """``(P_T, P_S)`` in [0, 1] for a ``4 x H x W`` normalised clue image.

    Runs in tiles with a 7-pixel halo (the receptive field's radius), so memory stays bounded on
    large images and the result equals a whole-image pass: ``tile`` x ``tile`` output pixels,
    or with ``tile=None`` the shape :func:`_tile_shape` chooses for the precision.
    ``precision``: see :data:`PRECISIONS` (the result is the same for any thread count either
    way; the tiling changes the time, and the result by float rounding at most).
    """
    if not isinstance(net, ConfidenceNet):
        raise InvalidArgumentError(f"net: got {type(net).__name__}, expected a ConfidenceNet")
    x = _validate.array("inputs", inputs, shape=(IN_CHANNELS, None, None), finite=True)
    t = None if tile is None else _validate.integer("tile", tile, minimum=16, maximum=8192)
    half = _resolve_precision(precision, next(net.parameters()).device.type) == "bfloat16"
    h, w = x.shape[1:]
    th, tw = _tile_shape(h, w, half) if t is None else (t, t)
    device = next(net.parameters()).device
    out = np.empty((OUT_CHANNELS, h, w), np.float32)
    # Replicate-pad once here, channels last (H x W x C); each tile then takes its halo from
    # real or replicated pixels, exactly what the whole-image pass would see. Channels-last is
    # oneDNN's direct convolution path, ~15 % less CPU than NCHW (same sums in another order:
    # outputs differ by ~1e-6); a full-width stripe of it is already a contiguous input.
    padded = np.pad(x.transpose(1, 2, 0), ((PAD, PAD), (PAD, PAD), (0, 0)), mode="edge")
    net.eval()
    with torch.inference_mode(), _exact_float32(device, half):
        fused = _fused_layers(net, half)
        for y0 in range(0, h, th):
            for x0 in range(0, w, tw):
                y1, x1 = min(h, y0 + th), min(w, x0 + tw)
                patch = np.ascontiguousarray(padded[y0 : y1 + 2 * PAD, x0 : x1 + 2 * PAD])
                inp = torch.from_numpy(patch).permute(2, 0, 1)[None].to(device)
                inp = inp.contiguous(memory_format=torch.channels_last)
                y = _fused_body(fused, inp, half) if fused is not None else None
                if y is None:
                    fused = None  # the fused path refused this input: the plain one from here
                    with torch.autocast(device.type, dtype=torch.bfloat16, enabled=half):
                        y = net.body(inp)
                out[:, y0:y1, x0:x1] = y[0].float().clamp_(0, 1).cpu().numpy()
    return out[0], out[1]


#: Each layer's ``(weight, bias)`` for :func:`_fused_body`.
_Layers = list[tuple[torch.Tensor, torch.Tensor]]


def _fused_layers(net: ConfidenceNet, half: bool) -> _Layers | None:
    """The network's weights for :func:`_fused_body` (cast to bfloat16 with ``half``, as
    autocast casts them), or None where that path is not available: not on the CPU, or a torch
    without oneDNN's fused convolution."""
    mkldnn = bool(torch.backends.mkldnn.is_available())  # type: ignore[no-untyped-call]
    if next(net.parameters()).device.type != "cpu" or not mkldnn:
        return None
    if getattr(torch.ops.mkldnn, "_convolution_pointwise", None) is None:
        return None
    dtype = torch.bfloat16 if half else torch.float32
    layers = []
    for conv in net.layers:
        assert isinstance(conv, nn.Conv2d) and conv.bias is not None
        weight = conv.weight.to(dtype).contiguous(memory_format=torch.channels_last)
        layers.append((weight, conv.bias.to(dtype)))
    return layers


def _fused_body(layers: _Layers, x: torch.Tensor, half: bool) -> torch.Tensor | None:
    """:meth:`ConfidenceNet.body` of a padded channels-last input on the CPU, each ReLU fused
    into its convolution as a oneDNN post-op: the same convolutions, the ReLU applied before
    the output is written instead of as a pass of its own over it (ReLU commutes with rounding
    to bfloat16), so the same values wherever the plain forward runs oneDNN's convolution too
    (always in bfloat16; in float32 on all but small inputs, where torch sums in another order:
    ~1e-7 apart; tested); 2.2x faster in bfloat16 on the AMX CPU the choice was measured on,
    ~10 % in float32 (docs/experiments.md). None where oneDNN refuses the input (then
    :meth:`~ConfidenceNet.body` runs)."""
    conv = torch.ops.mkldnn._convolution_pointwise
    y = x.to(torch.bfloat16) if half else x
    last = len(layers) - 1
    try:
        for i, (weight, bias) in enumerate(layers):
            post = "relu" if i < last else "none"
            y = conv(y, weight, bias, [0, 0], [1, 1], [1, 1], 1, post, [], "")
    except RuntimeError:
        return None
    return y


#: :func:`_tile_shape`'s bfloat16 tiles: at most this many input pixels (the output and its
#: 7-px halo, which sizes the activations), in stripes at most :data:`STRIPE_WIDTH` wide: 135 x
#: 960 output pixels at 960x540. Measured (``predict`` alone, AMX bfloat16, 2 threads): 960x540
#: in 256 x 256 squares 50 ms, in four 135 x 960 stripes 38 ms; 1920x1080 202 -> 155 ms;
#: 640x480 30 -> 25 ms; squares of 480 or one whole-image pass were slower (docs/speed.md).
STRIPE_PIXELS = 9 << 14
#: The widest stripe :func:`_tile_shape` makes (wider images are cut into equal columns too).
STRIPE_WIDTH = 1024
#: :func:`_tile_shape`'s float32 tiles (squares; stripes of :data:`STRIPE_PIXELS` were 5-15 %
#: slower there).
SQUARE_TILE = 256


def _tile_shape(height: int, width: int, half: bool) -> tuple[int, int]:
    """``(rows, columns)`` of :func:`predict`'s output tiles for a ``height x width`` image: in
    bfloat16 (``half``) equal stripes of at most :data:`STRIPE_PIXELS` input pixels (halo
    included), at most :data:`STRIPE_WIDTH` wide; in float32 :data:`SQUARE_TILE` squares."""
    if not half:
        return SQUARE_TILE, SQUARE_TILE
    columns = -(-width // STRIPE_WIDTH)
    tw = -(-width // columns)
    most = max(1, STRIPE_PIXELS // (tw + 2 * PAD) - 2 * PAD)
    stripes = -(-height // most)
    return -(-height // stripes), tw


@contextlib.contextmanager
def _exact_float32(device: torch.device, half: bool) -> Iterator[None]:
    """float32 on CUDA means float32: cuDNN would otherwise run the convolutions in TF32 (its
    default), whose outputs differ from the CPU's by ~1e-3. Only that flag changes, and it is
    restored afterwards."""
    if device.type != "cuda" or half:
        yield
        return
    before = torch.backends.cudnn.allow_tf32
    torch.backends.cudnn.allow_tf32 = False
    try:
        yield
    finally:
        torch.backends.cudnn.allow_tf32 = before


#: The shipped checkpoint (trained by ``rgbd train confidence``; README: training recipe).
WEIGHTS = Path(__file__).parent / "weights" / "confidence.pt"
#: The shipped checkpoint for fusing on the camera of the pair farther from the ToF (the same
#: network fine-tuned with such cases, docs/training.md): :func:`~rgbd_rs.fusion.fuse` uses it
#: there by itself. It is not the default elsewhere: on the camera beside the ToF it damaged a
#: precise ToF on rendered validation scenes the default handles (docs/experiments.md).
WEIGHTS_FAR = Path(__file__).parent / "weights" / "confidence_far.pt"
#: Checkpoint normalisation key of :attr:`ConfidenceEstimator.stereo_power` (optional; 1 if absent).
STEREO_POWER_KEY = "lc_stereo_power"
#: Checkpoint normalisation key of :attr:`ConfidenceEstimator.matcher` (optional; ``"opencv"``,
#: the matcher of the checkpoints written before it existed, if absent).
MATCHER_KEY = "stereo_matcher"
MATCHERS = ("census", "opencv")


class ConfidenceEstimator:
    """A trained :class:`ConfidenceNet` with the clue normalisation it was trained with.

    ``ConfidenceEstimator.load()`` reads the checkpoint shipped in the package (no download);
    ``load(path)`` any checkpoint written by ``rgbd train confidence``. A checkpoint of another
    architecture or without the normalisation raises :class:`~rgbd_rs.RgbdError` naming the file.

    ``stereo_power`` calibrates the stereo confidence for the LC accumulation: the estimator
    returns ``P_S ** stereo_power``. It is stored in the checkpoint (normalisation key
    :data:`STEREO_POWER_KEY`, written by ``rgbd train calibrate-confidence``, which chooses it on
    validation scenes); a checkpoint without it uses 1 (the network's output as it is).

    ``matcher`` is the stereo matcher whose disparities the network was trained on (its clues
    come from them; :func:`~rgbd_rs.fusion.fuse` runs that matcher with this estimator),
    normalisation key :data:`MATCHER_KEY`.

    ``precision`` is the arithmetic of the network's convolutions (:data:`PRECISIONS`; default
    :data:`DEFAULT_PRECISION`).
    """

    def __init__(
        self,
        net: ConfidenceNet,
        sigmas: npt.ArrayLike,
        source: str = "",
        *,
        stereo_power: float = 1.0,
        matcher: str = "opencv",
        precision: Precision = DEFAULT_PRECISION,
    ) -> None:
        if not isinstance(net, ConfidenceNet):
            raise InvalidArgumentError(f"net: got {type(net).__name__}, expected a ConfidenceNet")
        # Channels-last weights to match predict()'s channels-last inputs.
        self.net = net.to(memory_format=torch.channels_last)
        self.sigmas = _validate.array("sigmas", sigmas, shape=(IN_CHANNELS,), finite=True)
        if not isinstance(source, str):
            raise InvalidArgumentError(
                f"source: got {type(source).__name__}, expected a str (where the weights came from)"
            )
        self.source = source
        self.stereo_power = _validate.real("stereo_power", stereo_power, positive=True)
        self.matcher: Literal["census", "opencv"] = cast(
            Literal["census", "opencv"], _validate.choice("matcher", matcher, MATCHERS)
        )
        _resolve_precision(precision)
        self.precision: Precision = precision

    def _with(self, **changes: Any) -> ConfidenceEstimator:
        """This estimator with some keyword arguments of the constructor changed."""
        kw: dict[str, Any] = {
            "stereo_power": self.stereo_power,
            "matcher": self.matcher,
            "precision": self.precision,
        }
        return ConfidenceEstimator(self.net, self.sigmas, self.source, **(kw | changes))

    def with_stereo_power(self, power: float) -> ConfidenceEstimator:
        """The same network and normalisation with another stereo calibration power."""
        return self._with(stereo_power=power)

    def with_precision(self, precision: Precision) -> ConfidenceEstimator:
        """The same estimator computing in another precision (:data:`PRECISIONS`)."""
        return self._with(precision=precision)

    @classmethod
    def load(
        cls,
        path: str | Path | None = None,
        *,
        device: str = "cpu",
        precision: Precision = DEFAULT_PRECISION,
    ) -> ConfidenceEstimator:
        """The shipped weights (``path=None``: :data:`WEIGHTS`, those for the camera beside the
        ToF) or the checkpoint at ``path`` (:data:`WEIGHTS_FAR` for the far camera), computing
        in ``precision`` (:data:`PRECISIONS`)."""
        from rgbd_rs.nn.checkpoint import load_checkpoint

        _validate.device("device", device)
        file = WEIGHTS if path is None else _validate.path("path", path)
        ckpt = load_checkpoint(file, arch=ARCH, normalisation_keys=("sigmas",))
        width = ckpt.arch_config.get("width")
        if not isinstance(width, int) or isinstance(width, bool):
            raise RgbdError(f"{file}: arch_config holds no integer 'width' ({ckpt.arch_config})")
        net = ConfidenceNet(width)
        ckpt.load_weights(net)
        net.to(device)
        power = ckpt.normalisation.get(STEREO_POWER_KEY, 1.0)
        if not isinstance(power, (int, float)) or isinstance(power, bool) or not power > 0:
            raise RgbdError(
                f"{file}: normalisation {STEREO_POWER_KEY!r} is {power!r}, expected a number > 0"
            )
        matcher = ckpt.normalisation.get(MATCHER_KEY, "opencv")
        if matcher not in MATCHERS:
            raise RgbdError(
                f"{file}: normalisation {MATCHER_KEY!r} is {matcher!r}, expected one of {MATCHERS}"
            )
        return cls(
            net,
            ckpt.normalisation["sigmas"],
            str(file),
            stereo_power=float(power),
            matcher=str(matcher),
            precision=precision,
        )

    def __call__(
        self,
        reference_image: npt.ArrayLike,
        target_image: npt.ArrayLike,
        tof_disparity: npt.ArrayLike,
        tof_amplitude: npt.ArrayLike,
        stereo_disparity: npt.ArrayLike,
        *,
        reference: Literal["left", "right"] = "right",
    ) -> tuple[npt.NDArray[np.float32], npt.NDArray[np.float32]]:
        """``(P_T, P_S)`` on the reference camera, 0 where the source has no disparity
        (``P_S`` raised to :attr:`stereo_power`)."""
        from rgbd_rs.fusion.clues import _normalise, compute_clues

        clues = compute_clues(
            reference_image,
            target_image,
            tof_disparity,
            tof_amplitude,
            stereo_disparity,
            reference=reference,
        )
        p_t, p_s = predict(self.net, _normalise(clues, self.sigmas), precision=self.precision)
        p_t = np.where(np.isfinite(clues.maps[1]), p_t, 0).astype(np.float32)
        weighted = np.where(np.isfinite(clues.maps[2]), p_s, 0) ** self.stereo_power
        return p_t, weighted.astype(np.float32)
