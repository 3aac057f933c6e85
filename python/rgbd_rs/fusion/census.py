"""Our stereo matcher: census-cost semi-global matching in Rust (``crates/rgbd-stereo``).

A census transform (window ``census_width x census_height``, bits = which window pixels are
darker than the centre or the window mean) gives a pixelwise, gain- and bias-free matching cost
(Hamming distance) that, unlike a block sum, does not carry a nearer surface over its edge (the
foreground fattening OpenCV's 7x7 SGBM shows). The costs are aggregated along 4, 5 or 8 paths
with penalties ``p1`` (one-pixel steps) and ``p2`` (larger steps, optionally lowered where the
image has an edge along the path: ``P2 / (1 + dI / p2_contrast)``), the winner is refined to
sub-pixel (parabola or equiangular), then checked for uniqueness and against the other view's
winners read from the same sums (left-right check), and median- and speckle-filtered.

One ``H x W x D`` u16 volume is the only large buffer (``2 W H D`` bytes); the inner loops are
compiled for AVX-512, AVX2 and the portable baseline, chosen at run time, with the same bits.
Every default (:class:`CensusParams`) is defined in Rust (``SgmParams::new``) and was chosen on
the Middlebury train/val scenes: the window, penalties and filters by ``rgbd eval stereo``'s
measures (``tools/sweep_census.py``), ``vertical_tolerance=1`` on the same scenes with their
right images perturbed as a real rig's are (it costs 0.5 points of bad-2 on the pairs as given;
docs/experiments.md).
"""

from __future__ import annotations

import warnings
from dataclasses import dataclass, fields
from typing import Literal

import numpy as np
import numpy.typing as npt

from rgbd_rs import _rgbd_rs, _validate
from rgbd_rs._array_eq import array_eq
from rgbd_rs.errors import InvalidArgumentError, ShapeMismatchError
from rgbd_rs.fusion._inputs import F32, check_cost_volume, grey8, pair8
from rgbd_rs.fusion.rows import (
    ALIGN_THRESHOLD,
    MAX_CORRECTIONS,
    RowAlignment,
    _measure,
    _resample,
)

_DEFAULTS = _rgbd_rs.sgm_defaults()
#: Largest ``p2`` (eight paths of cost + P2 must fit a u16 sum) and median window side.
MAX_P2: int = _DEFAULTS["max_p2"]
MAX_MEDIAN: int = _DEFAULTS["max_median"]
#: Largest ``vertical_tolerance`` (target rows searched above and below).
MAX_VERTICAL: int = _DEFAULTS["max_vertical"]


@dataclass(frozen=True)
class CensusParams:
    """Every knob of the census matcher except the search range; defaults from the Rust core.

    Attributes:
        census_width, census_height: odd window sides (at most 64 bits in all).
        census_reference: ``"center"`` (classic census) or ``"mean"`` (compare with the window
            mean; the centre pixel then adds a bit).
        p1, p2: path penalties in census bits (``p1 < p2 <= MAX_P2``).
        p2_contrast: grey-level step that halves ``p2`` along a path (0 = constant ``p2``).
        paths: 4, 5 or 8 aggregation directions.
        subpixel: ``"parabola"``, ``"equiangular"`` or ``"off"``.
        lr_tolerance: left-right check tolerance in pixels (None = no check).
        uniqueness: margin in percent by which the winner must beat every cost more than one
            disparity away (0 = off).
        median: median filter side (1 = off; odd, at most ``MAX_MEDIAN``).
        speckle_size: connected regions (within ``speckle_range`` px) smaller than this many
            pixels are removed (0 = off).
        vertical_tolerance: target rows searched above and below each pixel's row (0 to
            ``MAX_VERTICAL``): its matching cost is the smallest over them. 0 = the rectified
            row only; 1 for a rig whose rectification leaves a vertical error near a pixel.
        align_rows: measure how far the other view's rows lie from the reference's after a
            first match, and where it reaches ``rows.ALIGN_THRESHOLD`` px, resample the other
            view's rows and match again (:mod:`rgbd_rs.fusion.rows`; Python-side, not in
            ``SgmParams``). Off = one match of the pair as given.
    """

    census_width: int = _DEFAULTS["census_width"]
    census_height: int = _DEFAULTS["census_height"]
    census_reference: Literal["center", "mean"] = _DEFAULTS["census_reference"]
    p1: int = _DEFAULTS["p1"]
    p2: int = _DEFAULTS["p2"]
    p2_contrast: float = _DEFAULTS["p2_contrast"]
    paths: int = _DEFAULTS["paths"]
    subpixel: Literal["parabola", "equiangular", "off"] = _DEFAULTS["subpixel"]
    lr_tolerance: int | None = _DEFAULTS["lr_tolerance"]
    uniqueness: int = _DEFAULTS["uniqueness"]
    median: int = _DEFAULTS["median"]
    speckle_size: int = _DEFAULTS["speckle_size"]
    speckle_range: float = _DEFAULTS["speckle_range"]
    vertical_tolerance: int = _DEFAULTS["vertical_tolerance"]
    align_rows: bool = True

    def __post_init__(self) -> None:
        _validate.integer("census_width", self.census_width, minimum=1, maximum=15)
        _validate.integer("census_height", self.census_height, minimum=1, maximum=15)
        _validate.choice("census_reference", self.census_reference, ("center", "mean"))
        _validate.integer("p1", self.p1, minimum=1, maximum=MAX_P2 - 1)
        _validate.integer("p2", self.p2, minimum=self.p1 + 1, maximum=MAX_P2)
        _validate.real("p2_contrast", self.p2_contrast, nonnegative=True, f32=True)
        if isinstance(self.paths, bool) or self.paths not in (4, 5, 8):
            raise InvalidArgumentError(f"paths: got {self.paths!r}, expected 4, 5 or 8")
        _validate.choice("subpixel", self.subpixel, ("parabola", "equiangular", "off"))
        if self.lr_tolerance is not None:
            _validate.integer("lr_tolerance", self.lr_tolerance, minimum=0, maximum=255)
        _validate.integer("uniqueness", self.uniqueness, minimum=0, maximum=99)
        _validate.integer("median", self.median, minimum=1, maximum=MAX_MEDIAN)
        if self.median % 2 == 0:
            raise InvalidArgumentError(f"median: got {self.median}, expected an odd side")
        _validate.integer("speckle_size", self.speckle_size, minimum=0, maximum=2**31)
        _validate.real("speckle_range", self.speckle_range, nonnegative=True, f32=True)
        _validate.integer(
            "vertical_tolerance", self.vertical_tolerance, minimum=0, maximum=MAX_VERTICAL
        )
        _validate.flag("align_rows", self.align_rows)
        bits = self.census_width * self.census_height - (self.census_reference == "center")
        if self.census_width % 2 == 0 or self.census_height % 2 == 0 or bits > 64:
            raise InvalidArgumentError(
                f"census_width: got a {self.census_width}x{self.census_height} window, expected "
                "odd sides and at most 64 bits (e.g. 9x7)"
            )

    def replace(self, **changes: object) -> CensusParams:
        """A copy with ``changes`` applied (validated)."""
        values = {f.name: getattr(self, f.name) for f in fields(self)}
        unknown = sorted(set(changes) - set(values))
        if unknown:
            raise InvalidArgumentError(
                f"changes: got unknown parameter(s) {unknown}, expected some of {sorted(values)}"
            )
        values.update(changes)
        return CensusParams(**values)


@array_eq
@dataclass(frozen=True)
class CensusMatch:
    """:func:`census_match`'s result on the reference view (``H x W`` float32).

    Attributes:
        disparity: ``d = u_left - u_right`` in pixels, NaN where rejected or not searchable.
        best: the winner's aggregated cost (None unless ``stats``).
        second: the smallest aggregated cost more than one disparity away from the winner
            (+inf if none; None unless ``stats``). ``second / best`` is the cost-curve ratio.
        rows: the row misalignment the other view was resampled by before the final match
            (:class:`~rgbd_rs.fusion.rows.RowAlignment`), None when it was matched as given.
    """

    disparity: F32
    best: F32 | None
    second: F32 | None
    rows: RowAlignment | None = None


def census_match(
    left: npt.ArrayLike,
    right: npt.ArrayLike,
    *,
    reference: Literal["left", "right"] = "right",
    max_disparity: int = 128,
    min_disparity: int = 0,
    params: CensusParams | None = None,
    stats: bool = False,
) -> CensusMatch:
    """Census SGM of a rectified pair on ``reference`` (see the module docs).

    Args:
        left, right: uint8 RGB or grey images of equal size.
        reference: the view the map lies on (``"right"`` as the thesis, or ``"left"``).
        max_disparity, min_disparity: the search range in pixels, inclusive.
        params: :class:`CensusParams` (default: the shipped defaults).
        stats: also return the aggregated cost curve's best and second-best costs.

    Warns (``RuntimeWarning``) when the pair's rows had to be aligned (``params.align_rows``):
    the map is then that of the resampled pair, and a re-rectified pair matches better.
    """
    raw, raw_r = pair8(left, right)
    # Sizes next: a huge (e.g. broadcast) input is refused before it is copied.
    h, w = raw.shape[:2]
    if h * w > _rgbd_rs.MAX_PIXELS:
        raise ShapeMismatchError(
            f"left: got {w} x {h} pixels, expected at most {_rgbd_rs.MAX_PIXELS}"
        )
    ref = _validate.choice("reference", reference, ("left", "right"))
    lo = _validate.integer("min_disparity", min_disparity, minimum=0, maximum=max(0, w - 2))
    hi = _validate.integer("max_disparity", max_disparity, minimum=lo + 1)
    if hi >= w:
        raise InvalidArgumentError(
            f"max_disparity: got {hi}, expected less than the image width {w}"
        )
    check_cost_volume(hi, w, h, hi - lo + 1)
    lft = grey8("left", raw)
    rgt = grey8("right", raw_r)
    if params is None:
        params = CensusParams()
    elif not isinstance(params, CensusParams):
        raise InvalidArgumentError(
            f"params: got {type(params).__name__}, expected CensusParams or None"
        )
    if not isinstance(stats, bool):
        raise InvalidArgumentError(f"stats: got {stats!r}, expected True or False")
    config = _rgbd_rs.SgmConfig(
        lo,
        hi,
        params.census_width,
        params.census_height,
        params.census_reference,
        params.p1,
        params.p2,
        float(params.p2_contrast),
        params.paths,
        params.subpixel,
        params.lr_tolerance,
        params.uniqueness,
        params.median,
        params.speckle_size,
        float(params.speckle_range),
        params.vertical_tolerance,
        stats,
    )
    disp, best, second = _rgbd_rs.census_sgm(lft, rgt, ref, config)
    if not params.align_rows:
        return CensusMatch(disp, best, second)
    return _aligned(lft, rgt, ref, config, CensusMatch(disp, best, second))


def _aligned(
    left: npt.NDArray[np.uint8],
    right: npt.NDArray[np.uint8],
    reference: str,
    config: _rgbd_rs.SgmConfig,
    first: CensusMatch,
) -> CensusMatch:
    """``first``, or the match of the pair with the other view's rows aligned to the reference's
    where :func:`~rgbd_rs.fusion.rows._measure` finds them apart (grey images)."""
    sign = -1 if reference == "left" else 1
    ref_img, other = (left, right) if reference == "left" else (right, left)
    out = first
    total: RowAlignment | None = None
    target = other
    for _ in range(MAX_CORRECTIONS):
        found = _measure(ref_img, target, out.disparity, sign)
        if found is None or found.max_offset < ALIGN_THRESHOLD:
            break
        total = found if total is None else total.plus(found)
        target = _resample(other, total)
        pair = (left, target) if reference == "left" else (target, right)
        disp, best, second = _rgbd_rs.census_sgm(pair[0], pair[1], reference, config)
        out = CensusMatch(disp, best, second, total)
    if out.rows is not None:
        view = "right" if reference == "left" else "left"
        warnings.warn(
            f"{view}: the pair's rows disagree by {out.rows.describe()}, + meaning the "
            f"{view} image's rows lie lower; matched after "
            f"resampling the {view} image's rows (re-rectify the pair for the best map, or "
            "match it as given with CensusParams(align_rows=False) or rgbd stereo "
            "--no-align-rows)",
            RuntimeWarning,
            stacklevel=3,
        )
    return out
