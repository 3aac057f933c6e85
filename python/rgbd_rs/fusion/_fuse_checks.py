"""What :func:`~rgbd_rs.fusion.fuse` checks once the ToF and stereo maps exist: depths in
another scale, a swapped pair, a ToF pose read the wrong way round or turned, and a ToF that
agrees with the stereo map almost nowhere (each a warning), and the ToF's orientation and depth
scale refined against the stereo map where they clearly fit better corrected."""

from __future__ import annotations

import dataclasses
import warnings
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

from rgbd_rs._array_eq import array_eq
from rgbd_rs.camera import ToFStereoRig
from rgbd_rs.fusion._inputs import F32, U8, disagreement_warning, scale_factor
from rgbd_rs.fusion._pose_check import pose_warning, turn_warning
from rgbd_rs.fusion.pose_refine import (
    MIN_REFINE_WIDTH,
    WIDE_DEGREES,
    PoseRefinement,
    _pose_error,
)
from rgbd_rs.fusion.scale_refine import (
    SCALE_GRID,
    ScaleRefinement,
    _clear_turn,
    _rescaled,
    _scale_and_turn,
)
from rgbd_rs.fusion.stereo import _same_search, _widest_range, search_range
from rgbd_rs.fusion.upsample import ToFOnReference, _densify_tof, _reproject_tof

#: The largest yaw / pitch ``fuse()``'s orientation refinement reaches, degrees (its wide probe's
#: :data:`~rgbd_rs.fusion.pose_refine.WIDE_DEGREES`, then a degree around the probe's best): a
#: turn found there is reported as the edge of the search.
POSE_SEARCH_DEGREES = WIDE_DEGREES + 1.0

#: Swapped left/right images. A pair's match score is the share of the pixels SGM can search
#: (those at least ``max_disparity`` from the image edge) that SGM matches and, where the ToF has
#: a disparity, matches within ``SWAP_AGREE`` px of it. Below ``SWAP_SUSPECT_SCORE`` the pair is
#: also matched with the images exchanged, and a score there of at least ``SWAP_GAIN`` times
#: (and at least ``SWAP_SUSPECT_SCORE``) means the images were swapped. Chosen on the synthetic
#: test set and Middlebury: correct pairs score 0.36-0.97, swapped ones 0.01-0.16. Without a ToF
#: the score is SGM's coverage alone, both orders are always matched, and the exchanged order
#: must reach ``SWAP_GAIN_STEREO_ONLY`` times the given one (there swapped pairs reach 0.28-0.68
#: of the correct order's 0.78-0.97, a ratio of 1.3 or more).
SWAP_AGREE = 2.0
SWAP_SUSPECT_SCORE = 0.25
SWAP_GAIN = 2.0
SWAP_GAIN_STEREO_ONLY = 1.2


def _match_score(stereo: F32, tof_disparity: F32, max_disparity: int, sign: int) -> float:
    """The share of searchable pixels SGM matches, consistently with the ToF where it has one."""
    w = stereo.shape[1]
    cols = slice(max_disparity, w) if sign < 0 else slice(0, max(0, w - max_disparity))
    st, tof = stereo[:, cols], tof_disparity[:, cols]
    if st.size == 0:
        return 0.0
    with np.errstate(invalid="ignore"):
        good = np.isfinite(st) & ~(np.abs(st - tof) >= SWAP_AGREE)
    return float(good.mean())


def _scale_check(
    left: U8,
    right: U8,
    reference: str,
    stereo: F32,
    tof_disparity: F32,
    widest: int | None,
    match: Callable[..., F32],
) -> tuple[str, float, F32] | None:
    """:func:`~rgbd_rs.fusion._inputs.scale_factor` of the ToF against the stereo map (with the
    map it was read on); where they disagree on most pixels and no factor explains it, once
    more against a map searched over ``widest`` (None: the caller's range stands): depths too
    far make the range derived from them too short for the pair's disparities."""
    said = scale_factor(tof_disparity, stereo)
    if said is not None:
        return (*said, stereo)
    if widest is None or disagreement_warning(tof_disparity, stereo) is None:
        return None
    wide = match(left, right, reference=reference, max_disparity=widest)
    said = scale_factor(tof_disparity, wide)
    return None if said is None else (*said, wide)


def _a_turn_explains(
    depth: F32, rig: ToFStereoRig, stereo: F32, factor: float, refine: bool
) -> bool:
    """Whether a clear turn of the ToF fits ``stereo`` better than its depths divided by
    ``factor`` do: on a slanted flat scene a pitch reads like a scale (Bull, 3 degrees of
    pitch: a factor of 0.74), and the refinement corrects it."""
    if not refine:
        return False
    turn = _clear_turn(depth, rig, stereo)
    return turn is not None and turn.error_after < _pose_error(
        _rescaled(depth, factor), rig, stereo
    )


def _swap_warning(
    left: U8,
    right: U8,
    reference: str,
    stereo: F32,
    tof_disparity: F32,
    dmax: int,
    match: Callable[..., F32],
) -> str | None:
    """A message when the pair looks swapped: SGM matches few pixels (its left-right check fails,
    or its disparities disagree with the ToF) as given and far more with the images exchanged,
    i.e. the pair's disparities as given are negative."""
    sign = 1 if reference == "right" else -1
    has_tof = bool(np.isfinite(tof_disparity).any())
    given = _match_score(stereo, tof_disparity, dmax, sign)
    if has_tof and given >= SWAP_SUSPECT_SCORE:
        return None
    exchanged = match(right, left, reference=reference, max_disparity=dmax, align_rows=False)
    swapped = _match_score(exchanged, tof_disparity, dmax, sign)
    gain = SWAP_GAIN if has_tof else SWAP_GAIN_STEREO_ONLY
    if swapped < max(SWAP_SUSPECT_SCORE, gain * given):
        return None
    return (
        f"left/right: the images look swapped: SGM matches {given:.0%} of the pixels as given "
        f"and {swapped:.0%} with left and right exchanged; check that the left image is the "
        "left camera's (the right camera sits baseline metres along +x of the left one)"
    )


@array_eq
@dataclass(frozen=True)
class Checked:
    """The maps :func:`~rgbd_rs.fusion.fuse` fuses once :func:`check_maps` has run: as given,
    or recomputed with the orientation (``found``) or depth scale (``rescale``) it corrected."""

    rig: ToFStereoRig
    depth: F32
    tof: ToFOnReference
    stereo: F32
    max_disparity: int
    tof_disparity: F32
    found: PoseRefinement | None
    rescale: ScaleRefinement | None

    @property
    def corrected(self) -> bool:
        """Whether the ToF's orientation or depth scale was corrected (the maps recomputed)."""
        return self.found is not None or self.rescale is not None


def check_maps(
    lft: U8,
    rgt: U8,
    asked: ToFStereoRig,
    r: ToFStereoRig,
    depth_map: F32,
    tof_amplitude: npt.ArrayLike,
    ref_img: U8,
    tof: ToFOnReference,
    st_map: F32,
    dmax: int,
    tof_disp: F32,
    *,
    max_disparity: int | None,
    match: Callable[..., F32],
    refine_pose: bool,
    no_tof: bool,
) -> Checked:
    """The checks of :func:`~rgbd_rs.fusion.fuse` (its arguments under its local names: ``r``
    the rig fused on, ``asked`` the rig as given; ``tof_disp`` the ToF's disparities within
    ``dmax``), each finding warned about as fuse() itself would, in fuse()'s order."""
    w = ref_img.shape[1]
    refine_pose = refine_pose and w >= MIN_REFINE_WIDTH  # see MIN_REFINE_WIDTH
    # Depths in another unit or scale first: the checks below read the ToF's disparities as true.
    off_scale = None
    if not no_tof:
        wide = None if max_disparity is not None else _widest_range(w)
        scaled_by = _scale_check(lft, rgt, r.reference, st_map, tof.disparity, wide, match)
        if scaled_by is not None and not _a_turn_explains(
            depth_map, r, scaled_by[2], scaled_by[1], refine_pose
        ):
            off_scale = scaled_by[0]
    if off_scale is not None:
        warnings.warn(off_scale, RuntimeWarning, stacklevel=3)
    swapped = (
        None
        if off_scale is not None
        else _swap_warning(lft, rgt, r.reference, st_map, tof.disparity, dmax, match)
    )
    if swapped is not None:
        warnings.warn(swapped, RuntimeWarning, stacklevel=3)
    # The ToF's depth scale against the stereo pair's first (a scale error shifts every ToF
    # disparity, which a turn would partly absorb), then a ToF turned by a fraction of a degree
    # is refined; a pose read the wrong way round is named (only when another reading beats
    # even the refined pose: a turn can make the inverted reading fit a flat scene better than
    # the turned pose as given); other disagreement only in general terms.
    refine = refine_pose and swapped is None and off_scale is None and not no_tof
    rescale, found = _scale_and_turn(depth_map, r, st_map) if refine else (None, None)
    fitted = None if found is None else found.pose
    # The readings are compared on the depths the fits chose (a depth scale a few percent off
    # otherwise makes the inverted reading fit better than the pose as given).
    checked = depth_map if rescale is None else _rescaled(depth_map, rescale.factor)
    wrong_way = (
        None
        if swapped is not None or off_scale is not None
        else pose_warning(checked, asked, r, st_map, fitted)
    )
    if wrong_way is not None:
        warnings.warn(wrong_way, RuntimeWarning, stacklevel=3)
        found = rescale = None  # fits made with a pose read the wrong way round
    if rescale is not None:
        warnings.warn(_rescaled_message(rescale), RuntimeWarning, stacklevel=3)
        depth_map = checked  # the rescaled depths the pose check read
    if found is not None:
        warnings.warn(_refined_message(found), RuntimeWarning, stacklevel=3)
        r = dataclasses.replace(r, tof_to_reference=found.pose)
    if found is not None or rescale is not None:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")  # said once already, for the given pose and depths
            tof = _densify_tof(_reproject_tof(depth_map, tof_amplitude, r), r, ref_img)
        if max_disparity is None:  # the corrected ToF's range, as a corrected rig would give
            refit = search_range(tof.disparity, w)
            if not _same_search(dmax, refit):
                st_map = match(lft, rgt, reference=r.reference, max_disparity=refit)
            dmax = refit
        tof_disp = np.where(tof.disparity <= dmax, tof.disparity, np.nan).astype(np.float32)
    # Several degrees off: only where the refinement did not act (its warning says when it
    # stopped at the edge of its search).
    quiet = swapped or off_scale or wrong_way or no_tof or found is not None or rescale is not None
    turned = None if quiet else turn_warning(depth_map, r, st_map)
    if turned is not None:
        warnings.warn(turned, RuntimeWarning, stacklevel=3)
    apart = (
        None
        if swapped or off_scale or wrong_way or turned
        else disagreement_warning(tof_disp, st_map)
    )
    if apart is not None:
        warnings.warn(apart, RuntimeWarning, stacklevel=3)
    return Checked(r, depth_map, tof, st_map, dmax, tof_disp, found, rescale)


def _refined_message(found: PoseRefinement) -> str:
    """The warning of a ToF orientation that ``fuse()`` refined against the stereo map."""
    return (
        f"rig: the ToF fits the stereo map better turned by {found.yaw:+.2f} degrees of yaw and "
        f"{found.pitch:+.2f} of pitch (disparity difference {found.error_before:.2f} -> "
        f"{found.error_after:.2f} px, truncated mean): fused with that orientation"
        f"{_edge_note(max(abs(found.yaw), abs(found.pitch)) >= POSE_SEARCH_DEGREES - 1e-6)}. "
        "Correct the calibration (the result's tof_pose is the pose fused with, relative to "
        "its reference camera; rgbd fuse writes it to fused.npz), or pass refine_pose=False "
        "(rgbd fuse --keep-pose) to fuse the pose as given"
    )


def _edge_note(at_edge: bool) -> str:
    """A clause for a fit that stopped at the edge of its search."""
    if not at_edge:
        return ""
    return (
        " (the edge of the search: the calibration may be further off than that, and the "
        "fused map worse than with a corrected one)"
    )


def _rescaled_message(found: ScaleRefinement) -> str:
    """The warning of a ToF depth scale that ``fuse()`` refined against the stereo map."""
    return (
        f"tof_depth/rig: the ToF's depths fit the stereo map better divided by {found.factor:.3f} "
        f"(disparity difference {found.error_before:.2f} -> {found.error_after:.2f} px, "
        f"truncated mean): fused with them rescaled"
        f"{_edge_note(found.factor in (float(SCALE_GRID[0]), float(SCALE_GRID[-1])))}. A ToF "
        "depth scale error, or a stereo baseline that far off, reads so; the result's "
        "tof_scale is the factor (rgbd fuse writes it to fused.npz). Pass refine_pose=False "
        "(rgbd fuse --keep-pose) to fuse the depths as given"
    )
