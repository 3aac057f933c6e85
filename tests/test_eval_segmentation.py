"""rgbd_rs.segmentation.evaluate and ``rgbd eval segmentation`` on a couple of NYUv2 frames with
the scikit-image peers (one- or two-point grids, so it stays fast)."""

from __future__ import annotations

import importlib
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pytest

pytest.importorskip("skimage")

from bad_input import Case, check, params
from rgbd_rs import InvalidArgumentError, metrics
from rgbd_rs.data import data_root
from rgbd_rs.data.nyuv2 import NYUV2_CAMERA, load_nyuv2_frame, region_ground_truth
from rgbd_rs.io import read_png
from rgbd_rs.segmentation import evaluate as E

ROOT = data_root()
pytestmark = pytest.mark.skipif(
    ROOT is None or not (ROOT / "nyuv2" / "frames").is_dir(), reason="NYUv2 frames not found"
)

SLIC = E.Method("slic (RGB)", E.slic_rgb, ({"n_segments": 25}, {"n_segments": 200}))
FZ_D = E.Method(
    "felzenszwalb (RGB-D)",
    E.felzenszwalb_rgbd,
    ({"scale": 300, "min_size": 2500, "depth_weight": 100},),
)


def _not_yet() -> E.Segmenter:
    raise ImportError("cannot import name 'segment'")


def test_tiny_evaluation_with_the_peers(tmp_path: Path) -> None:
    missing = E.Method(E.OURS_MERGED, _not_yet, kind="ours")
    report = E.evaluate(
        [46, 47], tuning_frames=[1], methods=[SLIC, FZ_D, missing], out=tmp_path, quiet=True
    )
    assert report.frames == (46, 47) and report.tuning_frames == (1,)
    assert [s.name for s in report.scores] == ["slic (RGB)", "felzenszwalb (RGB-D)"]
    assert report.missing == {E.OURS_MERGED: "cannot import name 'segment'"}
    assert report.count_match is None and "ours not available" in report.count_line()

    # The tuning kept the grid point with the lower VoI on frame 1.
    frame = load_nyuv2_frame(1)
    gt = region_ground_truth(frame.label40)
    vois = [
        metrics.variation_of_information(
            E.slic_rgb(n_segments=int(p["n_segments"]))(frame.rgb, frame.depth, NYUV2_CAMERA), gt
        )
        for p in SLIC.grid
    ]
    slic = report.scores[0]
    assert slic.params == SLIC.grid[int(np.argmin(vois))]
    assert slic.tuning_voi == pytest.approx(min(vois))
    assert np.isnan(report.scores[1].tuning_voi)  # one grid point: not tuned

    # The means are the per-frame metrics averaged.
    run = E.slic_rgb(n_segments=int(slic.params["n_segments"]))
    per = []
    for index in (46, 47):
        f = load_nyuv2_frame(index)
        labels = run(f.rgb, f.depth, NYUV2_CAMERA)
        g = region_ground_truth(f.label40)
        per.append(
            (
                metrics.variation_of_information(labels, g),
                metrics.rand_index(labels, g),
                metrics.boundary_recall(labels, g, tolerance=E.BOUNDARY_TOLERANCE),
                metrics.undersegmentation_error(labels, g),
                len(np.unique(labels)),
            )
        )
    want = np.mean(per, axis=0)
    got = (
        slic.voi,
        slic.rand_index,
        slic.boundary_recall,
        slic.undersegmentation_error,
        slic.segments,
    )
    np.testing.assert_allclose(got, want, rtol=1e-9)
    for s in report.scores:
        assert 0 < s.voi < 10 and 0.5 < s.rand_index <= 1 and s.seconds > 0
        assert 0 < s.boundary_recall <= 1 and 0 <= s.undersegmentation_error <= 1

    table = report.table()
    assert len(table.splitlines()) == 2 + 3
    assert "| slic (RGB) | n_segments=" in table and "not available" in table
    # One figure per frame: 3 x 2 panels of 320 px (with the grid's gaps and the depth bar).
    for name in ("0046", "0047"):
        fig = read_png(tmp_path / f"{name}.png")
        assert 3 * E.PANEL_WIDTH <= fig.shape[1] <= 3 * E.PANEL_WIDTH + 64
        assert fig.shape[0] > 2 * 240


def test_count_match_line() -> None:
    # A stand-in for our over-segmentation (SLIC itself): same count, so same boundary recall.
    fake = E.Method(E.OURS_OVER, E.slic_rgb, ({"n_segments": 100},), "ours")
    report = E.evaluate([46], tuning_frames=[46], methods=[fake], quiet=True)
    c = report.count_match
    assert c is not None
    assert abs(c.segments_slic - c.segments_ours) <= 0.1 * c.segments_ours
    assert 150 < c.segments_ours < 400  # COUNT_MATCH_SEGMENTS clusters requested
    assert c.boundary_recall_ours == pytest.approx(c.boundary_recall_slic, abs=0.05)
    assert "ours 0." in report.count_line() and "vs SLIC 0." in report.count_line()


def test_our_stages_plug_in(monkeypatch: pytest.MonkeyPatch) -> None:
    """Ours through stand-in stages with the announced APIs: features -> object with .vectors,
    oversegment(vectors, n_segments=, seed=), segment(...) -> .labels / .over. The same-count
    line reuses the pipeline's over-segmentation instead of computing it again."""
    calls = {"oversegment": 0, "segment": 0}

    def features(rgb: np.ndarray, depth: np.ndarray, camera: object) -> SimpleNamespace:
        return SimpleNamespace(vectors=rgb)

    def oversegment(vectors: np.ndarray, n_segments: int, *, seed: int) -> np.ndarray:
        calls["oversegment"] += 1
        return E.slic_rgb(n_segments=n_segments)(vectors, np.empty(0, np.float32), NYUV2_CAMERA)

    def segment(
        rgb: np.ndarray,
        depth: np.ndarray,
        camera: object,
        *,
        labeler: object = "auto",
        n_segments: int = 9,
        seed: int = 1,
    ) -> SimpleNamespace:
        assert labeler is None, "the fit-only row runs without a ConvNet"
        calls["segment"] += 1
        over = E.slic_rgb(n_segments=n_segments)(rgb, depth, camera)  # type: ignore[arg-type]
        return SimpleNamespace(over=over, labels=over // 8)

    for module, fn in (("features", features), ("oversegment", oversegment), ("pipeline", segment)):
        mod = importlib.import_module(f"rgbd_rs.segmentation.{module}")
        monkeypatch.setattr(mod, fn.__name__, fn)
    shown: dict[str, np.ndarray] = {}
    monkeypatch.setattr(
        E, "frame_figure", lambda path, frame, gt, results, peer: shown.update(results)
    )
    ours = [m for m in E.default_methods() if m.kind == "ours" and m.name != E.OURS_FULL]
    report = E.evaluate([46], tuning_frames=[1], methods=ours, quiet=True, out=Path("unused"))
    assert [s.name for s in report.scores] == [E.OURS_OVER, E.OURS_MERGED]
    # Tuning: both grids on frame 1; evaluation: once more each, and no third over-segmentation
    # for the same-count line when the merging was tuned to start from the same clusters (its
    # over-segmentation is reused).
    merged = report.scores[1]
    reused = merged.params["n_segments"] == E.COUNT_MATCH_SEGMENTS
    assert calls == {
        "oversegment": len(E.OVERSEGMENT_GRID) + 1 + (0 if reused else 1),
        "segment": len(E.MERGE_GRID) + 1,
    }
    assert merged.params in E.MERGE_GRID and not np.isnan(merged.tuning_voi)
    # The figure shows the over-segmentation the merging started from (the stand-in merges
    # by labels // 8), not the same-count line's.
    np.testing.assert_array_equal(shown[E.OURS_OVER] // 8, shown[E.OURS_MERGED])
    c = report.count_match
    assert c is not None and 150 < c.segments_ours < 400


def test_slic_at_matches_the_count() -> None:
    rgb = load_nyuv2_frame(46).rgb
    for target in (37, 150):
        got = len(np.unique(E._slic_at(rgb, target)))
        assert abs(got - target) <= 0.15 * target, (target, got)


def test_peers_take_depth_into_account() -> None:
    frame = load_nyuv2_frame(46)
    flat = np.full_like(frame.depth, 2.0)
    for make in (
        lambda w: E.slic_rgbd(n_segments=50, depth_weight=w),
        lambda w: E.felzenszwalb_rgbd(scale=300, min_size=500, depth_weight=w),
    ):
        with_depth = make(100)(frame.rgb, frame.depth, NYUV2_CAMERA)
        without = make(100)(frame.rgb, flat, NYUV2_CAMERA)
        assert not np.array_equal(with_depth, without)
    # Missing depth is 0 in the depth channel, not an error.
    holes = frame.depth.copy()
    holes[:50] = np.nan
    assert E.slic_rgbd(n_segments=50, depth_weight=10)(frame.rgb, holes, NYUV2_CAMERA).min() >= 0


def test_cli_writes_the_table(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    from rgbd_rs.cli import _args, segmentation_eval

    monkeypatch.setattr(E, "default_methods", lambda labeler="auto": [SLIC])
    monkeypatch.setattr(E, "nyuv2_frames", lambda split: [46])
    parser = _args.Parser(prog="rgbd")
    segmentation_eval.register(_args.Commands(parser.add_subparsers(dest="command")))
    args = parser.parse_args(
        ["eval", "segmentation", "--tuning-frames", "1", "--out", str(tmp_path), "--quiet"]
    )
    assert args.run(args) == 0
    text = (tmp_path / "table.md").read_text()
    assert "Parameters chosen by mean VoI on 1 train frames:" in text
    assert "- slic (RGB): n_segments=" in text
    assert "| slic (RGB) |" in text and "ours not available" in text
    assert (tmp_path / "0046.png").is_file()


BAD: list[Case] = [
    Case("evaluate", lambda: E.evaluate("val"), InvalidArgumentError, r"^split: got 'val'"),
    Case(
        "evaluate",
        lambda: E.evaluate([0]),
        InvalidArgumentError,
        r"^frames\[0\]: got 0",
        "index",
    ),
    Case("evaluate", lambda: E.evaluate([]), InvalidArgumentError, r"^frames: got no frame", "e"),
    Case("evaluate", lambda: E.evaluate(7), InvalidArgumentError, r"^frames: got 7", "int"),
    Case(
        "evaluate",
        lambda: E.evaluate([46], methods=[]),
        InvalidArgumentError,
        r"^methods: got \[\]",
        "no methods",
    ),
    Case(
        "evaluate",
        lambda: E.evaluate([46], methods=[E.Method("x", _not_yet)]),
        InvalidArgumentError,
        r"^methods: none is available",
        "none available",
    ),
    Case(
        "evaluate",
        lambda: E.evaluate([46], quiet="yes"),
        InvalidArgumentError,
        r"^quiet: got 'yes'",
        "quiet",
    ),
    Case(
        "evaluate",
        lambda: E.evaluate([46], out=3),
        InvalidArgumentError,
        r"^out: got 3",
        "out",
    ),
    Case(
        "Method.segmenter",
        lambda: SLIC.segmenter({"k": 3}),
        InvalidArgumentError,
        r"^params: got \{'k': 3\}, which slic \(RGB\) does not take",
    ),
    Case(
        "Method.segmenter",
        lambda: SLIC.segmenter({"n_segments": 0}),
        InvalidArgumentError,
        r"^n_segments: got 0",
        "value",
    ),
    Case(
        "Method.segmenter",
        lambda: FZ_D.segmenter({"scale": -1, "min_size": 1, "depth_weight": 1}),
        InvalidArgumentError,
        r"^scale: got -1",
        "scale",
    ),
]


@pytest.mark.parametrize("case", params(BAD))
def test_bad_input(case: Case) -> None:
    check(case)


def test_full_method_row_scores_the_labels() -> None:
    import torch

    from rgbd_rs.data.nyuv2 import LABEL13_NAMES
    from rgbd_rs.nn.semantic import SemanticNet
    from rgbd_rs.segmentation.labeling import SemanticLabeler

    torch.manual_seed(0)
    tiny = SemanticLabeler(SemanticNet(14, width=8, lcn_window=5), (80, 60), LABEL13_NAMES)
    full = [m for m in E.default_methods(labeler=tiny) if m.name == E.OURS_FULL]
    full = [E.Method(E.OURS_FULL, full[0].make, ({"n_segments": 60},), "ours")]
    report = E.evaluate([46], tuning_frames=[46], methods=full, quiet=True)
    assert [s.name for s in report.scores] == [E.OURS_FULL]
    sem = report.semantic
    assert sem is not None and sem.frames == 1
    labeled = int((load_nyuv2_frame(46).label13 > 0).sum())
    assert sem.network.sum() == sem.refined.sum() == labeled
    assert sem.network[0].sum() == 0, "unlabeled truth is left out"
    for acc in (*sem.network_accuracy, *sem.refined_accuracy):
        assert 0 <= acc <= 1
    assert "after segment refinement" in sem.table() and "| wall |" in sem.per_class_table()


def test_tuning_runs_of_the_full_method_are_not_scored() -> None:
    """The full method tuned on one frame, evaluated on another after a peer: the semantic
    scores hold the evaluation frame only (a tuning run's labels must not leak into them)."""
    import torch

    from rgbd_rs.data.nyuv2 import LABEL13_NAMES
    from rgbd_rs.nn.semantic import SemanticNet
    from rgbd_rs.segmentation.labeling import SemanticLabeler

    torch.manual_seed(0)
    tiny = SemanticLabeler(SemanticNet(14, width=8, lcn_window=5), (80, 60), LABEL13_NAMES)
    full = next(m for m in E.default_methods(labeler=tiny) if m.name == E.OURS_FULL)
    assert full.grid == E.MERGE_GRID and len(full.grid) > 1  # tuned like the peers
    full = E.Method(E.OURS_FULL, full.make, ({"n_segments": 30}, {"n_segments": 60}), "ours")
    report = E.evaluate([46], tuning_frames=[1], methods=[FZ_D, full], quiet=True)
    sem = report.semantic
    assert sem is not None and sem.frames == 1
    assert sem.network.sum() == int((load_nyuv2_frame(46).label13 > 0).sum())
