"""A cache remembers which data it was started from (a fingerprint of the source's names, labels
and shapes, or of its frames' files): resuming it from another pack or folder of the same name
is refused instead of mixing two datasets; caches made before the fingerprint still resume."""

from __future__ import annotations

import json
import warnings
from pathlib import Path

import numpy as np
import pytest

from modelnet_packs import modelnet10_subset
from rgbd_rs.data.calibration import save_camera
from rgbd_rs.errors import RgbdError
from rgbd_rs.io import write_png
from rgbd_rs.segmentation.semantic_data import FrameFolder, build_semantic_cache
from rgbd_rs.shapes.dataset import InputSpec, PointCloudSet, build_cache
from test_semantic_data import CAMERA, fake_cues, frames

VOLUME = InputSpec(representations=("volume",), normalisation="standardize")


def test_shape_cache_refuses_another_pack_of_the_same_name(
    shared_data: Path, tmp_path: Path
) -> None:
    (tmp_path / "a").mkdir()
    (tmp_path / "b").mkdir()
    a = modelnet10_subset(shared_data, tmp_path / "a" / "mini.npz", (0, 8), ((0, 3), (1, 2)))
    d = dict(np.load(a))
    np.savez(
        tmp_path / "b" / "mini.npz", **(d | {"points": d["points"][::-1], "name": d["name"][::-1]})
    )
    b = tmp_path / "b" / "mini.npz"
    build_cache(PointCloudSet(a), tmp_path / "c", spec=VOLUME, workers=1, quiet=True)
    build_cache(PointCloudSet(a), tmp_path / "c", spec=VOLUME, workers=1, quiet=True)  # resumes
    with pytest.raises(RgbdError, match=r"fingerprint: .* \(the source's shapes, names or labels"):
        build_cache(PointCloudSet(b), tmp_path / "c", spec=VOLUME, workers=1, quiet=True)
    # the same names and labels with other points (a pack sampled anew) are refused too
    d = dict(np.load(a))
    d["points"] = (d["points"].astype(np.float32) * 0.9).astype(d["points"].dtype)
    np.savez(tmp_path / "b" / "mini.npz", **d)
    with pytest.raises(RgbdError, match=r"fingerprint"):
        build_cache(PointCloudSet(tmp_path / "b" / "mini.npz"), tmp_path / "c", spec=VOLUME,
                    workers=1, quiet=True)  # fmt: skip
    # a cache written before fingerprints existed still resumes
    meta_file = tmp_path / "c" / "meta.json"
    meta = json.loads(meta_file.read_text())
    del meta["fingerprint"]
    meta_file.write_text(json.dumps(meta))
    build_cache(PointCloudSet(a), tmp_path / "c", spec=VOLUME, workers=1, quiet=True)


def _folder(root: Path, offset: int) -> Path:
    """Two frames named frame0, frame1 holding frames(3)[offset:offset + 2]'s content."""
    root.mkdir(parents=True)
    for k, f in enumerate(frames(3)[offset : offset + 2]):
        write_png(root / f"frame{k}_rgb.png", f.rgb)
        mm = np.nan_to_num(f.depth * 1000).round().astype(np.uint16)
        write_png(root / f"frame{k}_depth.png", mm, rgb=False)
        write_png(root / f"frame{k}_label13.png", f.label13, rgb=False)
    save_camera(root / "camera.json", CAMERA)
    return root


def test_semantic_cache_refuses_another_folder_of_the_same_frames(tmp_path: Path) -> None:
    a = FrameFolder(_folder(tmp_path / "a" / "frames", 0))
    b = FrameFolder(_folder(tmp_path / "b" / "frames", 1))  # other content, the same names
    assert b.names == a.names
    kw = {"size": (16, 12), "cues": fake_cues, "source": "frames", "quiet": True}
    build_semantic_cache(a, tmp_path / "c", **kw)  # type: ignore[arg-type]
    build_semantic_cache(a, tmp_path / "c", **kw)  # type: ignore[arg-type]
    with pytest.raises(RgbdError, match=r"fingerprint.*another folder of the same name"):
        build_semantic_cache(b, tmp_path / "c", **kw)  # type: ignore[arg-type]


def test_frame_folder_warns_of_incomplete_frames(tmp_path: Path) -> None:
    root = _folder(tmp_path / "f", 0)
    (root / "frame1_label13.png").unlink()
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        src = FrameFolder(root)
    assert src.names == ("frame0",)
    assert any("1 frame(s) without their" in str(w.message) for w in caught)


def test_frame_files_are_matched_by_their_frame_names() -> None:
    from rgbd_rs.segmentation.semantic_data import _of_a_frame

    names = {"living_room_0001", "000001", "a.b"}
    assert _of_a_frame("living_room_0001_rgb.png", names)
    assert _of_a_frame("camera_000001.json", names) and _of_a_frame("000001_depth.png", names)
    assert _of_a_frame("a.b_label13.png", names)
    assert not _of_a_frame("living_room_0002_rgb.png", names)
    assert not _of_a_frame("README.md", names) and not _of_a_frame("camera.json", names)
