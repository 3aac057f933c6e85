"""Copy the demo's figures into the docs as JPEG (docs/img/), so the site and the README show
what `rgbd demo` draws without committing megabytes of PNG.

    rgbd demo --out out/demo && python tools/docs_figures.py out/demo
"""

from __future__ import annotations

import argparse
from pathlib import Path

import cv2

from rgbd_rs.demo_page import FIGURES

#: JPEG quality of the copies (the panels are smooth colour maps: 85 keeps them clean).
QUALITY = 85


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("demo", type=Path, help="the folder `rgbd demo --out` wrote")
    ap.add_argument("--out", type=Path, default=Path("docs/img"))
    a = ap.parse_args()
    a.out.mkdir(parents=True, exist_ok=True)
    for name, _ in FIGURES:
        img = cv2.imread(str(a.demo / name), cv2.IMREAD_COLOR)
        if img is None:
            raise SystemExit(f"{a.demo / name}: missing or unreadable (run `rgbd demo` first)")
        target = a.out / (Path(name).stem + ".jpg")
        cv2.imwrite(str(target), img, [cv2.IMWRITE_JPEG_QUALITY, QUALITY])
        print(f"{target}: {target.stat().st_size // 1024} kB")


if __name__ == "__main__":
    main()
