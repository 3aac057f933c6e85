"""Synthetic labeled indoor frames (rgbd_rs.data.synth_indoor): determinism, shards, resume, the
labels against the scene geometry, the Kinect-like depth noise and holes, the CLI."""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np
import pytest

from rgbd_rs.cli import indoor as cli_indoor
from rgbd_rs.cli._args import Commands, Parser
from rgbd_rs.data.nyuv2 import LABEL13_NAMES
from rgbd_rs.data.synth_indoor import (
    IndoorFrames,
    _render,
    class_frequencies,
    generate_indoor,
    render_indoor_frame,
)
from rgbd_rs.data.synth_indoor_objects import CEILING, FLOOR, WALL

W, H = 80, 60


def _same(a: object, b: object) -> None:
    for key in ("index", "rgb", "label13", "camera"):
        va, vb = getattr(a, key), getattr(b, key)
        if isinstance(va, np.ndarray):
            np.testing.assert_array_equal(va, vb)
        else:
            assert va == vb
    np.testing.assert_array_equal(a.depth, b.depth)  # type: ignore[attr-defined]


def test_frame_is_deterministic_and_depends_on_seed_and_index() -> None:
    a = render_indoor_frame(3, 5, width=W, height=H)
    _same(a, render_indoor_frame(3, 5, width=W, height=H))
    assert a.name == "000005" and a.rgb.shape == (H, W, 3) and a.rgb.dtype == np.uint8
    assert a.depth.dtype == np.float32 and a.label13.dtype == np.uint8
    assert a.camera.width == W and a.camera.height == H
    assert not np.array_equal(a.rgb, render_indoor_frame(3, 6, width=W, height=H).rgb)
    assert not np.array_equal(a.rgb, render_indoor_frame(4, 5, width=W, height=H).rgb)


def test_shards_write_the_same_frames_as_one_run(tmp_path: Path) -> None:
    one, two = tmp_path / "one", tmp_path / "two"
    assert generate_indoor(one, 5, seed=2, width=32, height=24, quiet=True) == list(range(5))
    assert generate_indoor(two, 5, seed=2, shard=(1, 2), width=32, height=24, quiet=True) == [1, 3]
    generate_indoor(two, 5, seed=2, shard=(0, 2), width=32, height=24, quiet=True)
    names = sorted(p.name for p in one.iterdir())
    assert names == sorted(p.name for p in two.iterdir())
    for n in names:
        assert (one / n).read_bytes() == (two / n).read_bytes(), n
    frames = IndoorFrames(one)
    assert len(frames) == 5 and frames.indices == list(range(5))
    _same(frames[3], render_indoor_frame(2, 3, width=32, height=24))
    assert frames[-1].index == 4


def test_resume_skips_complete_frames_and_refuses_another_seed(tmp_path: Path) -> None:
    generate_indoor(tmp_path, 3, seed=0, width=32, height=24, quiet=True)
    keep = tmp_path / "000000_rgb.png"
    before = keep.stat().st_mtime_ns
    redo = tmp_path / "000001_depth.png"
    good = redo.read_bytes()
    redo.unlink()  # an interrupted frame: incomplete, so not listed and redone
    assert IndoorFrames(tmp_path).indices == [0, 2]
    os.utime(keep, ns=(before - 10**9, before - 10**9))
    generate_indoor(tmp_path, 3, seed=0, width=32, height=24, quiet=True)
    assert keep.stat().st_mtime_ns == before - 10**9  # not rewritten
    assert redo.read_bytes() == good
    from rgbd_rs import InvalidArgumentError

    with pytest.raises(InvalidArgumentError, match=r"^out: got a folder holding"):
        generate_indoor(tmp_path, 3, seed=1, width=32, height=24, quiet=True)


def test_labels_follow_the_geometry_of_the_placed_objects() -> None:
    seen: set[int] = set()
    for k in range(16):
        frame, scene, truth = _render(11, k, W, H)
        labels = set(np.unique(frame.label13).tolist())
        assert labels <= {p.label for p in scene.parts}
        assert 0 not in labels  # a closed room: every ray hits something
        seen |= labels
        # World points of the true depth: floor pixels lie on y = 0, ceiling pixels on the
        # ceiling plane, wall pixels on the room's boundary (doors are walls too, a few cm in).
        cam, pose = frame.camera, scene.pose.inverse()
        v, u = np.mgrid[0:H, 0:W]
        pts = np.stack([(u - cam.cx) / cam.fx * truth, (v - cam.cy) / cam.fy * truth, truth], -1)
        world = pts.reshape(-1, 3) @ pose.rotation.T + pose.translation
        lab = frame.label13.ravel()
        np.testing.assert_allclose(world[lab == FLOOR, 1], 0.0, atol=1e-3)
        if (lab == CEILING).any():
            ceil = world[lab == CEILING, 1]
            np.testing.assert_allclose(ceil, ceil.min(), atol=1e-3)
        lo, hi = world.min(axis=0), world.max(axis=0)
        wx, wz = world[lab == WALL, 0], world[lab == WALL, 2]
        to_edge = np.minimum.reduce([wx - lo[0], hi[0] - wx, wz - lo[2], hi[2] - wz])
        assert np.all(to_edge < 0.05)
    assert {FLOOR, WALL} <= seen and len(seen) >= 10, sorted(seen)


def test_depth_noise_grows_with_depth_and_holes_exist() -> None:
    near, far, holes = [], [], []
    for k in range(6):
        frame, _, truth = _render(5, k, 320, 240)
        err = frame.depth - truth
        ok = np.isfinite(err) & (np.abs(err) < 0.3)  # away from jagged edges
        near.append(err[ok & (truth > 1.5) & (truth < 2.5)])
        far.append(err[ok & (truth > 3.5) & (truth < 4.5)])
        holes.append(np.isnan(frame.depth).mean())

    def robust_sd(e: list[np.ndarray]) -> float:
        x = np.concatenate(e)
        return float(1.4826 * np.median(np.abs(x - np.median(x))))

    sd_near, sd_far = robust_sd(near), robust_sd(far)
    # sigma_z ~ 1.425e-3 z^2 (k drawn in 1.0e-3..1.85e-3, quantisation included): ~5.7 mm
    # at 2 m, ~23 mm at 4 m.
    assert 0.002 < sd_near < 0.012, sd_near
    assert sd_far > 2.5 * sd_near, (sd_near, sd_far)
    assert 0.005 < np.mean(holes) < 0.5


def test_holes_grow_beyond_the_working_range() -> None:
    counts = np.zeros((2, 2))  # [near, far] x [holes, pixels]
    for k in range(40):
        frame, _, truth = _render(8, k, 48, 36)
        for row, sel in enumerate((truth < 3.0, truth > 6.0)):
            counts[row] += [np.isnan(frame.depth[sel]).sum(), sel.sum()]
    assert counts[1, 1] > 100, "no far pixels: the test needs larger rooms"
    near, far = counts[:, 0] / counts[:, 1]
    assert far > 0.4 and far > 3 * near, (near, far)


def test_class_frequencies_sum_to_one_and_walls_dominate() -> None:
    labels = [render_indoor_frame(1, k, width=64, height=48).label13 for k in range(10)]
    f = class_frequencies(labels)
    assert f.shape == (len(LABEL13_NAMES),) and abs(f.sum() - 1) < 1e-12
    assert f[WALL] == f.max()


def _cli(*args: str) -> int:
    p = Parser(prog="rgbd")
    cli_indoor.register(Commands(p.add_subparsers(dest="command")))
    ns = p.parse_args(list(args))
    return int(ns.run(ns))


def test_cli_writes_frames_preview_and_stats(tmp_path: Path, capsys) -> None:  # type: ignore[no-untyped-def]
    out = tmp_path / "d"
    common = ["--out", str(out), "--width", "32", "--height", "24", "--quiet"]
    assert _cli("synth-indoor", *common, "--count", "3", "--shard", "1/2", "--seed", "4") == 0
    assert IndoorFrames(out).indices == [1]
    assert _cli("synth-indoor", *common, "--count", "2", "--seed", "4", "--stats") == 0
    text = capsys.readouterr().out
    assert "wall" in text and "synthetic (2)" in text
    assert _cli("synth-indoor", *common, "--count", "1", "--preview") == 0
    assert (out / "preview.png").stat().st_size > 0
    with pytest.raises(SystemExit):
        _cli("synth-indoor", *common, "--count", "2", "--shard", "2/2")
