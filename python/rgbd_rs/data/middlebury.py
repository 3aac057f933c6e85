"""Reader for the Middlebury stereo pairs in ``../shared/data/middlebury`` (2003 quarter-size
``im2/im6/disp2/disp6`` with disparity = PNG / 4; 2005/2006 ``view1/view5/disp1/disp5`` with
disparity = PNG / 2 for the half-size images (>= 600 px wide) and PNG / 3 for the third-size ones;
0 = unknown, returned as NaN). The ground truth of these sets is 8-bit; a 16-bit disparity PNG
(another convention, e.g. KITTI's x 256) raises :class:`~rgbd_rs.RgbdError` instead of being
divided by the 8-bit scale.

The shared data README calls Reindeer and Wood2 third-size (/3), but they are 671 and 686 px wide,
the 2005/2006 *half*-size images: SGBM's disparities were a median 1.50x the /3 values, and agree
with /2 (see ``tests/test_datasets.py``)."""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np
import numpy.typing as npt

from rgbd_rs._array_eq import array_eq
from rgbd_rs.errors import InvalidArgumentError, RgbdError
from rgbd_rs.io import read_png

F32 = npt.NDArray[np.float32]
U8 = npt.NDArray[np.uint8]

#: (left, right, left GT, right GT, PNG value per pixel of disparity) of each naming scheme;
#: 0 = by image width (2005/2006 half size /2, third size /3).
SCHEMES = (
    ("view1.png", "view5.png", "disp1.png", "disp5.png", 0.0),
    ("im2.png", "im6.png", "disp2.png", "disp6.png", 4.0),
)
#: 2005/2006 images at least this wide are half size (full size is 1240-1396 px wide).
HALF_SIZE_MIN_WIDTH = 600


@array_eq
@dataclass(frozen=True)
class MiddleburyPair:
    """A rectified pair (uint8 RGB) with ground-truth disparity of both views (NaN = unknown)."""

    name: str
    left: U8
    right: U8
    disparity_left: F32
    disparity_right: F32
    scale: float


def load_middlebury(folder: str | Path) -> MiddleburyPair:
    """Read one scene folder (e.g. ``.../middlebury/Cones``)."""
    if not isinstance(folder, (str, Path)) or not str(folder):
        raise InvalidArgumentError(f"folder: got {folder!r}, expected a scene folder path")
    folder = Path(folder)
    for left, right, dl, dr, scale in SCHEMES:
        if (folder / left).is_file():
            imgs = [read_png(folder / f) for f in (left, right)]
            if scale == 0.0:
                scale = 2.0 if imgs[0].shape[1] >= HALF_SIZE_MIN_WIDTH else 3.0
            disp = []
            for f in (dl, dr):
                raw = read_png(folder / f)
                if raw.ndim != 2:
                    raise RgbdError(f"{folder / f}: expected a single-channel disparity PNG")
                if raw.dtype != np.uint8:
                    raise RgbdError(
                        f"{folder / f}: got a {raw.dtype} disparity PNG, expected 8-bit (the "
                        "2003-2006 ground truth); other encodings (e.g. 16-bit x 256) are not "
                        "Middlebury's and would be misread by the /2, /3, /4 scales"
                    )
                disp.append(np.where(raw > 0, raw / np.float32(scale), np.nan).astype(np.float32))
            shapes = {s.shape[:2] for s in [*imgs, *disp]}
            if len(shapes) != 1:
                raise RgbdError(f"{folder}: image and disparity sizes differ ({sorted(shapes)})")
            return MiddleburyPair(folder.name, imgs[0], imgs[1], disp[0], disp[1], scale)
    raise RgbdError(f"{folder}: no view1.png or im2.png (not a Middlebury scene folder)")
