"""Bad input to :mod:`rgbd_rs.shapes.scaling` (see tests/test_bad_input.py for the contract and
the meta-test that counts these cases)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from bad_input import Case, check, params
from rgbd_rs import InvalidArgumentError
from rgbd_rs.meshes import box
from rgbd_rs.shapes.dataset import ShapeSource
from rgbd_rs.shapes.scaling import ScaledCopies

ARG = InvalidArgumentError


class _Src(ShapeSource):
    kind = "mesh"

    def __init__(self, names: tuple[str, ...] = ("a", "b")) -> None:
        self.path = Path("x")
        self.classes = ("c",)
        self.labels = np.zeros(len(names), np.int64)
        self.splits = np.zeros(len(names), np.uint8)
        self.names = names

    def load(self, index: int):  # type: ignore[no-untyped-def]
        return box((1.0, 1.0, 1.0))


CASES: list[Case] = [
    Case("ScaledCopies", lambda: ScaledCopies("pack.npz", 1), ARG, r"^source: got str"),  # type: ignore[arg-type]
    Case("ScaledCopies", lambda: ScaledCopies(_Src(), 0), ARG, r"^copies", "zero"),
    Case("ScaledCopies", lambda: ScaledCopies(_Src(), 1, (2.0, 1.0)), ARG, r"^scale_range", "lh"),
    Case("ScaledCopies", lambda: ScaledCopies(_Src(), 1, (0.0, 1.0)), ARG, r"^scale_range", "0"),
    Case("ScaledCopies", lambda: ScaledCopies(_Src(), 1, (1e-50, 1e-50)), ARG, r"^scale", "tiny"),
    Case("ScaledCopies", lambda: ScaledCopies(_Src(), 1, (1.0, 1e30)), ARG, r"^scale", "huge"),
    Case("ScaledCopies", lambda: ScaledCopies(_Src(), 1, seed=-1), ARG, r"^seed", "seed"),
    Case("ScaledCopies", lambda: ScaledCopies(_Src(), 1, turn=-1.0), ARG, r"^turn: got -1", "t-"),
    Case("ScaledCopies", lambda: ScaledCopies(_Src(), 1, turn=181.0), ARG, r"^turn: .*180", "t+"),
    Case("ScaledCopies", lambda: ScaledCopies(_Src(), 1, jitter=np.nan), ARG, r"^jitter", "jn"),
    Case("ScaledCopies", lambda: ScaledCopies(_Src(), 1, jitter=0.6), ARG, r"^jitter: .*0.5", "j+"),
    Case("ScaledCopies", lambda: ScaledCopies(_Src(), 1, turn="5"), ARG, r"^turn: got '5'", "ts"),  # type: ignore[arg-type]
    Case("ScaledCopies.load", lambda: ScaledCopies(_Src(()), 1).load(0), ARG, r"^index", "empty"),
    Case("ScaledCopies", lambda: ScaledCopies(_Src(("a#1",)), 1), ARG, r"^source: got shape names"),
    Case("ScaledCopies.load", lambda: ScaledCopies(_Src(), 1).load(9), ARG, r"^index"),
    Case("ScaledCopies.scale", lambda: ScaledCopies(_Src(), 1).scale(-1), ARG, r"^index"),
    Case("ScaledCopies.turn_angle", lambda: ScaledCopies(_Src(), 1).turn_angle(9), ARG, r"^index"),
    Case("ScaledCopies", lambda: ScaledCopies(_Src(), 1, drop=0.96), ARG, r"^drop: got 0.96", "d+"),
    Case("ScaledCopies", lambda: ScaledCopies(_Src(), 1, drop=np.nan), ARG, r"^drop", "dn"),
    Case(
        "ScaledCopies.kept", lambda: ScaledCopies(_Src(), 1, drop=0.5).kept(9, 10), ARG, r"^index"
    ),
    Case("ScaledCopies.kept", lambda: ScaledCopies(_Src(), 1).kept(2, -1), ARG, r"^count", "c-"),
]


@pytest.mark.parametrize("case", params(CASES))
def test_bad_input(case: Case) -> None:
    check(case)
