"""The nine per-pixel cues of the semantic-labeling ConvNet (thesis eq. 4.2, §4.6).

``R, G, B`` (colour in [0, 1]), the three HHA channels (Gupta et al. 2014, scaled to [0, 1]),
and three surface-fitting cues from the spline fits of the over-segmentation's segments (§4.5):
the fitting error ``f`` (distance of each pixel's 3-D point to its segment's surface, metres) and
the principal curvatures ``c1 >= c2`` (1/m) of that surface at the pixel.

Where a cue is undefined (no depth, a segment too small to fit) it is 0. The fitting cues have
heavy tails at depth edges and on tiny segments: the error, and the two curvatures jointly, are
clipped to ``±`` their :data:`CLIP_PERCENTILE`-th percentile of absolute values over the frame, a
rule without a unit (metres vs millimetres and any scene scale give the same cue up to one
factor, which the network's per-channel local contrast normalisation removes). The thesis does
not say how it bounded these cues (METHOD_NOTES §5 and its summary of gaps): the clip is ours.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

from rgbd_rs import _validate
from rgbd_rs._array_eq import array_eq
from rgbd_rs.camera import PinholeCamera
from rgbd_rs.errors import InvalidArgumentError, ShapeMismatchError
from rgbd_rs.segmentation.features import Features, features
from rgbd_rs.segmentation.hha import hha_details
from rgbd_rs.segmentation.oversegment import DEFAULT_N_SEGMENTS, oversegment
from rgbd_rs.surface import SegmentFits

__all__ = ["CHANNELS", "CLIP_PERCENTILE", "SemanticCues", "cue_maps", "semantic_cues"]

F32 = npt.NDArray[np.float32]
U8 = npt.NDArray[np.uint8]
I32 = npt.NDArray[np.int32]

#: Channel names of :meth:`SemanticCues.stack`, in order (eq. 4.2).
CHANNELS: tuple[str, ...] = (
    "r",
    "g",
    "b",
    "hha_disparity",
    "hha_height",
    "hha_angle",
    "f",
    "c1",
    "c2",
)
#: Percentile of |cue| over a frame at which the fitting error and curvatures are clipped.
CLIP_PERCENTILE = 99.0


@array_eq
@dataclass(frozen=True)
class SemanticCues:
    """The cues of one frame and what they were computed from."""

    #: ``H x W x 3`` uint8 colour.
    rgb: U8
    #: ``H x W x 3`` uint8 HHA image.
    hha: U8
    #: ``H x W`` fitting error (metres, clipped), 0 where undefined.
    error: F32
    #: ``H x W`` larger / smaller principal curvature (1/m, clipped), 0 where undefined.
    k1: F32
    k2: F32
    #: ``H x W`` int32 over-segmentation whose segments were fitted (-1 = no depth).
    over: I32

    def stack(self) -> F32:
        """``9 x H x W`` float32 in :data:`CHANNELS` order: colour and HHA in [0, 1]."""
        out = np.empty((9, *self.error.shape), np.float32)
        out[0:3] = np.moveaxis(self.rgb, -1, 0) / np.float32(255)
        out[3:6] = np.moveaxis(self.hha, -1, 0) / np.float32(255)
        out[6] = self.error
        out[7] = self.k1
        out[8] = self.k2
        return out


def _clip(*maps: F32) -> list[F32]:
    """NaN -> 0, then clip to the frame's :data:`CLIP_PERCENTILE`-th percentile of |value| over
    all ``maps`` together (one bound for k1 and k2 keeps ``k1 >= k2``)."""
    vs = [np.nan_to_num(m.astype(np.float32), nan=0.0, posinf=0.0, neginf=0.0) for m in maps]
    nz = np.concatenate([np.abs(v[v != 0]) for v in vs])
    if nz.size:
        bound = np.float32(np.percentile(nz, CLIP_PERCENTILE))
        for v in vs:
            np.clip(v, -bound, bound, out=v)
    return vs


def cue_maps(
    rgb: npt.ArrayLike,
    depth: npt.ArrayLike,
    camera: PinholeCamera,
    *,
    feats: Features | None = None,
    over: npt.ArrayLike | None = None,
    fits: SegmentFits | None = None,
    hha_image: npt.ArrayLike | None = None,
    n_segments: int = DEFAULT_N_SEGMENTS,
    seed: int = 0,
) -> SemanticCues:
    """The cues of eq. 4.2 with their parts; any stage already computed can be passed in.

    Args:
        rgb: ``H x W x 3`` uint8 colour registered to ``depth``.
        depth: ``H x W`` metres, NaN/0 = missing.
        camera: the ideal pinhole of both images.
        feats: :func:`~rgbd_rs.segmentation.features` of the frame (else computed).
        over: the over-segmentation (``H x W`` int, -1 = none; else :func:`oversegment` with
            ``n_segments`` clusters and ``seed``).
        fits: :class:`~rgbd_rs.surface.SegmentFits` of ``over`` built with ``surfaces=True``
            (else built here with the defaults).
        hha_image: the frame's HHA (else computed).

    Raises:
        InvalidArgumentError / ShapeMismatchError: as the stages they call, and for parts that
            do not match the frame.
    """
    f = features(rgb, depth, camera) if feats is None else feats
    if not isinstance(f, Features):
        raise InvalidArgumentError(f"feats: got {type(f).__name__}, expected Features or None")
    h, w = f.points.shape[:2]
    if over is None:
        seg = oversegment(f.vectors, n_segments, seed=seed, quiet=True)
    else:
        seg = _validate.array("over", np.asarray(over), shape=(h, w), dtype=np.int32)
    if fits is None:
        fits = SegmentFits(f.points, seg)
    elif not isinstance(fits, SegmentFits):
        raise InvalidArgumentError(f"fits: got {type(fits).__name__}, expected SegmentFits")
    elif fits.shape != (h, w):
        raise ShapeMismatchError(f"fits: got fits of a {fits.shape} image, expected {(h, w)}")
    maps = fits.maps(f.points)
    if hha_image is None:
        hh = hha_details(depth, camera).image
    else:
        hh = _validate.array("hha_image", hha_image, shape=(h, w, 3), dtype=np.uint8)
    colour = _validate.array("rgb", rgb, shape=(h, w, 3), dtype=np.uint8)
    (error,) = _clip(maps.error)
    k1, k2 = _clip(maps.k1, maps.k2)
    return SemanticCues(
        rgb=colour,
        hha=hh,
        error=error,
        k1=k1,
        k2=k2,
        over=seg.astype(np.int32, copy=False),
    )


def semantic_cues(
    rgb: npt.ArrayLike,
    depth: npt.ArrayLike,
    camera: PinholeCamera,
    *,
    n_segments: int = DEFAULT_N_SEGMENTS,
    seed: int = 0,
) -> F32:
    """``9 x H x W`` float32 network input of one frame (:data:`CHANNELS`; see the module
    docstring). Deterministic given ``seed`` (the over-segmentation's)."""
    return cue_maps(rgb, depth, camera, n_segments=n_segments, seed=seed).stack()
