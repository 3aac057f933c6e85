"""The learning curve of a `rgbd train shapes` run as a PNG: loss (left) and accuracy (right) per
epoch, on the training batches (augmented, in train mode, as drawn) and the validation shapes,
the chosen epoch (best.pt) marked. Reads the history stored in the run's last.pt.

    python tools/plot_learning_curve.py --checkpoint RUN/last.pt --out curve.png [--title T]
"""

from __future__ import annotations

import argparse
from pathlib import Path

import cv2
import numpy as np

from rgbd_rs.nn.checkpoint import load_checkpoint

W, H, M = 520, 340, 56  # panel size and margin, pixels
TRAIN, VAL, BEST = (200, 120, 40), (40, 90, 220), (60, 160, 60)  # BGR
FONT = cv2.FONT_HERSHEY_SIMPLEX


def _ticks(lo: float, hi: float, n: int = 5) -> list[float]:
    step = (hi - lo) / n
    mag = 10 ** np.floor(np.log10(step))
    step = min((m * mag for m in (1, 2, 2.5, 5, 10) if m * mag >= step), default=step)
    return [float(v) for v in np.arange(np.ceil(lo / step) * step, hi + 1e-12, step)]


def _labels(values: list[float]) -> list[str]:
    """The values with the fewest decimals that print each of them exactly (87.5, not 88)."""
    for d in range(5):
        if all(abs(round(v, d) - v) <= 1e-6 * max(1.0, abs(v)) for v in values):
            break
    return [f"{v:.{d}f}" for v in values]


def panel(
    title: str,
    epochs: list[int],
    series: list[tuple[str, list[float | None], tuple[int, ...]]],
    best: int | None,
    percent: bool,
) -> np.ndarray:
    img = np.full((H, W, 3), 255, np.uint8)
    # Missing and non-finite values (no validation set, a NaN metric) are not drawn.
    series = [
        (name, [v if v is not None and np.isfinite(v) else None for v in ys], color)
        for name, ys, color in series
    ]
    values = [v for _, ys, _ in series for v in ys if v is not None]
    if not values:
        cv2.putText(img, f"{title}: no values", (M, 20), FONT, 0.5, (0, 0, 0), 1, cv2.LINE_AA)
        return img
    # A first epoch's loss far above the rest (a fresh wide network) would flatten the others:
    # past a ratio of 8 the loss axis is logarithmic.
    log = not percent and min(values) > 0 and max(values) > 8 * min(values)
    f = np.log10 if log else (lambda v: v)
    lo, hi = float(f(min(values))), float(f(max(values)))
    pad = 0.05 * (hi - lo or 1.0)
    lo, hi = lo - pad, hi + pad
    unit = " (%)" if percent else " (log axis)" if log else ""
    x0, x1, y0 = M, W - 16, H - 40
    # The legend sits in the title row unless the title reaches it; then in a row of its own.
    legend_x = x1 - 250
    two_rows = x0 + cv2.getTextSize(title + unit, FONT, 0.5, 1)[0][0] + 12 > legend_x
    legend_y, y1 = (38, 48) if two_rows else (20, 30)

    def xe(e: float) -> int:
        return int(x0 + (e - epochs[0]) / max(epochs[-1] - epochs[0], 1) * (x1 - x0))

    def px(e: float, v: float) -> tuple[int, int]:
        return xe(e), int(y0 + (float(f(v)) - lo) / (hi - lo) * (y1 - y0))

    ticks = (
        [float(10.0**k * m) for k in range(int(np.floor(lo)), int(np.ceil(hi)) + 1)
         for m in (1, 2, 5) if lo <= np.log10(10.0**k * m) <= hi]
        if log else _ticks(lo, hi)
    )  # fmt: skip
    for t, label in zip(ticks, _labels([100 * t if percent else t for t in ticks]), strict=True):
        _, y = px(epochs[0], t)
        cv2.line(img, (x0, y), (x1, y), (225, 225, 225), 1)
        cv2.putText(img, label, (4, y + 4), FONT, 0.4, (60, 60, 60), 1, cv2.LINE_AA)
    for e in epochs:
        x = xe(e)
        cv2.putText(img, str(e), (x - 4, y0 + 16), FONT, 0.4, (60, 60, 60), 1, cv2.LINE_AA)
    cv2.rectangle(img, (x0, y1), (x1, y0), (0, 0, 0), 1)
    if best is not None:
        x = xe(best)
        cv2.line(img, (x, y1), (x, y0), BEST, 1)
        cv2.putText(img, "chosen", (x - 54, y0 - 6), FONT, 0.4, BEST, 1, cv2.LINE_AA)
    # A series with no value (no validation set) is neither drawn nor named.
    drawn = [(name, ys, color) for name, ys, color in series if any(v is not None for v in ys)]
    for k, (name, ys, color) in enumerate(drawn):
        pts = [px(e, v) for e, v in zip(epochs, ys, strict=True) if v is not None]
        if len(pts) > 1:
            cv2.polylines(img, [np.array(pts, np.int32)], False, color, 2, cv2.LINE_AA)
        for p in pts:
            cv2.circle(img, p, 3, color, -1, cv2.LINE_AA)
        lx = legend_x + 90 * k  # clear of the curves
        cv2.line(img, (lx, legend_y - 4), (lx + 16, legend_y - 4), color, 2, cv2.LINE_AA)
        cv2.putText(img, name, (lx + 20, legend_y), FONT, 0.45, color, 1, cv2.LINE_AA)
    cv2.putText(img, title + unit, (x0, 20), FONT, 0.5, (0, 0, 0), 1, cv2.LINE_AA)
    cv2.putText(img, "epoch", (W // 2 - 20, H - 6), FONT, 0.45, (0, 0, 0), 1, cv2.LINE_AA)
    return img


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--checkpoint", type=Path, required=True, help="the run's last.pt")
    p.add_argument("--out", type=Path, required=True)
    p.add_argument("--title", default="")
    a = p.parse_args()
    ckpt = load_checkpoint(a.checkpoint)
    h = ckpt.history
    if not h:
        raise SystemExit(f"{a.checkpoint}: no completed epoch")
    epochs = [int(e["epoch"]) for e in h]
    loss = panel(
        f"{a.title} loss".strip(), epochs,
        [("train", [e["train_loss"] for e in h], TRAIN),
         ("validation", [e["val_loss"] for e in h], VAL)],
        ckpt.best_epoch, percent=False,
    )  # fmt: skip
    acc = panel(
        f"{a.title} accuracy".strip(), epochs,
        [("train", [e.get("train_metric") for e in h], TRAIN),
         ("validation", [e.get("val_metric") for e in h], VAL)],
        ckpt.best_epoch, percent=True,
    )  # fmt: skip
    a.out.parent.mkdir(parents=True, exist_ok=True)
    cv2.imwrite(str(a.out), np.hstack([loss, acc]))
    print(f"wrote {a.out} (best epoch {ckpt.best_epoch} marked)")


if __name__ == "__main__":
    main()
