"""A stereo image with no texture to match: blank, saturated, dark or covered.

Where every pixel of a window holds one grey level, a matcher has nothing to match: the census
matcher's costs are the same at every disparity there (its map holds a guess, the smallest
disparity searched, with no check to remove it by default) and OpenCV's SGBM leaves the pixels
invalid. A real image has such windows only in small saturated or black patches: measured on
the 20 train / val Middlebury scenes of the shared data (both views; their textureless Midd1,
Midd2 and Lampshade1 included), the share of pixels whose :data:`BLANK_WINDOW` x
:data:`BLANK_WINDOW` window holds a single grey level is at most 0.9 % (Lampshade1's right
view, the 7 test scenes at most 0.2 %); the 50 NYUv2 colour frames (Kinect v1, with their white
border and blown-out windows and lamps: not stereo, but what a cheap camera gives) at most
10.2 %, median 3.6 %, the Azure Kinect colour frame 0.2 %. A lens cap, a blown-out or an unlit
frame covers most of the view; :data:`BLANK_SHARE` is half of it, so the warning reads only when
most of a view cannot be matched.
"""

from __future__ import annotations

import cv2
import numpy as np
import numpy.typing as npt

#: Side of the window (px) that must hold a single grey level: the census matcher's window.
BLANK_WINDOW = 5
#: Share of a view's pixels in such windows above which :func:`blank_note` warns. Chosen: most
#: of the view, 5x the largest share of the real frames measured (10.2 %, NYUv2).
BLANK_SHARE = 0.5


def blank_share(image: npt.NDArray[np.uint8]) -> float:
    """Share of ``image``'s pixels whose :data:`BLANK_WINDOW`-px window (clipped at the image
    border) holds a single level (in every channel of a colour image: OpenCV's SGBM matches
    colour, so a texture of colours of one grey level is one it can match)."""
    kernel = np.ones((BLANK_WINDOW, BLANK_WINDOW), np.uint8)
    top = cv2.dilate(image, kernel, borderType=cv2.BORDER_REPLICATE)
    low = cv2.erode(image, kernel, borderType=cv2.BORDER_REPLICATE)
    flat = top == low
    return float((flat.all(axis=2) if flat.ndim == 3 else flat).mean())


def blank_note(left: npt.NDArray[np.uint8], right: npt.NDArray[np.uint8]) -> str | None:
    """A warning's text naming the view (``left`` / ``right`` uint8, as the matcher reads them:
    grey for the census matcher, colour for OpenCV's) of which more than :data:`BLANK_SHARE`
    has no texture, else None."""
    shares = {"left": blank_share(left), "right": blank_share(right)}
    name = max(shares, key=lambda k: shares[k])
    share = shares[name]
    if share <= BLANK_SHARE:
        return None
    return (
        f"{name}: {share:.0%} of the image has no texture ({BLANK_WINDOW}x{BLANK_WINDOW} windows "
        f"of a single grey level: blank, saturated, unlit or covered), expected under "
        f"{BLANK_SHARE:.0%}: nothing can be matched there, so the census matcher's disparities "
        "there are guesses and OpenCV's are missing; check the camera's exposure and lens"
    )
