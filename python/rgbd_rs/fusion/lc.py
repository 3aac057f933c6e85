"""Stage 4: the locally consistent (LC) fusion kernel (crates/rgbd-fusion) and the plain LC
stereo refinement of thesis §2.4.2."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

from rgbd_rs import _rgbd_rs, _validate
from rgbd_rs.errors import InvalidArgumentError
from rgbd_rs.fusion._inputs import F32, disparity_map, rgb8, unit_map, views
from rgbd_rs.fusion.crosscheck import _consistent, _warp_to_target

#: The defaults and limits live in crates/rgbd-fusion (``LcParams::for_width``, ``MAX_RADIUS``);
#: read here through the binding so the two languages cannot disagree.
_DEFAULTS = _rgbd_rs.LcConfig.for_width(960)
#: Largest window half-size.
MAX_RADIUS: int = _rgbd_rs.MAX_RADIUS
#: :func:`lc_refine`'s default bin width (pixels). Fusion's one-pixel default was chosen for two
#: sources on validation scenes; refining one map keeps the literature's finer quarter-pixel bins
#: (a one-pixel bin averages near outliers into the result: tests/test_fusion.py).
REFINE_BIN_WIDTH = 0.25

#: Most disparity maps :func:`lc_fuse` takes (the native fusion's limit).
MAX_SOURCES = 8


@dataclass(frozen=True)
class LcParams:
    """LC constants (eq. 2.16) and the support window.

    ``radius`` defaults (None) to the literature's 39 x 39 window at 1920 px width, scaled to
    the image (960 px -> radius 10); ``gamma_s`` to gamma_s = 12 at radius 19, scaled with the
    radius (radius 10 -> 6.3). ``stride`` samples every ``stride``-th row and column of the
    window (same extent, 1/stride^2 of the work); the kernel caps it at the radius.
    ``cross_check`` runs the accumulation in the target view too and keeps only pixels on which
    the two views agree (:mod:`rgbd_rs.fusion.crosscheck`; twice the time, lower density).
    Defaults are defined once, in ``crates/rgbd-fusion/src/lc.rs``.
    """

    radius: int | None = None
    gamma_s: float | None = None
    gamma_c: float = _DEFAULTS.gamma_c
    gamma_t: float = _DEFAULTS.gamma_t
    truncation: float = _DEFAULTS.truncation
    bin_width: float = _DEFAULTS.bin_width
    stride: int = _DEFAULTS.stride
    cross_check: bool = False

    def __post_init__(self) -> None:
        # Every field checked when the parameters are made (native() checks them again).
        if self.radius is not None:
            _validate.integer("radius", self.radius, minimum=1, maximum=MAX_RADIUS)
        if self.gamma_s is not None:
            _validate.real("gamma_s", self.gamma_s, positive=True, f32=True)
        for name in ("gamma_c", "gamma_t", "truncation", "bin_width"):
            _validate.real(name, getattr(self, name), positive=True, f32=True)
        _validate.integer("stride", self.stride, minimum=1)
        _validate.flag("cross_check", self.cross_check)

    def resolved(self, width: int) -> tuple[int, float]:
        """``(radius, gamma_s)`` for an image ``width`` pixels wide."""
        if self.radius is None:
            r = _rgbd_rs.LcConfig.for_width(_validate.size("width", width)).radius
        else:
            r = _validate.integer("radius", self.radius, minimum=1, maximum=MAX_RADIUS)
        if self.gamma_s is not None:
            return r, _validate.real("gamma_s", self.gamma_s, positive=True, f32=True)
        return r, _rgbd_rs.LcConfig.gamma_s_for_radius(r)

    def native(self, width: int, target_sign: int) -> _rgbd_rs.LcConfig:
        """The validated native parameter object for an image ``width`` pixels wide."""
        target_sign = _validate.sign("target_sign", target_sign)
        radius, gamma_s = self.resolved(width)  # both validated there
        return _rgbd_rs.LcConfig(
            radius,
            gamma_s,
            _validate.real("gamma_c", self.gamma_c, positive=True, f32=True),
            _validate.real("gamma_t", self.gamma_t, positive=True, f32=True),
            _validate.real("truncation", self.truncation, positive=True, f32=True),
            _validate.real("bin_width", self.bin_width, positive=True, f32=True),
            _validate.integer("stride", self.stride, minimum=1),
            target_sign,
        )


def lc_fuse(
    reference_image: npt.ArrayLike,
    target_image: npt.ArrayLike,
    disparities: list[npt.ArrayLike],
    confidences: list[npt.ArrayLike | None] | None = None,
    *,
    target_sign: int = 1,
    params: LcParams | None = None,
) -> tuple[F32, F32]:
    """LC accumulation of one or more disparity maps on the reference image (eq. 2.16, 3.1).

    Args:
        reference_image, target_image: uint8 RGB of the reference and the other camera.
        disparities: ``H x W`` maps (``d = u_left - u_right``, NaN = none).
        confidences: one ``H x W`` map in [0, 1] (or None = all ones) per disparity map.
        target_sign: +1 if the target pixel of reference x is x + d (reference = right camera),
            -1 if x - d (reference = left camera).
        params: :class:`LcParams`.

    Returns:
        ``(disparity, plausibility)``: fused sub-pixel disparity (NaN where no hypothesis
        reached) and the winner's share of the plausibility each pixel received.
    """
    ref = rgb8("reference_image", reference_image)
    h, w = ref.shape[:2]
    tgt = rgb8("target_image", target_image, (w, h), of="reference_image's size")
    if not isinstance(disparities, (list, tuple)) or not disparities:
        raise InvalidArgumentError(
            f"disparities: got {type(disparities).__name__}, expected a non-empty list of maps"
        )
    if len(disparities) > MAX_SOURCES:
        raise InvalidArgumentError(
            f"disparities: got {len(disparities)} maps, expected 1 to {MAX_SOURCES} (LC fuses "
            f"at most {MAX_SOURCES} sources)"
        )
    ds = [disparity_map(f"disparities[{i}]", d, (h, w)) for i, d in enumerate(disparities)]
    if confidences is not None and not isinstance(confidences, (list, tuple)):
        raise InvalidArgumentError(
            f"confidences: got {type(confidences).__name__}, expected a list of maps or None"
        )
    cs_in = [None] * len(ds) if confidences is None else list(confidences)
    if len(cs_in) != len(ds):
        raise InvalidArgumentError(
            f"confidences: got {len(cs_in)} maps, expected {len(ds)} (one per disparity map)"
        )
    cs: list[F32 | None] = []
    for i, c in enumerate(cs_in):
        if c is None:
            cs.append(None)
            continue
        cs.append(unit_map(f"confidences[{i}]", c, (h, w)))
    if not any(np.isfinite(d).any() for d in ds):
        raise InvalidArgumentError(
            "disparities: got only NaN, expected at least one valid disparity to fuse"
        )
    target_sign = _validate.sign("target_sign", target_sign)
    p = LcParams() if params is None else params
    if not isinstance(p, LcParams):
        raise InvalidArgumentError(f"params: got {type(p).__name__}, expected LcParams")
    config = p.native(w, target_sign)
    disp, share = _rgbd_rs.lc_fuse(ref, tgt, ds, cs, config)
    if not p.cross_check:
        return disp, share
    warped = [_warp_to_target(d, c, target_sign) for d, c in zip(ds, cs, strict=True)]
    back, _ = _rgbd_rs.lc_fuse(
        tgt,
        ref,
        [d for d, _ in warped],
        [c for _, c in warped],
        config.with_target_sign(-target_sign),
    )
    checked = _consistent(disp, back, target_sign)
    return checked, np.where(np.isfinite(checked), share, np.nan).astype(np.float32)


def lc_refine(
    disparity: npt.ArrayLike,
    left: npt.ArrayLike,
    right: npt.ArrayLike,
    *,
    reference: str = "left",
    params: LcParams | None = None,
) -> F32:
    """Mattoccia's LC refinement of a disparity map (thesis §2.4.2, eq. 2.16-2.19).

    ``disparity`` lies on the ``reference`` view of the rectified pair ``left``/``right``
    (``d = u_left - u_right``); every pixel's disparity is re-decided from the plausibilities
    its neighbours lend it. Holes within the window are filled. Without ``params``, the defaults
    with :data:`REFINE_BIN_WIDTH` bins.
    """
    ref_name = _validate.choice("reference", reference, ("left", "right"))
    lft = rgb8("left", left)
    rgt = rgb8("right", right, (lft.shape[1], lft.shape[0]), of="left's size")
    d = disparity_map("disparity", disparity, (lft.shape[0], lft.shape[1]))
    if not np.isfinite(d).any():
        raise InvalidArgumentError(
            "disparity: got only NaN, expected at least one valid disparity to refine"
        )
    ref, tgt, sign = views(lft, rgt, ref_name)
    p = LcParams(bin_width=REFINE_BIN_WIDTH) if params is None else params
    out, _ = lc_fuse(ref, tgt, [d], None, target_sign=sign, params=p)
    return out
