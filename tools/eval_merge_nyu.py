"""Eq. 4.8 on real data: does the fit test alone merge what should merge?

On every NYUv2 frame of ../shared/data with a large wall (label13 = 12) and floor (= 5) region,
the largest connected wall region is split at its median column into two segments (one surface:
should merge) and tested against the largest floor region (two surfaces: should not). Prints,
per knot spacing and criterion, how often eq. 4.8 gets each right.

    python tools/eval_merge_nyu.py
"""

from __future__ import annotations

import cv2
import numpy as np

from rgbd_rs import PinholeCamera
from rgbd_rs.data.paths import data_root
from rgbd_rs.surface import SegmentFits

NYU = PinholeCamera(
    fx=518.857901, fy=519.469611, cx=325.582449, cy=253.736166, width=640, height=480
)
WALL, FLOOR = 12, 5


def largest(mask: np.ndarray) -> np.ndarray:
    n, cc = cv2.connectedComponents(mask.astype(np.uint8))
    if n < 2:
        return np.zeros_like(mask)
    return cc == np.argmax(np.bincount(cc[mask]))


def cases() -> list[tuple[str, np.ndarray, np.ndarray]]:
    root = data_root()
    if root is None:
        raise SystemExit("shared data not found: set RGBD_DATA")
    out = []
    for f in sorted((root / "nyuv2" / "frames").glob("*_depth.png")):
        idx = f.name[:4]
        depth = cv2.imread(str(f), cv2.IMREAD_UNCHANGED).astype(np.float32) / 1000.0
        lab = cv2.imread(str(f.with_name(f"{idx}_label13.png")), cv2.IMREAD_UNCHANGED)
        wall, floor = largest(lab == WALL), largest(lab == FLOOR)
        if wall.sum() < 10000 or floor.sum() < 5000:
            continue
        mid = np.median(np.nonzero(wall)[1])
        col = np.arange(640)[None, :]
        labels = np.full(depth.shape, -1, np.int32)
        labels[wall & (col < mid)] = 0
        labels[wall & (col >= mid)] = 1
        labels[floor] = 2
        out.append((idx, NYU.depth_to_points(depth), labels))
    return out


def main() -> None:
    frames = cases()
    print(f"{len(frames)} NYUv2 frames with a wall and a floor region\n")
    print("| spacing | criterion | wall halves merged | wall/floor kept apart |")
    print("|---|---|---|---|")
    for spacing in (8, 16, 32, 64):
        for crit in ("gcv", "mse"):
            same = apart = 0
            for _, pts, labels in frames:
                s = SegmentFits(pts, labels, spacing=spacing, criterion=crit)
                same += s.should_merge(0, 1)
                apart += not (s.should_merge(0, 2) or s.should_merge(1, 2))
            print(f"| {spacing} | {crit} | {same}/{len(frames)} | {apart}/{len(frames)} |")


if __name__ == "__main__":
    main()
