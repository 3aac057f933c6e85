"""A re-run into the same --out keeps the previous run's outputs until it has finished: an
interrupted or failed re-run leaves the last complete result (not an empty folder)."""

from __future__ import annotations

from pathlib import Path

import pytest

from rgbd_rs.cli import _args
from rgbd_rs.cli._args import PREVIOUS, _backup, finish_outputs, output_folder

OUTPUTS = ("a.txt", "b.txt", "merge/*.png")


def _first_run(out: Path) -> None:
    output_folder(out, OUTPUTS)
    for name in ("a.txt", "b.txt", "merge/0001.png"):
        (out / name).parent.mkdir(parents=True, exist_ok=True)
        (out / name).write_text("old " + name)
    (out / "notes.md").write_text("mine")
    finish_outputs(True)


def test_an_interrupted_rerun_puts_the_previous_outputs_back(tmp_path: Path) -> None:
    _first_run(tmp_path)
    output_folder(tmp_path, OUTPUTS)
    assert not (tmp_path / "a.txt").exists(), "the new run starts from a clean folder"
    (tmp_path / "a.txt").write_text("new, partial")
    finish_outputs(False)  # interrupted
    assert (tmp_path / "a.txt").read_text() == "old a.txt"
    assert (tmp_path / "merge" / "0001.png").read_text() == "old merge/0001.png"
    assert (tmp_path / "notes.md").read_text() == "mine"
    assert not list(tmp_path.glob(PREVIOUS + "*"))


def test_a_finished_rerun_drops_them(tmp_path: Path) -> None:
    _first_run(tmp_path)
    output_folder(tmp_path, OUTPUTS)
    (tmp_path / "a.txt").write_text("new")
    finish_outputs(True)
    assert (tmp_path / "a.txt").read_text() == "new"
    assert not (tmp_path / "b.txt").exists(), "a stale output of the previous run is gone"
    assert not list(tmp_path.glob(PREVIOUS + "*")) and not _args._STAGED


def test_a_run_killed_outright_is_recovered_by_the_next(tmp_path: Path) -> None:
    _first_run(tmp_path)
    output_folder(tmp_path, OUTPUTS)
    (tmp_path / "a.txt").write_text("partial")
    _args._STAGED.clear()  # SIGKILL: nothing finished the folder
    output_folder(tmp_path, OUTPUTS)  # the next run: the last complete outputs set aside again
    finish_outputs(False)
    assert (tmp_path / "a.txt").read_text() == "old a.txt"


def test_cli_rerun_that_fails_keeps_the_outputs(
    shared_data: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    from rgbd_rs.cli import main
    from rgbd_rs.data.stereo_scenes import load_stereo_scene
    from rgbd_rs.io import write_png

    scene = load_stereo_scene("Tsukuba")
    write_png(tmp_path / "l.png", scene.left)
    write_png(tmp_path / "r.png", scene.right)
    argv = ["stereo", "--left", str(tmp_path / "l.png"), "--right", str(tmp_path / "r.png")]
    argv += ["--max-disparity", "20", "--out", str(tmp_path / "o")]
    assert main(argv) == 0
    before = (tmp_path / "o" / "disparity.npz").read_bytes()
    import rgbd_rs.cli.stereo as st

    def broken(*args: object, **kwargs: object) -> None:
        raise KeyboardInterrupt  # Ctrl-C while the previews are drawn

    monkeypatch.setattr(st, "_warn_if_swapped", broken)
    assert main(argv) == 130
    assert (tmp_path / "o" / "disparity.npz").read_bytes() == before
    assert {p.name for p in (tmp_path / "o").iterdir()} == {
        "disparity.npz",
        "disparity.png",
        "preview.png",
    }


def test_two_commands_in_one_folder_keep_their_own(tmp_path: Path) -> None:
    """A second command writing into the same --out while the first runs does not take the
    first one's set-aside outputs for a dead run's."""
    _first_run(tmp_path)
    other = ("x.md",)
    (tmp_path / "x.md").write_text("other's old")
    output_folder(tmp_path, OUTPUTS)  # the first command re-runs...
    output_folder(tmp_path, other)  # ...while the other one starts
    assert _backup(tmp_path, OUTPUTS) != _backup(tmp_path, other)
    (tmp_path / "x.md").write_text("other's new")
    (tmp_path / "a.txt").write_text("new")
    finish_outputs(True)
    assert (tmp_path / "a.txt").read_text() == "new"
    assert (tmp_path / "x.md").read_text() == "other's new"
