"""The `rgbd` command line: help, demo, reproject, and every bad run ending in one line."""

from __future__ import annotations

import argparse
import json
import subprocess
import sys
import warnings
import zlib
from pathlib import Path

import numpy as np
import pytest

from rgbd_rs.cli import main


def run(*args: str) -> subprocess.CompletedProcess[str]:
    return subprocess.run(
        [sys.executable, "-m", "rgbd_rs.cli", *args], capture_output=True, text=True, check=False
    )


def test_help_lists_commands() -> None:
    res = run("--help")
    assert res.returncode == 0
    assert "demo" in res.stdout and "reproject" in res.stdout
    assert run("demo", "--help").returncode == 0


def test_demo_prints_measurements(tmp_path: Path, shared_data: Path) -> None:
    res = run("demo", "--out", str(tmp_path))
    assert res.returncode == 0, res.stderr
    assert "max error" in res.stdout and "Azure Kinect" in res.stdout
    assert "semantic labeling of NYUv2 frame 0046" in res.stdout and "VoI" in res.stdout
    assert "pyvista_airplane.ply: airplane" in res.stdout
    assert "stanford_bunny.off (y up): " in res.stdout  # classified upright
    assert (tmp_path / "segmentation.png").stat().st_size > 1000
    assert (tmp_path / "synthetic_reprojection.png").stat().st_size > 1000
    assert (tmp_path / "kinect_depth_to_color.png").stat().st_size > 1000


def test_reproject_writes_outputs(tmp_path: Path, shared_data: Path) -> None:
    tof = shared_data / "tof"
    code = main(
        [
            "reproject",
            "--frame",
            str(tof / "azure_kinect_frame.npz"),
            "--calib",
            str(tof / "azure_kinect_calibration.json"),
            "--out",
            str(tmp_path),
        ]
    )
    assert code == 0
    with np.load(tmp_path / "depth.npz") as z:
        assert z["depth"].shape == (720, 1280)
    assert (tmp_path / "depth_mm.png").exists() and (tmp_path / "preview.png").exists()
    assert not list(tmp_path.glob("*.tmp*"))


def test_reproject_undistort_feeds_segment(tmp_path: Path, shared_data: Path) -> None:
    """The real Kinect frame to segments: `rgbd reproject --undistort` writes a pinhole camera,
    the undistorted colour and depth, which `rgbd segment` takes as they are."""
    from rgbd_rs.data.calibration import load_camera

    tof = shared_data / "tof"
    frame, calib = tof / "azure_kinect_frame.npz", tof / "azure_kinect_calibration.json"
    rep = tmp_path / "rep"
    argv = ["reproject", "--frame", str(frame), "--calib", str(calib), "--out", str(rep)]
    assert main([*argv, "--undistort"]) == 0
    cam = load_camera(rep / "camera.json")
    assert cam.distortion.is_identity and (cam.width, cam.height) == (1280, 720)
    # colour and depth are resampled onto that camera, not copied
    from rgbd_rs.data import load_azure_kinect_calibration, load_azure_kinect_frame
    from rgbd_rs.io import read_png

    cal, kinect = load_azure_kinect_calibration(calib), load_azure_kinect_frame(frame)
    color = read_png(rep / "color.png")
    np.testing.assert_array_equal(color, cal.color.undistort_image(kinect.color))
    assert not np.array_equal(color, kinect.color)
    with np.load(rep / "depth.npz") as z:
        depth = z["depth"]
    assert 0.3 < np.isfinite(depth).mean() < 0.8 and 0.3 < np.nanmedian(depth) < 5
    seg = tmp_path / "seg"
    argv = ["segment", "--rgb", str(rep / "color.png"), "--depth", str(rep / "depth.npz")]
    argv += ["--calib", str(rep / "camera.json"), "--out", str(seg), "--labeler", "none"]
    assert main([*argv, "--segments", "40", "--quiet"]) == 0
    labels = np.load(seg / "labels.npy")
    assert labels.shape == (720, 1280) and len(np.unique(labels[labels >= 0])) > 3
    # A re-run into the same folders leaves none of the earlier run's files beside its own.
    for stale in ("semantic.npy", "semantic.png", "network.png", "merge/0000.png"):
        (seg / stale).parent.mkdir(exist_ok=True)
        (seg / stale).write_bytes(b"an earlier run's output")
    (seg / "notes.txt").write_text("the user's own file")
    assert main([*argv, "--segments", "40", "--quiet"]) == 0
    assert sorted(p.name for p in seg.iterdir()) == [
        "labels.npy",
        "labels.png",
        "merge",
        "notes.txt",
        "over.npy",
        "overlay.png",
        "segments.png",
    ]
    assert not list((seg / "merge").iterdir())
    assert main(["reproject", "--frame", str(frame), "--calib", str(calib), "--out", str(rep)]) == 0
    assert not (rep / "color.png").exists() and not (rep / "camera.json").exists()


def test_out_must_be_a_folder_and_reach_the_colour_camera(
    tmp_path: Path, shared_data: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    tof = shared_data / "tof"
    calib = tof / "azure_kinect_calibration.json"
    frame = ["--frame", str(tof / "azure_kinect_frame.npz")]
    (tmp_path / "file").write_text("x")
    with pytest.raises(SystemExit):
        main(["reproject", *frame, "--calib", str(calib), "--out", str(tmp_path / "file")])
    assert "argument --out: got " in capsys.readouterr().err
    # The colour camera's translation in millimetres: no ToF pixel reaches the colour image.
    cal = json.loads(calib.read_text())
    far = tmp_path / "far.json"
    for cam in cal["CalibrationInformation"]["Cameras"]:
        cam["Rt"]["Translation"] = [v * 1000 for v in cam["Rt"]["Translation"]]
    far.write_text(json.dumps(cal))
    out = tmp_path / "rep"
    assert main(["reproject", *frame, "--calib", str(far), "--out", str(out)]) == 2
    assert "coverage 0 %" in capsys.readouterr().err and not out.exists()


def test_bad_input_is_a_clean_error(tmp_path: Path, capsys) -> None:  # type: ignore[no-untyped-def]
    code = main(
        [
            "reproject",
            "--frame",
            str(tmp_path / "missing.npz"),
            "--calib",
            str(tmp_path / "missing.json"),
            "--out",
            str(tmp_path),
        ]
    )
    assert code == 2
    err = capsys.readouterr().err
    assert err.startswith("rgbd: error: --calib: could not read") and "missing.json" in err
    assert "(no such file)" in err


# -- every bad run: one line on stderr, exit status 2, no traceback -----------------------------


@pytest.fixture(scope="module")
def fuse_inputs(tmp_path_factory: pytest.TempPathFactory) -> dict[str, Path]:
    """Valid small inputs of `rgbd fuse` (the synthetic rig at 1/8 size); tests break one."""
    from rgbd_rs.data import save_rig, synth3_rig
    from rgbd_rs.io import write_png

    d = tmp_path_factory.mktemp("fuse_inputs")
    tex = np.random.default_rng(0).integers(0, 255, (135, 270, 3)).astype(np.uint8)
    # A wall 22 px of disparity away on this rig (right x sees left x + d), about 1 m; the ToF
    # agrees exactly (baseline x focal / 22 m: at 1 m it would read 1 % off the images'
    # disparity, which fuse() would rescale, with a warning).
    write_png(d / "l.png", tex[:, :240])
    write_png(d / "r.png", tex[:, 22:262])
    rig = synth3_rig(0.125)
    wall = rig.stereo.baseline * rig.stereo.focal / 22
    np.save(d / "depth.npy", np.full((424, 512), wall, np.float32))
    np.save(d / "amp.npy", np.ones((424, 512), np.float32))
    save_rig(d / "calib.json", rig)
    return {
        "--left": d / "l.png",
        "--right": d / "r.png",
        "--tof-depth": d / "depth.npy",
        "--tof-amplitude": d / "amp.npy",
        "--calib": d / "calib.json",
        "--out": d / "out",
    }


def _fuse_argv(inputs: dict[str, Path], **replace: Path) -> list[str]:
    args = {**inputs, **{"--" + k.replace("_", "-"): v for k, v in replace.items()}}
    return ["fuse", *[s for flag, path in args.items() for s in (flag, str(path))]]


def _bad_file(tmp: Path, name: str, data: bytes) -> Path:
    p = tmp / name
    p.write_bytes(data)
    return p


def _pickled_npz(path: Path, key: str = "depth") -> Path:
    np.savez(path, **{key: np.array([{"depth": 1.0}], dtype=object)})
    return path


def _assert_one_line_error(res: subprocess.CompletedProcess[str], *needles: str) -> None:
    assert res.returncode == 2, (res.returncode, res.stdout, res.stderr)
    assert "Traceback" not in res.stderr, res.stderr
    lines = res.stderr.strip().splitlines()
    assert len(lines) == 1, res.stderr
    assert lines[0].startswith("rgbd: error: "), lines[0]
    for n in needles:
        assert n in lines[0], (n, lines[0])


@pytest.mark.parametrize(
    "case",
    [
        "missing --left",
        "truncated .npy",
        "empty .npy",
        "missing .npy",
        "3-D .npy",
        "object .npy",
        "strings in the calibration",
        "malformed calibration",
        "calibration is a list",
        "a camera lacks a key",
        "bad --reference",
        "8-bit depth PNG",
        "bad --depth-scale",
        "--weights with heuristic",
        "maps with heuristic",
        "tiny --depth-scale",
        "pickled .npz",
        "one-camera calibration",
        "--weights not a checkpoint",
        "--precision with uniform",
    ],
)
def test_bad_fuse_runs_end_in_one_line(
    case: str, fuse_inputs: dict[str, Path], tmp_path: Path
) -> None:
    import json

    good = fuse_inputs
    header = np.lib.format.magic(1, 0)
    replace, needles = {
        "missing --left": ({"left": tmp_path / "nope.png"}, ("--left", "nope.png")),
        "truncated .npy": (
            {"tof_depth": _bad_file(tmp_path, "t.npy", good["--tof-depth"].read_bytes()[:90])},
            ("--tof-depth", "t.npy", "truncated"),
        ),
        "empty .npy": (
            {"tof_depth": _bad_file(tmp_path, "e.npy", b"")},
            ("--tof-depth", "e.npy", "empty"),
        ),
        "missing .npy": (
            {"tof_amplitude": tmp_path / "gone.npy"},
            ("--tof-amplitude", "gone.npy", "not found"),
        ),
        "3-D .npy": (
            {"tof_depth": _save(tmp_path / "3d.npy", np.ones((2, 2, 2)))},
            ("--tof-depth", "3d.npy", "shape"),
        ),
        "object .npy": (
            {"tof_depth": _bad_file(tmp_path, "o.npy", header + b"garbage")},
            ("--tof-depth", "o.npy"),
        ),
        "strings in the calibration": (
            {"calib": _edit_json(good["--calib"], tmp_path / "s.json", "365.9")},
            ("--calib", "s.json", "fx"),
        ),
        "malformed calibration": (
            {"calib": _bad_file(tmp_path, "m.json", b"{")},
            ("--calib", "m.json", "malformed"),
        ),
        "calibration is a list": (
            {"calib": _bad_file(tmp_path, "l.json", json.dumps([1]).encode())},
            ("--calib", "l.json"),
        ),
        "a camera lacks a key": (
            {"calib": _edit_json(good["--calib"], tmp_path / "k.json", None)},
            ("--calib", "k.json", "calibration: camera 'tof' has no key 'fx'"),
        ),
        "bad --reference": ({"reference": Path("middle")}, ("--reference", "'middle'")),
        "8-bit depth PNG": (
            {"tof_depth": _png(tmp_path / "d8.png", np.full((424, 512), 200, np.uint8))},
            ("--tof-depth", "d8.png", "8-bit PNG", "16-bit"),
        ),
        "bad --depth-scale": ({"depth_scale": Path("0")}, ("--depth-scale", "got 0")),
        "maps with heuristic": (
            {
                "confidence": Path("uniform"),
                "tof_confidence": tmp_path / "t.npy",
                "stereo_confidence": tmp_path / "s.npy",
            },
            ("--confidence uniform", "--tof-confidence/--stereo-confidence"),
        ),
        "maps with convnet asked": (  # a fuzz found an explicit convnet ignored silently
            {
                "confidence": Path("convnet"),
                "tof_confidence": tmp_path / "t.npy",
                "stereo_confidence": tmp_path / "s.npy",
            },
            ("--confidence convnet", "--tof-confidence/--stereo-confidence"),
        ),
        "tiny --depth-scale": ({"depth_scale": Path("1e-300")}, ("--depth-scale", "1e-300")),
        "pickled .npz": (
            {"tof_depth": _pickled_npz(tmp_path / "p.npz")},
            ("--tof-depth", "p.npz", "it holds Python objects, not plain numeric arrays"),
        ),
        "one-camera calibration": (
            {"calib": Path(__file__).parents[1] / "examples" / "nyu_camera.json"},
            ("--calib", "holds one camera, expected a ToF + stereo rig", "`rgbd reproject`"),
        ),
        "--weights not a checkpoint": (
            {"weights": _bad_file(tmp_path, "w.pt", b"PK\x03\x04 not a zip")},
            ("--weights", "w.pt", "not a readable rgbd_rs checkpoint (it is not a torch"),
        ),
        "--weights with heuristic": (
            {"confidence": Path("heuristic"), "weights": tmp_path / "w.pt"},
            ("--weights", "--confidence heuristic", "only with --confidence convnet"),
        ),
        "--precision with uniform": (
            {"confidence": Path("uniform"), "precision": Path("float32")},
            ("--precision", "--confidence uniform", "only with --confidence convnet"),
        ),
    }[case]
    res = run(*_fuse_argv(good, **replace))
    _assert_one_line_error(res, *needles)
    for leak in ("allow_pickle", "PytorchStreamReader", "inline_container", "has no key 'stereo'"):
        assert leak not in res.stderr, res.stderr


def test_reproject_of_a_pickled_frame_says_what_the_file_holds(
    tmp_path: Path, shared_data: Path
) -> None:
    calib = shared_data / "tof" / "azure_kinect_calibration.json"
    frame = tmp_path / "x_depth.npz"
    obj = np.array([{"depth": 1.0}], dtype=object)
    np.savez(frame, depth_mm=obj, ir=np.zeros((2, 2)), color=np.zeros((2, 2, 3), np.uint8))
    res = run("reproject", "--frame", str(frame), "--calib", str(calib), "--out", str(tmp_path))
    _assert_one_line_error(res, "x_depth.npz", "it holds Python objects")
    assert "allow_pickle" not in res.stderr


def test_reproject_names_the_frame_map_that_does_not_fit_the_calibration(
    tmp_path: Path, shared_data: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    calib = shared_data / "tof" / "azure_kinect_calibration.json"
    real = np.load(shared_data / "tof" / "azure_kinect_frame.npz")
    small = {
        "depth": dict(depth_mm=np.full((10, 10), 1000, np.uint16), ir=np.ones((10, 10), np.uint16)),
        "colour": dict(depth_mm=real["depth_mm"], ir=real["ir"]),
    }
    colours = {"depth": real["color"], "colour": np.zeros((100, 100, 3), np.uint8)}
    want = {
        "depth": "--frame depth_mm: got shape (10, 10), expected (576, 640)",
        "colour": "--frame color: got size 100x100, expected the calibration's colour camera "
        "1280x720 (--calib)",
    }
    for name, arrays in small.items():
        frame = tmp_path / f"{name}.npz"
        np.savez(frame, color=colours[name], **arrays)
        for extra in (["--undistort"], []):
            out = tmp_path / name
            out.mkdir(exist_ok=True)
            (out / "depth.npz").write_bytes(b"an earlier run's output")
            argv = ["reproject", "--frame", str(frame), "--calib", str(calib), *extra]
            assert main([*argv, "--out", str(out)]) == 2
            assert capsys.readouterr().err == f"rgbd: error: {want[name]}\n"
            # Refused before anything in --out was replaced.
            assert (out / "depth.npz").read_bytes() == b"an earlier run's output"


def _png(path: Path, arr: np.ndarray) -> Path:
    import cv2

    assert cv2.imwrite(str(path), arr)
    return path


def test_load_map_depth_units_and_reproject_output(tmp_path: Path) -> None:
    """--depth-scale converts a 16-bit PNG; 8-bit depth PNGs are refused; a .npz from `rgbd
    reproject` (depth + amplitude) gives its depth."""
    from rgbd_rs import InvalidArgumentError
    from rgbd_rs.cli.fusion import load_map

    png = _png(tmp_path / "d.png", np.array([[1234, 0], [5000, 65535]], np.uint16))
    mm = load_map("--depth", png, png_scale=1e-3, depth=True)
    np.testing.assert_allclose(mm, [[1.234, np.nan], [5.0, 65.535]], rtol=1e-6)
    tum = load_map("--depth", png, png_scale=1 / 5000, depth=True)
    np.testing.assert_allclose(tum, mm / 5, rtol=1e-6)
    with pytest.raises(InvalidArgumentError, match=r"^--depth: .*d8\.png: got an 8-bit PNG"):
        load_map("--depth", _png(tmp_path / "d8.png", np.ones((2, 2), np.uint8)), depth=True)
    amp8 = load_map("--tof-amplitude", tmp_path / "d8.png")  # any map but depth may be 8-bit
    assert amp8.dtype == np.float32
    npz = tmp_path / "r.npz"
    np.savez(npz, depth=np.full((2, 3), 1.5, np.float32), amplitude=np.ones((2, 3)))
    np.testing.assert_array_equal(load_map("--depth", npz, depth=True), np.full((2, 3), 1.5))
    with pytest.raises(InvalidArgumentError, match=r"expected exactly one array"):
        load_map("--tof-amplitude", npz)
    for dtype in (np.uint16, np.int32, np.bool_):  # raw millimetres, or a mask, are not metres
        np.save(tmp_path / "i.npy", np.ones((2, 2), dtype))
        with pytest.raises(InvalidArgumentError, match=r"^--depth: .*i\.npy: got dtype .*metres"):
            load_map("--depth", tmp_path / "i.npy", depth=True)
    from rgbd_rs.cli.fusion import DEPTH_PNG_SCALE, depth_png_scale

    assert depth_png_scale("--depth", png, None) == DEPTH_PNG_SCALE
    assert depth_png_scale("--depth", png, 2e-4) == 2e-4
    with pytest.raises(InvalidArgumentError, match=r"^--depth-scale: given with --depth .*r\.npz"):
        depth_png_scale("--depth", npz, 1e-3)


def _save(path: Path, arr: np.ndarray) -> Path:
    np.save(path, arr)
    return path


def _edit_json(src: Path, dst: Path, fx: object) -> Path:
    import json

    doc = json.loads(src.read_text())
    if fx is None:
        del doc["tof"]["fx"]
    else:
        doc["tof"]["fx"] = fx
    dst.write_text(json.dumps(doc))
    return dst


@pytest.mark.parametrize(
    ("argv", "needles"),
    [
        (["eval", "fusion", "--synth", "x", "--limit", "0"], ("--limit", "got 0")),
        (["eval", "fusion", "--synth", "x", "--stride", "-1"], ("--stride", "got -1")),
        (["eval", "fusion", "--synth", "/nonexistent/ds"], ("--synth", "manifest.json")),
        (["eval", "fusion"], ("--synth/--middlebury",)),
        (["eval"], ("WHAT",)),
        (["synth", "--out", "OUT", "--scale", "1000"], ("--scale", "got 1000")),
        (["synth", "--out", "OUT", "--scale", "nan"], ("--scale",)),
        (["synth", "--out", "OUT", "--train", "-3"], ("--train", "got -3")),
        (["synth", "--out", "OUT", "--seed", "x"], ("--seed", "got 'x'")),
        (["reproject", "--frame", "a", "--calib", "b"], ("--out",)),
        (
            ["reproject", "--frame", "a", "--calib", "b", "--out", "o", "--splat-radius", "9"],
            ("--splat-radius", "got 9"),
        ),
        (["fuse", "--left", "a"], ("required",)),
        (["synth-indoor", "--out", "o", "--count", "0"], ("--count", "got 0")),
        (["synth-indoor", "--out", "o", "--shard", "-1/2"], ("--shard", "got '-1/2'")),
        (["semantic", "cache", "--frames", "x", "--out", "o", "--size", "-8x4"], ("got '-8x4'",)),
        (["nonsense"], ("invalid choice",)),
    ],
    ids=lambda v: " ".join(v) if isinstance(v, list) else None,
)
def test_bad_command_lines_end_in_one_line(
    argv: list[str], needles: tuple[str, ...], tmp_path: Path
) -> None:
    argv = [str(tmp_path / "out") if a == "OUT" else a for a in argv]
    res = run(*argv)
    _assert_one_line_error(res, *needles)
    assert not (tmp_path / "out").exists(), "rejected before anything was written"


def test_a_bound_copied_from_the_message_passes() -> None:
    """16/1080 printed as 0.0148148 was itself refused."""
    from rgbd_rs.cli._args import real

    parse = real(16 / 1080, 4, low_open=False)
    with pytest.raises(argparse.ArgumentTypeError) as refused:
        parse("0.0148148")
    bound = str(refused.value).split(">= ")[1].split(" ")[0]
    assert bound == "0.014814814814814815" and parse(bound) == 16 / 1080
    with pytest.raises(argparse.ArgumentTypeError, match=r"expected a number > 0 and <= 0\.9$"):
        real(0, 0.9)("1")


def test_eval_fusion_on_an_empty_split_is_one_line(tmp_path: Path) -> None:
    ds = tmp_path / "ds"
    made = run("synth", "--out", str(ds), "--train", "0", "--test", "1", "--scale", "0.05")
    assert made.returncode == 0, made.stderr
    res = run(
        "eval", "fusion", "--synth", str(ds), "--split", "train", "--out", str(tmp_path / "e")
    )
    _assert_one_line_error(res, "--synth: got", "no scene in its train split")
    # the training commands say the same of the split they read, before any work
    res = run("train", "confidence", "--data", str(ds), "--out", str(tmp_path / "t"))
    _assert_one_line_error(res, f"--data: got {ds} with no train scene", "rgbd synth --train N")
    empty = tmp_path / "empty"
    made = run("synth", "--out", str(empty), "--train", "1", "--test", "0", "--scale", "0.05")
    assert made.returncode == 0, made.stderr
    out = tmp_path / "c.pt"
    res = run("train", "calibrate-confidence", "--data", str(empty), "--out", str(out))
    _assert_one_line_error(res, f"--data: got {empty} with no test scene")
    assert not (tmp_path / "t").exists() and not out.exists()


def test_synth_scale_1000_is_refused_before_allocating(tmp_path: Path) -> None:
    """Also the library call behind it (the CLI's own check is argparse's)."""
    from rgbd_rs import InvalidArgumentError
    from rgbd_rs.data import write_dataset

    with pytest.raises(InvalidArgumentError, match=r"^scale: got 1000"):
        write_dataset(tmp_path / "ds", scale=1000.0)
    assert not (tmp_path / "ds").exists()


def test_unwritable_output_is_one_line(tmp_path: Path) -> None:
    blocker = tmp_path / "file"
    blocker.write_text("a file where the output folder should go")
    res = run("synth", "--out", str(blocker / "sub"), "--preview", "--scale", "0.02")
    _assert_one_line_error(res, "file")


def test_eval_and_train_are_groups_pipelines_extend() -> None:
    """`rgbd eval WHAT`: fusion registers its WHAT from its own module."""
    from rgbd_rs.cli._args import GROUPS, Commands

    assert set(GROUPS) == {"eval", "train"}
    res = run("eval", "--help")
    assert res.returncode == 0 and "fusion" in res.stdout
    # A later pipeline adds `rgbd eval segmentation` without touching fusion's module: every
    # pipeline registers with the same Commands, which shares the groups.
    from rgbd_rs.cli import PIPELINES
    from rgbd_rs.cli._args import Parser

    parser = Parser(prog="rgbd")
    commands = Commands(parser.add_subparsers(dest="command"))
    for pipeline in PIPELINES:
        pipeline.register(commands)
    commands.group_command("eval", "demo_what", lambda args: 0, help="h", description="d")
    assert parser.parse_args(["eval", "demo_what"]).run is not None
    assert parser.parse_args(["eval", "fusion"]).run is not None
    res = run("train", "--help")
    assert res.returncode == 0 and "confidence" in res.stdout


def test_a_warning_is_one_line_and_the_run_succeeds(
    fuse_inputs: dict[str, Path], tmp_path: Path
) -> None:
    dead = _save(tmp_path / "dead.npy", np.full((424, 512), np.nan, np.float32))
    res = run(*_fuse_argv(fuse_inputs, tof_depth=dead, out=tmp_path / "out"))
    assert res.returncode == 0, res.stderr
    assert res.stderr.strip().splitlines() == [
        "rgbd: warning: --tof-depth: no valid ToF pixel reaches the reference camera; returning "
        "the stereo-only LC result"
    ]
    assert (tmp_path / "out" / "fused.npz").is_file()


def test_a_folder_given_as_a_file_is_named(fuse_inputs: dict[str, Path], tmp_path: Path) -> None:
    res = run(*_fuse_argv(fuse_inputs, calib=tmp_path))
    _assert_one_line_error(res, "--calib", "is a folder")


def test_fuse_prints_the_search_range_and_each_inputs_coverage(
    fuse_inputs: dict[str, Path], tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    import re

    assert main(_fuse_argv(fuse_inputs, out=tmp_path / "a")) == 0
    out = capsys.readouterr().out
    # The wall at 22 px: the range covers it with a margin (26 px), searched in whole 16-px
    # steps (a fuzz: it printed 0-26 while the matcher searched 0-31).
    assert (
        "SGM search range: 0-31 px (from the ToF disparities: 26 px, searched in whole 16-px steps)"
        in out
    )
    cover = re.search(
        r"valid pixels on the right camera: ToF (\S+)%, SGM (\S+)% \(\w+\), either (\S+)%, "
        r"fused (\S+)%",
        out,
    )
    assert cover is not None, out
    tof, sgm, either, fused = (float(v) for v in cover.groups())
    assert tof > 90 and 50 < sgm < 97 and fused > 90  # SGM: nothing in the border band
    # Nothing an input measured is left blank.
    assert fused >= either - 0.05
    assert "fused pixels taken from one input where LC had no value or nothing to check" in out
    argv = [*_fuse_argv(fuse_inputs, out=tmp_path / "b"), "--reference", "left"]
    # The fixture's ToF sits below the right camera: the left one is the far camera.
    with warnings.catch_warnings():
        warnings.simplefilter("always")
        assert main([*argv, "--max-disparity", "40"]) == 0
    out, err = capsys.readouterr()
    assert "Fuse on the right camera: reference='right' (rgbd fuse --reference right)" in err
    assert (
        "SGM search range: 0-47 px (--max-disparity: 40 px, searched in whole 16-px steps)" in out
    )
    assert "valid pixels on the left camera" in out


def test_fuse_help_documents_the_calibration_layout() -> None:
    res = run("fuse", "--help")
    assert res.returncode == 0
    for needle in ("examples/calibration.json", '"tof_to_reference"', "baseline", "--reference"):
        assert needle in res.stdout, needle


@pytest.mark.parametrize("case", ["swapped images", "depth in millimetres"])
def test_implausible_input_is_one_line(
    case: str, fuse_inputs: dict[str, Path], tmp_path: Path
) -> None:
    if case == "swapped images":
        replace = {"left": fuse_inputs["--right"], "right": fuse_inputs["--left"]}
        needle, status = "rgbd: warning: --left/--right: the images look swapped", 0
    else:  # refused, as rgbd segment refuses it
        replace = {"tof_depth": _save(tmp_path / "mm.npy", np.full((424, 512), 1000.0))}
        needle, status = "rgbd: error: --tof-depth: the ToF depths look like millimetres", 2
    res = run(*_fuse_argv(fuse_inputs, out=tmp_path / "out", **replace))
    assert res.returncode == status, res.stderr
    lines = res.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith(needle), res.stderr


def test_png_and_camera_errors_name_the_file(
    tmp_path: Path, shared_data: Path, capfd: pytest.CaptureFixture[str]
) -> None:
    from rgbd_rs import RgbdError
    from rgbd_rs.data.calibration import load_camera
    from rgbd_rs.io import read_png

    good = (shared_data / "nyuv2" / "frames" / "0001_rgb.png").read_bytes()
    cut = tmp_path / "t.png"
    cut.write_bytes(good[: len(good) // 2])
    with pytest.raises(RgbdError, match=r"t\.png: corrupt or truncated image"):
        read_png(cut)
    assert "WARN" not in capfd.readouterr().err, "no OpenCV log line before our error"
    (tmp_path / "tail.png").write_bytes(good + b"\0\0")  # bytes after IEND still decode
    assert read_png(tmp_path / "tail.png").shape == (480, 640, 3)
    flipped = bytearray(good)
    flipped[len(good) // 2] ^= 0xFF  # inside an IDAT chunk: its CRC no longer matches
    (tmp_path / "f.png").write_bytes(bytes(flipped))
    with pytest.raises(RgbdError, match=r"f\.png: corrupt .*'IDAT' fails its CRC check"):
        read_png(tmp_path / "f.png")
    assert "libpng" not in capfd.readouterr().err, "no libpng line before our error"
    # A text chunk whose CRC fails is skipped, as libpng would (after a warning line).
    iend = good.rindex(b"IEND") - 4
    text = b"tEXtComment\0hello"
    bad_text = len(text[4:]).to_bytes(4, "big") + text + b"\0\0\0\0"  # a wrong CRC
    (tmp_path / "x.png").write_bytes(good[:iend] + bad_text + good[iend:])
    np.testing.assert_array_equal(read_png(tmp_path / "x.png"), read_png(cut.with_name("tail.png")))
    assert "libpng" not in capfd.readouterr().err
    # Valid CRCs, odd content: a junk colour profile reads silently (the pixels are fine); a
    # header that disagrees with the pixel data is refused with libpng's reason, not printed.
    import struct

    def chunk(kind: bytes, data: bytes) -> bytes:
        return (
            struct.pack(">I", len(data)) + kind + data + struct.pack(">I", zlib.crc32(kind + data))
        )

    sig, ihdr, rest = good[:8], good[8:33], good[33:]
    (tmp_path / "icc.png").write_bytes(
        sig + ihdr + chunk(b"iCCP", b"icc\0\0" + zlib.compress(b"junk")) + rest
    )
    assert read_png(tmp_path / "icc.png").shape == (480, 640, 3)
    small = chunk(b"IHDR", struct.pack(">IIBBBBB", 3, 2, 8, 2, 0, 0, 0))
    (tmp_path / "hdr.png").write_bytes(sig + small + rest)
    with pytest.raises(RgbdError, match=r"hdr\.png: corrupt or truncated image \(IDAT: Too much"):
        read_png(tmp_path / "hdr.png")
    err = capfd.readouterr().err
    assert "libpng" not in err and "grfmt" not in err, err
    cam = tmp_path / "c.json"
    cam.write_text('{"fx": -500, "fy": 500, "cx": 320, "cy": 240, "width": 640, "height": 480}')
    with pytest.raises(
        RgbdError, match=r"c\.json: invalid calibration \(camera .camera.: fx: got -5"
    ):
        load_camera(cam)


def test_fuse_precision_float32_is_the_float32_estimators_result(
    fuse_inputs: dict[str, Path], tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    from rgbd_rs.data import load_rig
    from rgbd_rs.fusion import fuse
    from rgbd_rs.io import read_png
    from rgbd_rs.nn.confidence import WEIGHTS_FAR, ConfidenceEstimator

    g = fuse_inputs
    inputs = (
        read_png(g["--left"]),
        read_png(g["--right"]),
        np.load(g["--tof-depth"]),
        np.load(g["--tof-amplitude"]),
        load_rig(g["--calib"]),
    )
    # On the camera far from the ToF (the left one here), --precision alone keeps the network
    # fuse() picks there.
    for name, reference, weights in (
        ("f32", [], None),
        ("far", ["--reference", "left"], WEIGHTS_FAR),
    ):
        argv = [*_fuse_argv(g, out=tmp_path / name), "--precision", "float32", *reference]
        net = ConfidenceEstimator.load(weights, precision="float32")
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")  # the far camera's warning (tested elsewhere)
            assert main(argv) == 0
            want = fuse(*inputs, confidence=net, reference="left" if reference else None)
        capsys.readouterr()
        saved = np.load(tmp_path / name / "fused.npz")["disparity"]
        np.testing.assert_array_equal(saved, want.disparity)


def test_fuse_precision_choices_are_the_libraries() -> None:
    """The parser spells the choices out (building it must not import torch): they must stay
    the ConvNet's PRECISIONS."""
    from rgbd_rs.cli import build_parser
    from rgbd_rs.nn.confidence import PRECISIONS

    parser = build_parser()
    fuse = next(
        a
        for a in parser._subparsers._group_actions[0].choices["fuse"]._actions  # type: ignore[union-attr]
        if "--precision" in a.option_strings
    )
    assert tuple(fuse.choices or ()) == PRECISIONS


def test_flagged_words_the_error_and_can_let_warnings_through_as_they_come() -> None:
    import warnings

    from rgbd_rs.cli._args import flagged
    from rgbd_rs.errors import InvalidArgumentError

    when: list[str] = []

    def call() -> None:
        warnings.warn("exclude: a warning", RuntimeWarning, stacklevel=1)
        when.append("after the warning")
        raise InvalidArgumentError("exclude: got 'x', expected a training shape")

    for too, shown in ((True, "--exclude-names: a warning"), (False, "exclude: a warning")):
        when.clear()
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            with pytest.raises(InvalidArgumentError, match=r"^--exclude-names: got 'x'"):
                flagged({"exclude": "--exclude-names"}, call, warnings_too=too)
        assert [str(w.message) for w in caught] == [shown] and when


def test_fuse_preview_shows_the_source_and_a_saturated_depth_png_is_named(
    fuse_inputs: dict[str, Path], tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """The preview carries the source map the guide tells users to mask; a rig in millimetres
    (every length x1000) fuses the same disparities, whose depths overflow depth_mm.png: said."""
    import dataclasses

    import cv2

    from rgbd_rs.camera import Pose, StereoRig
    from rgbd_rs.data import load_rig, save_rig

    assert main(_fuse_argv(fuse_inputs, out=tmp_path / "m")) == 0
    preview = cv2.imread(str(tmp_path / "m" / "preview.png"))
    assert preview.shape[0] > 900, "three rows of panels: the source map is the seventh"
    capsys.readouterr()
    rig = load_rig(fuse_inputs["--calib"])
    p = rig.tof_to_reference
    mm = dataclasses.replace(
        rig,
        stereo=StereoRig(rig.stereo.left, rig.stereo.right, rig.stereo.baseline * 1000),
        tof_to_reference=Pose(p.rotation, p.translation * 1000),
    )
    save_rig(tmp_path / "mm.json", mm)
    metres = float(np.load(fuse_inputs["--tof-depth"]).flat[0])
    np.save(tmp_path / "depth_mm.npy", np.full((424, 512), metres * 1000, np.float32))
    argv = _fuse_argv(fuse_inputs, calib=tmp_path / "mm.json", tof_depth=tmp_path / "depth_mm.npy")
    assert main([*argv[:-2], "--out", str(tmp_path / "mm")]) == 0
    err = capsys.readouterr().err
    assert "rgbd: warning: depth_mm.png: 100% of the pixels lie beyond 65.535 m" in err, err
    a = np.load(tmp_path / "m" / "fused.npz")["disparity"]
    b = np.load(tmp_path / "mm" / "fused.npz")["disparity"]
    # The same disparities, up to float32 rounding of a depth ~0.98 m x 1000 (one pixel of
    # 32,400 flips between two LC hypotheses).
    assert np.array_equal(np.isnan(a), np.isnan(b))
    assert (np.abs(a - b)[~np.isnan(a)] <= 0.01).mean() >= 0.999


def test_an_output_folder_holding_an_input_under_an_output_name_is_refused(
    fuse_inputs: dict[str, Path], tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """A fuzz found `rgbd stereo`, `fuse` and `segment` overwriting an input that sat in --out
    under the name of one of their outputs (a left image called disparity.png): refused before
    any work, the input left as it was."""
    import shutil

    out = tmp_path / "out"
    out.mkdir()
    left = out / "disparity.png"
    shutil.copy(fuse_inputs["--left"], left)
    before = left.read_bytes()
    right = str(fuse_inputs["--right"])
    stereo = ["stereo", "--left", str(left), "--right", right, "--max-disparity", "30"]
    assert main([*stereo, "--out", str(out)]) == 2
    err = capsys.readouterr().err
    assert err.startswith("rgbd: error: --out: ") and "is the input --left" in err, err
    assert left.read_bytes() == before and sorted(p.name for p in out.iterdir()) == [left.name]
    # The same file through a different spelling of the folder, or through a link named as
    # the output (the message names the output it would write).
    assert main([*stereo, "--out", str(out / ".." / "out")]) == 2
    capsys.readouterr()
    linked = tmp_path / "linked"
    linked.mkdir()
    (linked / "preview.png").symlink_to(left)
    assert main([*stereo, "--out", str(linked)]) == 2
    assert (
        "would get a new preview.png, but that file is the input --left" in capsys.readouterr().err
    )
    assert main(_fuse_argv(fuse_inputs, left=left, out=out)) == 2
    assert "is the input --left" in capsys.readouterr().err
    assert left.read_bytes() == before
    overlay = out / "overlay.png"
    shutil.copy(fuse_inputs["--left"], overlay)
    seg = ["segment", "--rgb", str(overlay), "--depth", str(fuse_inputs["--tof-depth"])]
    seg += ["--calib", str(fuse_inputs["--calib"]), "--out", str(out), "--segments", "8"]
    assert main(seg) == 2
    assert "is the input --rgb" in capsys.readouterr().err
    # The same inputs with another output folder run.
    assert main([*stereo, "--out", str(tmp_path / "elsewhere")]) == 0
    assert left.read_bytes() == before


def test_disparities_past_the_png_range_are_said(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """A fuzz found `rgbd stereo` writing 323 px as 255.996 in disparity.png without a word."""
    from rgbd_rs.cli._maps import disparity_png_note
    from rgbd_rs.io import read_png, write_png

    assert disparity_png_note(np.array([[255.99, np.nan, 0.0]]), "x.npz") is None
    note = disparity_png_note(np.array([[300.0, 10.0, np.nan, 256.5]]), "x.npz")
    assert note is not None and "2 pixels (50.0%)" in note and "up to 300.0 px" in note
    tex = np.random.default_rng(1).integers(0, 255, (60, 700, 3)).astype(np.uint8)
    write_png(tmp_path / "l.png", tex[:, :400])
    write_png(tmp_path / "r.png", tex[:, 260:660])  # 260 px of disparity
    argv = ["stereo", "--left", str(tmp_path / "l.png"), "--right", str(tmp_path / "r.png")]
    assert main([*argv, "--max-disparity", "300", "--out", str(tmp_path / "o")]) == 0
    err = capsys.readouterr().err
    assert "rgbd: warning: disparity.png: " in err and "disparity.npz holds them" in err, err
    with np.load(tmp_path / "o" / "disparity.npz") as z:
        assert np.nanmedian(z["disparity"][:, 280:]) == pytest.approx(260, abs=0.5)
    assert read_png(tmp_path / "o" / "disparity.png").max() == 65535


def test_an_unwritable_out_is_refused_before_the_work(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """A fuzz found `rgbd train shapes --out /proc/x` failing only after a whole epoch, and
    `train calibrate-confidence` naming a temporary file: every command checks --out first."""
    a_file = tmp_path / "a_file"
    a_file.write_text("x")
    for out, said in (
        ("/proc/x", "nothing can be written in /proc"),
        (str(a_file / "x.pt"), "a_file is a file: expected a path in a folder"),
    ):
        # The inputs do not exist either: --out is the first thing checked.
        argv = ["train", "shapes", "--cache", str(tmp_path / "none"), "--out", out]
        assert main(argv) == 2
        err = capsys.readouterr().err
        assert err.startswith(f"rgbd: error: --out: got {out}, but ") and said in err, err
    assert main(["train", "shapes", "--cache", str(tmp_path / "none"), "--out", str(tmp_path)]) == 2
    assert "--out" not in capsys.readouterr().err  # a writable --out: the next error is another
    assert sorted(p.name for p in tmp_path.iterdir()) == ["a_file"]  # the probe left nothing
    # A link to nowhere (a review found the work done, then "File exists").
    (tmp_path / "dangling").symlink_to(tmp_path / "nowhere" / "zz")
    for out in (tmp_path / "dangling", tmp_path / "dangling" / "sub"):
        assert main(["train", "shapes", "--cache", str(tmp_path / "none"), "--out", str(out)]) == 2
        err = capsys.readouterr().err
        assert "dangling is a link to" in err and "which does not exist" in err, err


def test_values_the_fuzz_found_taken_silently_are_refused(
    fuse_inputs: dict[str, Path], tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """A --stride past --radius was capped without a word, an empty --labeler read as auto,
    and --segments accepted counts the over-segmentation refuses (or takes minutes on)."""
    from rgbd_rs.cli.segmentation import MAX_SEGMENTS

    argv = _fuse_argv(fuse_inputs, out=tmp_path / "f")
    assert main([*argv, "--radius", "3", "--stride", "4"]) == 2
    assert (
        capsys.readouterr().err == "rgbd: error: --stride: got 4, expected at most --radius (3)\n"
    )
    seg = ["segment", "--rgb", str(fuse_inputs["--left"]), "--depth", str(tmp_path / "none.npy")]
    seg += ["--calib", str(fuse_inputs["--calib"]), "--out", str(tmp_path / "s")]
    assert main([*seg, "--labeler", ""]) == 2
    assert "--labeler: got an empty value" in capsys.readouterr().err
    with pytest.raises(SystemExit):
        main([*seg, "--segments", str(MAX_SEGMENTS + 1)])
    assert "--segments" in capsys.readouterr().err


def test_a_dead_tof_frame_says_where_the_search_range_came_from(
    fuse_inputs: dict[str, Path], tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """A fuzz found `SGM search range: 0-160 px (from the ToF disparities)` printed for a ToF
    frame without a valid pixel."""
    dead = tmp_path / "dead.npy"
    np.save(dead, np.full((424, 512), np.nan, np.float32))
    with warnings.catch_warnings():
        warnings.simplefilter("always")  # the dead frame's warning, printed by the CLI
        assert main(_fuse_argv(fuse_inputs, tof_depth=dead, out=tmp_path / "o")) == 0
    dead_out = capsys.readouterr().out
    assert "(no ToF disparity: the largest range the width allows" in dead_out, dead_out
    # A handful of valid pixels bound nothing either (one pixel capped the search at its own
    # disparity, and SGM missed every nearer surface): the widest range, a warning, the reason.
    few = np.load(fuse_inputs["--tof-depth"])
    keep = np.zeros(few.shape, bool)
    keep[200:204, 250:254] = True
    np.save(tmp_path / "few.npy", np.where(keep, few, np.nan).astype(np.float32))
    argv = _fuse_argv(fuse_inputs, tof_depth=tmp_path / "few.npy", out=tmp_path / "f")
    with warnings.catch_warnings():
        warnings.simplefilter("always")  # printed by the CLI
        assert main(argv) == 0
    out, err = capsys.readouterr()
    assert "rgbd: warning: --tof-depth: valid ToF pixels cover 0.07" in err, err
    assert "too few to bound the stereo search" in err and "--max-disparity" in err
    assert "(too few ToF disparities: the largest range the width allows" in out, out
    widest = dead_out.split("SGM search range: ")[1].split(" px")[0]
    assert f"SGM search range: {widest} px (too few" in out


def test_train_confidence_names_a_data_folder_without_a_dataset(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """A fuzz found `nonexist/manifest.json: file not found` without the flag that named it."""
    argv = ["train", "confidence", "--data", str(tmp_path / "none"), "--out", str(tmp_path / "o")]
    assert main(argv) == 2
    err = capsys.readouterr().err
    assert err.startswith(f"rgbd: error: --data: got {tmp_path / 'none'}, expected a dataset"), err


def test_calibrate_confidence_refuses_a_folder_as_its_checkpoint_first(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """A fuzz found a folder --out refused only after every scene, naming an internal `path`."""
    argv = ["train", "calibrate-confidence", "--data", str(tmp_path / "none")]
    assert main([*argv, "--out", str(tmp_path)]) == 2
    err = capsys.readouterr().err
    want = f"--out: got {tmp_path}, a folder; expected the calibrated checkpoint's file"
    assert err == f"rgbd: error: {want}\n"
