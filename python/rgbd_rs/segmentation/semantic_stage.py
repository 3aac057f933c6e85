"""The semantic stage of :func:`~rgbd_rs.segmentation.segment` (thesis §4.6-4.7): choose the
ConvNet, and compute its class PDFs from the stages the pipeline already ran.

``labeler="auto"`` (the default of ``segment``) runs the weights shipped in the package when
they are installed and falls back to fit-only merging (with a one-time warning) when they are
not; ``None`` asks for the fit-only baseline; a :class:`SemanticLabeler` or a checkpoint path
runs that network. The PDFs reuse the pipeline's features, over-segmentation and spline fits, so
the cues of eq. 4.2 cost only the HHA and the per-pixel maps.
"""

from __future__ import annotations

import os
import warnings
from functools import lru_cache
from pathlib import Path

import numpy as np
import numpy.typing as npt

from rgbd_rs.camera import PinholeCamera
from rgbd_rs.errors import InvalidArgumentError, RgbdError
from rgbd_rs.segmentation.cues import SemanticCues, cue_maps
from rgbd_rs.segmentation.features import Features
from rgbd_rs.segmentation.hha import HhaResult
from rgbd_rs.segmentation.labeling import CUE_FUNCTION, SemanticLabeler, _weights_path
from rgbd_rs.segmentation.oversegment import DEFAULT_N_SEGMENTS
from rgbd_rs.surface import SegmentFits

__all__ = ["AUTO", "LabelerArg"]

#: ``labeler`` value: the shipped weights when installed, else fit-only merging.
AUTO = "auto"

LabelerArg = SemanticLabeler | str | os.PathLike[str] | None


@lru_cache(maxsize=4)
def _load(path: str, stamp: float) -> SemanticLabeler:
    """Checkpoints loaded once per process (keyed by path and modification time)."""
    return SemanticLabeler.load(None if path == "" else path)


_warned: set[str] = set()


def _resolve_labeler(labeler: LabelerArg) -> SemanticLabeler | None:
    """The labeler ``labeler`` names (see the module docstring); None for fit-only merging."""
    if labeler is None or isinstance(labeler, SemanticLabeler):
        return labeler
    if isinstance(labeler, str) and labeler == AUTO:
        file = _weights_path()
        if not file.is_file():
            if AUTO not in _warned:
                _warned.add(AUTO)
                warnings.warn(
                    f"{file}: no shipped semantic ConvNet weights; segment() merges by surface "
                    "fits only (pass labeler=None to choose that without this warning)",
                    stacklevel=3,
                )
            return None
        return _load("", file.stat().st_mtime)
    if isinstance(labeler, (str, os.PathLike)) and str(labeler):
        file = Path(labeler)
        if not file.is_file():
            raise RgbdError(f"labeler: {file}: no such checkpoint file")
        return _load(str(file), file.stat().st_mtime)
    raise InvalidArgumentError(
        f"labeler: got {labeler!r:.60}, expected 'auto', None, a SemanticLabeler or a "
        "checkpoint path"
    )


def _class_pdfs(
    labeler: SemanticLabeler,
    rgb: npt.ArrayLike,
    depth: npt.ArrayLike,
    camera: PinholeCamera,
    *,
    feats: Features,
    hha: HhaResult,
    over: npt.NDArray[np.int32],
    fits: SegmentFits,
    n_segments: int,
    seed: int,
) -> tuple[npt.NDArray[np.float32], SemanticCues]:
    """``H x W x C`` PDFs of the frame and the cues they came from; ``hha`` is the frame's
    :func:`~rgbd_rs.segmentation.hha.hha_details`, ``fits`` must hold the surface fits of
    ``over`` (``surfaces=True``) and must not have merged yet.

    ``over`` (made with ``n_segments`` clusters and ``seed``) is reused for the cues only when
    those are the settings the network's training cues used (the cue function's default cluster
    count and the labeler's seed); otherwise the cues get their own over-segmentation and fits,
    so the network always sees the kind of input it was trained on."""
    if labeler.cues not in (None, CUE_FUNCTION):
        raise RgbdError(
            f"{labeler.source}: a network trained on the cues of {labeler.cues}, not "
            f"{CUE_FUNCTION}; segment() can only run networks trained on the latter"
        )
    if n_segments == DEFAULT_N_SEGMENTS and seed == labeler.seed:
        cues = cue_maps(rgb, depth, camera, feats=feats, over=over, fits=fits, hha_image=hha.image)
    else:
        cues = cue_maps(rgb, depth, camera, feats=feats, hha_image=hha.image, seed=labeler.seed)
    return labeler.pdfs_from_full_cues(cues.stack()), cues
