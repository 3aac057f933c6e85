"""Choose the census matcher's defaults on the Middlebury train + val scenes (never test).

Coordinate descent from the current defaults: each round tries every value of every parameter
of GRID with the others fixed and keeps the best; the objective is the issue's target, the worse
of our bad-2 and edge-band bad-1 as a fraction of OpenCV SGBM-HH 7x7's on the same scenes
(lower is better). Prints every setting tried and the chosen parameters.

    python tools/sweep_census.py [--rounds 2] [--split train val]
"""

from __future__ import annotations

import argparse
from typing import Any

from rgbd_rs.data import load_stereo_scenes
from rgbd_rs.fusion.census import CensusParams
from rgbd_rs.fusion.evaluate_stereo import census_matcher, evaluate, opencv_matcher

GRID: dict[str, list[Any]] = {
    "census": [(5, 5), (7, 5), (7, 7), (9, 7), (9, 9), (11, 5)],
    "census_reference": ["center", "mean"],
    "p1": [4, 7, 10, 15, 20],
    "p2": [40, 80, 120, 200, 300],
    "p2_contrast": [0.0, 4.0, 8.0, 16.0, 32.0],
    "lr_tolerance": [None, 1, 2, 3],
    "uniqueness": [0, 5, 10, 15],
    "median": [1, 3, 5],
    "speckle_size": [0, 20, 60, 150],
    "speckle_range": [1.0, 2.0],
    "subpixel": ["parabola", "equiangular"],
    "paths": [4, 5, 8],
}


def apply(p: CensusParams, key: str, value: Any) -> CensusParams | None:
    try:
        if key == "census":
            return p.replace(census_width=value[0], census_height=value[1])
        return p.replace(**{key: value})
    except ValueError:  # e.g. p2 <= p1
        return None


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--rounds", type=int, default=2)
    ap.add_argument("--split", nargs="+", default=["train", "val"], choices=["train", "val"])
    args = ap.parse_args()
    scenes = [s for split in args.split for s in load_stereo_scenes(split)]
    peer = evaluate(scenes, {"hh7": opencv_matcher(7)})
    b2, eb = peer.mean("hh7", "bad2"), peer.mean("hh7", "edge_bad1")
    print(
        f"OpenCV HH 7x7 on {len(scenes)} scenes: bad-2 {100 * b2:.2f} %, "
        f"edge bad-1 {100 * eb:.2f} %"
    )
    cache: dict[CensusParams, tuple[float, float, float]] = {}

    def score(p: CensusParams) -> float:
        if p not in cache:
            t = evaluate(scenes, {"ours": census_matcher(p)})
            r2, re = t.mean("ours", "bad2") / b2, t.mean("ours", "edge_bad1") / eb
            cache[p] = (max(r2, re), r2, re)
            print(f"  {max(r2, re):.4f} (bad-2 x{r2:.3f}, edge x{re:.3f})  {p}", flush=True)
        return cache[p][0]

    best = CensusParams()
    score(best)
    for rnd in range(args.rounds):
        changed = False
        for key, values in GRID.items():
            for v in values:
                cand = apply(best, key, v)
                if cand is not None and score(cand) < score(best):
                    best, changed = cand, True
        print(f"round {rnd + 1}: {cache[best]} {best}", flush=True)
        if not changed:
            break
    print("chosen:", best, cache[best])


if __name__ == "__main__":
    main()
