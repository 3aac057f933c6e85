"""Stage 2: semi-global matching on the rectified pair (thesis §3.7: OpenCV SGBM with the
Birchfield-Tomasi pixel cost, 8 paths, 7x7 window, left-right check), expressed on the
reference camera, plus the pointwise matching-cost curve used by the stereo confidence.

OpenCV computes disparities for its left input. For a right reference both images are mirrored
and swapped (mirrored right = a "left" view whose match lies at x - d), then the result is
mirrored back.

:func:`search_range` derives SGM's search range from a ToF disparity map robustly (flying pixels
ignored), so one wrong ToF sample cannot blind most of the image.
"""

from __future__ import annotations

import math
import warnings
from collections.abc import Iterator
from typing import Literal, cast

import cv2
import numpy as np
import numpy.typing as npt

from rgbd_rs import _rgbd_rs, _validate
from rgbd_rs.errors import InvalidArgumentError, ShapeMismatchError
from rgbd_rs.fusion._blank import blank_note
from rgbd_rs.fusion._inputs import F32, check_cost_volume, grey8, rgb8
from rgbd_rs.fusion._range_cut import range_cut_note
from rgbd_rs.fusion.census import CensusParams, census_match

#: SGBM block size (thesis §3.7) and smoothness penalties (OpenCV's documented 8/32 x 3 x n^2).
BLOCK_SIZE = 7
P1_FACTOR = 8
P2_FACTOR = 32
#: Left-right check tolerance (px) and uniqueness margin (%); chosen.
DISP12_MAX_DIFF = 1
UNIQUENESS = 5


#: OpenCV SGBM searches ``numDisparities`` in steps of this many pixels.
DISPARITY_STEP = 16

#: :func:`search_range`: the ToF disparity map is median-filtered over this window (flying
#: pixels, isolated or in thin lines along depth edges, vanish), its ``RANGE_PERCENTILE``-th
#: percentile is taken and widened by ``RANGE_MARGIN`` (ToF noise, SGM's sub-pixel margin).
#: Chosen.
RANGE_MEDIAN_WINDOW = 5
RANGE_PERCENTILE = 99.5
RANGE_MARGIN = 1.15
#: The derived range never exceeds this fraction of the image width: SGM finds nothing in the
#: first ``max_disparity`` columns beside the image edge, so a wider range would leave most of
#: the image to the ToF alone (pass ``max_disparity`` to search further). Also the fallback
#: when the ToF has no valid pixel. Chosen.
MAX_RANGE_FRACTION = 1 / 3
#: A ToF whose (median-filtered) valid pixels cover less than this share of the reference image
#: is no sample of the scene's depths: the range is the widest, as with no ToF (one valid pixel
#: capped the search at its disparity, and SGM missed every nearer surface). Chosen: a handful
#: of pixels, far below what a ToF that sees the scene covers.
MIN_RANGE_COVERAGE = 0.01


def _num_disparities(min_disparity: int, max_disparity: int) -> int:
    span = max_disparity - min_disparity
    return DISPARITY_STEP * max(1, -(-span // DISPARITY_STEP))


def _max_search(width: int, min_disparity: int = 0, block_size: int = BLOCK_SIZE) -> int:
    """The largest ``max_disparity`` :func:`sgm` accepts on an image ``width`` pixels wide.

    OpenCV needs ``width - (min_disparity + numDisparities) > block_size // 2`` with
    ``numDisparities`` a multiple of 16 (else it raises, as its results would depend on
    uninitialised memory). Below ``min_disparity + 1`` no search range fits.
    """
    room = width - min_disparity - block_size // 2 - 1
    return min_disparity + DISPARITY_STEP * (room // DISPARITY_STEP)


def _widest_range(width: int) -> int:
    """The largest range :func:`search_range` gives on images ``width`` pixels wide (the
    range of a ToF map without a valid pixel)."""
    return max(1, min(width - 1, _max_search(width), int(MAX_RANGE_FRACTION * width)))


def search_range(tof_disparity: npt.ArrayLike, width: int | None = None) -> int:
    """SGM's ``max_disparity`` for a scene whose ToF disparity (on the reference camera, NaN =
    none) is ``tof_disparity``.

    The map is median-filtered over ``RANGE_MEDIAN_WINDOW`` x ``RANGE_MEDIAN_WINDOW`` pixels
    (NaN counts as no disparity), its ``RANGE_PERCENTILE``-th percentile times ``RANGE_MARGIN``
    is rounded up, and the result is clamped to ``[DISPARITY_STEP, MAX_RANGE_FRACTION x width]``
    and to :func:`_max_search` (what OpenCV SGBM allows on that width). A ToF map without a
    valid pixel, or with valid pixels on less than ``MIN_RANGE_COVERAGE`` of the map, gives the
    upper clamp. ``width`` defaults to the map's.
    """
    return _range_and_coverage(tof_disparity, width)[0]


def _range_and_coverage(
    tof_disparity: npt.ArrayLike, width: int | None = None
) -> tuple[int, float]:
    """:func:`search_range`, and the share of the map whose ToF disparity it read (the valid
    pixels after the median filter; compare with ``MIN_RANGE_COVERAGE``), from one filter pass."""
    d = np.asarray(_validate.array("tof_disparity", tof_disparity, shape=(None, None)), np.float32)
    w = d.shape[1] if width is None else _validate.integer("width", width, minimum=2)
    top = _widest_range(w)
    with np.errstate(invalid="ignore"):
        filled = np.where(np.isfinite(d) & (d > 0), d, 0).astype(np.float32)
    smooth = cv2.medianBlur(filled, RANGE_MEDIAN_WINDOW)
    valid = smooth[smooth > 0]
    share = valid.size / d.size
    if valid.size < MIN_RANGE_COVERAGE * d.size:
        return top, share
    want = math.ceil(float(np.percentile(valid, RANGE_PERCENTILE)) * RANGE_MARGIN)
    return int(min(top, max(DISPARITY_STEP, want))), share


#: :func:`_predict_search_range`'s dilation sides, tried in turn until the spread samples cover
#: ``MIN_RANGE_COVERAGE`` of the map after the median filter: 3 px fills the gaps between
#: samples ~2 px apart (a 512 x 424 ToF on a 1280 x 720 camera); a ToF of a quarter of the pixels
#: per axis (512 x 424 on 4K, 256 x 212 on 1080p) leaves its samples 4-8 px apart, which 3 px
#: left as isolated dots the median filter removed, and the guess fell back to the widest range
#: (1279 px at 4K: a cost volume refused; at 1080p a 640-px search, 1.8 GB and 14 s, thrown away).
PREDICT_DILATIONS = (3, 5, 9, 17, 33)


def _predict_search_range(sparse_disparity: npt.ArrayLike, width: int | None = None) -> int:
    """:func:`search_range` predicted from the ToF disparities splatted onto the reference lattice
    before upsampling (samples ~2 px apart, NaN between them), so SGM can start while the ToF is
    upsampled: the samples are spread by a grey dilation (filling the gaps between them; the
    first side of :data:`PREDICT_DILATIONS` whose result covers ``MIN_RANGE_COVERAGE`` of the
    map after the median filter: 3 x 3 on samples ~2 px apart) and the result goes through
    :func:`search_range`. On the synthetic test set, six generated scenes and Middlebury it lands
    within 1 px of the upsampled map's range and in the same 16-px SGBM step in 23 of 24 scenes;
    :func:`rgbd_rs.fusion.fuse` re-runs SGM in the others.
    """
    d = np.asarray(
        _validate.array("sparse_disparity", sparse_disparity, shape=(None, None)), np.float32
    )
    with np.errstate(invalid="ignore"):
        filled = np.where(np.isfinite(d) & (d > 0), d, 0).astype(np.float32)
    none = np.full(d.shape, np.nan, np.float32)
    if not filled.any():
        return search_range(none, width)
    for side in PREDICT_DILATIONS:
        kernel = np.ones((side, side), np.uint8)
        spread = cv2.dilate(filled, kernel)
        # The coverage of the samples' own footprint (the spread eroded back): a wide spread of
        # a ToF that sees a small corner must not read as enough samples.
        closed = cv2.erode(spread, kernel)
        if (
            _range_and_coverage(np.where(closed > 0, closed, np.nan), width)[1]
            >= MIN_RANGE_COVERAGE
        ):
            return search_range(np.where(spread > 0, spread, np.nan), width)
    return search_range(none, width)


def _same_search(a: int, b: int, min_disparity: int = 0) -> bool:
    """Whether :func:`sgm` gives the same map for ``max_disparity`` ``a`` and ``b`` (OpenCV
    searches whole steps of :data:`DISPARITY_STEP`, so only the step count matters)."""
    return _num_disparities(min_disparity, a) == _num_disparities(min_disparity, b)


def _whole_steps(max_disparity: int, min_disparity: int = 0) -> int:
    """The largest disparity OpenCV SGBM searches for ``max_disparity``: ``min_disparity +
    numDisparities - 1``, with ``numDisparities`` the span rounded up to whole steps of
    :data:`DISPARITY_STEP` (so 15 for 16, 31 for 17..32). Giving the census matcher this range
    makes its map, like SGBM's, the same for every ``max_disparity`` :func:`_same_search` calls
    the same."""
    return min_disparity + _num_disparities(min_disparity, max_disparity) - 1


#: The matchers :func:`sgm` runs.
METHODS = ("census", "opencv")


def sgm(
    left: npt.ArrayLike,
    right: npt.ArrayLike,
    *,
    reference: str = "right",
    max_disparity: int = 128,
    min_disparity: int = 0,
    block_size: int = BLOCK_SIZE,
    method: str = "opencv",
    params: CensusParams | None = None,
) -> F32:
    """Semi-global matching disparity (``d = u_left - u_right``) on the ``reference`` view;
    NaN = invalid.

    ``method="census"`` runs our matcher (:func:`~rgbd_rs.fusion.census.census_match`: census
    costs, SGM paths, sub-pixel, optional left-right and uniqueness checks; ``params`` sets its
    knobs, the search range is ``min_disparity..max_disparity`` inclusive).

    ``method="opencv"`` runs OpenCV's SGBM (MODE_HH, Birchfield-Tomasi costs over
    ``block_size`` blocks: the thesis' matcher, the peer of ours, and the one the earlier
    confidence checkpoints were trained on: :func:`~rgbd_rs.fusion.fuse` runs it for them);
    there, invalid means what SGBM marks invalid (left-right check, uniqueness, the image
    border) and its outputs at the lower end of the search, ``d = min_disparity``: SGBM parks
    pixels there that it could not match and cannot refine them to sub-pixel.

    Args:
        left, right: the rectified pair, uint8 RGB (or grey) of equal size.
        reference: ``"right"`` (the thesis' output camera) or ``"left"``.
        max_disparity, min_disparity: search range in pixels (OpenCV rounds it up to a multiple
            of 16).
        block_size: OpenCV's odd matching window (7 as in the thesis).
        method: ``"opencv"`` or ``"census"``.
        params: :class:`~rgbd_rs.fusion.census.CensusParams` (``method="census"`` only).

    Warns (RuntimeWarning) when over 1 % of the matched pixels lie in the range's top pixel:
    the range likely ends before the nearest surface (:mod:`rgbd_rs.fusion._range_cut`); and
    when most of a view has no texture to match (blank, saturated or covered:
    :mod:`rgbd_rs.fusion._blank`).
    """
    disparity = _sgm(
        left,
        right,
        reference=reference,
        max_disparity=max_disparity,
        min_disparity=min_disparity,
        block_size=block_size,
        method=method,
        params=params,
    )
    top = _searched_top(method, int(min_disparity), int(max_disparity))
    note = range_cut_note(disparity, top, "max_disparity")
    if note is not None:
        warnings.warn(note, RuntimeWarning, stacklevel=2)
    blank = blank_note(*_as_matched(method, left, right))
    if blank is not None:
        warnings.warn(blank, RuntimeWarning, stacklevel=2)
    return disparity


def _as_matched(
    method: str, left: npt.ArrayLike, right: npt.ArrayLike
) -> tuple[npt.NDArray[np.uint8], npt.NDArray[np.uint8]]:
    """The pair as ``method`` matches it: grey for ours, colour for OpenCV's SGBM."""
    if method == "census":
        return grey8("left", left), grey8("right", right)
    return rgb8("left", left), rgb8("right", right)


def _searched_top(method: str, min_disparity: int, max_disparity: int) -> int:
    """The largest disparity the matcher can output: ``max_disparity`` for ours, for OpenCV's
    SGBM the top of its range rounded up to whole steps of :data:`DISPARITY_STEP`."""
    if method == "opencv":
        return min_disparity + _num_disparities(min_disparity, max_disparity) - 1
    return max_disparity


def _sgm(
    left: npt.ArrayLike,
    right: npt.ArrayLike,
    *,
    reference: str = "right",
    max_disparity: int = 128,
    min_disparity: int = 0,
    block_size: int = BLOCK_SIZE,
    method: str = "opencv",
    params: CensusParams | None = None,
) -> F32:
    """:func:`sgm` without its range check (``fuse`` and the evaluations set their own ranges;
    ``rgbd stereo`` words the check for its flags)."""
    kind = _validate.choice("method", method, METHODS)
    if kind == "census":
        if block_size != BLOCK_SIZE:
            raise InvalidArgumentError(
                f"block_size: got {block_size!r}, expected the default with method='census' "
                "(the census window is params.census_width x params.census_height)"
            )
        ref_c = _validate.choice("reference", reference, ("left", "right"))
        return census_match(
            left,
            right,
            reference=cast(Literal["left", "right"], ref_c),
            max_disparity=max_disparity,
            min_disparity=min_disparity,
            params=params,
        ).disparity
    if params is not None:
        raise InvalidArgumentError(
            "params: got CensusParams, expected None with method='opencv' (OpenCV's knob is "
            "block_size)"
        )
    lft = rgb8("left", left)
    rgt = rgb8("right", right, (lft.shape[1], lft.shape[0]), of="left's size")
    ref = _validate.choice("reference", reference, ("left", "right"))
    lo = _validate.integer(
        "min_disparity", min_disparity, minimum=0, maximum=max(0, lft.shape[1] - 2)
    )
    hi = _validate.integer("max_disparity", max_disparity, minimum=lo + 1)
    if hi >= lft.shape[1]:
        raise InvalidArgumentError(
            f"max_disparity: got {hi}, expected less than the image width {lft.shape[1]}"
        )
    bs = _validate.integer("block_size", block_size, minimum=1, maximum=11)
    if bs % 2 == 0:
        raise InvalidArgumentError(f"block_size: got {bs}, expected an odd number")
    limit = _max_search(lft.shape[1], lo, bs)
    if limit <= lo:
        raise ShapeMismatchError(
            f"left: got an image {lft.shape[1]} px wide, expected at least "
            f"{lo + DISPARITY_STEP + bs // 2 + 1} px for min_disparity={lo} (OpenCV SGBM searches "
            f"{DISPARITY_STEP} disparities at least and needs a {bs // 2 + 1} px margin)"
        )
    if hi > limit:
        raise InvalidArgumentError(
            f"max_disparity: got {hi}, expected at most {limit} on an image {lft.shape[1]} px "
            f"wide (OpenCV SGBM searches in steps of {DISPARITY_STEP} and needs a "
            f"{bs // 2 + 1} px margin)"
        )
    check_cost_volume(hi, lft.shape[1], lft.shape[0], _num_disparities(lo, hi))
    return _sgbm_disparity(lft, rgt, ref, lo, hi, bs)


def _sgbm_matcher(lo: int, hi: int, bs: int, mode: int = cv2.STEREO_SGBM_MODE_HH) -> cv2.StereoSGBM:
    """OpenCV's SGBM as :func:`sgm` configures it (``mode`` HH by default; benchmarks and the
    stereo evaluation also run 3WAY), arguments unchecked."""
    return cv2.StereoSGBM.create(
        minDisparity=lo,
        numDisparities=_num_disparities(lo, hi),
        blockSize=bs,
        P1=P1_FACTOR * 3 * bs * bs,
        P2=P2_FACTOR * 3 * bs * bs,
        disp12MaxDiff=DISP12_MAX_DIFF,
        uniquenessRatio=UNIQUENESS,
        mode=mode,
    )


def _sgbm_disparity(
    lft: npt.NDArray[np.uint8],
    rgt: npt.NDArray[np.uint8],
    ref: str,
    lo: int,
    hi: int,
    bs: int,
    mode: int = cv2.STEREO_SGBM_MODE_HH,
) -> F32:
    """:func:`sgm`'s OpenCV path on checked inputs: the right reference matches the mirrored,
    swapped pair; outputs at ``d <= lo`` are NaN (see :func:`sgm`)."""
    matcher = _sgbm_matcher(lo, hi, bs, mode)
    try:
        if ref == "left":
            raw = matcher.compute(lft, rgt)
        else:
            raw = matcher.compute(
                np.ascontiguousarray(rgt[:, ::-1]), np.ascontiguousarray(lft[:, ::-1])
            )
            raw = raw[:, ::-1]
    except cv2.error as exc:  # OpenCV's allocation refused: a MemoryError in our words
        if "Insufficient memory" not in str(exc):
            raise
        size = f"{lft.shape[1]} x {lft.shape[0]} x {_num_disparities(lo, hi)}"
        raise MemoryError(
            f"max_disparity: out of memory: OpenCV SGBM could not allocate its cost volume "
            f"({size}, about 4 bytes each); free memory, or search fewer disparities or a "
            "smaller image"
        ) from None
    disp = raw.astype(np.float32) / 16.0
    disp[raw <= lo * 16] = np.nan
    return np.ascontiguousarray(disp)


def _cost_slices(
    r_img: F32, t_img: F32, sign: int, dmax: int, block: int
) -> Iterator[tuple[int, F32]]:
    """Box-aggregated absolute grey difference at each integer disparity (inf off-image)."""
    h, w = r_img.shape
    for d in range(dmax + 1):
        diff = np.full((h, w), 255.0, np.float32)
        if sign > 0:  # target x + d
            diff[:, : w - d] = np.abs(r_img[:, : w - d] - t_img[:, d:])
        else:  # target x - d
            diff[:, d:] = np.abs(r_img[:, d:] - t_img[:, : w - d])
        cost = np.asarray(
            cv2.blur(diff, (block, block), borderType=cv2.BORDER_REPLICATE), np.float32
        )
        if sign > 0:
            cost[:, w - d :] = np.inf
        else:
            cost[:, :d] = np.inf
        yield d, cost


def cost_curve_stats(
    reference_image: npt.ArrayLike,
    target_image: npt.ArrayLike,
    disparity: npt.ArrayLike,
    *,
    target_sign: int = 1,
    max_disparity: int = 128,
    block_size: int = BLOCK_SIZE,
) -> tuple[F32, F32, F32]:
    """Reads the pointwise cost curve (mean absolute grey difference over a ``block_size`` box,
    integer disparities ``0..max_disparity``) that SGBM keeps internal.

    Returns ``(c1, c2, c_at)``: the curve's minimum, its second minimum away from the first
    (|d - argmin| > 1) and its value at ``disparity`` (rounded half to even; NaN where that is NaN
    or outside ``0..max_disparity``). Computed natively (``crates/rgbd-fusion/src/costcurve.rs``,
    parallel bands of rows, one box-sum pass per disparity) without storing the ``D x H x W``
    volume; equal bit for bit to the numpy/OpenCV formulation ``_cost_curve_stats_numpy``.
    """
    ref = rgb8("reference_image", reference_image)
    tgt = rgb8(
        "target_image", target_image, (ref.shape[1], ref.shape[0]), of="reference_image's size"
    )
    h, w = ref.shape[:2]
    disp = np.asarray(_validate.array("disparity", disparity, shape=(h, w)), np.float32)
    target_sign = _validate.sign("target_sign", target_sign)
    dmax = _validate.integer("max_disparity", max_disparity, minimum=1, maximum=w - 1)
    bs = _validate.integer("block_size", block_size, minimum=1, maximum=31)
    r_grey = np.asarray(cv2.cvtColor(ref, cv2.COLOR_RGB2GRAY), np.uint8)
    t_grey = np.asarray(cv2.cvtColor(tgt, cv2.COLOR_RGB2GRAY), np.uint8)
    return _rgbd_rs.cost_curve_stats(r_grey, t_grey, disp, target_sign, dmax, bs)


def _cost_curve_stats_numpy(
    r_grey: npt.NDArray[np.uint8],
    t_grey: npt.NDArray[np.uint8],
    disp: F32,
    sign: int,
    dmax: int,
    bs: int,
) -> tuple[F32, F32, F32]:
    """:func:`cost_curve_stats` in numpy/OpenCV (the reference the native kernel equals bit for
    bit; kept for the tests and benches/bench_fusion.py)."""
    r_img, t_img = r_grey.astype(np.float32), t_grey.astype(np.float32)
    h, w = r_img.shape
    c1 = np.full((h, w), np.inf, np.float32)
    arg = np.zeros((h, w), np.int32)
    at = np.full((h, w), np.nan, np.float32)
    want = np.where(np.isfinite(disp), np.rint(disp), -1).astype(np.int32)
    for d, cost in _cost_slices(r_img, t_img, sign, dmax, bs):
        better = cost < c1
        c1[better] = cost[better]
        arg[better] = d
        hit = want == d
        at[hit] = cost[hit]
    c2 = np.full((h, w), np.inf, np.float32)
    for d, cost in _cost_slices(r_img, t_img, sign, dmax, bs):
        far = np.abs(arg - d) > 1
        np.minimum(c2, np.where(far, cost, np.inf), out=c2)
    return c1, c2, at
