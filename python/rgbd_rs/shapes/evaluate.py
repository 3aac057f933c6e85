"""Evaluation of shape classifiers (``rgbd eval shapes``): thesis Tables 5.2-5.4 / 5.6.

:func:`evaluate` runs a checkpoint over a cache split (ModelNet's official test split by
default) and returns a :class:`ShapeEvaluation`: overall accuracy (Table 5.2's "average
accuracy" is the fraction of test shapes classified correctly), per-class accuracy (Tables 5.4,
5.6), the confusion matrix (Table 5.3, rows = true class, in percent of the row) as markdown
and as a PNG heat map. :func:`ablation_markdown` lays several evaluations out as Table 5.2
(rows = representations, columns = datasets).
"""

from __future__ import annotations

import os
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import numpy.typing as npt
import torch
from tqdm import tqdm

from rgbd_rs import _validate
from rgbd_rs._array_eq import array_eq
from rgbd_rs._progress import bar_options
from rgbd_rs.errors import InvalidArgumentError, RgbdError, ShapeMismatchError
from rgbd_rs.shapes.augment import _mirror_pair, _quarter_turns
from rgbd_rs.shapes.classify import ShapeClassifier
from rgbd_rs.shapes.dataset import ShapeCache

__all__ = ["ShapeEvaluation", "ablation_markdown", "evaluate", "row_name"]

#: Thesis Table 5.2 (ModelNet10, ModelNet40), for the reports' reference column.
THESIS_TABLE_5_2 = {
    "depth": (0.932, 0.880),
    "volume": (0.922, 0.869),
    "curvature": (0.909, 0.852),
    "combined": (0.936, 0.893),
}
#: Heat-map cell side (pixels) and label column width.
_CELL, _LABEL = 44, 120


def row_name(representations: Sequence[str]) -> str:
    """Table 5.2's row of a representation set: its single name, or ``"combined"`` for the
    thesis' three (``"depth+volume"`` for other combinations)."""
    from rgbd_rs.nn.shapes import _parse_representations

    names = list(representations) if not isinstance(representations, str) else representations
    reps = _parse_representations(names)
    if len(reps) == 1:
        return reps[0]
    if set(reps) == {"depth", "volume", "curvature"}:
        return "combined"
    return "+".join(reps)


@array_eq
@dataclass(frozen=True)
class ShapeEvaluation:
    """One checkpoint on one split: ``confusion[t, p]`` counts shapes of true class ``t``
    predicted ``p``."""

    classes: tuple[str, ...]
    confusion: npt.NDArray[np.int64]
    representations: tuple[str, ...]
    checkpoint: str
    dataset: str
    split: str
    #: True when probabilities were averaged over four quarter turns about z.
    turns: bool = False
    #: True when probabilities were averaged over the shape and its mirror image (x -> -x).
    mirror: bool = False
    #: Quarter turns about z (counter-clockwise, 0-3) every shape was turned by before it was
    #: read: how the classifier does on shapes that do not face ModelNet's way.
    turned: int = 0

    def __post_init__(self) -> None:
        if not isinstance(self.classes, tuple) or not all(isinstance(c, str) for c in self.classes):
            raise InvalidArgumentError(
                f"classes: got {self.classes!r}, expected a tuple of class names"
            )
        k = len(self.classes)
        m = _validate.asarray("confusion", self.confusion)
        if m.shape != (k, k):
            raise ShapeMismatchError(
                f"confusion: got shape {m.shape}, expected ({k}, {k}) for {k} classes"
            )
        if m.dtype.kind not in "iuf" or (
            m.size
            and not (
                np.isfinite(m).all()
                and (m >= 0).all()
                and (m <= 2**62).all()
                and (m == np.round(m)).all()
            )
        ):
            raise InvalidArgumentError(
                "confusion: got values that are not counts (negative, fractional, NaN or inf), "
                "expected non-negative whole numbers"
            )
        object.__setattr__(self, "confusion", m.astype(np.int64))
        if not isinstance(self.representations, tuple) or not all(
            isinstance(r, str) for r in self.representations
        ):
            raise InvalidArgumentError(
                f"representations: got {self.representations!r}, expected a tuple of names"
            )
        for name in ("checkpoint", "dataset", "split"):
            if not isinstance(getattr(self, name), str):
                raise InvalidArgumentError(
                    f"{name}: got {type(getattr(self, name)).__name__}, expected a str"
                )
        for name in ("turns", "mirror"):
            _validate.flag(name, getattr(self, name))
        _validate.integer("turned", self.turned, minimum=0, maximum=3)

    @property
    def count(self) -> int:
        """Shapes evaluated."""
        return int(self.confusion.sum())

    @property
    def accuracy(self) -> float:
        """Overall accuracy (correct / all)."""
        return float(np.trace(self.confusion) / max(self.count, 1))

    @property
    def per_class(self) -> dict[str, float]:
        """Accuracy of each class (recall; NaN for a class without test shapes)."""
        rows = self.confusion.sum(axis=1)
        with np.errstate(invalid="ignore", divide="ignore"):
            acc = np.diag(self.confusion) / rows
        return {c: float(a) for c, a in zip(self.classes, acc, strict=True)}

    @property
    def mean_class_accuracy(self) -> float:
        """Mean of the per-class accuracies over classes with test shapes."""
        vals = [v for v in self.per_class.values() if np.isfinite(v)]
        return float(np.mean(vals)) if vals else float("nan")

    def per_class_markdown(self) -> str:
        """Table 5.4's layout: class, accuracy, samples."""
        rows = self.confusion.sum(axis=1)
        lines = ["| class | accuracy | samples |", "|---|---:|---:|"]
        for (c, a), n in zip(self.per_class.items(), rows, strict=True):
            lines.append(f"| {c} | {_pct(a)} | {int(n)} |")
        return "\n".join(lines)

    def confusion_markdown(self) -> str:
        """Table 5.3's layout: rows = true class, columns = predicted, percent of the row."""
        pct = _row_percent(self.confusion)
        head = "| true \\ predicted | " + " | ".join(self.classes) + " |"
        lines = [head, "|---|" + "---:|" * len(self.classes)]
        for c, row in zip(self.classes, pct, strict=True):
            lines.append(f"| {c} | " + " | ".join(f"{v:.0f}" for v in row) + " |")
        return "\n".join(lines)

    def summary(self) -> str:
        """One line: accuracy, mean class accuracy, count, representations, checkpoint."""
        tta = (
            (f"; shapes turned {90 * self.turned} degrees" if self.turned else "")
            + ("; 4 turns averaged" if self.turns else "")
            + ("; mirror averaged" if self.mirror else "")
        )
        return (
            f"{self.dataset} {self.split}: accuracy {_pct(self.accuracy)}, mean class accuracy "
            f"{_pct(self.mean_class_accuracy)} over {self.count} shapes "
            f"({row_name(self.representations)}{tta}; {self.checkpoint})"
        )

    def markdown(self) -> str:
        """Summary, per-class table and confusion matrix."""
        return "\n\n".join(
            [
                f"**{self.summary()}**",
                self.per_class_markdown(),
                "Confusion matrix (% of each true class):",
                self.confusion_markdown(),
            ]
        )

    def heatmap(self) -> npt.NDArray[np.uint8]:
        """The confusion matrix (percent of each row) as a BGR heat map with class labels."""
        import cv2

        from rgbd_rs.viz import colorize

        pct = _row_percent(self.confusion)
        k = len(self.classes)
        cells = colorize(pct, vmin=0.0, vmax=100.0, colormap=cv2.COLORMAP_VIRIDIS)
        grid = cv2.resize(cells, (k * _CELL, k * _CELL), interpolation=cv2.INTER_NEAREST)
        img = np.full((k * _CELL + _LABEL, k * _CELL + _LABEL, 3), 255, np.uint8)
        img[_LABEL:, _LABEL:] = grid
        font, scale = cv2.FONT_HERSHEY_SIMPLEX, 0.35
        for i, name in enumerate(self.classes):
            y = _LABEL + i * _CELL + _CELL // 2 + 4
            cv2.putText(img, name[:16], (4, y), font, scale, (0, 0, 0), 1, cv2.LINE_AA)
            text = np.full((_CELL, _LABEL, 3), 255, np.uint8)
            cv2.putText(
                text, name[:16], (4, _CELL // 2 + 4), font, scale, (0, 0, 0), 1, cv2.LINE_AA
            )
            # the predicted-class labels run upwards above their columns
            img[:_LABEL, _LABEL + i * _CELL : _LABEL + (i + 1) * _CELL] = np.rot90(text)
            for j in range(k):
                v = pct[i, j]
                if v >= 0.5:
                    colour = (0, 0, 0) if v > 60 else (255, 255, 255)
                    org = (_LABEL + j * _CELL + 6, _LABEL + i * _CELL + _CELL // 2 + 4)
                    cv2.putText(img, f"{v:.0f}", org, font, scale, colour, 1, cv2.LINE_AA)
        return img

    def write(self, folder: str | os.PathLike[str], stem: str = "eval") -> list[Path]:
        """``stem.md`` (:meth:`markdown`) and ``stem_confusion.png`` (:meth:`heatmap`)."""
        from rgbd_rs.io import write_png

        out = _validate.path("folder", folder)
        if not isinstance(stem, str) or not stem or Path(stem).name != stem or stem in (".", ".."):
            raise InvalidArgumentError(
                f"stem: got {stem!r}, expected a plain file name (no folders) for the report"
            )
        if out.exists() and not out.is_dir():
            raise RgbdError(f"{out}: is a file, expected a folder for the report")
        out.mkdir(parents=True, exist_ok=True)
        md = out / f"{stem}.md"
        md.write_text(self.markdown() + "\n")
        png = write_png(out / f"{stem}_confusion.png", self.heatmap()[:, :, ::-1])
        return [md, png]


def _pct(v: float) -> str:
    return "-" if not np.isfinite(v) else f"{100 * v:.1f}%"


def _row_percent(confusion: np.ndarray) -> npt.NDArray[np.float64]:
    rows = confusion.sum(axis=1, keepdims=True)
    return np.asarray(100.0 * confusion / np.maximum(rows, 1), np.float64)


def evaluate(
    checkpoint: str | os.PathLike[str] | ShapeClassifier,
    cache: ShapeCache | str | os.PathLike[str],
    *,
    split: str = "test",
    batch_size: int = 64,
    device: str = "cpu",
    turns: bool = False,
    mirror: bool = False,
    quiet: bool = True,
    turned: int = 0,
) -> ShapeEvaluation:
    """Accuracy of ``checkpoint`` on ``cache``'s ``split`` (``"test"``, ``"train"``, ``"all"``).
    ``turns``: average each shape's probabilities over its four quarter turns about z
    (:mod:`rgbd_rs.shapes.augment`); ``mirror``: average them over the shape and its mirror image
    in x (both: over all eight). ``turned``: turn every shape by that many quarter turns about
    z first (0-3), to measure shapes that do not face ModelNet's way. ``quiet=False`` shows a
    progress bar over the shapes.
    A cache computed with other inputs (resolution, normalisation, classes, missing
    representations) raises :class:`RgbdError` naming both, as does one with shapes of
    ``split`` still to compute."""
    clf = (
        checkpoint
        if isinstance(checkpoint, ShapeClassifier)
        else ShapeClassifier.load(checkpoint, device=device)
    )
    c = cache if isinstance(cache, ShapeCache) else ShapeCache(cache)
    bs = _validate.integer("batch_size", batch_size, minimum=1, maximum=1_000_000)
    _check_compatible(clf, c)
    data = c.dataset(split, clf.spec.representations)
    k = len(c.classes)
    confusion = np.zeros((k, k), np.int64)
    loader = torch.utils.data.DataLoader(data, batch_size=bs, shuffle=False)
    for name, flag in (("turns", turns), ("mirror", mirror), ("quiet", quiet)):
        if not isinstance(flag, bool):
            raise InvalidArgumentError(f"{name}: got {flag!r}, expected True or False")
    k = _validate.integer("turned", turned, minimum=0, maximum=3)
    shapes = clf.net.shapes
    bar = tqdm(total=len(data), desc="evaluate", unit="shape", **bar_options(quiet))
    with bar:  # closed on an exception too
        for x, y in loader:
            if k:
                x = _quarter_turns(x, shapes)[k]
            views = _mirror_pair(x, shapes) if mirror else [x]
            if turns:
                views = [t for v in views for t in _quarter_turns(v, shapes)]
            probs = sum(np.asarray(clf.probabilities_of_inputs(v)) for v in views)
            pred = np.asarray(probs).argmax(axis=1)
            np.add.at(confusion, (y.numpy(), pred), 1)
            bar.update(len(y))
    return ShapeEvaluation(
        classes=c.classes,
        confusion=confusion,
        representations=clf.spec.representations,
        checkpoint=clf.source,
        dataset=str(c.meta.get("source", c.path.name)),
        split=split,
        turns=turns,
        mirror=mirror,
        turned=k,
    )


def _check_compatible(clf: ShapeClassifier, cache: ShapeCache) -> None:
    a, b = clf.spec, cache.spec
    diffs = [
        f"{name} {getattr(a, name)!r} in the checkpoint, {getattr(b, name)!r} in the cache"
        for name in ("view_resolution", "volume_resolution", "normalisation")
        if getattr(a, name) != getattr(b, name)
    ]
    missing = [r for r in a.representations if r not in b.representations]
    if missing:
        diffs.append(f"the cache lacks {missing}")
    if clf.classes != cache.classes:
        diffs.append(f"classes {list(clf.classes)} vs {list(cache.classes)}")
    if diffs:
        raise RgbdError(
            f"{clf.source}: does not fit the cache {cache.path}: "
            + "; ".join(diffs)
            + " (build the cache with the network's settings: `rgbd shapes cache --resolution "
            f"{a.view_resolution} --volume-resolution {a.volume_resolution} --representations "
            f"{','.join(a.representations)} --normalisation {a.normalisation}`)"
        )


def ablation_markdown(results: Mapping[str, Sequence[ShapeEvaluation]]) -> str:
    """Table 5.2: one row per representation set, one column per dataset (``results`` maps a
    dataset label such as ``"ModelNet10"`` to its evaluations), with the thesis' numbers."""
    if not isinstance(results, Mapping) or not results:
        raise InvalidArgumentError(
            "results: expected a non-empty dict of dataset name -> evaluations"
        )
    cols = list(results)
    table: dict[str, dict[str, float]] = {}
    for col, evals in results.items():
        for e in evals:
            if not isinstance(e, ShapeEvaluation):
                raise InvalidArgumentError(
                    f"results[{col!r}]: got {type(e).__name__}, expected ShapeEvaluation"
                )
            table.setdefault(row_name(e.representations), {})[col] = e.accuracy
    head = "| representation | " + " | ".join(cols) + " | thesis ModelNet10 | thesis ModelNet40 |"
    lines = [head, "|---|" + "---:|" * (len(cols) + 2)]
    order = [*THESIS_TABLE_5_2, *sorted(set(table) - set(THESIS_TABLE_5_2))]
    for row in (r for r in order if r in table):  # Table 5.2's row order, then the others
        accs = table[row]
        thesis = THESIS_TABLE_5_2.get(row)
        ref = [_pct(v) for v in thesis] if thesis else ["-", "-"]
        vals = [_pct(accs[c]) if c in accs else "-" for c in cols]
        lines.append(f"| {row} | " + " | ".join(vals + ref) + " |")
    return "\n".join(lines)
