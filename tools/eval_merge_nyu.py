"""Eq. 4.8 on real data: does the fit test alone merge what should merge?

On every NYUv2 frame of ../shared/data with a large wall (label13 = 12) and floor (= 5) region,
the largest connected wall region is split at its median column into two segments (one surface:
should merge) and tested against the largest floor region (two surfaces: should not). Prints,
per criterion and its parameters, how often eq. 4.8 gets each right: the old criteria ("gcv",
"mse" on the 3-D points, per knot spacing) and the seam test ("seam", per test-grid spacing and
tolerance; the default marked). Then harder checks for the default seam test:

* the wall halves split at the median *row* (top / bottom: should merge);
* wall vs floor only on the frames where the two share a seam (the main column also counts pairs
  that do not meet, which the seam test never merges);
* wall vs every adjacent region of a geometrically different class (floor, ceiling, bed, chair,
  sofa, table, furniture; touching the wall, >= 2000 pixels): should not merge;
* the default with the noise scale off by a factor (another sensor with the Kinect model);
* the seam test's local union fit (``test_window``, the default) against the exact one
  (``test_window=None``): decisions on all the pairs above and the union test's cost.

    python tools/eval_merge_nyu.py            # everything
    python tools/eval_merge_nyu.py --window   # the local-vs-exact table only
"""

from __future__ import annotations

import sys
import time
from dataclasses import dataclass

import cv2
import numpy as np

from rgbd_rs import PinholeCamera
from rgbd_rs.data.paths import data_root
from rgbd_rs.surface import (
    DEFAULT_TEST_SPACING,
    DEFAULT_TEST_WINDOW,
    DEFAULT_TOLERANCE,
    KINECT_V1_NOISE_SCALE,
    SegmentFits,
)

NYU = PinholeCamera(
    fx=518.857901, fy=519.469611, cx=325.582449, cy=253.736166, width=640, height=480
)
WALL, FLOOR = 12, 5
#: label13 classes whose surfaces differ from a wall's: bed, ceiling, chair, floor, furniture,
#: sofa, table (not books, objects, pictures, TVs, windows, which may be flush with the wall).
OTHER = {1: "bed", 3: "ceiling", 4: "chair", 5: "floor", 6: "furniture", 9: "sofa", 10: "table"}


@dataclass
class Frame:
    idx: str
    points: np.ndarray
    #: 0, 1: wall halves (left / right); 2: floor.
    labels: np.ndarray
    #: 0, 1: wall halves (top / bottom).
    rows: np.ndarray
    #: 0: the wall; 1..: adjacent regions of OTHER classes.
    adjacent: np.ndarray
    #: Whether a wall half and the floor share a seam (default test grid).
    touching: bool


def largest(mask: np.ndarray) -> np.ndarray:
    n, cc = cv2.connectedComponents(mask.astype(np.uint8))
    if n < 2:
        return np.zeros_like(mask)
    return np.asarray(cc == np.argmax(np.bincount(cc[mask])))


def _near(mask: np.ndarray) -> np.ndarray:
    return np.asarray(cv2.dilate(mask.astype(np.uint8), np.ones((7, 7), np.uint8)), bool)


def cases() -> list[Frame]:
    root = data_root()
    if root is None:
        raise SystemExit("shared data not found: set RGBD_DATA")
    out = []
    for f in sorted((root / "nyuv2" / "frames").glob("*_depth.png")):
        idx = f.name[:4]
        depth = np.asarray(cv2.imread(str(f), cv2.IMREAD_UNCHANGED), np.float32) / 1000.0
        lab = np.asarray(cv2.imread(str(f.with_name(f"{idx}_label13.png")), cv2.IMREAD_UNCHANGED))
        wall, floor = largest(np.equal(lab, WALL)), largest(np.equal(lab, FLOOR))
        if wall.sum() < 10000 or floor.sum() < 5000:
            continue
        v, u = np.nonzero(wall)
        col = np.arange(640)[None, :]
        row = np.arange(480)[:, None]
        labels = np.full(depth.shape, -1, np.int32)
        labels[wall & (col < np.median(u))] = 0
        labels[wall & (col >= np.median(u))] = 1
        labels[floor] = 2
        rows = np.full(depth.shape, -1, np.int32)
        rows[wall & (row < np.median(v))] = 0
        rows[wall & (row >= np.median(v))] = 1
        adjacent = np.full(depth.shape, -1, np.int32)
        adjacent[wall] = 0
        near = _near(wall)
        for c in OTHER:
            n, cc = cv2.connectedComponents(np.equal(lab, c).astype(np.uint8))
            for k in range(1, n):
                region = cc == k
                if region.sum() >= 2000 and (region & near).any():
                    adjacent[region] = adjacent.max() + 1
        pts = NYU.depth_to_points(depth)
        s = SegmentFits(pts, labels)
        touching = s.seam(0, 2) > 0 or s.seam(1, 2) > 0
        out.append(Frame(idx, pts, labels, rows, adjacent, touching))
    return out


def decide(frames: list[Frame], **kw: object) -> tuple[int, int]:
    same = apart = 0
    for fr in frames:
        s = SegmentFits(fr.points, fr.labels, **kw)  # type: ignore[arg-type]
        same += s.should_merge(0, 1)
        apart += not (s.should_merge(0, 2) or s.should_merge(1, 2))
    return same, apart


def main() -> None:
    frames = cases()
    n = len(frames)
    print(f"{n} NYUv2 frames with a wall and a floor region\n")
    if "--window" not in sys.argv[1:]:
        tables(frames)
    window_table(frames)


def tables(frames: list[Frame]) -> None:
    n = len(frames)
    print("| criterion | spacing | test spacing | tolerance | wall halves merged ", end="")
    print("| wall/floor kept apart |")
    print("|---|---|---|---|---|---|")
    for spacing in (8, 16, 32, 64):
        for crit in ("gcv", "mse"):
            same, apart = decide(frames, spacing=spacing, criterion=crit)
            print(f"| {crit} | {spacing} | | | {same}/{n} | {apart}/{n} |")
    for ts in (8, 16, 32):
        for tol in (0.5, 1.0, 2.0):
            same, apart = decide(frames, test_spacing=ts, tolerance=tol)
            default = ts == DEFAULT_TEST_SPACING and tol == DEFAULT_TOLERANCE
            name = "**seam (default)**" if default else "seam"
            print(f"| {name} | | {ts} | {tol:g} | {same}/{n} | {apart}/{n} |")

    print("\nHarder checks, default seam test:\n")
    print("| check | pairs | right |")
    print("|---|---|---|")
    ok = sum(SegmentFits(fr.points, fr.rows).should_merge(0, 1) for fr in frames)
    print(f"| wall halves split at the median row merged | {n} | {ok}/{n} |")
    touch = [fr for fr in frames if fr.touching]
    print(f"| frames where the floor meets a wall half (shares a seam) | {n} | {len(touch)}/{n} |")
    ok = sum(
        not (s.should_merge(0, 2) or s.should_merge(1, 2))
        for s in (SegmentFits(fr.points, fr.labels) for fr in touch)
    )
    print(f"| wall/floor kept apart, frames where they touch | {len(touch)} | {ok}/{len(touch)} |")
    pairs = kept = 0
    for fr in frames:
        s = SegmentFits(fr.points, fr.adjacent)
        for k in range(1, int(fr.adjacent.max()) + 1):
            if s.seam(0, k) == 0:
                continue
            pairs += 1
            kept += not s.should_merge(0, k)
    others = "/".join(sorted(OTHER.values()))
    print(f"| wall vs touching {others} kept apart | {pairs} | {kept}/{pairs} |")

    print("\nDefault seam test with a wrong noise scale (another sensor read with this model):\n")
    print("| noise scale | wall halves merged | wall/floor kept apart |")
    print("|---|---|---|")
    for factor in (0.25, 0.5, 1.0, 2.0, 4.0):
        same, apart = decide(frames, noise_scale=KINECT_V1_NOISE_SCALE * factor)
        print(f"| {factor:g} x Kinect v1 | {same}/{n} | {apart}/{n} |")


def window_table(frames: list[Frame]) -> None:
    n = len(frames)
    print("\nLocal union fit (test_window = control points freed around the contested ones) vs")
    print("the exact union fit (None), default seam test otherwise:\n")
    windows: list[int | None] = [None, 0, 1, 2, 3]
    print(
        "| test window | wall halves merged | wall/floor kept apart | halves (rows) merged ", end=""
    )
    print("| wall vs other kept apart | decisions unlike exact ", end="")
    print("| max relative change of the union's χ² ", end="")
    print("| ms per union test |")
    print("|---|---|---|---|---|---|---|---|")
    ref: list[tuple[bool, float]] = []
    for w in windows:
        same, apart, rows, kept, pairs, elapsed = 0, 0, 0, 0, 0, 0.0
        out: list[tuple[bool, float]] = []
        for fr in frames:
            tests = [(fr.labels, 0, 1), (fr.labels, 0, 2), (fr.labels, 1, 2), (fr.rows, 0, 1)]
            tests += [(fr.adjacent, 0, k) for k in range(1, int(fr.adjacent.max()) + 1)]
            made: dict[int, SegmentFits] = {}
            for lab, i, j in tests:
                if id(lab) not in made:
                    made[id(lab)] = SegmentFits(fr.points, lab, test_window=w)
                s = made[id(lab)]
                t0 = time.perf_counter()
                e = s.union_error(i, j)
                elapsed += time.perf_counter() - t0
                m = s.should_merge(i, j)
                seam = s.seam(i, j)
                # The union's χ² (noise variances), relative changes below.
                chi = e * (s.size(i) + s.size(j)) + DEFAULT_TOLERANCE * seam
                out.append((m, chi))
                if lab is fr.adjacent:
                    if seam > 0:
                        pairs += 1
                        kept += not m
                elif lab is fr.rows:
                    rows += m
                elif j == 1:
                    same += m
            apart += not (out[-len(tests) + 1][0] or out[-len(tests) + 2][0])
        if w is None:
            ref = out
        differ = sum(a[0] != b[0] for a, b in zip(out, ref, strict=True))
        worst = max(
            (
                abs(a[1] - b[1]) / max(abs(b[1]), 1.0)
                for a, b in zip(out, ref, strict=True)
                if np.isfinite(b[1])
            ),
            default=0.0,
        )
        name = "None (exact)" if w is None else str(w)
        if w == DEFAULT_TEST_WINDOW:
            name = f"**{w} (default)**"
        print(
            f"| {name} | {same}/{n} | {apart}/{n} | {rows}/{n} | {kept}/{pairs} | {differ}/", end=""
        )
        print(f"{len(out)} | {worst:.2g} | {elapsed * 1e3 / len(out):.3f} |")


if __name__ == "__main__":
    main()
