"""Per-pixel class PDFs of an RGB-D frame from the semantic ConvNet (thesis §4.6).

``SemanticLabeler.load()`` reads the weights shipped in the package
(``rgbd_rs/nn/weights/semantic_nyuv2.pt``: NYUv2's 13 classes, 0 = unlabeled) or any
``rgbd train semantic`` checkpoint. :meth:`SemanticLabeler.pdfs` computes the 9 cues of eq. 4.2
(:func:`rgbd_rs.segmentation.cues.semantic_cues`) at the frame's size, reduces them to the
network's input size (320 x 240 in the thesis) as the training cache did (block means), runs the
network and upsamples the 1/4-resolution PDFs bilinearly to the frame's size: ``H x W x C``
float32, each pixel summing to 1 over the classes, the unlabeled class at probability 0 (so the
class index is the NYUv2 ``label13`` value and region merging's Bhattacharyya similarity runs
over the 13 real classes). :meth:`SemanticLabeler.labels` is their argmax (1..13).
"""

from __future__ import annotations

import dataclasses
import os
from pathlib import Path
from typing import Any

import numpy as np
import numpy.typing as npt
import torch

from rgbd_rs import _validate
from rgbd_rs.camera import PinholeCamera
from rgbd_rs.errors import InvalidArgumentError, RgbdError, ShapeMismatchError
from rgbd_rs.nn.semantic import ARCH, N_CUES, SemanticNet, class_probabilities

__all__ = ["WEIGHT_FILE", "SemanticLabeler", "_weights_path"]

#: The cue function :meth:`SemanticLabeler.pdfs` runs (what the caches record by default).
CUE_FUNCTION = "rgbd_rs.segmentation.cues.semantic_cues"

#: The checkpoint the package ships (trained on synthetic scenes, fine-tuned on NYUv2 frames).
WEIGHT_FILE = "semantic_nyuv2.pt"
_WEIGHTS_DIR = Path(__file__).resolve().parents[1] / "nn" / "weights"


def _weights_path() -> Path:
    """Where the package keeps its semantic ConvNet weights (the file may be absent)."""
    return _WEIGHTS_DIR / WEIGHT_FILE


#: The largest cue magnitude the network sees (float16's, the training cache's dtype).
_F16_MAX = float(np.finfo(np.float16).max)


class SemanticLabeler:
    """A trained :class:`~rgbd_rs.nn.semantic.SemanticNet` with its input size (w, h), class
    names and ignored class (None: every class is a real one)."""

    def __init__(
        self,
        net: SemanticNet,
        input_size: tuple[int, int],
        classes: tuple[str, ...],
        *,
        ignore_index: int | None = 0,
        seed: int = 0,
        cues: str | None = CUE_FUNCTION,
        source: str = "",
    ) -> None:
        if not isinstance(net, SemanticNet):
            raise InvalidArgumentError(f"net: got {type(net).__name__}, expected a SemanticNet")
        if not isinstance(input_size, (tuple, list)) or len(input_size) != 2:
            raise InvalidArgumentError(f"input_size: got {input_size!r}, expected (width, height)")
        w = _validate.integer("input_size[0]", input_size[0], minimum=4, maximum=_validate.MAX_SIDE)
        h = _validate.integer("input_size[1]", input_size[1], minimum=4, maximum=_validate.MAX_SIDE)
        if (
            not isinstance(classes, (tuple, list))
            or len(classes) != net.n_classes
            or not all(isinstance(c, str) for c in classes)
        ):
            got = len(classes) if isinstance(classes, (tuple, list)) else type(classes).__name__
            raise InvalidArgumentError(
                f"classes: got {got} names, expected {net.n_classes} (str), the network's classes"
            )
        if ignore_index is not None:
            _validate.integer("ignore_index", ignore_index, maximum=net.n_classes - 1)
        self.net = net
        self.input_size = (w, h)
        self.classes = tuple(classes)
        self.ignore_index = ignore_index
        self.seed = _validate.integer("seed", seed, maximum=2**32 - 1)
        self.cues = cues
        self.source = source

    @classmethod
    def load(
        cls,
        path: str | os.PathLike[str] | None = None,
        *,
        n_classes: int | None = None,
        input_size: tuple[int, int] | None = None,
        device: str = "cpu",
    ) -> SemanticLabeler:
        """The shipped weights (``path=None``) or the checkpoint at ``path``. ``n_classes`` /
        ``input_size`` (w, h), when given, must be the checkpoint's (a pipeline built for 14
        classes refuses a 40-class network with a clear error instead of mislabeling)."""
        from rgbd_rs.nn.checkpoint import load_checkpoint

        _validate.device("device", device)
        if path is None:
            file = _weights_path()
            if not file.is_file():
                raise RgbdError(
                    f"{file}: no shipped semantic ConvNet weights in this installation; train "
                    "with `rgbd train semantic` and pass the checkpoint"
                )
        elif not isinstance(path, (str, os.PathLike)) or not str(path):
            raise InvalidArgumentError(f"path: got {path!r}, expected a checkpoint file")
        else:
            file = Path(path)
        if n_classes is not None:
            n_classes = _validate.integer("n_classes", n_classes, minimum=2)
        if input_size is not None and (
            not isinstance(input_size, (tuple, list)) or len(input_size) != 2
        ):
            raise InvalidArgumentError(f"input_size: got {input_size!r}, expected (width, height)")
        ckpt = load_checkpoint(file, arch=ARCH, normalisation_keys=("input_size", "classes"))
        norm = ckpt.normalisation
        try:
            net = SemanticNet.from_config(ckpt.arch_config)
            size = tuple(int(v) for v in norm["input_size"])
            classes = tuple(str(c) for c in norm["classes"])
            ignore = norm.get("ignore_index", 0)
            out = cls(
                net, size, classes,  # type: ignore[arg-type]
                ignore_index=None if ignore is None else int(ignore),
                seed=int(norm.get("cue_seed") or 0), cues=norm.get("cues", CUE_FUNCTION),
                source=str(file),
            )  # fmt: skip
        except (RgbdError, TypeError, ValueError) as exc:
            raise RgbdError(f"{file}: invalid semantic ConvNet checkpoint ({exc})") from None
        if n_classes is not None and n_classes != net.n_classes:
            raise RgbdError(
                f"{file}: a network of {net.n_classes} classes, expected {n_classes}; use a "
                f"checkpoint trained on {n_classes}-class labels"
            )
        if input_size is not None and tuple(input_size) != out.input_size:
            raise RgbdError(
                f"{file}: a network for {out.input_size[0]} x {out.input_size[1]} inputs, "
                f"expected {input_size[0]} x {input_size[1]}"
            )
        state = {k: v.float() if v.is_floating_point() else v for k, v in ckpt.model_state.items()}
        dataclasses.replace(ckpt, model_state=state).load_weights(net)
        net.to(device)
        net.eval()
        return out

    def pdfs_of_cues(
        self, cues: npt.ArrayLike | torch.Tensor, size: tuple[int, int] | None = None
    ) -> npt.NDArray[np.float32]:
        """PDFs of cues already at the network's input size: ``9 x h x w`` or ``N x 9 x h x w``
        -> ``h x w x C`` or ``N x h x w x C`` float32, upsampled to ``size`` = (height, width)
        when given (default: the cues' own size)."""
        x = cues if isinstance(cues, torch.Tensor) else torch.from_numpy(_cue_array(cues))
        single = x.ndim == 3
        if single:
            x = x[None]
        w, h = self.input_size
        if x.ndim != 4 or tuple(x.shape[1:]) != (N_CUES, h, w):
            raise ShapeMismatchError(
                f"cues: got shape {tuple(x.shape)}, expected ({N_CUES}, {h}, {w}) or "
                f"(N, {N_CUES}, {h}, {w}), the network's input size"
            )
        out_size = (h, w) if size is None else size
        device = next(self.net.parameters()).device
        with torch.inference_mode():
            # Missing cues (NaN, and inf as everywhere) count as 0 and the rest is clipped into
            # float16's range, as in the training cache (3e38 overflowed the LCN into NaN PDFs).
            x = torch.nan_to_num(x.to(device, torch.float32), nan=0.0, posinf=0.0, neginf=0.0)
            x = x.clamp(-_F16_MAX, _F16_MAX)
            logits = self.net(x)
            p = class_probabilities(logits, out_size, ignore_index=self.ignore_index)
        arr = np.ascontiguousarray(p.permute(0, 2, 3, 1).cpu().numpy(), dtype=np.float32)
        return arr[0] if single else arr

    def pdfs_from_full_cues(self, cues: npt.ArrayLike) -> npt.NDArray[np.float32]:
        """PDFs (``H x W x C``) of a frame's ``9 x H x W`` cues at its own size (what
        :func:`~rgbd_rs.segmentation.cues.semantic_cues` returns): reduced to the input size,
        classified, upsampled back to ``H x W``."""
        from rgbd_rs.segmentation.semantic_data import downsample_cues

        x = _cue_array(cues)
        if x.ndim != 3 or x.shape[0] != N_CUES:
            raise ShapeMismatchError(
                f"cues: got shape {x.shape}, expected ({N_CUES}, H, W), the 9 cues of eq. 4.2"
            )
        self._fits_input("cues", x.shape[2], x.shape[1])
        small = downsample_cues(x, self.input_size)
        return self.pdfs_of_cues(small, (int(x.shape[1]), int(x.shape[2])))

    def _fits_input(self, name: str, width: int, height: int) -> None:
        """Refuses a frame smaller than the network's input (the cues are reduced to it, never
        enlarged)."""
        w, h = self.input_size
        if width < w or height < h:
            raise ShapeMismatchError(
                f"{name}: got a {width}x{height} frame, smaller than the labeling network's "
                f"{w}x{h} input; expected a frame at least {w}x{h}"
            )

    def pdfs(
        self, rgb: npt.ArrayLike, depth: npt.ArrayLike, camera: PinholeCamera
    ) -> npt.NDArray[np.float32]:
        """``H x W x C`` float32 class PDFs of a frame (``rgb`` H x W x 3 uint8, ``depth`` H x W
        float32 metres, NaN = hole, ``camera`` their intrinsics); every pixel sums to 1 (holes
        too: their cues are the colour ones, geometry 0)."""
        from rgbd_rs.segmentation.cues import semantic_cues

        if self.cues not in (None, CUE_FUNCTION):
            raise RgbdError(
                f"{self.source}: a network trained on the cues of {self.cues}, not "
                f"{CUE_FUNCTION}; compute those and call pdfs_from_full_cues"
            )
        shape = tuple(getattr(rgb, "shape", ()))
        if len(shape) == 3:  # checked before the cues are computed (the cues check the rest)
            self._fits_input("rgb", int(shape[1]), int(shape[0]))
        return self.pdfs_from_full_cues(semantic_cues(rgb, depth, camera, seed=self.seed))

    def labels(
        self, rgb: npt.ArrayLike, depth: npt.ArrayLike, camera: PinholeCamera
    ) -> npt.NDArray[np.uint8]:
        """``H x W`` uint8 class of each pixel (argmax of :meth:`pdfs`; never the ignored
        class)."""
        out: npt.NDArray[np.uint8] = self.pdfs(rgb, depth, camera).argmax(axis=-1).astype(np.uint8)
        return out


def _cue_array(cues: Any) -> np.ndarray:
    x = _validate.asarray("cues", cues)
    if x.dtype.kind not in "iuf":
        raise InvalidArgumentError(f"cues: got dtype {x.dtype}, expected real numbers")
    if x.ndim not in (3, 4):
        raise ShapeMismatchError(
            f"cues: got shape {x.shape}, expected ({N_CUES}, H, W) or (N, {N_CUES}, H, W)"
        )
    return np.ascontiguousarray(x, dtype=np.float32)
