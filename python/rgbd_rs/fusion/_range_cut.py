"""A search range that ends before the nearest surface: the matches pile up at its top.

A stereo matcher cannot return a disparity beyond the top of its range; surfaces nearer than the
range reaches are matched to the best disparity it holds, and many land in its top pixel.
Measured on the 20 train / val Middlebury scenes of the shared data (``sgm`` with ranges of 1.15x,
0.8x and 0.6x the ground truth's largest disparity; OpenCV's SGBM searches up to its range
rounded up to whole steps of 16, the top used here): with a range 1 px or more beyond the scene
at most 0.05 % (ours) / 0.13 % (SGBM) of the matched pixels lie within 1 px of the top; with a
range cut short by 2 px or more at least 1.5 % (ours, with a left-right check) / 1.7 % (ours) /
1.97 % (SGBM) on all but one pair (SGBM on Midd1 at 63 px against 69: 0.04 %, few pixels beyond),
most 5-60 %. :data:`RANGE_CUT_SHARE` sits between. A range that ends within a pixel of the nearest
surface can read as cut too (Tsukuba's lamp at 14 px under SGBM's top of 15: 4.4 %): the warning
says "at or before".
"""

from __future__ import annotations

import numpy as np
import numpy.typing as npt

#: Share of matched pixels within :data:`RANGE_CUT_BAND` px of the range's top that reads as cut.
RANGE_CUT_SHARE = 0.01
#: Width of the top band (px).
RANGE_CUT_BAND = 1.0


def range_cut_share(disparity: npt.ArrayLike, max_disparity: float) -> float:
    """Share of ``disparity``'s finite values at or above ``max_disparity - RANGE_CUT_BAND``
    (0 when none is finite)."""
    d = np.asarray(disparity, dtype=np.float64)
    found = d[np.isfinite(d)]
    if not found.size:
        return 0.0
    return float((found >= float(max_disparity) - RANGE_CUT_BAND).mean())


def range_cut_note(
    disparity: npt.ArrayLike,
    max_disparity: float,
    flag: str,
    advice: str = "search further (a larger max_disparity)",
) -> str | None:
    """A warning's text when ``disparity`` piles up at the top of its search range (``flag``
    names what set the range, ``advice`` what to change), else None."""
    share = range_cut_share(disparity, max_disparity)
    if share <= RANGE_CUT_SHARE:
        return None
    return (
        f"{flag}: {share:.1%} of the matched pixels lie within {RANGE_CUT_BAND:g} px of the "
        f"search range's top ({max_disparity:g} px), expected under {RANGE_CUT_SHARE:.0%}: the "
        "range likely ends at or before the nearest surface, whose disparities are then wrong "
        f"if before; {advice}"
    )
