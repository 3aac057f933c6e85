"""A resumed ``rgbd train shapes`` run must repeat the recipe fields that shape training but
not the network (split, augmentation, loss): they are recorded in the checkpoint when not at
their defaults, and a resume with other values is refused, naming the field and both values."""

from __future__ import annotations

from pathlib import Path

import pytest

from modelnet_packs import modelnet10_subset
from rgbd_rs.cli import main
from rgbd_rs.errors import RgbdError
from rgbd_rs.nn.checkpoint import load_checkpoint
from rgbd_rs.nn.train import TrainConfig
from rgbd_rs.shapes.dataset import InputSpec, build_cache
from rgbd_rs.shapes.train import ShapeRecipe, train_shapes


@pytest.fixture(scope="module")
def cache(tmp_path_factory: pytest.TempPathFactory, shared_data: Path) -> Path:
    root = tmp_path_factory.mktemp("shapes_resume")
    pack = modelnet10_subset(shared_data, root / "pack.npz", (1, 5), ((0, 4), (1, 1)))
    spec = InputSpec(representations=("volume",), normalisation="standardize")
    build_cache(pack, root / "cache", spec=spec, quiet=True)
    return root / "cache"


def _cfg(epochs: int) -> TrainConfig:
    return TrainConfig(epochs=epochs, batch_size=4, lr=0.05, seed=1, device="cpu")


def test_default_recipe_records_nothing_new(cache: Path, tmp_path: Path) -> None:
    train_shapes(cache, tmp_path, recipe=ShapeRecipe(width=2), config=_cfg(1), quiet=True)
    norm = load_checkpoint(tmp_path / "last.pt").normalisation
    assert "recipe" not in norm and "exclude" not in norm


@pytest.mark.parametrize(
    ("change", "what"),
    [
        ({"label_smoothing": 0.2}, r"'label_smoothing': 0\.1.*-> \{.*'label_smoothing': 0\.2"),
        (
            {"mixup": 0.0},
            r"'mixup': 0\.3\} -> \{'val_fraction': 0\.5, 'label_smoothing': 0\.1\}\. ",
        ),
        ({"mirror": True}, r"-> \{.*'mirror': True"),
        ({"val_fraction": 0.25}, r"'val_fraction': 0\.5.*'val_fraction': 0\.25"),
    ],
)
def test_resume_refuses_another_recipe(
    cache: Path, tmp_path: Path, change: dict[str, object], what: str
) -> None:
    base = {"width": 2, "label_smoothing": 0.1, "mixup": 0.3, "val_fraction": 0.5}
    train_shapes(cache, tmp_path, recipe=ShapeRecipe(**base), config=_cfg(1), quiet=True)  # type: ignore[arg-type]
    rec = load_checkpoint(tmp_path / "last.pt").normalisation["recipe"]
    assert rec == {"val_fraction": 0.5, "label_smoothing": 0.1, "mixup": 0.3}
    other = ShapeRecipe(**(base | change))  # type: ignore[arg-type]
    with pytest.raises(
        RgbdError, match=r"cannot resume: normalisation\['recipe'\] differs: \{.*" + what
    ):
        train_shapes(cache, tmp_path, recipe=other, config=_cfg(2), quiet=True)
    # the same recipe resumes (one more epoch), and --no-resume starts afresh with the other
    train_shapes(cache, tmp_path, recipe=ShapeRecipe(**base), config=_cfg(2), quiet=True)  # type: ignore[arg-type]
    assert load_checkpoint(tmp_path / "last.pt").epoch == 2
    train_shapes(cache, tmp_path, recipe=other, config=_cfg(1), resume=False, quiet=True)
    assert load_checkpoint(tmp_path / "last.pt").epoch == 1


def test_cli_names_the_difference(
    cache: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    argv = ["train", "shapes", "--cache", str(cache), "--width", "2", "--epochs", "1"]
    argv += ["--quiet", "--device", "cpu", "--out", str(tmp_path / "run")]
    assert main([*argv, "--label-smoothing", "0.1"]) == 0
    capsys.readouterr()
    assert main([*argv, "--epochs", "2"]) == 2
    err = capsys.readouterr().err
    assert "{'label_smoothing': 0.1} -> None" in err and "--no-resume" in err


def test_a_run_from_before_the_record_still_resumes(cache: Path, tmp_path: Path) -> None:
    """A checkpoint written before recipes were recorded resumes with a warning (its recipe
    cannot be checked), keeping its old record."""
    import torch

    recipe = ShapeRecipe(width=2, label_smoothing=0.1)
    train_shapes(cache, tmp_path, recipe=recipe, config=_cfg(1), quiet=True)
    raw = torch.load(tmp_path / "last.pt", map_location="cpu", weights_only=False)
    del raw["normalisation"]["recipe"]
    torch.save(raw, tmp_path / "last.pt")
    with pytest.warns(RuntimeWarning, match=r"written before runs recorded their recipe"):
        train_shapes(cache, tmp_path, recipe=recipe, config=_cfg(2), quiet=True)
    ckpt = load_checkpoint(tmp_path / "last.pt")
    assert ckpt.epoch == 2 and "recipe" not in ckpt.normalisation
