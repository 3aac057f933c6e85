"""Evaluation measures shared by the pipelines: RMS error (the fusion tables' RMS disparity
error), depth-edge alignment, and the segmentation measures (Variation of Information, Rand
Index, boundary recall, under-segmentation error, pixel / mean class accuracy, confusion matrix),
computed from a contingency table of paired labels so they are fast on 640x480 frames."""

from __future__ import annotations

import math
from dataclasses import dataclass

import cv2
import numpy as np
import numpy.typing as npt

from rgbd_rs import _validate
from rgbd_rs._array_eq import array_eq
from rgbd_rs.errors import InvalidArgumentError, ShapeMismatchError

__all__ = [
    "bad_pixel_rate",
    "boundary_recall",
    "confusion_matrix",
    "depth_edges",
    "edge_alignment",
    "edge_band",
    "mean_class_accuracy",
    "pixel_accuracy",
    "rand_index",
    "rms_error",
    "undersegmentation_error",
    "variation_of_information",
]

#: Relative depth step that counts as a depth edge in :func:`edge_alignment` (5 %).
DEPTH_EDGE_REL_STEP = 0.05


def _nothing_to_compare(masked: bool) -> str:
    """The message for no pixel to compare, naming the mask only when one was given."""
    if masked:
        return "mask: got no pixel where estimate and truth are both finite, expected at least one"
    return (
        "estimate: got no pixel where it and truth are both finite, expected at least one "
        "(NaN / inf mark missing values)"
    )


def rms_error(
    estimate: npt.ArrayLike, truth: npt.ArrayLike, mask: npt.ArrayLike | None = None
) -> float:
    """Root-mean-square of ``estimate - truth`` over the pixels where both are finite (and
    ``mask`` is true): the RMS disparity error of thesis Table 3.2 for disparity maps.

    Computed in the inputs' float32, so equal inputs give equal figures everywhere (in float64
    where the squares would overflow float32). No pixel to
    compare raises :class:`~rgbd_rs.InvalidArgumentError`.
    """
    try:
        ndim = max(np.ndim(estimate), 1)
    except ValueError:  # ragged input: let the validator word the error
        ndim = 1
    e = _validate.array("estimate", estimate, shape=(None,) * ndim)
    t = _validate.array("truth", truth, shape=e.shape)
    keep = np.isfinite(e) & np.isfinite(t)
    if mask is not None:
        m = _validate.asarray("mask", mask)
        if m.dtype != np.bool_:
            raise InvalidArgumentError(f"mask: got dtype {m.dtype}, expected a boolean array")
        if m.shape != e.shape:
            raise ShapeMismatchError(f"mask: got shape {m.shape}, expected {e.shape}")
        keep &= m
    if not keep.any():
        raise InvalidArgumentError(_nothing_to_compare(mask is not None))
    diff = e[keep] - t[keep]
    with np.errstate(over="ignore"):
        rms = float(np.sqrt(np.mean(diff**2)))
    if not math.isfinite(rms):  # squares beyond float32 (errors > 1.8e19): float64 holds them
        wide = e[keep].astype(np.float64) - t[keep].astype(np.float64)
        rms = float(np.sqrt(np.mean(wide**2)))
    return rms


def bad_pixel_rate(
    estimate: npt.ArrayLike,
    truth: npt.ArrayLike,
    threshold: float,
    mask: npt.ArrayLike | None = None,
) -> float:
    """Fraction of the compared pixels (both finite, and ``mask``) whose absolute error exceeds
    ``threshold`` (the ">1 px" / ">2 px" bad-pixel rates of stereo benchmarks)."""
    t = _validate.real("threshold", threshold, nonnegative=True)
    # float64: a finite value beyond float32's range is an error to count, not a missing pixel.
    e = _validate.array("estimate", estimate, shape=(None, None), dtype=np.float64)
    g = _validate.array("truth", truth, shape=e.shape, dtype=np.float64)
    keep = np.isfinite(e) & np.isfinite(g)
    if mask is not None:
        m = _validate.asarray("mask", mask)
        if m.dtype != np.bool_ or m.shape != e.shape:
            raise ShapeMismatchError(
                f"mask: got {m.dtype} of shape {m.shape}, expected bool of shape {e.shape}"
            )
        keep &= m
    if not keep.any():
        raise InvalidArgumentError(_nothing_to_compare(mask is not None))
    with np.errstate(over="ignore"):  # two values near float64's limit: an infinite error
        return float(np.mean(np.abs(e[keep] - g[keep]) > t))


def edge_band(
    depth: npt.ArrayLike, width: int = 2, rel_step: float = DEPTH_EDGE_REL_STEP
) -> npt.NDArray[np.bool_]:
    """Pixels within ``width`` pixels (chessboard distance) of a depth edge of ``depth`` (or of a
    disparity map: a relative step is the same in both). :func:`depth_edges` marks the side with
    the smaller value (the nearer one for depth, the farther for disparity); ``width >= 1``
    covers both sides either way."""
    w = _validate.integer("width", width, maximum=1000)
    edges = depth_edges(depth, rel_step)
    if w == 0:
        return edges
    kernel = np.ones((2 * w + 1, 2 * w + 1), np.uint8)
    return np.asarray(cv2.dilate(edges.astype(np.uint8), kernel) > 0)


def depth_edges(
    depth: npt.ArrayLike, rel_step: float = DEPTH_EDGE_REL_STEP
) -> npt.NDArray[np.bool_]:
    """Pixels whose right or lower neighbour differs in depth by more than ``rel_step`` (relative),
    marked on the nearer side (the occluding contour). Needs both samples valid: NaN, infinite,
    0 and negative values are holes (no edge at a hole's border)."""
    d = _validate.array("depth", depth, shape=(None, None))
    with np.errstate(invalid="ignore"):
        d = np.where(np.isfinite(d) & (d > 0), d, np.float32(np.nan)).astype(np.float32)
    rel_step = _validate.real("rel_step", rel_step, positive=True)
    edges = np.zeros(d.shape, bool)
    # A step beyond float32's range marks nothing (no numpy overflow warning on the way).
    rel_step = min(rel_step, float(np.finfo(np.float32).max))
    with np.errstate(invalid="ignore", over="ignore"):
        for a, b, ea, eb in (
            (d[:, :-1], d[:, 1:], edges[:, :-1], edges[:, 1:]),
            (d[:-1, :], d[1:, :], edges[:-1, :], edges[1:, :]),
        ):
            step = np.abs(a - b) > rel_step * np.minimum(a, b)
            ea |= step & (a < b)
            eb |= step & (b < a)
    return edges


def edge_alignment(depth: npt.ArrayLike, image: npt.ArrayLike, max_distance: float = 2.0) -> float:
    """Fraction of depth edges that lie within ``max_distance`` pixels of an image (Canny) edge.

    A registration check: a depth map correctly reprojected onto a colour camera has its
    occluding contours on the colour image's edges.
    """
    d = _validate.array("depth", depth, shape=(None, None))
    img = _validate.asarray("image", image)
    if img.dtype != np.uint8:
        raise InvalidArgumentError(f"image: got dtype {img.dtype}, expected uint8")
    if img.shape[:2] != d.shape or img.ndim not in (2, 3) or (img.ndim == 3 and img.shape[2] < 3):
        raise ShapeMismatchError(
            f"image: got shape {img.shape}, expected {d.shape} or {(*d.shape, 3)} (the depth size)"
        )
    max_distance = _validate.real("max_distance", max_distance, nonnegative=True)
    gray = (
        np.ascontiguousarray(img)
        if img.ndim == 2
        else cv2.cvtColor(np.ascontiguousarray(img[:, :, :3]), cv2.COLOR_RGB2GRAY)
    )
    canny = cv2.Canny(gray, 50, 150)
    dist = cv2.distanceTransform((canny == 0).astype(np.uint8), cv2.DIST_L2, 3)
    edges = depth_edges(d)
    if not edges.any():
        raise InvalidArgumentError("depth: got a map without depth edges, expected at least one")
    # Every distance is finite, so a limit beyond float32's range is float32's largest value.
    limit = np.float32(min(max_distance, float(np.finfo(np.float32).max)))
    return float((dist[edges] <= limit).mean())


# -- segmentation metrics ----------------------------------------------------------------------
#
# Which pixels are compared (every segmentation metric below, the same rule): a pixel counts iff
# its segmentation / prediction label is >= 0 and its truth label is >= 0 and differs from
# ``ignore`` (when ``ignore`` is not None). Everything else is left out before any counting, as if
# the image had only the compared pixels (boundary_recall keeps the pixel grid; see there).

#: Most (segment, truth) label pairs held as a dense contingency table before switching to a
#: sparse (np.unique) one: a dense table larger than this many cells would cost more than sorting.
DENSE_TABLE_MAX_CELLS = 1 << 24


def _labels(name: str, value: object) -> npt.NDArray[np.int64]:
    """An ``H x W`` integer label image as int64 (bool and float images refused)."""
    a = _validate.asarray(name, value)
    if a.dtype.kind not in "iu":
        raise InvalidArgumentError(
            f"{name}: got dtype {a.dtype}, expected an integer label image (int/uint)"
        )
    if a.ndim != 2 or a.size == 0:
        raise ShapeMismatchError(
            f"{name}: got shape {tuple(a.shape)}, expected a non-empty (H, W) label image"
        )
    if a.dtype == np.uint64 and a.size and int(a.max()) > np.iinfo(np.int64).max:
        raise InvalidArgumentError(f"{name}: got labels above 2**63 - 1, expected int64 labels")
    return np.asarray(a, dtype=np.int64)


def _ignore(ignore: object) -> int | None:
    if ignore is None:
        return None
    if isinstance(ignore, bool) or not isinstance(ignore, (int, np.integer)):
        raise InvalidArgumentError(f"ignore: got {ignore!r}, expected an integer label or None")
    # Labels are compared as int64: a value outside it would silently match nothing.
    return _validate.integer("ignore", ignore, minimum=-(2**63), maximum=2**63 - 1)


def _pair(
    segmentation: object,
    truth: object,
    ignore: object,
    names: tuple[str, str] = ("segmentation", "truth"),
) -> tuple[npt.NDArray[np.int64], npt.NDArray[np.int64], npt.NDArray[np.bool_]]:
    """Both label images (int64) and the mask of compared pixels; raises when there is none."""
    s = _labels(names[0], segmentation)
    t = _labels(names[1], truth)
    if t.shape != s.shape:
        raise ShapeMismatchError(
            f"{names[1]}: got shape {tuple(t.shape)}, expected {tuple(s.shape)} (the {names[0]}'s)"
        )
    ign = _ignore(ignore)
    valid = (s >= 0) & (t >= 0)
    if ign is not None:
        valid &= t != ign
    if not valid.any():
        raise InvalidArgumentError(
            f"{names[1]}: got no pixel that is labelled in both {names[0]} (>= 0) and {names[1]} "
            f"(>= 0, != ignore={ign}), expected at least one to compare"
        )
    return s, t, valid


def _compact(x: npt.NDArray[np.int64]) -> tuple[npt.NDArray[np.int64], int]:
    """Non-negative labels renumbered 0..n-1 (order kept) and n; a lookup table when the label
    range is small, else np.unique."""
    lo, hi = int(x.min()), int(x.max())
    if hi - lo < 4 * x.size + 1024:
        present = np.bincount(x - lo, minlength=hi - lo + 1) > 0
        lut = np.cumsum(present) - 1
        return lut[x - lo], int(present.sum())
    uniq, inv = np.unique(x, return_inverse=True)
    return inv.reshape(-1).astype(np.int64), int(uniq.size)


@array_eq
@dataclass(frozen=True)
class _Table:
    """The non-zero cells of the contingency table of the compared pixels: ``counts[k]`` pixels
    carry segment ``rows[k]`` and truth label ``cols[k]``; ``seg``/``gt`` are the marginals."""

    rows: npt.NDArray[np.int64]
    cols: npt.NDArray[np.int64]
    counts: npt.NDArray[np.int64]
    seg: npt.NDArray[np.int64]
    gt: npt.NDArray[np.int64]

    @property
    def n(self) -> int:
        return int(self.seg.sum())


def _table(s: npt.NDArray[np.int64], t: npt.NDArray[np.int64]) -> _Table:
    si, ns = _compact(s)
    ti, nt = _compact(t)
    flat = si * nt + ti
    if ns * nt <= max(DENSE_TABLE_MAX_CELLS, 4 * flat.size):
        dense = np.bincount(flat, minlength=ns * nt)
        cells = np.flatnonzero(dense)
        counts = dense[cells]
    else:
        cells, counts = np.unique(flat, return_counts=True)
    rows, cols = np.divmod(cells, nt)
    return _Table(
        rows.astype(np.int64),
        cols.astype(np.int64),
        counts.astype(np.int64),
        np.bincount(si, minlength=ns).astype(np.int64),
        np.bincount(ti, minlength=nt).astype(np.int64),
    )


def _compared_table(segmentation: object, truth: object, ignore: object) -> _Table:
    s, t, valid = _pair(segmentation, truth, ignore)
    return _table(s[valid], t[valid])


def _entropy_sum(counts: npt.NDArray[np.int64]) -> float:
    """``sum c log c`` (natural log, 0 log 0 = 0)."""
    c = counts[counts > 0].astype(np.float64)
    return float(np.sum(c * np.log(c)))


def variation_of_information(
    segmentation: npt.ArrayLike, truth: npt.ArrayLike, *, ignore: int | None = None
) -> float:
    """Variation of Information ``VoI = H(S|T) + H(T|S)`` between a segmentation ``S`` and the
    ground truth ``T`` (Meila 2007), in **nats** (natural logarithm, as the segmentation
    benchmarks of Arbelaez et al. and thesis Table 4.1). 0 = identical partitions; lower is
    better. ``skimage.metrics.variation_of_information`` reports the same two terms in bits
    (log2): multiply their sum by ``ln 2`` to compare.

    Labels are integer ``H x W`` images; only the compared pixels count (segmentation >= 0,
    truth >= 0 and truth != ``ignore``), as if the image held nothing else.
    """
    tab = _compared_table(segmentation, truth, ignore)
    n = tab.n
    # H(S|T) + H(T|S) = 2 H(S,T) - H(S) - H(T), with H(X) = log n - sum(c log c) / n.
    joint = _entropy_sum(tab.counts)
    value = (_entropy_sum(tab.seg) + _entropy_sum(tab.gt) - 2.0 * joint) / n
    return max(0.0, float(value))


def rand_index(
    segmentation: npt.ArrayLike, truth: npt.ArrayLike, *, ignore: int | None = None
) -> float:
    """Rand Index: the fraction of pixel pairs on which segmentation and ground truth agree
    (same segment in both, or different in both), over the compared pixels (segmentation >= 0,
    truth >= 0 and truth != ``ignore``); 1 = identical, higher is better. Equals
    ``sklearn.metrics.rand_score`` on those pixels (1.0 when only one pixel is compared)."""
    tab = _compared_table(segmentation, truth, ignore)
    n = tab.n
    if n < 2:
        return 1.0

    def pairs(c: npt.NDArray[np.int64]) -> int:
        return int(np.sum(c * (c - 1)) // 2)

    total = n * (n - 1) // 2
    same_both = pairs(tab.counts)
    disagree = pairs(tab.seg) + pairs(tab.gt) - 2 * same_both
    return float((total - disagree) / total)


def undersegmentation_error(
    segmentation: npt.ArrayLike, truth: npt.ArrayLike, *, ignore: int | None = None
) -> float:
    """Under-segmentation error in the corrected form of Neubert & Protzel (2012): every segment
    ``S`` that overlaps a ground-truth region ``G`` costs the smaller of its part inside
    (``|S ∩ G|``) and outside (``|S \\ G|``) of it, summed over all overlapping pairs and
    divided by the number of compared pixels:
    ``UE = (1/N) sum_G sum_{S ∩ G != ∅} min(|S ∩ G|, |S \\ G|)``. 0 = every segment inside one
    region; lower is better. Sizes count the compared pixels only (segmentation >= 0,
    truth >= 0 and truth != ``ignore``)."""
    tab = _compared_table(segmentation, truth, ignore)
    outside = tab.seg[tab.rows] - tab.counts
    return float(np.minimum(tab.counts, outside).sum() / tab.n)


def _boundaries(
    labels: npt.NDArray[np.int64], valid: npt.NDArray[np.bool_], *, both: bool = True
) -> np.ndarray:
    """Pixels of ``valid`` with a 4-neighbour of another label: a neighbour in ``valid`` when
    ``both``, any neighbour in the image otherwise (the outline of each valid region)."""
    b = np.zeros(labels.shape, bool)
    for a, c, va, vc, ba, bc in (
        (labels[:, :-1], labels[:, 1:], valid[:, :-1], valid[:, 1:], b[:, :-1], b[:, 1:]),
        (labels[:-1, :], labels[1:, :], valid[:-1, :], valid[1:, :], b[:-1, :], b[1:, :]),
    ):
        differ = a != c
        if both:
            differ &= va & vc
        ba |= differ & va
        bc |= differ & vc
    return b


def boundary_recall(
    segmentation: npt.ArrayLike,
    truth: npt.ArrayLike,
    *,
    tolerance: int = 2,
    ignore: int | None = None,
) -> float:
    """Fraction of ground-truth boundary pixels that lie within ``tolerance`` pixels
    (chessboard distance: a ``(2 tolerance + 1)²`` window) of a segment boundary; higher is
    better (1 = every ground-truth boundary found).

    A ground-truth boundary pixel is a compared pixel (segmentation >= 0, truth >= 0 and
    truth != ``ignore``) with a 4-neighbour of another truth value, labelled or not: the outline
    of every labelled region, on its labelled side (unlabelled pixels are never boundary pixels
    themselves, but a region ends where they start: NYUv2's annotators leave unlabelled gaps
    between objects, so boundaries between two labelled regions alone would miss most object
    outlines). Likewise a segment boundary pixel is a pixel of a segment (>= 0) with a
    4-neighbour of another value (another segment, or no segment), on both sides between two
    segments. No ground-truth boundary among the compared pixels raises
    :class:`~rgbd_rs.InvalidArgumentError`.
    """
    tol = _validate.integer("tolerance", tolerance, maximum=1000)
    s, t, valid = _pair(segmentation, truth, ignore)
    ign = _ignore(ignore)
    labelled = t >= 0 if ign is None else (t >= 0) & (t != ign)
    gt_edges = _boundaries(t, labelled, both=False) & valid
    if not gt_edges.any():
        raise InvalidArgumentError(
            "truth: got no boundary of a labelled region among the compared pixels, "
            "expected at least one"
        )
    seg_edges = _boundaries(s, s >= 0, both=False)
    if tol > 0:
        kernel = np.ones((2 * tol + 1, 2 * tol + 1), np.uint8)
        seg_edges = cv2.dilate(seg_edges.astype(np.uint8), kernel) > 0
    return float(seg_edges[gt_edges].mean())


def _class_pair(
    pred: object, truth: object, n_classes: object, ignore: object
) -> tuple[npt.NDArray[np.int64], npt.NDArray[np.int64], int]:
    """Compared prediction/truth class labels (1-D) and the class count, checked to lie in
    ``[0, n_classes)``."""
    k = _validate.integer("n_classes", n_classes, minimum=1, maximum=1 << 16)
    ign = _ignore(ignore)
    if ign is not None and not 0 <= ign < k:
        raise InvalidArgumentError(
            f"ignore: got {ign}, expected None or a class in [0, {k}) (n_classes={k})"
        )
    p, t, valid = _pair(pred, truth, ign, names=("pred", "truth"))
    for name, a in (("pred", p), ("truth", t)):
        top = int(a.max())
        if top >= k:
            raise InvalidArgumentError(
                f"{name}: got class {top}, expected classes in [0, {k}) (n_classes={k})"
            )
    return p[valid], t[valid], k


def confusion_matrix(
    pred: npt.ArrayLike, truth: npt.ArrayLike, *, n_classes: int, ignore: int | None = 0
) -> npt.NDArray[np.int64]:
    """``n_classes x n_classes`` pixel counts, rows = truth class, columns = predicted class,
    over the compared pixels (pred >= 0, truth >= 0 and truth != ``ignore``): row ``ignore``
    stays zero, while a prediction of class ``ignore`` on a labelled pixel is counted (in column
    ``ignore``), as an error. Classes are integers in ``[0, n_classes)``; for NYUv2's 13 classes
    with 0 = unlabelled that is ``n_classes=14, ignore=0``."""
    p, t, k = _class_pair(pred, truth, n_classes, ignore)
    return np.bincount(t * k + p, minlength=k * k).reshape(k, k).astype(np.int64)


def pixel_accuracy(pred: npt.ArrayLike, truth: npt.ArrayLike, *, ignore: int | None = 0) -> float:
    """Fraction of the compared pixels (pred >= 0, truth >= 0 and truth != ``ignore``) whose
    predicted class equals the true class."""
    p, t, valid = _pair(pred, truth, _ignore(ignore), names=("pred", "truth"))
    return float(np.mean(p[valid] == t[valid]))


def mean_class_accuracy(
    pred: npt.ArrayLike, truth: npt.ArrayLike, *, n_classes: int, ignore: int | None = 0
) -> float:
    """Mean over the classes of the per-class recall ``C[c, c] / sum_j C[c, j]`` of
    :func:`confusion_matrix` ``C``; the mean runs over the classes other than ``ignore`` that
    occur in the compared truth pixels (classes absent from the truth are left out, not counted
    as 0)."""
    cm = confusion_matrix(pred, truth, n_classes=n_classes, ignore=ignore)
    support = cm.sum(axis=1)
    present = support > 0
    return float(np.mean(np.diag(cm)[present] / support[present]))
