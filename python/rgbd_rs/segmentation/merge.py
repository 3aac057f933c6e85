"""Region merging (thesis §4.7, Algorithm 1) and its fit-only baseline (the thesis' ref. [74]).

:func:`adjacency` finds the couples of touching segments whose shared boundary passes the depth,
colour and normal tests of eq. 4.3-4.5; :func:`merge_regions` runs Algorithm 1 on them: with
per-pixel class PDFs, couples whose Bhattacharyya similarity (eq. 4.7) of mean PDFs (eq. 4.6)
reaches ``t_sim`` are processed in order of similarity and merged when the spline fit of the
union passes eq. 4.8 (:meth:`rgbd_rs.surface.SegmentFits.should_merge`); without PDFs, couples
that pass eq. 4.8 are merged in order of relative fit improvement
``1 - e_ij (n_i + n_j) / (e_i n_i + e_j n_j)``. The queue, the fits and the bookkeeping run in
Rust (``crates/rgbd-segment``).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

from rgbd_rs import _rgbd_rs, _validate
from rgbd_rs._array_eq import array_eq
from rgbd_rs.errors import InvalidArgumentError, ShapeMismatchError
from rgbd_rs.segmentation.refine import DEFAULT_POOLING, POOLINGS
from rgbd_rs.surface import DEFAULT_TEST_SPACING, SegmentFits

__all__ = [
    "T_C",
    "T_D",
    "T_SIM",
    "T_THETA_DEG",
    "MergeResult",
    "MergeStep",
    "adjacency",
    "majority_classes",
    "merge_regions",
]

#: Eq. 4.7: smallest similarity of a couple that enters the queue (thesis: 0.77).
T_SIM: float = _rgbd_rs.T_SIM
#: Eq. 4.3: largest depth step (metres) across the boundary of adjacent segments (0.2 m).
T_D: float = _rgbd_rs.T_D
#: Eq. 4.4: largest CIELab distance across the boundary of adjacent segments (10).
T_C: float = _rgbd_rs.T_C
#: Eq. 4.5: largest angle (degrees) between normals across the boundary (4°).
T_THETA_DEG: float = _rgbd_rs.T_THETA_DEG

#: How far from 1 a pixel's PDF may sum (float32 softmax outputs, bilinear resizing).
PDF_SUM_TOLERANCE = 1e-3


@dataclass(frozen=True)
class MergeStep:
    """One merge of Algorithm 1: segment ``absorbed`` joined ``kept`` (labels of the input)."""

    kept: int
    absorbed: int
    #: The couple's priority: similarity (eq. 4.7) or relative fit improvement (fit-only mode).
    score: float
    error_kept: float
    error_absorbed: float
    error_union: float


@array_eq
@dataclass(frozen=True)
class MergeResult:
    """What :func:`merge_regions` returns."""

    #: ``H x W`` int32 final segments (each keeps one of its parts' input labels), -1 = none.
    labels: np.ndarray
    #: ``H x W`` int32 input segmentation.
    initial: np.ndarray
    #: The merges in order.
    history: tuple[MergeStep, ...]
    #: ``"similarity"`` (Algorithm 1 with PDFs) or ``"fit"`` (fit-only baseline).
    mode: str
    #: ``H x W`` int32 class of each final segment (by the ``pooling`` of :func:`merge_regions`:
    #: the argmax of its mean PDF by default), -1 = none; None without PDFs.
    semantic: np.ndarray | None = None

    @property
    def n_segments(self) -> int:
        """Number of final segments."""
        return int(np.unique(self.labels[self.labels >= 0]).size)

    def labels_after(self, steps: int) -> np.ndarray:
        """The segmentation after the first ``steps`` merges (frames of Fig. 4.5)."""
        k = _validate.integer("steps", steps, minimum=0, maximum=len(self.history))
        ids, inverse = np.unique(self.initial, return_inverse=True)
        parent = np.arange(ids.size)
        slot = {int(v): i for i, v in enumerate(ids)}
        for step in self.history[:k]:
            parent[slot[step.absorbed]] = slot[step.kept]
        root = parent.copy()
        for _ in range(k):  # each merge lengthens a chain by at most one
            nxt = parent[root]
            if np.array_equal(nxt, root):
                break
            root = nxt
        out = ids[root][inverse.reshape(self.initial.shape)]
        return np.where(self.initial >= 0, out, -1).astype(np.int32)


#: The image size :data:`~rgbd_rs.surface.DEFAULT_TEST_SPACING` (16 px) was set for: NYUv2's
#: 640 x 480 Kinect frames, by their larger side. ``segment()`` scales the seam test's knot
#: spacing with the frame's larger side, so a segment spans the same number of knots at any
#: resolution (:func:`merge_regions` called alone keeps 16 px unless given ``fits``). Measured
#: on six NYUv2 train frames merged at half resolution from the same over-segmentation: 16 px
#: kept 27-62 % more segments than at full resolution (VoI against the full-resolution result
#: 0.96 on average), 8 px 0.75; neither closer to the ground truth.
SEAM_SPACING_SIDE = 640


def _seam_spacing(shape: tuple[int, ...]) -> float:
    """The seam test's knot spacing (pixels) on a frame of ``shape`` (``H, W, ...``):
    :data:`~rgbd_rs.surface.DEFAULT_TEST_SPACING` at a larger side of :data:`SEAM_SPACING_SIDE`,
    in proportion elsewhere (at least 1 px)."""
    side = max(int(shape[0]), int(shape[1]))
    return max(1.0, DEFAULT_TEST_SPACING * side / SEAM_SPACING_SIDE)


def _labels(labels: npt.ArrayLike, shape: tuple[int, ...] | None = None) -> np.ndarray:
    raw = _validate.asarray("labels", labels)
    if raw.dtype.kind not in "iu":
        raise InvalidArgumentError(f"labels: got dtype {raw.dtype}, expected an integer array")
    want = (None, None) if shape is None else shape
    lab = _validate.array("labels", raw, shape=want, dtype=np.int64)
    if lab.max() > np.iinfo(np.int32).max:
        raise InvalidArgumentError(f"labels: got a label {lab.max()}, expected < 2**31")
    if lab.max() < 0:
        raise InvalidArgumentError("labels: got no label >= 0, expected at least one segment")
    return np.ascontiguousarray(np.maximum(lab, -1), dtype=np.int32)


def _cue(name: str, value: npt.ArrayLike | None, shape: tuple[int, int]) -> np.ndarray | None:
    if value is None:
        return None
    return _validate.array(name, value, shape=(*shape, 3))


def adjacency(
    labels: npt.ArrayLike,
    *,
    points: npt.ArrayLike | None = None,
    lab: npt.ArrayLike | None = None,
    normals: npt.ArrayLike | None = None,
    touching: bool = False,
    max_depth_step: float = T_D,
    max_color_distance: float = T_C,
    max_normal_angle: float = T_THETA_DEG,
) -> np.ndarray:
    """The couples of adjacent segments of ``labels``: a ``(P, 2)`` int32 array of labels.

    Two 4-connected segments are adjacent when, along more than half of their shared boundary,
    the depth step is at most ``max_depth_step`` metres (eq. 4.3; the z of ``points``), the
    CIELab distance at most ``max_color_distance`` (eq. 4.4; ``lab``, ``H x W x 3``) and the
    angle between the normals at most ``max_normal_angle`` degrees (eq. 4.5; ``normals``, unit
    vectors). Each test runs only when its cue is given; a boundary point where a cue is NaN
    does not vote in that test, and a test without votes fails. ``touching=True`` skips the
    tests (every touching couple is adjacent: the thesis' faster option).
    """
    return _adjacency(
        _labels(labels),
        points=points,
        lab=lab,
        normals=normals,
        touching=touching,
        max_depth_step=max_depth_step,
        max_color_distance=max_color_distance,
        max_normal_angle=max_normal_angle,
    )


def _adjacency(
    lab32: np.ndarray,
    *,
    points: npt.ArrayLike | None,
    lab: npt.ArrayLike | None,
    normals: npt.ArrayLike | None,
    touching: bool,
    max_depth_step: float,
    max_color_distance: float,
    max_normal_angle: float,
) -> np.ndarray:
    """:func:`adjacency` of labels already checked by ``_labels``."""
    shape = (lab32.shape[0], lab32.shape[1])
    depth = None
    if points is not None:
        pts = _validate.array("points", points, shape=(*shape, 3))
        if max_depth_step == T_D:  # the default step is metres; a caller's is in its own unit
            _validate.metric_points(
                "points", pts, f"max_depth_step's default ({T_D:g}) is", "give max_depth_step"
            )
        depth = np.ascontiguousarray(pts[..., 2], dtype=np.float32)
    c, n = _cue("lab", lab, shape), _cue("normals", normals, shape)
    for name, v, hi in (
        ("max_depth_step", max_depth_step, np.inf),
        ("max_color_distance", max_color_distance, np.inf),
        ("max_normal_angle", max_normal_angle, 180.0),
    ):
        x = _validate.real(name, v, nonnegative=True)
        if not x <= hi:
            raise InvalidArgumentError(f"{name}: got {v!r}, expected a value in [0, {hi}]")
    if not isinstance(touching, bool):
        raise InvalidArgumentError(f"touching: got {touching!r}, expected True or False")
    if touching:
        depth = c = n = None
    pairs, _, ok = _rgbd_rs.segment_boundaries(
        lab32,
        depth,
        c,
        n,
        float(max_depth_step),
        float(max_color_distance),
        float(np.deg2rad(max_normal_angle)),
    )
    return np.ascontiguousarray(pairs[ok])


def _pdfs(pdfs: npt.ArrayLike, shape: tuple[int, int]) -> np.ndarray:
    p = _validate.array("pdfs", pdfs, shape=(*shape, None))
    # One native pass: non-finite count, minimum, worst per-pixel sum (float64).
    bad, low, worst = _rgbd_rs.pdf_stats(p)
    if bad:
        raise InvalidArgumentError(f"pdfs: got {bad} non-finite values, expected finite values")
    if p.shape[2] < 2:
        raise ShapeMismatchError(f"pdfs: got {p.shape[2]} class(es), expected at least 2")
    if low < 0:
        raise InvalidArgumentError(f"pdfs: got a negative value {p.min()}, expected PDFs >= 0")
    if worst > PDF_SUM_TOLERANCE:
        raise InvalidArgumentError(
            f"pdfs: got per-pixel sums off 1 by up to {worst:.3g}, expected class PDFs that sum "
            f"to 1 (within {PDF_SUM_TOLERANCE}; apply a softmax over the last axis)"
        )
    return p


def majority_classes(labels: npt.ArrayLike, pdfs: npt.ArrayLike) -> np.ndarray:
    """§4.7's final labelling: each segment takes the most common per-pixel class (argmax of
    ``pdfs``) among its pixels. Returns an ``H x W`` int32 class image, -1 outside segments."""
    lab32 = _labels(labels)
    p = _pdfs(pdfs, (lab32.shape[0], lab32.shape[1]))
    return _majority(lab32, p)


def _majority(labels: np.ndarray, pdfs: np.ndarray) -> np.ndarray:
    # Native: per-pixel argmax (first maximum), per-segment vote (smaller class on ties).
    return _rgbd_rs.majority_classes(
        np.ascontiguousarray(labels, dtype=np.int32), np.ascontiguousarray(pdfs, np.float32)
    )


def merge_regions(
    labels: npt.ArrayLike,
    points: npt.ArrayLike,
    *,
    pdfs: npt.ArrayLike | None = None,
    lab: npt.ArrayLike | None = None,
    normals: npt.ArrayLike | None = None,
    touching: bool = False,
    t_sim: float = T_SIM,
    fits: SegmentFits | None = None,
    max_depth_step: float = T_D,
    max_color_distance: float = T_C,
    max_normal_angle: float = T_THETA_DEG,
    pooling: str = DEFAULT_POOLING,
) -> MergeResult:
    """Merges the segments of ``labels`` (``H x W`` int, -1 = none) by Algorithm 1.

    ``points`` (``H x W x 3`` metres, NaN = no depth) feed the spline fits of eq. 4.8 and the
    depth test of the adjacency; ``lab`` and ``normals`` (``H x W x 3``) its colour and normal
    tests (see :func:`adjacency`; ``touching=True`` skips them). With ``pdfs`` (``H x W x C``
    per-pixel class probabilities summing to 1) couples are ordered and gated by their
    similarity (eq. 4.6-4.7, threshold ``t_sim``) and each final segment gets a class
    (``pooling``: ``"mean"``, the argmax of its mean PDF, eq. 4.6's descriptor, the default as in
    :func:`~rgbd_rs.segmentation.pipeline.segment`, or ``"majority"``, the most common per-pixel
    argmax; as :func:`rgbd_rs.segmentation.refine.segment_classes`);
    without them the fit-only baseline merges couples in order of fit improvement.

    ``fits`` lets callers choose the fit options (:class:`~rgbd_rs.surface.SegmentFits` built on
    the same ``points`` and ``labels``); it is merged in place and afterwards describes the final
    segments (e.g. for curvature maps, which need ``surfaces=True``). By default it is built with
    its default options and ``surfaces=False``.
    """
    lab32 = _labels(labels)
    shape = (lab32.shape[0], lab32.shape[1])
    pts = _validate.array("points", points, shape=(*shape, 3))
    metric = [
        *(["the seam test's default Kinect noise law"] if fits is None else []),
        *(
            [f"max_depth_step's default ({T_D:g})"]
            if max_depth_step == T_D and not touching
            else []
        ),
    ]
    verb = " are" if len(metric) > 1 else " is"
    _validate.metric_points(
        "points",
        pts,
        " and ".join(metric) + verb if metric else None,
        "give fits=SegmentFits(points, labels, noise_scale=..., surfaces=False) and max_depth_step",
    )
    p = None if pdfs is None else _pdfs(pdfs, shape)
    t = _validate.real("t_sim", t_sim, nonnegative=True)
    pool = _validate.choice("pooling", pooling, POOLINGS)
    if t > 1.0:
        raise InvalidArgumentError(f"t_sim: got {t_sim!r}, expected a similarity in [0, 1]")
    if fits is None:
        # The merging needs the seam test only, not the surface fits (a third of the cost).
        fits = SegmentFits(pts, lab32, surfaces=False)
    elif not isinstance(fits, SegmentFits):
        raise InvalidArgumentError(
            f"fits: got {type(fits).__name__}, expected a rgbd_rs.surface.SegmentFits"
        )
    elif fits.shape != shape or not np.array_equal(fits.labels(), lab32):
        raise InvalidArgumentError(
            "fits: got fits of another segmentation, expected SegmentFits(points, labels) built "
            "on these labels and not merged yet"
        )
    pairs = _adjacency(
        lab32,
        points=pts,
        lab=lab,
        normals=normals,
        touching=touching,
        max_depth_step=max_depth_step,
        max_color_distance=max_color_distance,
        max_normal_angle=max_normal_angle,
    )
    # semantic: each final segment's class, from the votes or PDF sums of the native
    # descriptors' pass (None without PDFs).
    out, kept, absorbed, score, errors, semantic = fits._merge_natively(
        lambda native: _rgbd_rs.merge_regions(native, pairs, p, t, pool == "mean")
    )
    history = tuple(
        MergeStep(int(k), int(a), float(s), float(e[0]), float(e[1]), float(e[2]))
        for k, a, s, e in zip(kept, absorbed, score, errors, strict=True)
    )
    return MergeResult(
        labels=out,
        initial=lab32,
        history=history,
        mode="fit" if p is None else "similarity",
        semantic=semantic,
    )
