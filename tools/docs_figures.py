"""Copy the demo's figures (or one figure of another command) into the docs as JPEG
(docs/img/), so the site and the README show what the commands draw without committing
megabytes of PNG.

    rgbd demo --out out/demo && python tools/docs_figures.py out/demo
    rgbd eval fusion --real test --laws 1 --scenes Cones,Teddy --out out/readme_fusion
    python tools/docs_figures.py --figure out/readme_fusion/real_test/figure.png fusion_real
"""

from __future__ import annotations

import argparse
from pathlib import Path

import cv2

from rgbd_rs.demo_page import FIGURES

#: JPEG quality of the copies (the panels are smooth colour maps: 85 keeps them clean).
QUALITY = 85


def _copy(source: Path, target: Path) -> None:
    img = cv2.imread(str(source), cv2.IMREAD_COLOR)
    if img is None:
        raise SystemExit(f"{source}: missing or unreadable (run the command that draws it first)")
    cv2.imwrite(str(target), img, [cv2.IMWRITE_JPEG_QUALITY, QUALITY])
    print(f"{target}: {target.stat().st_size // 1024} kB")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("demo", type=Path, nargs="?", help="the folder `rgbd demo --out` wrote")
    ap.add_argument(
        "--figure",
        nargs=2,
        metavar=("PNG", "NAME"),
        help="copy this one figure as OUT/NAME.jpg instead of the demo's",
    )
    ap.add_argument("--out", type=Path, default=Path("docs/img"))
    a = ap.parse_args()
    if (a.demo is None) == (a.figure is None):
        ap.error("give either the demo folder or --figure PNG NAME")
    a.out.mkdir(parents=True, exist_ok=True)
    if a.figure is not None:
        _copy(Path(a.figure[0]), a.out / f"{a.figure[1]}.jpg")
        return
    for name, _ in FIGURES:
        _copy(a.demo / name, a.out / (Path(name).stem + ".jpg"))


if __name__ == "__main__":
    main()
