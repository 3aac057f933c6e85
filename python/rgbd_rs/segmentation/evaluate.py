"""Side-by-side segmentation evaluation on the NYUv2 frames (``rgbd eval segmentation``).

Every method is a function ``(rgb, depth, camera) -> labels`` (``H x W`` integers, < 0 = no
segment), built by a :class:`Method` from one point of its parameter grid. The protocol:

1. *Tuning*: each method runs at every point of its (small) grid on the tuning frames (default:
   the train split, NNNN <= 43); the point with the lowest mean Variation of Information wins.
   Ours are tuned like the peers: the number of over-segmentation clusters the merging starts
   from (:data:`MERGE_GRID`; the merging's own thresholds stay the thesis'). A method with a
   single grid point is not tuned.
2. *Evaluation*: each method runs once per evaluation frame (default: the test split,
   NNNN >= 46) at its chosen point; the table holds the means of VoI, Rand index, boundary
   recall, under-segmentation error (:mod:`rgbd_rs.metrics`), the number of segments and the
   seconds per frame of the method's call alone.
3. *Same count*: our over-segmentation at :data:`COUNT_MATCH_SEGMENTS` segments against SLIC
   (RGB) run to produce the same number of segments on each frame: boundary recall of both.

The ground truth is :func:`rgbd_rs.data.nyuv2.region_ground_truth` of the 40-class labels:
semantic regions, not the object instances of thesis Table 4.1, so the figures are not
comparable with the thesis' one to one. Unlabeled pixels (-1) are left out of every metric.

The peers are scikit-image's ``felzenszwalb`` and ``slic``, each on the colour image alone and
on colour + depth:

* ``slic`` (RGB): scikit-image converts to CIELab itself; compactness :data:`SLIC_COMPACTNESS`.
* ``slic`` (RGB-D): a 4-channel image ``(L, a, b, depth_weight * depth[m])`` (Lab units per
  metre); scikit-image rescales a multichannel image to [0, 1] as a whole, so the compactness is
  divided by the image's value span to keep the colour/space balance of the RGB run.
* ``felzenszwalb`` (RGB): on the uint8 image (scikit-image scales it to [0, 1]).
* ``felzenszwalb`` (RGB-D): a 4-channel float image ``(R/255, G/255, B/255,
  depth_weight * depth[m] / 255)`` (grey levels per metre), whose edge weights are the
  Euclidean distance over the four channels.

Missing depth (NaN) is 0 in the depth channel of the peers. Ours: the normalized-cuts
over-segmentation of the 9-D features (:mod:`rgbd_rs.segmentation.oversegment`) and the
fit-only merging of the pipeline (:mod:`rgbd_rs.segmentation.pipeline`), both picked up when
those modules provide them (the report lists what was not available).
"""

from __future__ import annotations

import itertools
import time
import warnings
from collections.abc import Callable, Iterable, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import numpy.typing as npt
from tqdm import tqdm

from rgbd_rs import _rgbd_rs, _validate, metrics
from rgbd_rs._progress import bar_options
from rgbd_rs.camera import PinholeCamera
from rgbd_rs.data.nyuv2 import (
    NYUV2_CAMERA,
    NyuFrame,
    load_nyuv2_frame,
    nyuv2_frames,
    region_ground_truth,
)
from rgbd_rs.errors import InvalidArgumentError, RgbdError
from rgbd_rs.segmentation.evaluate_semantic import LAST_FULL, LabelingScores

__all__ = [
    "CountMatch",
    "EvaluationReport",
    "Method",
    "MethodScore",
    "default_methods",
    "evaluate",
]

U8 = npt.NDArray[np.uint8]
F32 = npt.NDArray[np.float32]
Labels = npt.NDArray[np.integer[Any]]
#: A segmentation method at fixed parameters: ``(rgb, depth, camera) -> labels``.
Segmenter = Callable[[U8, F32, PinholeCamera], Labels]
Params = Mapping[str, float]

#: scikit-image's default SLIC compactness (colour distance in Lab units vs. grid spacing).
SLIC_COMPACTNESS = 10.0
#: Gaussian pre-smoothing of felzenszwalb (scikit-image's and the paper's default).
FELZENSZWALB_SIGMA = 0.8
#: Clusters of our over-segmentation for the same-count boundary-recall line and the fit-only
#: row: the pipeline's default, which gives ~300 segments after splitting on NYUv2 (the issue
#: compares at ~300).
COUNT_MATCH_SEGMENTS = _rgbd_rs.OVERSEG_DEFAULT_SEGMENTS
#: Pixels within this distance of a segment boundary find a ground-truth boundary.
BOUNDARY_TOLERANCE = 2
#: Seed of our over-segmentation (k-means / Nyström sampling).
SEED = 0

#: Row names of our methods (the figure's panels look them up).
OURS_OVER = "ours: over-segmentation"
OURS_MERGED = "ours: fit-only merging"
OURS_FULL = "ours: full method (ConvNet + fits)"

#: The parameter grids swept on the tuning frames.
FELZENSZWALB_GRID: tuple[Params, ...] = tuple(
    {"scale": s, "min_size": m} for s, m in itertools.product((100, 300), (1000, 2500))
)
FELZENSZWALB_RGBD_GRID: tuple[Params, ...] = tuple(
    {"scale": s, "min_size": 2500, "depth_weight": w}
    for s, w in itertools.product((100, 300), (30, 100))
)
SLIC_GRID: tuple[Params, ...] = tuple({"n_segments": n} for n in (15, 25, 50))
SLIC_RGBD_GRID: tuple[Params, ...] = tuple(
    {"n_segments": n, "depth_weight": w} for n, w in itertools.product((15, 25), (10, 30))
)
OVERSEGMENT_GRID: tuple[Params, ...] = tuple({"n_segments": n} for n in (100, 300))
#: Over-segmentation clusters the fit-only and the full merging start from (the pipeline's
#: default last). Chosen grid: VoI on semantic regions favours few segments (README).
MERGE_GRID: tuple[Params, ...] = tuple(
    {"n_segments": n} for n in (30, 60, 100, COUNT_MATCH_SEGMENTS)
)


# -- the methods -------------------------------------------------------------------------------


def _depth_channel(depth: F32, weight: float) -> npt.NDArray[np.float64]:
    """``weight * depth``, 0 where the depth is missing (NaN, inf or <= 0, as everywhere)."""
    d = depth.astype(np.float64)
    return np.where(np.isfinite(d) & (d > 0), d, 0.0) * weight


def _pixels(min_size: float) -> int:
    """A minimum segment size as skimage's C integer: sizes past any image's pixel count
    (2**31) all mean "one segment" and are clamped there."""
    return int(min(min_size, _validate.MAX_INT))


def felzenszwalb_rgb(*, scale: float, min_size: float) -> Segmenter:
    """scikit-image ``felzenszwalb`` on the colour image."""
    from skimage.segmentation import felzenszwalb

    scale = _validate.real("scale", scale, positive=True)
    min_size = _validate.real("min_size", min_size, nonnegative=True)

    def run(rgb: U8, depth: F32, camera: PinholeCamera) -> Labels:
        return np.asarray(
            felzenszwalb(rgb, scale=scale, sigma=FELZENSZWALB_SIGMA, min_size=_pixels(min_size))
        )

    return run


def felzenszwalb_rgbd(*, scale: float, min_size: float, depth_weight: float) -> Segmenter:
    """scikit-image ``felzenszwalb`` on ``(RGB, depth_weight * depth)`` / 255 (grey levels per
    metre)."""
    from skimage.segmentation import felzenszwalb

    scale = _validate.real("scale", scale, positive=True)
    min_size = _validate.real("min_size", min_size, nonnegative=True)
    depth_weight = _validate.real("depth_weight", depth_weight, nonnegative=True)

    def run(rgb: U8, depth: F32, camera: PinholeCamera) -> Labels:
        image = np.concatenate(
            [rgb.astype(np.float64), _depth_channel(depth, depth_weight)[:, :, None]], axis=2
        )
        with warnings.catch_warnings():  # "4 channels may not be intended": they are
            warnings.simplefilter("ignore", RuntimeWarning)
            out = felzenszwalb(
                image / 255.0, scale=scale, sigma=FELZENSZWALB_SIGMA, min_size=_pixels(min_size)
            )
        return np.asarray(out)

    return run


def slic_rgb(*, n_segments: int) -> Segmenter:
    """scikit-image ``slic`` on the colour image (CIELab, compactness 10)."""
    from skimage.segmentation import slic

    n = _validate.integer("n_segments", n_segments, minimum=1)

    def run(rgb: U8, depth: F32, camera: PinholeCamera) -> Labels:
        return np.asarray(slic(rgb, n_segments=n, compactness=SLIC_COMPACTNESS, start_label=0))

    return run


def slic_rgbd(*, n_segments: int, depth_weight: float) -> Segmenter:
    """scikit-image ``slic`` on ``(L, a, b, depth_weight * depth)`` (Lab units per metre)."""
    from skimage.color import rgb2lab
    from skimage.segmentation import slic

    n = _validate.integer("n_segments", n_segments, minimum=1)
    depth_weight = _validate.real("depth_weight", depth_weight, nonnegative=True)

    def run(rgb: U8, depth: F32, camera: PinholeCamera) -> Labels:
        image = np.concatenate(
            [rgb2lab(rgb), _depth_channel(depth, depth_weight)[:, :, None]], axis=2
        )
        span = max(float(image.max() - image.min()), 1e-12)
        return np.asarray(
            slic(
                image,
                n_segments=n,
                compactness=SLIC_COMPACTNESS / span,
                start_label=0,
                channel_axis=-1,
                convert2lab=False,
            )
        )

    return run


class _LastOver:
    """The over-segmentation the fit-only pipeline started from on the latest frame, so the
    same-count line reuses it instead of computing it a second time (keyed by the identity of
    the frame's arrays, which it keeps alive so the ids cannot be reused)."""

    def __init__(self) -> None:
        self.key: tuple[np.ndarray, np.ndarray, int] | None = None
        self.over: Labels | None = None

    def store(self, rgb: U8, depth: F32, n_segments: int, over: Labels) -> None:
        self.key, self.over = (rgb, depth, n_segments), over

    def get(self, rgb: U8, depth: F32, n_segments: int | None = None) -> Labels | None:
        """The stored over-segmentation of this frame (at ``n_segments`` clusters; None: at
        whatever count the fit-only row ran), or None."""
        k = self.key
        if k is not None and k[0] is rgb and k[1] is depth and n_segments in (None, k[2]):
            return self.over
        return None


_LAST_OVER = _LastOver()


def ours_oversegment(*, n_segments: int) -> Segmenter:
    """Our normalized-cuts over-segmentation of the 9-D features (features + oversegment)."""
    from rgbd_rs.segmentation.features import features
    from rgbd_rs.segmentation.oversegment import oversegment

    n = _validate.integer("n_segments", n_segments, minimum=1)

    def run(rgb: U8, depth: F32, camera: PinholeCamera) -> Labels:
        return oversegment(features(rgb, depth, camera).vectors, n_segments=n, seed=SEED)

    return run


def ours_fit_merge(*, n_segments: int = COUNT_MATCH_SEGMENTS) -> Segmenter:
    """The pipeline's fit-only merging (surface fits alone, the thesis' reference [74]): the
    pipeline without class PDFs, on ``n_segments`` over-segmentation clusters."""
    from rgbd_rs.segmentation.pipeline import segment

    n = _validate.integer("n_segments", n_segments, minimum=2)

    def run(rgb: U8, depth: F32, camera: PinholeCamera) -> Labels:
        result = segment(rgb, depth, camera, labeler=None, n_segments=n, seed=SEED)
        _LAST_OVER.store(rgb, depth, n, result.over)
        return result.labels

    return run


@dataclass(frozen=True)
class Method:
    """A row of the table: ``make(**params)`` builds the segmenter for one grid point; the grid
    is swept on the tuning frames (one point: nothing to tune)."""

    name: str
    make: Callable[..., Segmenter]
    grid: tuple[Params, ...] = ({},)
    #: ``"peer"`` or ``"ours"``.
    kind: str = "peer"

    def segmenter(self, params: Params) -> Segmenter:
        """The segmenter at ``params`` (one grid point: parameter name -> value)."""
        if not isinstance(params, Mapping) or not all(isinstance(k, str) for k in params):
            raise InvalidArgumentError(
                f"params: got {params!r}, expected a mapping of parameter names to values"
            )
        try:
            return self.make(**params)
        except TypeError as exc:  # an unknown or missing keyword of make()
            raise InvalidArgumentError(
                f"params: got {dict(params)!r}, which {self.name} does not take ({exc})"
            ) from None


def default_methods(labeler: Any = "auto") -> list[Method]:
    """The peers (scikit-image) and ours, in table order; the full method runs ``labeler``
    (the shipped semantic ConvNet by default; a checkpoint path or a SemanticLabeler)."""

    def full(*, n_segments: int) -> Segmenter:
        from rgbd_rs.segmentation.evaluate_semantic import ours_full

        return ours_full(n_segments=n_segments, seed=SEED, labeler=labeler)

    return [
        Method("felzenszwalb (RGB)", felzenszwalb_rgb, FELZENSZWALB_GRID),
        Method("felzenszwalb (RGB-D)", felzenszwalb_rgbd, FELZENSZWALB_RGBD_GRID),
        Method("slic (RGB)", slic_rgb, SLIC_GRID),
        Method("slic (RGB-D)", slic_rgbd, SLIC_RGBD_GRID),
        Method(OURS_OVER, ours_oversegment, OVERSEGMENT_GRID, "ours"),
        Method(OURS_MERGED, ours_fit_merge, MERGE_GRID, "ours"),
        Method(OURS_FULL, full, MERGE_GRID, "ours"),
    ]


def _available(method: Method) -> str | None:
    """None when ``method`` can be built, else why not (our stages not landed yet)."""
    try:
        method.segmenter(method.grid[0])
    except (ImportError, AttributeError, RgbdError) as exc:
        return str(exc).split(" (")[0]
    return None


# -- results -----------------------------------------------------------------------------------


@dataclass(frozen=True)
class MethodScore:
    """Means over the evaluation frames of one method at its chosen parameters."""

    name: str
    params: dict[str, float]
    voi: float
    rand_index: float
    boundary_recall: float
    undersegmentation_error: float
    segments: float
    seconds: float
    #: Mean VoI on the tuning frames at the chosen parameters (NaN: one grid point, not tuned).
    tuning_voi: float


@dataclass(frozen=True)
class CountMatch:
    """Boundary recall of our over-segmentation and of SLIC (RGB) at the same segment count."""

    segments_ours: float
    segments_slic: float
    boundary_recall_ours: float
    boundary_recall_slic: float


@dataclass(frozen=True)
class EvaluationReport:
    """What :func:`evaluate` measured."""

    frames: tuple[int, ...]
    tuning_frames: tuple[int, ...]
    scores: tuple[MethodScore, ...]
    count_match: CountMatch | None
    #: Methods left out, with the reason (e.g. our stage not available yet).
    missing: dict[str, str] = field(default_factory=dict)
    #: Pixel / class accuracy of the full method's labels (None when it did not run).
    semantic: LabelingScores | None = None

    def table(self) -> str:
        """The Markdown table (means over the evaluation frames)."""
        lines = [
            "| method | parameters (tuned by VoI) | VoI ↓ | RI ↑ | boundary recall ↑ | "
            "under-seg. error ↓ | segments | s / frame |",
            "|---|---|---|---|---|---|---|---|",
        ]
        for s in self.scores:
            p = ", ".join(f"{k}={v:g}" for k, v in s.params.items()) or "defaults"
            lines.append(
                f"| {s.name} | {p} | {s.voi:.2f} | {s.rand_index:.3f} | "
                f"{s.boundary_recall:.3f} | {s.undersegmentation_error:.3f} | "
                f"{s.segments:.0f} | {s.seconds:.2f} |"
            )
        for name, why in self.missing.items():
            lines.append(f"| {name} | not available ({why}) | | | | | | |")
        return "\n".join(lines)

    def count_line(self) -> str:
        """The same-count boundary-recall line."""
        c = self.count_match
        if c is None:
            return (
                f"over-segmentation at {COUNT_MATCH_SEGMENTS} clusters: ours not available, "
                "no comparison"
            )
        return (
            f"over-segmentation at {COUNT_MATCH_SEGMENTS} clusters (ours: "
            f"{COUNT_MATCH_SEGMENTS} clusters, {c.segments_ours:.0f} segments after splitting; "
            f"SLIC (RGB) run to the same count per frame: {c.segments_slic:.0f}): boundary "
            f"recall (tolerance {BOUNDARY_TOLERANCE} px) ours {c.boundary_recall_ours:.3f} vs "
            f"SLIC {c.boundary_recall_slic:.3f}"
        )


# -- figures -----------------------------------------------------------------------------------

#: Width of one panel of the per-frame figure (pixels).
PANEL_WIDTH = 320


def frame_figure(
    path: Path,
    frame: NyuFrame,
    gt: npt.NDArray[np.int32],
    results: Mapping[str, Labels],
    peer: str | None,
) -> Path:
    """One frame's PNG: colour, depth (a colour bar in metres), ground truth / our
    over-segmentation, merged, best peer (boundaries drawn, segment counts in the titles;
    pixels without a region in the "no data" grey, a method that did not run says so in
    white)."""
    from rgbd_rs.viz import (
        as_bgr,
        grid,
        image_panel,
        map_panel,
        outline_segments,
        paint_segments,
        save_png,
    )

    w = PANEL_WIDTH
    panels = [
        image_panel(as_bgr(frame.rgb), f"{frame.name} colour", width=w),
        map_panel(frame.depth, "depth", unit="m", width=w),
        image_panel(paint_segments(gt), f"ground truth ({int(gt.max()) + 1} regions)", width=w),
    ]
    for name in (OURS_OVER, OURS_MERGED, peer):
        labels = None if name is None else results.get(name)
        if labels is None:
            blank = np.full((*gt.shape, 3), 255, np.uint8)
            panels.append(image_panel(blank, f"{name or 'peer'}: not run", width=w))
        else:
            outlined = outline_segments(frame.rgb, labels)
            panels.append(image_panel(outlined, f"{name} ({_count(labels)})", width=w))
    return save_png(path, grid(panels, columns=3))


# -- the protocol ------------------------------------------------------------------------------


def _frame_list(name: str, value: object) -> list[int]:
    if isinstance(value, str):
        return nyuv2_frames(value)
    if not isinstance(value, Iterable):
        raise InvalidArgumentError(
            f"{name}: got {value!r}, expected 'all', 'train', 'test' or a list of frame indices"
        )
    out = [_validate.integer(f"{name}[{i}]", v, minimum=1) for i, v in enumerate(value)]
    if not out:
        raise InvalidArgumentError(f"{name}: got no frame, expected at least one")
    return out


def _count(labels: Labels) -> int:
    return int(np.unique(labels[labels >= 0]).size)


def _recall(labels: Labels, gt: npt.NDArray[np.int32]) -> float:
    """Boundary recall, NaN on a frame without any ground-truth boundary to find (left out of
    the mean)."""
    try:
        return metrics.boundary_recall(labels, gt, tolerance=BOUNDARY_TOLERANCE)
    except InvalidArgumentError:
        return float("nan")


def _scores(labels: Labels, gt: npt.NDArray[np.int32]) -> tuple[float, float, float, float]:
    return (
        metrics.variation_of_information(labels, gt),
        metrics.rand_index(labels, gt),
        _recall(labels, gt),
        metrics.undersegmentation_error(labels, gt),
    )


def _slic_at(rgb: U8, target: int) -> Labels:
    """SLIC (RGB) with about ``target`` segments: one run at ``target``, one corrected by the
    count it produced; the closer of the two."""
    first = slic_rgb(n_segments=target)(rgb, np.empty(0, np.float32), NYUV2_CAMERA)
    got = _count(first)
    if got == target:
        return first
    second = slic_rgb(n_segments=max(1, round(target * target / max(got, 1))))(
        rgb, np.empty(0, np.float32), NYUV2_CAMERA
    )
    return first if abs(got - target) <= abs(_count(second) - target) else second


def _tune(
    methods: Sequence[Method], frames: Sequence[NyuFrame], quiet: bool
) -> list[tuple[Params, float]]:
    """Per method, the grid point with the lowest mean VoI on ``frames`` and that VoI (NaN for
    a method with one grid point: nothing to tune, so it does not run)."""
    sums = [np.zeros(len(m.grid)) for m in methods]
    makers = [[m.segmenter(p) for p in m.grid] if len(m.grid) > 1 else [] for m in methods]
    if any(makers):
        for frame in tqdm(frames, desc="tuning", unit="frame", **bar_options(quiet)):
            gt = region_ground_truth(frame.label40)
            for i, runs in enumerate(makers):
                for j, run in enumerate(runs):
                    labels = run(frame.rgb, frame.depth, NYUV2_CAMERA)
                    LAST_FULL.take()  # a tuning run's labels are never scored as semantic ones
                    sums[i][j] += metrics.variation_of_information(labels, gt)
    out = []
    for m, s, runs in zip(methods, sums, makers, strict=True):
        best = int(np.argmin(s))
        out.append((m.grid[best], float(s[best] / len(frames)) if runs else float("nan")))
    return out


def evaluate(
    frames: str | Sequence[int] = "test",
    *,
    tuning_frames: str | Sequence[int] = "train",
    methods: Sequence[Method] | None = None,
    out: str | Path | None = None,
    quiet: bool = False,
) -> EvaluationReport:
    """Run the protocol of this module on the NYUv2 frames of the shared data.

    Args:
        frames: the evaluation frames: ``"test"`` (NNNN >= 46), ``"train"``, ``"all"`` or
            frame indices.
        tuning_frames: the frames the grids are swept on (default the train split).
        methods: the rows (default :func:`default_methods`); a method whose stage is not
            available yet (ImportError / AttributeError when built) is listed in
            ``missing`` instead.
        out: a folder for one figure per evaluation frame (``NNNN.png``: colour, depth, ground
            truth, the over-segmentation the fit-only merging started from (at
            :data:`COUNT_MATCH_SEGMENTS` without that row), the merged result, the peer with the
            lowest tuning VoI); None = none.
        quiet: no progress bars.
    """
    eval_ids = _frame_list("frames", frames)
    tune_ids = _frame_list("tuning_frames", tuning_frames)
    if not isinstance(quiet, bool):
        raise InvalidArgumentError(f"quiet: got {quiet!r}, expected True or False")
    chosen_methods = default_methods() if methods is None else list(methods)
    if not chosen_methods or not all(isinstance(m, Method) for m in chosen_methods):
        raise InvalidArgumentError(
            f"methods: got {methods!r}, expected a non-empty list of Method or None"
        )
    folder = None
    if out is not None:
        if not isinstance(out, (str, Path)) or not str(out):
            raise InvalidArgumentError(f"out: got {out!r}, expected a folder path or None")
        folder = Path(out)

    missing: dict[str, str] = {}
    usable = []
    for m in chosen_methods:
        why = _available(m)
        if why is None:
            usable.append(m)
        else:
            missing[m.name] = why
    if not usable:
        raise InvalidArgumentError(f"methods: none is available ({missing})")

    tuned = _tune(usable, [load_nyuv2_frame(i) for i in tune_ids], quiet)
    runs = [m.segmenter(p) for m, (p, _) in zip(usable, tuned, strict=True)]
    ours_over = next((m for m in usable if m.name == OURS_OVER), None)
    count_run = (
        None if ours_over is None else ours_over.segmenter({"n_segments": COUNT_MATCH_SEGMENTS})
    )
    best_peer = min(
        (i for i, m in enumerate(usable) if m.kind == "peer"),
        key=lambda i: tuned[i][1],
        default=None,
    )

    semantic = LabelingScores() if any(m.name == OURS_FULL for m in usable) else None
    per = np.zeros((len(eval_ids), len(usable), 6))
    match = np.zeros((len(eval_ids), 4))
    for k, index in enumerate(
        tqdm(eval_ids, desc="evaluating", unit="frame", **bar_options(quiet))
    ):
        frame = load_nyuv2_frame(index)
        gt = region_ground_truth(frame.label40)
        results: dict[str, Labels] = {}
        for i, (m, run) in enumerate(zip(usable, runs, strict=True)):
            t0 = time.perf_counter()
            labels = run(frame.rgb, frame.depth, NYUV2_CAMERA)
            seconds = time.perf_counter() - t0
            results[m.name] = labels
            per[k, i] = (*_scores(labels, gt), _count(labels), seconds)
            full = LAST_FULL.take()
            if semantic is not None and full is not None:
                semantic.add(full, frame.label13)
        start = _LAST_OVER.get(frame.rgb, frame.depth)  # what the fit-only merging started from
        if count_run is not None:
            ours = _LAST_OVER.get(frame.rgb, frame.depth, COUNT_MATCH_SEGMENTS)
            if ours is None:
                ours = count_run(frame.rgb, frame.depth, NYUV2_CAMERA)
            theirs = _slic_at(frame.rgb, _count(ours))
            match[k] = (
                _count(ours),
                _count(theirs),
                _recall(ours, gt),
                _recall(theirs, gt),
            )
            results[OURS_OVER] = ours
        if start is not None:  # the figure shows the over-segmentation the merging started from
            results[OURS_OVER] = start
        if folder is not None:
            peer = None if best_peer is None else usable[best_peer].name
            frame_figure(folder / f"{frame.name}.png", frame, gt, results, peer)

    with warnings.catch_warnings():  # a column all NaN stays NaN
        warnings.simplefilter("ignore", RuntimeWarning)
        means = np.nanmean(per, axis=0)
        match_means = np.nanmean(match, axis=0)
    scores = tuple(
        MethodScore(
            name=m.name,
            params=dict(p),
            voi=float(means[i, 0]),
            rand_index=float(means[i, 1]),
            boundary_recall=float(means[i, 2]),
            undersegmentation_error=float(means[i, 3]),
            segments=float(means[i, 4]),
            seconds=float(means[i, 5]),
            tuning_voi=v,
        )
        for i, (m, (p, v)) in enumerate(zip(usable, tuned, strict=True))
    )
    count_match = None if count_run is None else CountMatch(*(float(v) for v in match_means))
    return EvaluationReport(
        tuple(eval_ids), tuple(tune_ids), scores, count_match, missing, semantic
    )
