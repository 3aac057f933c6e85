"""Bad torch devices: every network loader, the trainer's config and each ``--device`` flag
refuse them naming the argument (a bad value used to end in a torch traceback)."""

from __future__ import annotations

import pytest
import torch

from bad_input import Case, check, params
from rgbd_rs.cli import main
from rgbd_rs.errors import InvalidArgumentError
from rgbd_rs.nn import ConfidenceEstimator, TrainConfig
from rgbd_rs.segmentation import SemanticLabeler
from rgbd_rs.shapes import ShapeClassifier

ARG = InvalidArgumentError
NO_CUDA = not torch.cuda.is_available()

CASES: list[Case] = [
    Case(
        "SemanticLabeler.load",
        lambda: SemanticLabeler.load(device="tpu"),
        ARG,
        r"^device: got 'tpu'",
        "device",
    ),
    Case(
        "ConfidenceEstimator.load",
        lambda: ConfidenceEstimator.load(device="gpu"),
        ARG,
        r"^device: got 'gpu'",
        "device",
    ),
    Case(
        "ShapeClassifier.load",
        lambda: ShapeClassifier.load(device="cuda:x"),
        ARG,
        r"^device: got 'cuda:x'",
        "device",
    ),
    Case(
        "TrainConfig",
        lambda: TrainConfig(device="cuda:-1"),
        ARG,
        r"^device: got 'cuda:-1'",
        "device",
    ),
]
if NO_CUDA:
    CASES.append(
        Case(
            "ShapeClassifier.load",
            lambda: ShapeClassifier.load(device="cuda"),
            ARG,
            r"CUDA is not available",
            "no cuda",
        )
    )


@pytest.mark.parametrize("case", params(CASES))
def test_bad_input(case: Case) -> None:
    check(case)


def test_train_config_checks_cuda_at_setup_not_at_construction() -> None:
    # A config written for a GPU machine still loads (and resumes) on a CPU one.
    assert TrainConfig(device="cuda:3").device == "cuda:3"


@pytest.mark.parametrize(
    ("argv", "expected"),
    [
        (["semantic", "score", "--cache", "C", "--device", "tpu"], "got 'tpu', expected one of"),
        (["eval", "shapes", "--cache", "C", "--device", "auto"], "got 'auto', expected one of"),
        (["train", "shapes", "--cache", "C", "--out", "O", "--device", "x"], "got 'x'"),
    ]
    + (
        [(["eval", "shapes", "--cache", "C", "--device", "cuda:0"], "CUDA is not available")]
        if NO_CUDA
        else []
    ),
)
def test_device_flag_fails_while_parsing(
    argv: list[str], expected: str, capsys: pytest.CaptureFixture[str]
) -> None:
    with pytest.raises(SystemExit) as info:
        main(argv)
    assert info.value.code == 2
    err = capsys.readouterr().err
    assert err.startswith("rgbd: error: argument --device: ") and expected in err
    assert err.count("\n") == 1 and "Traceback" not in err
