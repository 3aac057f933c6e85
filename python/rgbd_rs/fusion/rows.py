"""A stereo pair whose rows disagree: measured from a first match, undone by resampling rows.

A rectified pair puts a scene point on the same row of both images. A real rig's rectification
leaves some error (a calibration a little off, a camera knocked after calibrating): the point
lands ``dy`` rows lower or higher in the other image, by a constant (a vertical shift), growing
across the image (a turn about the optical axis) or down it (a focal length off). The census
matcher searches one row either way (``CensusParams.vertical_tolerance``), which covers about a
pixel; past it, matching breaks down (Middlebury train + val, bad-2: 28.7 % at 2 px against
6.8 % rectified).

:func:`measure_row_alignment` measures the misalignment from a first match: at up to
:data:`MAX_SAMPLES` textured pixels with a disparity, a 7 x 7 patch of the reference view is
compared (zero-mean normalised cross-correlation) with the other view's patch at the matched
column on the rows ``-ROW_SEARCH .. ROW_SEARCH`` around it; the best row, refined to sub-pixel by
a parabola, is that pixel's ``dy``. A plane ``dy(u, v) = offset + slope_x (u - w/2) / w +
slope_y (v - h/2) / h`` in the other view's pixels is fitted to them by trimmed least squares.
:func:`align_rows` resamples the other view's rows by it (bicubic), so that the matcher meets
the pair rectified. :func:`~rgbd_rs.fusion.census.census_match` does both when
``CensusParams.align_rows`` is on (the default): where the fitted plane reaches
:data:`ALIGN_THRESHOLD` px anywhere, the other view is resampled and matched again, at most
:data:`MAX_CORRECTIONS` times.

Every constant was chosen on the Middlebury train + val pairs with the right image shifted,
sheared and stretched vertically (docs/experiments.md); the pairs as given read below 0.1 px
and are never resampled.
"""

from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np
import numpy.typing as npt

from rgbd_rs import _validate
from rgbd_rs.errors import InvalidArgumentError, ShapeMismatchError
from rgbd_rs.fusion._inputs import F32, U8, grey8, image8, pair8

#: Patch radius of the row comparison (7 x 7 patches).
PATCH_RADIUS = 3
#: Rows searched above and below a matched pixel.
ROW_SEARCH = 4
#: Pixels compared at most (an even subsample of the textured matched pixels).
MAX_SAMPLES = 500
#: A patch needs this mean ``|I(v + 1) - I(v - 1)|`` (grey levels) to tell rows apart.
MIN_TEXTURE = 1.0
#: A row comparison counts when its best correlation reaches this (and lies inside the search).
MIN_CORRELATION = 0.7
#: Nothing is measured unless this share of the compared pixels count: a first match too poor
#: to read rows from (a pair given the wrong way round, or no pair at all) counts 0.03-0.34 on
#: the Middlebury train + val scenes (a swapped pair with a left-right check up to 0.47), their
#: pairs as given 0.79-0.98, 2 px apart 0.56-0.93.
MIN_CLEAR_SHARE = 0.5
#: Fewer agreeing pixels than this (or than a fifth of the compared ones): nothing is measured.
MIN_SAMPLES = 50
#: Resample and match again where the fitted misalignment reaches this many pixels anywhere.
ALIGN_THRESHOLD = 0.5
#: Corrections at most (a 3-px shift needs two: the first match is too poor to read all of it).
MAX_CORRECTIONS = 2
#: A slope across (down) the image is fitted only where the compared pixels' columns (rows)
#: spread over the image: their standard deviation at least this share of its width (height),
#: as a band 35 % of it does (a whole textured image: 0.29). A narrow band cannot tell a slope
#: from the sub-pixel noise of its offsets (±0.15 px on a pair matched with itself), which a
#: slope fitted to a textured band 15 % of the height carried to 0.6 px at the far edge.
#: Chosen: the samples of every Middlebury train + val pair (either reference) spread 0.19 or more.
MIN_FIT_SPREAD = 0.1


@dataclass(frozen=True)
class RowAlignment:
    """How far the other view's rows lie from the reference view's, as a plane.

    A point on row ``v`` of the reference view lies on row ``v + dy(u, v)`` of the other view
    (``u`` its column there), with ``dy(u, v) = offset + slope_x (u - w/2) / w + slope_y (v - h/2)
    / h``: positive = lower in the other view.

    Attributes:
        offset: the misalignment at the image centre, px.
        slope_x: its change from the left to the right border, px (a turn about the optical
            axis).
        slope_y: its change from the top to the bottom border, px (a focal length off).
        width, height: the image size it was measured on.
        samples: pixels that agreed with the plane.
        spread: their robust standard deviation about it, px.
    """

    offset: float
    slope_x: float
    slope_y: float
    width: int
    height: int
    samples: int
    spread: float

    def __post_init__(self) -> None:
        for name in ("offset", "slope_x", "slope_y"):
            object.__setattr__(self, name, _validate.real(name, getattr(self, name)))
        object.__setattr__(self, "spread", _validate.real("spread", self.spread, nonnegative=True))
        object.__setattr__(self, "width", _validate.integer("width", self.width, minimum=1))
        object.__setattr__(self, "height", _validate.integer("height", self.height, minimum=1))
        object.__setattr__(self, "samples", _validate.integer("samples", self.samples))

    @property
    def max_offset(self) -> float:
        """The largest ``|dy|`` over the image (at a corner), px."""
        return abs(self.offset) + 0.5 * abs(self.slope_x) + 0.5 * abs(self.slope_y)

    def field(self) -> F32:
        """``dy`` at every pixel of the other view (``height x width`` float32)."""
        h, w = self.height, self.width
        u = (np.arange(w, dtype=np.float32) - w / 2) / w
        v = (np.arange(h, dtype=np.float32) - h / 2) / h
        f = self.offset + self.slope_x * u[None, :] + self.slope_y * v[:, None]
        return np.ascontiguousarray(f, dtype=np.float32)

    def plus(self, other: RowAlignment) -> RowAlignment:
        """This misalignment followed by ``other`` (measured after this one was undone)."""
        if not isinstance(other, RowAlignment):
            raise InvalidArgumentError(
                f"other: got {type(other).__name__}, expected a RowAlignment"
            )
        if (other.width, other.height) != (self.width, self.height):
            raise ShapeMismatchError(
                f"other: got one measured on {other.width}x{other.height} pixels, expected "
                f"{self.width}x{self.height} (this one's size)"
            )
        return RowAlignment(
            self.offset + other.offset,
            self.slope_x + other.slope_x,
            self.slope_y + other.slope_y,
            self.width,
            self.height,
            other.samples,
            other.spread,
        )

    def describe(self) -> str:
        """One line for a warning or a log (+: the other view's rows lie lower)."""
        parts = [f"{self.offset:+.2f} px at the centre"]
        if abs(self.slope_x) >= 0.1:
            parts.append(f"{self.slope_x:+.2f} px from left to right")
        if abs(self.slope_y) >= 0.1:
            parts.append(f"{self.slope_y:+.2f} px from top to bottom")
        return f"up to {self.max_offset:.2f} px (" + ", ".join(parts) + ")"


def _samples(ref: U8, disparity: F32, sign: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Textured matched reference pixels (rows, columns) and their columns in the other view:
    a grid of about ``4 MAX_SAMPLES`` pixels, thinned evenly to ``MAX_SAMPLES``."""
    h, w = ref.shape
    r, k = PATCH_RADIUS, ROW_SEARCH
    step = max(1, int(np.sqrt(h * w / (4 * MAX_SAMPLES))))
    ys, xs = np.mgrid[r + k + 1 : h - r - k - 1 : step, r + 1 : w - r - 1 : step]
    ys, xs = ys.ravel(), xs.ravel()
    d = disparity[ys, xs]
    with np.errstate(invalid="ignore"):
        u = xs + sign * d
        ok = np.isfinite(u) & (u >= r + 1) & (u < w - r - 2)
    ys, xs, u = ys[ok], xs[ok], u[ok]
    rows = ys[:, None] + np.arange(-r - 1, r + 2)
    cols = (xs[:, None] + np.arange(-r, r + 1))[:, None, :]
    patch = ref[rows[:, :, None], cols].astype(np.float32)
    texture = np.abs(patch[:, 2:] - patch[:, :-2]).mean(axis=(1, 2))
    ok = texture >= MIN_TEXTURE
    ys, xs, u = ys[ok], xs[ok], u[ok]
    if len(ys) > MAX_SAMPLES:
        pick = np.linspace(0, len(ys) - 1, MAX_SAMPLES).astype(np.int64)
        ys, xs, u = ys[pick], xs[pick], u[pick]
    return ys, xs, u


def _centred(patches: F32) -> tuple[F32, F32]:
    p = patches - patches.mean(axis=(1, 2), keepdims=True)
    return p, np.sqrt((p * p).sum(axis=(1, 2))) + 1e-3


def _row_offsets(
    ref: U8, other: U8, ys: np.ndarray, xs: np.ndarray, u: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """Each sample's sub-pixel row offset in the other view, where its correlation is clear."""
    r, k = PATCH_RADIUS, ROW_SEARCH
    off = np.arange(-r, r + 1)
    pl, nl = _centred(
        ref[(ys[:, None] + off)[:, :, None], (xs[:, None] + off)[:, None, :]].astype(np.float32)
    )
    # One gather of the other view's strip (rows -r-k .. r+k, columns u0-r .. u0+r+1), then
    # the sub-pixel column once; each row offset is a slice of it.
    u0 = np.floor(u).astype(np.int64)
    fu = (u - u0).astype(np.float32)[:, None, None]
    rows = ys[:, None] + np.arange(-r - k, r + k + 1)
    cols = u0[:, None] + np.arange(-r, r + 2)
    strip = other[rows[:, :, None], cols[:, None, :]].astype(np.float32)
    strip = strip[:, :, :-1] * (1 - fu) + strip[:, :, 1:] * fu
    scores = np.empty((len(ys), 2 * k + 1), np.float32)
    for i in range(2 * k + 1):
        p, npn = _centred(strip[:, i : i + 2 * r + 1, :])
        scores[:, i] = (pl * p).sum(axis=(1, 2)) / (nl * npn)
    best = scores.argmax(axis=1)
    clear = (best > 0) & (best < 2 * k) & (scores.max(axis=1) >= MIN_CORRELATION)
    b = best[clear]
    s = scores[clear]
    j = np.arange(len(b))
    lo, mid, hi = s[j, b - 1], s[j, b], s[j, b + 1]
    curve = lo - 2 * mid + hi
    with np.errstate(divide="ignore", invalid="ignore"):
        frac = np.where(curve < 0, 0.5 * (lo - hi) / curve, 0.0)
    return np.flatnonzero(clear), (b - k) + np.clip(frac, -0.5, 0.5)


def _fit(u: np.ndarray, v: np.ndarray, dy: np.ndarray, w: int, h: int) -> RowAlignment | None:
    """The trimmed least-squares plane, or None when too few pixels agree with it."""
    a = np.stack([np.ones_like(dy), (u - w / 2) / w, (v - h / 2) / h], axis=1)
    keep = np.ones(len(dy), bool)
    spread = 0.0
    coef = np.zeros(3)
    for _ in range(3):
        if keep.sum() < MIN_SAMPLES:
            return None
        # A slope the samples kept cannot tell from noise stays 0 (MIN_FIT_SPREAD).
        fit = a[keep]
        fit = fit * np.r_[True, fit[:, 1:].std(axis=0) >= MIN_FIT_SPREAD]
        coef = np.linalg.lstsq(fit, dy[keep], rcond=None)[0]
        res = np.abs(dy - a @ coef)
        spread = float(np.median(res[keep]) * 1.4826)
        keep = res <= max(0.3, 3 * spread)
    n = int(keep.sum())
    if n < max(MIN_SAMPLES, len(dy) // 5):
        return None
    return RowAlignment(float(coef[0]), float(coef[1]), float(coef[2]), w, h, n, spread)


def measure_row_alignment(
    left: npt.ArrayLike,
    right: npt.ArrayLike,
    disparity: npt.ArrayLike,
    *,
    reference: str = "right",
) -> RowAlignment | None:
    """How far the other view's rows lie from ``reference``'s (see the module docs).

    Args:
        left, right: the pair, uint8 RGB or grey of one size.
        disparity: a disparity map on ``reference`` (``d = u_left - u_right``, NaN = none), e.g.
            a first :func:`~rgbd_rs.fusion.census.census_match` of the pair.
        reference: the view ``disparity`` lies on, ``"right"`` or ``"left"``.

    Returns:
        The fitted :class:`RowAlignment`, or None when nothing can be read: fewer than
        :data:`MIN_SAMPLES` textured matched pixels, fewer than :data:`MIN_CLEAR_SHARE` of them
        with a clear best row, or fewer than a fifth of those agreeing with one plane. Offsets
        beyond about 3 px are not read (the row search reaches 4, and the first match is too
        poor there).
    """
    lft, rgt = pair8(left, right)
    h, w = lft.shape[:2]
    disp = _validate.array("disparity", disparity, dtype=np.float32, shape=(h, w))
    ref = _validate.choice("reference", reference, ("left", "right"))
    sign = -1 if ref == "left" else 1
    lft, rgt = grey8("left", lft), grey8("right", rgt)
    ref_img, other = (lft, rgt) if ref == "left" else (rgt, lft)
    return _measure(ref_img, other, np.asarray(disp, np.float32), sign)


def _measure(ref: U8, other: U8, disparity: F32, sign: int) -> RowAlignment | None:
    h, w = ref.shape
    if h < 2 * (PATCH_RADIUS + ROW_SEARCH + 2) or w < 2 * PATCH_RADIUS + 4:
        return None
    ys, xs, u = _samples(ref, disparity, sign)
    if len(ys) < MIN_SAMPLES:
        return None
    clear, dy = _row_offsets(ref, other, ys, xs, u)
    if len(clear) < MIN_CLEAR_SHARE * len(ys):
        return None
    return _fit(u[clear], ys[clear].astype(np.float64), dy, w, h)


def align_rows(image: npt.ArrayLike, alignment: RowAlignment) -> U8:
    """The other view resampled (bicubic, borders repeated) so that its rows meet the reference
    view's: pixel ``(u, v)`` takes the value at ``(u, v + dy(u, v))``. (The matcher resamples
    the grey image; resampling colour first and then converting differs by a grey level or two.)

    Args:
        image: the other view (uint8 RGB or grey) of the size ``alignment`` was measured on.
        alignment: :func:`measure_row_alignment`'s result.
    """
    img = image8("image", image)
    if not isinstance(alignment, RowAlignment):
        raise InvalidArgumentError(
            f"alignment: got {type(alignment).__name__}, expected a RowAlignment"
        )
    if img.shape[:2] != (alignment.height, alignment.width):
        raise ShapeMismatchError(
            f"image: got {img.shape[1]}x{img.shape[0]} pixels, expected {alignment.width}x"
            f"{alignment.height} (the size the alignment was measured on)"
        )
    return _resample(img, alignment)


def _resample(image: U8, alignment: RowAlignment) -> U8:
    h, w = image.shape[:2]
    cols = np.broadcast_to(np.arange(w, dtype=np.float32)[None, :], (h, w))
    rows = np.arange(h, dtype=np.float32)[:, None] + alignment.field()
    out = cv2.remap(
        np.ascontiguousarray(image),
        np.ascontiguousarray(cols),
        np.ascontiguousarray(rows, dtype=np.float32),
        cv2.INTER_CUBIC,
        borderMode=cv2.BORDER_REPLICATE,
    )
    return np.ascontiguousarray(out, dtype=np.uint8)
