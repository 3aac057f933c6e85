"""The segmentation pipeline of thesis ch. 4: 9-D features (eq. 4.1) -> normalized-cuts
over-segmentation (§4.4) -> spline fits of every segment (§4.5) -> HHA and the semantic ConvNet's
class PDFs (§4.6) -> region merging (Algorithm 1, §4.7) -> a class per final segment.

Each stage is a plain function of :mod:`rgbd_rs.segmentation` and can be called alone;
:func:`segment` runs them in order and times each. With class PDFs (given, or from the ConvNet:
the shipped weights by default) the merging is Algorithm 1; without, the fit-only baseline.
"""

from __future__ import annotations

import time
import warnings
from dataclasses import dataclass, field

import numpy as np
import numpy.typing as npt

from rgbd_rs import _validate
from rgbd_rs._array_eq import array_eq
from rgbd_rs.camera import PinholeCamera
from rgbd_rs.errors import InvalidArgumentError, ShapeMismatchError
from rgbd_rs.holes import DEFAULT_FILL_RADIUS, SPARSE_SHARE, _isolated_share, fill_depth_holes
from rgbd_rs.segmentation.features import NORMAL_RADIUS, Features, features
from rgbd_rs.segmentation.hha import GRAVITY_RADIUS, hha_details, square_normals
from rgbd_rs.segmentation.labeling import SemanticLabeler
from rgbd_rs.segmentation.merge import MergeResult, _seam_spacing, merge_regions
from rgbd_rs.segmentation.oversegment import DEFAULT_N_SEGMENTS, oversegment
from rgbd_rs.segmentation.refine import DEFAULT_POOLING, POOLINGS
from rgbd_rs.segmentation.semantic_stage import AUTO, LabelerArg, _class_pdfs, _resolve_labeler
from rgbd_rs.surface import SegmentFits

__all__ = ["ADJACENCY_NORMAL_RADIUS", "Segmentation", "segment"]

#: Window half-size of the normals the adjacency's eq. 4.5 test compares (21 x 21, the HHA
#: gravity normals). The thesis' T_theta = 4 deg is kept; on Kinect depth the 7 x 7 normals of the
#: features differ by more than that across most boundaries of one surface, which blocks merges
#: (5 NYUv2 train frames, fit-only merging: VoI 1.95 -> 1.45, RI 0.903 -> 0.878, 176 -> 103
#: segments).
ADJACENCY_NORMAL_RADIUS = GRAVITY_RADIUS
#: A median valid depth above this (metres) warns that the unit may be off: RGB-D cameras of
#: the Kinect / ToF class measure up to ~10 m (depth in millimetres, a median above 50, is
#: refused by the features). It catches 0.1 mm read as millimetres (10x too far) on any scene
#: beyond 1 m; TUM's 1/5000 m read as millimetres (5x) only on scenes beyond 2 m.
MAX_PLAUSIBLE_MEDIAN_DEPTH_M = 10.0
#: A median valid depth below this (metres) warns too: no RGB-D camera of that class focuses a
#: scene at under 5 cm (depth in kilometres, or metres scaled twice, lands here).
MIN_PLAUSIBLE_MEDIAN_DEPTH_M = 0.05


def _depth_unit_warning(points: npt.NDArray[np.float32]) -> str | None:
    """The warning for ``points`` (``H x W x 3`` metres) whose median depth is implausible for
    an RGB-D camera, or None."""
    z = points[..., 2]
    z = z[np.isfinite(z)]
    med = float(np.median(z)) if z.size else 0.0
    if MIN_PLAUSIBLE_MEDIAN_DEPTH_M <= med <= MAX_PLAUSIBLE_MEDIAN_DEPTH_M or not z.size:
        return None
    where = (
        f"beyond the ~{MAX_PLAUSIBLE_MEDIAN_DEPTH_M:g} m"
        if med > MAX_PLAUSIBLE_MEDIAN_DEPTH_M
        else f"below the ~{MIN_PLAUSIBLE_MEDIAN_DEPTH_M:g} m"
    )
    return (
        f"depth: median {med:.3g} m, {where} an RGB-D camera measures: check the depth unit "
        "(metres; with `rgbd segment`, --depth-scale for a PNG that is not in millimetres)"
    )


#: Depth units 16-bit depth PNGs are written in (metres per count): millimetres (Kinect,
#: RealSense, Azure Kinect), 1/5000 m (TUM RGB-D), 0.1 mm (NYUv2's raw HHA depth), 1/4000 m
#: (RealSense's 0.25 mm mode), centimetres.
PNG_DEPTH_UNITS_M = (1e-3, 2e-4, 1e-4, 2.5e-4, 1e-2)
#: The median depth a plausible unit should give (metres): a typical indoor RGB-D scene.
TYPICAL_MEDIAN_DEPTH_M = 2.5


def _suggested_depth_scale(median_m: float, scale: float) -> float | None:
    """The common PNG depth unit (:data:`PNG_DEPTH_UNITS_M`) that brings a median depth of
    ``median_m`` metres, read with ``scale`` metres per count, into the plausible range
    nearest :data:`TYPICAL_MEDIAN_DEPTH_M`; None if ``median_m`` is plausible already or no
    common unit makes it so.

    >>> _suggested_depth_scale(31.0, 1e-3)  # NYUv2's 0.1 mm counts read as millimetres
    0.0001
    """
    if not (median_m > 0 and scale > 0 and np.isfinite(median_m) and np.isfinite(scale)):
        return None
    if MIN_PLAUSIBLE_MEDIAN_DEPTH_M <= median_m <= MAX_PLAUSIBLE_MEDIAN_DEPTH_M:
        return None  # the unit given is plausible: nothing to fix
    counts = median_m / scale
    fits = [
        u
        for u in PNG_DEPTH_UNITS_M
        if u != scale and MIN_PLAUSIBLE_MEDIAN_DEPTH_M <= counts * u <= MAX_PLAUSIBLE_MEDIAN_DEPTH_M
    ]
    if not fits:
        return None
    return min(fits, key=lambda u: abs(np.log(counts * u / TYPICAL_MEDIAN_DEPTH_M)))


@array_eq
@dataclass(frozen=True)
class Segmentation:
    """What :func:`segment` returns."""

    #: ``H x W`` int32 over-segmentation (§4.4), -1 where the depth is missing (after the
    #: holes within ``fill_radius`` of a measured pixel were filled).
    over: np.ndarray
    #: ``H x W`` int32 final segments after merging, -1 where the depth is missing (as ``over``).
    labels: np.ndarray
    #: The merging's history and, with PDFs, the class of each final segment.
    merge: MergeResult
    #: The per-pixel features the stages used (Lab, points, normals, 9-D vectors).
    features: Features
    #: The seam-test fits of the final segments (with the surface fits only when the ConvNet ran:
    #: for fitting error and curvature maps build ``SegmentFits(features.points, labels)``).
    fits: SegmentFits = field(compare=False)  # compared through the labels
    #: Seconds spent in each stage, in order (not compared: two equal runs differ in time).
    seconds: dict[str, float] = field(default_factory=dict, compare=False)
    #: ``H x W x C`` class PDFs the merging used (the ConvNet's or the caller's), else None.
    pdfs: np.ndarray | None = None
    #: ``H x W`` int32 class of each final segment (§4.7 refinement with :attr:`pooling`), -1
    #: where no segment is; None without PDFs.
    semantic: np.ndarray | None = None
    #: How :attr:`semantic` pools each segment's PDFs (see
    #: :func:`rgbd_rs.segmentation.refine.segment_classes`).
    pooling: str = DEFAULT_POOLING

    @property
    def network_labels(self) -> np.ndarray | None:
        """``H x W`` int32 per-pixel argmax of :attr:`pdfs` (the network's own labeling, before
        the segment refinement of §4.7), else None."""
        return None if self.pdfs is None else self.pdfs.argmax(axis=-1).astype(np.int32)

    @property
    def refined_labels(self) -> np.ndarray | None:
        """``H x W`` int32 class per pixel after the segment refinement of §4.7 (:attr:`semantic`),
        the network's own class where no segment is (no depth), else None."""
        net, sem = self.network_labels, self.semantic
        if net is None or sem is None:
            return None
        return np.where(sem >= 0, sem, net).astype(np.int32)


def _frame_size(shape: tuple[int, ...], net: SemanticLabeler | None) -> None:
    """Refuse, in ``segment()``'s words, a frame smaller than its normals' window or (with a
    ConvNet) than the network's input (the stages would name their own arguments)."""
    h, w = int(shape[0]), int(shape[1])
    if max(h, w) < NORMAL_RADIUS:
        raise ShapeMismatchError(
            f"depth: got a {w}x{h} frame, expected at least {NORMAL_RADIUS} px on its longer "
            "side (the normals' window)"
        )
    if net is not None:
        nw, nh = net.input_size
        if w < nw or h < nh:
            raise ShapeMismatchError(
                f"rgb: got a {w}x{h} frame, smaller than the labeling network's {nw}x{nh} input; "
                f"expected a frame at least {nw}x{nh}, or no network (labeler=None; rgbd "
                "segment --labeler none): merging by surface fits only"
            )


def segment(
    rgb: npt.ArrayLike,
    depth: npt.ArrayLike,
    camera: PinholeCamera,
    *,
    pdfs: npt.ArrayLike | None = None,
    labeler: LabelerArg = AUTO,
    n_segments: int = DEFAULT_N_SEGMENTS,
    touching: bool = False,
    pooling: str = DEFAULT_POOLING,
    fill_radius: float | None = DEFAULT_FILL_RADIUS,
    seed: int = 0,
    quiet: bool = True,
) -> Segmentation:
    """Segments an RGB-D frame: ``rgb`` ``H x W x 3`` uint8, ``depth`` ``H x W`` float32 metres
    (NaN, 0 or negative = missing), ``camera`` the intrinsics of both (registered depth).

    Holes in the depth within ``fill_radius`` pixels of a measured pixel take its depth first
    (scattered holes, sparse depth; 0 keeps every hole, None fills them all), and the ConvNet's
    HHA cue is computed
    on the depth with every hole filled, as the network was trained
    (:mod:`rgbd_rs.holes`). Pixels still without depth are ``-1`` in the output.

    ``pdfs`` (``H x W x C`` per-pixel class probabilities) switch the merging from the fit-only
    baseline to Algorithm 1 and label every final segment. Without them, ``labeler`` computes
    them: ``"auto"`` runs the semantic ConvNet shipped in the package (fit-only merging, with a
    warning, when none is installed), a :class:`~rgbd_rs.segmentation.labeling.SemanticLabeler`
    or a checkpoint path runs that network, None asks for fit-only merging. ``n_segments`` is
    the number of normalized-cuts clusters of the over-segmentation (disconnected clusters are
    split, so the over-segmentation has somewhat more segments); ``touching=True`` treats every
    pair of touching segments as adjacent (the thesis' faster option) instead of the boundary
    tests of eq. 4.3-4.5. ``pooling`` is how each final segment's class comes from its pixels'
    PDFs: ``"mean"`` (argmax of the mean PDF) or ``"majority"`` (most common per-pixel class);
    see :mod:`rgbd_rs.segmentation.refine`. Deterministic given ``seed``.
    """
    touching = _validate.flag("touching", touching)
    quiet = _validate.flag("quiet", quiet)
    if not isinstance(camera, PinholeCamera):
        raise InvalidArgumentError(
            f"camera: got {type(camera).__name__}, expected a rgbd_rs.PinholeCamera"
        )
    n = _validate.integer("n_segments", n_segments, minimum=2)
    pooling = _validate.choice("pooling", pooling, POOLINGS)
    radius = (
        None
        if fill_radius is None
        else _validate.real("fill_radius", fill_radius, nonnegative=True)
    )
    seconds: dict[str, float] = {}
    t = time.perf_counter()

    def lap(stage: str) -> None:
        nonlocal t
        now = time.perf_counter()
        seconds[stage] = now - t
        t = now

    net = None if pdfs is not None else _resolve_labeler(labeler)  # loaded once per process
    depth = fill_depth_holes(depth, radius)  # NaN where still missing
    colour = _validate.asarray("rgb", rgb)
    if colour.ndim >= 2 and colour.shape[:2] != depth.shape:
        raise ShapeMismatchError(
            f"depth: got {depth.shape[1]}x{depth.shape[0]} pixels, expected the rgb image's "
            f"{colour.shape[1]}x{colour.shape[0]}: register the depth to the colour camera first "
            "(rgbd_rs.reproject_depth, or `rgbd reproject` for an Azure Kinect recording)"
        )
    _frame_size(depth.shape, None)
    # With the ConvNet, HHA is a cue, on the depth with every hole filled (as Gupta et al. and
    # the network's NYUv2 training frames) and the remaining holes left out of its 7x7 normals,
    # which are the features' normals too (computed once).
    hh = None
    if net is not None:
        hh = hha_details(fill_depth_holes(depth, None), camera, raw_depth=depth)
    f = features(rgb, depth, camera, normals=None if hh is None else hh.normals)
    unit = _depth_unit_warning(f.points)
    if unit is not None:
        warnings.warn(unit, RuntimeWarning, stacklevel=2)
    lonely = _isolated_share(depth)  # after the features' checks of the frame's size
    if lonely > SPARSE_SHARE:
        warnings.warn(
            f"depth: {lonely:.0%} of its measured pixels have no measured neighbour after "
            f"filling the holes within fill_radius={radius:g} px: each becomes a segment of "
            "its own; densify the depth (`rgbd reproject --splat-radius`) or raise fill_radius",
            RuntimeWarning,
            stacklevel=2,
        )
    lap("features")
    usable = int(np.count_nonzero(~np.isnan(f.vectors).any(axis=2)))
    if usable < n:  # said of the depth: the caller may never have set n_segments
        raise InvalidArgumentError(
            f"depth: got {usable} pixels with usable depth (after filling the holes within "
            f"fill_radius), expected at least n_segments={n} (the over-segmentation's clusters):"
            " give denser depth, or fewer n_segments"
        )
    _frame_size(depth.shape, net)  # after the depth's own checks, before the long stages
    over = oversegment(f.vectors, n, seed=seed, quiet=quiet)
    lap("oversegment")
    # The ConvNet's cues need the surface fits; the merging alone needs only the seam test.
    fits = SegmentFits(
        f.points,
        over,
        surfaces=net is not None,
        test_spacing=_seam_spacing(np.shape(depth)),
    )
    lap("fits")
    if net is not None and hh is not None:
        pdfs, _ = _class_pdfs(
            net, rgb, depth, camera, feats=f, hha=hh, over=over, fits=fits, n_segments=n, seed=seed
        )
        lap("semantic")
    # a window wider than the frame is the whole frame (clipped at the border): the same normals
    r = min(ADJACENCY_NORMAL_RADIUS, max(np.shape(depth)[:2]))
    normals = None if touching else square_normals(depth, camera, radius=r)
    # The merge's own descriptors (eq. 4.6 sums, argmax votes) give each final segment's class.
    merged = merge_regions(
        over,
        f.points,
        pdfs=pdfs,
        lab=f.lab,
        normals=normals,
        touching=touching,
        fits=fits,
        pooling=pooling,
    )
    lap("merge")
    return Segmentation(
        over=over,
        labels=merged.labels,
        merge=merged,
        features=f,
        fits=fits,
        seconds=seconds,
        pdfs=None if merged.mode == "fit" else np.asarray(pdfs, np.float32),
        semantic=merged.semantic,
        pooling=pooling,
    )
