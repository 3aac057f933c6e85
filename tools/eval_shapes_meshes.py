"""Shape classifiers on the ModelNet meshes of the shared data (`meshes/modelnet*_CLASS_*.off`):
the mesh path of `classify()` (a mesh is sampled into the points the network was trained on),
not the point packs. Prints each mesh's predicted class per checkpoint and the count right.

    python tools/eval_shapes_meshes.py --checkpoint A.pt [B.pt ...] [--data DIR]
"""

from __future__ import annotations

import argparse
import os
import re
from pathlib import Path

from rgbd_rs.shapes.classify import ShapeClassifier

MESH = re.compile(r"modelnet(10|40)_(.+)_\d+\.off$")


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--checkpoint", type=Path, nargs="+", required=True)
    default = Path(os.environ.get("RGBD_DATA", Path(__file__).parents[2] / "shared" / "data"))
    p.add_argument("--data", type=Path, default=default, help="the shared data folder")
    a = p.parse_args()
    meshes = sorted(m for m in (a.data / "meshes").glob("modelnet*.off") if MESH.search(m.name))
    for ckpt in a.checkpoint:
        clf = ShapeClassifier.load(ckpt)
        right = 0
        rows = []
        for m in meshes:
            match = MESH.search(m.name)
            assert match is not None
            truth = match.group(2)
            if truth not in clf.classes:
                continue
            best, probs = clf(m)
            right += best == truth
            rows.append(f"  {m.name}: {best} ({probs[best]:.2f})")
        print(f"{ckpt}: {right}/{len(rows)} meshes right")
        print("\n".join(rows))


if __name__ == "__main__":
    main()
