"""Synthetic labeled indoor frames (rgbd_rs.data.synth_indoor): determinism, shards, resume, the
labels against the scene geometry, the Kinect-like depth noise and holes, the CLI."""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np
import pytest

from rgbd_rs import PinholeCamera, Pose
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
from rgbd_rs.data.synth_indoor_objects import CEILING, FLOOR, WALL, Part
from rgbd_rs.data.synth_indoor_scene import IndoorScene
from rgbd_rs.data.synth_indoor_sensor import _kinect_depth
from rgbd_rs.errors import RgbdError
from rgbd_rs.meshes import quad
from rgbd_rs.render import Material, Scene

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
    assert IndoorFrames(tmp_path).requested == 3 and IndoorFrames(tmp_path).missing == [1]
    # ... and a reader of the frames for training refuses the folder until it is finished
    from rgbd_rs.segmentation.semantic_data import SyntheticFrames, open_frames

    with pytest.raises(RgbdError, match=r"1 of the 3 frames asked for not complete \(frames 1:"):
        open_frames(tmp_path)
    assert SyntheticFrames(tmp_path, partial=True).names == ("000000", "000002")
    os.utime(keep, ns=(before - 10**9, before - 10**9))
    generate_indoor(tmp_path, 3, seed=0, width=32, height=24, quiet=True)
    assert keep.stat().st_mtime_ns == before - 10**9  # not rewritten
    assert redo.read_bytes() == good
    from rgbd_rs import InvalidArgumentError

    with pytest.raises(
        InvalidArgumentError, match=r"^out: got a folder holding .*\(seed: 0 there, 1 now\)"
    ):
        generate_indoor(tmp_path, 3, seed=1, width=32, height=24, quiet=True)
    # Shards of two seeds never mix: the first shard to run writes the manifest, whichever.
    mixed = tmp_path / "mixed"
    generate_indoor(mixed, 2, seed=1, shard=(1, 2), width=32, height=24, quiet=True)
    with pytest.raises(InvalidArgumentError, match=r"^out: got a folder holding"):
        generate_indoor(mixed, 2, seed=2, shard=(0, 2), width=32, height=24, quiet=True)


def test_labels_follow_the_geometry_and_walls_dominate() -> None:
    seen: set[int] = set()
    labels = []
    for k in range(10):
        frame, scene, truth = _render(11, k, W, H)
        present = set(np.unique(frame.label13).tolist())
        assert present <= {p.label for p in scene.parts}
        assert 0 not in present  # a closed room: every ray hits something
        seen |= present
        labels.append(frame.label13)
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
    f = class_frequencies(labels)
    assert f.shape == (len(LABEL13_NAMES),) and abs(f.sum() - 1) < 1e-12
    assert f[WALL] == f.max() and f[0] == 0


def _strips(dark_lower: bool = True) -> tuple[IndoorScene, list[float]]:
    """Walls at 1.5 .. 9.5 m, one per vertical image strip, tilted by ~6 degrees (so the true
    disparity sweeps the quantisation steps); the lower half of each is a black surface (IR
    albedo 0.005) when ``dark_lower``."""
    cam = PinholeCamera(200.0, 200.0, 79.5, 59.5, 160, 120)
    depths = [1.5, 2.0, 3.0, 4.0, 5.0, 6.0, 8.5, 9.5]
    scene, parts = Scene(), []
    bright = Material((0.6, 0.6, 0.6), 0.6)
    black = Material((0.005, 0.005, 0.005), 0.005)
    for k, z in enumerate(depths):
        x0, x1 = ((20 * k - 1 - cam.cx) / cam.fx * z, (20 * k + 20 - cam.cx) / cam.fx * z)
        for y0, y1, m in ((-z, 0.0, bright), (0.0, z, black if dark_lower else bright)):
            z0, z1 = z * (1 + 0.1 * y0 / z), z * (1 + 0.1 * y1 / z)
            mesh = quad([[x0, y0, z0], [x1, y0, z0], [x1, y1, z1], [x0, y1, z1]])
            scene.add(mesh, m)
            parts.append(Part(mesh, m, WALL))
    return IndoorScene(scene, parts, cam, Pose.identity(), "test"), depths


def _measure(scene: IndoorScene, seed: int) -> tuple[np.ndarray, np.ndarray]:
    built = scene.scene.build()
    gb = built.gbuffer(scene.camera, scene.pose)
    depth = _kinect_depth(np.random.default_rng(seed), gb, built, scene)
    return depth, gb.depth


def test_depth_noise_grows_as_z_squared() -> None:
    scene, depths = _strips(dark_lower=False)
    errs: list[list[np.ndarray]] = [[] for _ in depths]
    for seed in range(4):
        depth, truth = _measure(scene, seed)
        for k in range(len(depths)):
            e = ((depth - truth) / truth**2)[:, 20 * k + 4 : 20 * k + 16]
            errs[k].append(e[np.isfinite(e)])
    # sigma_z / z^2 = k, drawn in 1.0e-3 .. 1.85e-3 (quantisation included), at every depth:
    # the noise grows as z^2. (A quantised error: a MAD would be 0, so the plain deviation.)
    ratio = np.array([np.concatenate(e).std() for e in errs[:5]])  # 1.5 .. 5 m
    assert np.all((ratio > 0.9e-3) & (ratio < 2.0e-3)), ratio
    assert ratio.max() < 1.5 * ratio.min(), ratio
    bias = np.median(np.concatenate(errs[1])) * 2.0**2
    assert abs(bias) < 0.003, bias


def test_holes_on_black_surfaces_and_beyond_the_range() -> None:
    scene, depths = _strips()
    depth, _ = _measure(scene, 0)
    hole = np.isnan(depth)
    upper = [hole[:60, 20 * k + 4 : 20 * k + 16].mean() for k in range(len(depths))]
    lower = [hole[60:, 20 * k + 4 : 20 * k + 16].mean() for k in range(len(depths))]
    assert max(upper[:4]) < 0.1, upper  # bright, 1.5 .. 4 m: measured
    assert min(upper[-2:]) > 0.6, upper  # 8.5, 9.5 m: beyond the working range
    assert np.mean(lower[2:6]) > 0.6, lower  # black at 3 .. 6 m: lost
    frame = render_indoor_frame(5, 0, width=160, height=120)
    assert 0.005 < np.isnan(frame.depth).mean() < 0.5


def _cli(*args: str) -> int:
    p = Parser(prog="rgbd")
    cli_indoor.register(Commands(p.add_subparsers(dest="command")))
    ns = p.parse_args(list(args))
    return int(ns.run(ns))


def test_cli_writes_frames_preview_and_stats(
    tmp_path: Path,
    capsys: pytest.CaptureFixture[str],
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    import rgbd_rs.data.paths

    monkeypatch.setattr(rgbd_rs.data.paths, "data_root", lambda: None)  # skip reading NYUv2
    out = tmp_path / "d"
    common = ["--out", str(out), "--width", "32", "--height", "24", "--quiet"]
    assert _cli("synth-indoor", *common, "--count", "3", "--shard", "1/2", "--seed", "4") == 0
    assert IndoorFrames(out).indices == [1] and IndoorFrames(out).missing == [0, 2]
    assert _cli("synth-indoor", *common, "--count", "2", "--seed", "4", "--stats") == 0
    text = capsys.readouterr().out
    assert "wall" in text and "synthetic (2)" in text
    assert _cli("synth-indoor", *common, "--count", "1", "--preview") == 0
    assert (out / "preview.png").stat().st_size > 0
    with pytest.raises(SystemExit):
        _cli("synth-indoor", *common, "--count", "2", "--shard", "2/2")
