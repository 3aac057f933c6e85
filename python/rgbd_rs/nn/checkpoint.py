"""Training checkpoints: what a trained network needs to be used again, and to resume training.

A checkpoint is one ``torch.save`` file holding only plain types (dicts, lists, tuples, str,
numbers, None and tensors), so :func:`load_checkpoint` reads it with ``weights_only=True`` and
loading a file never executes code. It records the format tag :data:`FORMAT`, the architecture
name and its constructor arguments, the training configuration, the input normalisation
statistics, the package version and git revision that wrote it, how far training got (epoch and
step within the epoch), the weights, the optimizer/scheduler/RNG states and the loss history.

Files are written atomically (a temporary file in the same folder, then ``os.replace``): an
interrupted write leaves the previous checkpoint intact, never a truncated one.
"""

from __future__ import annotations

import dataclasses
import functools
import importlib.metadata
import os
import random
import subprocess
import tempfile
import warnings
from collections.abc import Collection, Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import torch

from rgbd_rs import _validate
from rgbd_rs._array_eq import array_eq
from rgbd_rs._reasons import reason
from rgbd_rs.errors import InvalidArgumentError, RgbdError

#: Format tag of every checkpoint this module writes; bump it when the layout changes.
FORMAT = "rgbd_rs.checkpoint/1"

_PLAIN_SCALARS = (str, int, float, bool, type(None))


def _plain(name: str, value: object) -> Any:
    """Check that ``value`` holds only types a ``weights_only`` load accepts; return a copy.

    Numpy scalars become Python numbers; other types (numpy arrays, objects) raise an
    :class:`InvalidArgumentError` naming the offending key path under ``name``.
    """
    if isinstance(value, _PLAIN_SCALARS):
        return value
    if isinstance(value, np.generic) and value.dtype.kind in "biuf":
        return value.item()
    if isinstance(value, torch.Tensor):
        return value.detach().cpu().clone()
    if isinstance(value, Mapping):
        out: dict[str, Any] = {}
        for key, item in value.items():
            if not isinstance(key, str):
                raise InvalidArgumentError(f"{name}: got key {key!r}, expected str keys")
            out[key] = _plain(f"{name}[{key!r}]", item)
        return out
    if isinstance(value, (list, tuple)):
        items = [_plain(f"{name}[{i}]", item) for i, item in enumerate(value)]
        return items if isinstance(value, list) else tuple(items)
    raise InvalidArgumentError(
        f"{name}: got {type(value).__name__}, expected plain values only (dict with str keys, "
        "list, tuple, str, int, float, bool, None or torch.Tensor; convert numpy arrays with "
        ".tolist() or torch.from_numpy)"
    )


def _package_version() -> str | None:
    """``rgbd_rs.__version__``, else the installed distribution's version, else None."""
    import rgbd_rs

    version = getattr(rgbd_rs, "__version__", None)
    if isinstance(version, str):
        return version
    try:
        return importlib.metadata.version("rgbd_rs")
    except importlib.metadata.PackageNotFoundError:
        return None


@functools.cache
def git_revision() -> str | None:
    """The commit of the git checkout the package is imported from, or None (never raises).

    Only a repository whose top level holds this very package counts: an installed package in
    a virtualenv that happens to sit inside another project's repository reports None.
    """
    package = Path(__file__).resolve().parents[1]
    try:
        out = subprocess.run(
            ["git", "-C", str(package), "rev-parse", "--show-toplevel", "HEAD"],
            capture_output=True,
            text=True,
            timeout=10,
            check=True,
        ).stdout.split()
        if len(out) != 2:
            return None
        top, rev = Path(out[0]).resolve(), out[1]
        return rev if package in (top / "python" / "rgbd_rs", top / "rgbd_rs") else None
    except (OSError, subprocess.SubprocessError, ValueError):
        return None


def _cuda_started() -> bool:
    return bool(torch.cuda.is_initialized())  # type: ignore[no-untyped-call]


def _capture_rng() -> dict[str, Any]:
    """The states of Python's, numpy's (legacy global) and torch's (CPU and CUDA) generators."""
    state = np.random.get_state(legacy=True)  # noqa: NPY002 - the global one datasets use
    assert isinstance(state, tuple)  # legacy=True always returns the tuple form
    return {
        "python": random.getstate(),
        "numpy": {
            "keys": torch.from_numpy(state[1].astype(np.int64)),
            "pos": int(state[2]),
            "has_gauss": int(state[3]),
            "cached_gaussian": float(state[4]),
        },
        "torch": torch.get_rng_state(),
        "cuda": torch.cuda.get_rng_state_all() if _cuda_started() else [],
    }


def _restore_rng(state: Mapping[str, Any]) -> None:
    """Inverse of :func:`_capture_rng` (tensors may have been mapped to another device)."""
    random.setstate(state["python"])
    np_state = state["numpy"]
    np.random.set_state(  # noqa: NPY002
        (
            "MT19937",
            np_state["keys"].cpu().numpy().astype(np.uint32),
            int(np_state["pos"]),
            int(np_state["has_gauss"]),
            float(np_state["cached_gaussian"]),
        )
    )
    torch.set_rng_state(state["torch"].cpu())
    cuda = [t.cpu() for t in state.get("cuda", [])]
    if cuda and torch.cuda.is_available() and len(cuda) == torch.cuda.device_count():
        torch.cuda.set_rng_state_all(cuda)


@array_eq
@dataclass(frozen=True)
class Checkpoint:
    """The contents of a checkpoint file (see the module docstring).

    ``epoch`` counts completed epochs and ``step`` the optimizer steps done within the next one
    (0 at an epoch boundary). ``config`` is :class:`~rgbd_rs.nn.train.TrainConfig` as a dict.
    ``history`` holds one dict per completed epoch: ``epoch`` (1-based), ``train_loss``,
    ``val_loss`` (None without validation) and ``lr``. ``optimizer_state``, ``scheduler_state``
    and ``rng_state`` are None in an inference-only copy (:meth:`stripped`); ``rng_state`` is
    ``{"ranks": [...]}``, the generators' states of each process (one in a single process).
    """

    path: Path
    arch: str
    arch_config: dict[str, Any]
    normalisation: dict[str, Any]
    model_state: dict[str, torch.Tensor]
    config: dict[str, Any] = field(default_factory=dict)
    version: str | None = None
    git_revision: str | None = None
    epoch: int = 0
    step: int = 0
    world_size: int = 1
    optimizer_state: dict[str, Any] | None = None
    scheduler_state: dict[str, Any] | None = None
    rng_state: dict[str, Any] | None = None
    history: list[dict[str, Any]] = field(default_factory=list)
    best_val_loss: float | None = None
    best_epoch: int | None = None
    #: Sums over the steps already done in the current epoch (``loss_sum``, ``samples``).
    partial: dict[str, float] = field(default_factory=dict)

    def stripped(self) -> Checkpoint:
        """A copy for inference only: no optimizer, scheduler or RNG state (a third the size
        with Adam); it loads like any checkpoint but cannot resume training."""
        return dataclasses.replace(
            self, optimizer_state=None, scheduler_state=None, rng_state=None, partial={}
        )

    def load_weights(self, model: torch.nn.Module) -> None:
        """``model.load_state_dict(self.model_state)``; a mismatch raises :class:`RgbdError`
        naming the file (e.g. a checkpoint of the same arch built with another width)."""
        if not isinstance(model, torch.nn.Module):
            got = type(model).__name__
            raise InvalidArgumentError(f"model: got {got}, expected a torch nn.Module")
        try:
            model.load_state_dict(self.model_state)
        except RuntimeError as exc:
            raise RgbdError(
                f"{self.path}: weights do not fit the model (arch {self.arch!r}, "
                f"arch_config {self.arch_config}): {exc}"
            ) from None


def _same(a: object, b: object) -> bool:
    """Equality of plain values that compares tensors by value (``==`` on tensors is ambiguous)."""
    if isinstance(a, torch.Tensor) or isinstance(b, torch.Tensor):
        return (
            isinstance(a, torch.Tensor)
            and isinstance(b, torch.Tensor)
            and a.shape == b.shape
            and a.dtype == b.dtype
            and torch.equal(a.cpu(), b.cpu())
        )
    if isinstance(a, dict) and isinstance(b, dict):
        return a.keys() == b.keys() and all(_same(a[k], b[k]) for k in a)
    if isinstance(a, (list, tuple)) and isinstance(b, (list, tuple)):
        return len(a) == len(b) and all(_same(x, y) for x, y in zip(a, b, strict=True))
    return a == b


def _resume_differences(
    ckpt: Checkpoint,
    *,
    arch: str,
    arch_config: Mapping[str, Any],
    normalisation: Mapping[str, Any],
    config: Mapping[str, Any],
    world_size: int,
    may_change: Collection[str] = (),
) -> list[str]:
    """What keeps training from resuming from ``ckpt`` with these settings, one phrase each
    (empty when it can). ``may_change`` lists config fields allowed to differ."""
    out = []
    if ckpt.arch != arch:
        out.append(f"arch {ckpt.arch!r} in the checkpoint, {arch!r} now")
    parts = {"arch_config": arch_config, "config": config, "normalisation": normalisation}
    for part, new in parts.items():
        old = getattr(ckpt, part)
        for key in sorted(set(old) | set(new)):
            if (part == "config" and key in may_change) or _same(old.get(key), new.get(key)):
                continue
            plain = not any(_is_array(v) for v in (old.get(key), new.get(key)))
            shown = f": {old.get(key)!r} -> {new.get(key)!r}" if plain else ""
            out.append(f"{part}[{key!r}] differs{shown}")
    if ckpt.world_size != world_size:
        out.append(f"{ckpt.world_size} processes in the checkpoint, {world_size} now")
    states = (ckpt.rng_state or {}).get("ranks")
    if ckpt.optimizer_state is None or ckpt.scheduler_state is None or states is None:
        out.append("it is an inference-only copy without optimizer state")
    elif not isinstance(states, list) or len(states) != ckpt.world_size:
        out.append("its RNG states do not match its number of processes")
    return out


def _is_array(value: object) -> bool:
    """Whether ``value`` is or holds an array or tensor (too long to show in a message)."""
    if isinstance(value, Mapping):
        return any(_is_array(v) for v in value.values())
    if isinstance(value, (list, tuple)):
        return len(value) > 16 or any(_is_array(v) for v in value)
    return hasattr(value, "shape")


def _to_file(ckpt: Checkpoint) -> dict[str, Any]:
    data = {f.name: getattr(ckpt, f.name) for f in dataclasses.fields(ckpt) if f.name != "path"}
    data["format"] = FORMAT
    return data


def _check_fields(c: Checkpoint) -> None:
    """The fields save_checkpoint writes have the types load_checkpoint will expect."""
    if not isinstance(c.arch, str) or not c.arch:
        raise InvalidArgumentError(f"checkpoint.arch: got {c.arch!r}, expected a name")
    for name in ("arch_config", "normalisation", "model_state", "config"):
        if not isinstance(getattr(c, name), Mapping):
            got = type(getattr(c, name)).__name__
            raise InvalidArgumentError(f"checkpoint.{name}: got {got}, expected a dict")
    bad = [k for k, v in c.model_state.items() if not isinstance(v, torch.Tensor)]
    if bad:
        raise InvalidArgumentError(
            f"checkpoint.model_state: {bad[:3]} are not tensors, expected a module's state_dict"
        )
    for name in ("epoch", "step"):
        _validate.integer(f"checkpoint.{name}", getattr(c, name))
    _validate.integer("checkpoint.world_size", c.world_size, minimum=1)
    if not isinstance(c.history, list):
        got = type(c.history).__name__
        raise InvalidArgumentError(f"checkpoint.history: got {got}, expected a list")


def save_checkpoint(checkpoint: Checkpoint, path: str | os.PathLike[str]) -> Path:
    """Write ``checkpoint`` to ``path`` atomically (mode 0644); return the path written."""
    if not isinstance(checkpoint, Checkpoint):
        raise InvalidArgumentError(
            f"checkpoint: got {type(checkpoint).__name__}, expected a Checkpoint"
        )
    _check_fields(checkpoint)
    path = _validate.path("path", path)
    if path.is_dir():
        raise InvalidArgumentError(f"path: got {path}, a folder; expected a checkpoint file path")
    path.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(dir=path.parent, prefix=f".{path.name}.", suffix=".tmp")
    try:
        with os.fdopen(fd, "wb") as f:
            torch.save(_to_file(checkpoint), f)
            f.flush()
            os.fsync(f.fileno())
        os.chmod(tmp, 0o644)  # mkstemp makes it private; a checkpoint is an ordinary file
        os.replace(tmp, path)
    except RuntimeError as exc:
        Path(tmp).unlink(missing_ok=True)
        # torch's zip writer reports a failed write (a full disk) as a RuntimeError raised
        # while handling the OSError: say it in the OSError's words, naming the file.
        cause = exc.__context__
        if isinstance(cause, OSError):
            raise RgbdError(
                f"{path}: could not be written ({cause.strerror or cause}); the previous "
                "checkpoint there, if any, is intact"
            ) from None
        raise
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise
    return path


_REQUIRED = ("arch", "arch_config", "model_state")


def load_checkpoint(
    path: str | os.PathLike[str],
    *,
    arch: str | None = None,
    normalisation_keys: Collection[str] = (),
    map_location: str | torch.device = "cpu",
) -> Checkpoint:
    """Read a checkpoint written by :func:`~rgbd_rs.nn.train.train` or :func:`save_checkpoint`.

    ``arch`` (when given) must equal the stored architecture name, and every key of
    ``normalisation_keys`` must be in the stored normalisation. A missing file, a file that is
    not an rgbd_rs checkpoint (unreadable, unsafe to load, or another format tag), another
    architecture or missing normalisation raise :class:`RgbdError` naming the file and what
    differs. Tensors are mapped to ``map_location``.
    """
    if not isinstance(path, (str, os.PathLike)) or not str(path):
        raise InvalidArgumentError(f"path: got {path!r}, expected a checkpoint file path")
    if (
        isinstance(normalisation_keys, str)
        or not isinstance(normalisation_keys, Collection)
        or not all(isinstance(k, str) for k in normalisation_keys)
    ):
        raise InvalidArgumentError(
            f"normalisation_keys: got {normalisation_keys!r}, expected a collection of names"
        )
    if arch is not None and not isinstance(arch, str):
        raise InvalidArgumentError(
            f"arch: got {type(arch).__name__}, expected an architecture name (str) or None"
        )
    path = Path(path)
    if not isinstance(map_location, (str, torch.device)):
        raise InvalidArgumentError(
            f"map_location: got {type(map_location).__name__}, expected 'cpu', 'cuda[:N]' or a "
            "torch.device"
        )
    try:
        torch.device(map_location)
    except (RuntimeError, ValueError):
        raise InvalidArgumentError(
            f"map_location: got {map_location!r}, expected 'cpu', 'cuda[:N]' or a torch.device"
        ) from None
    if path.is_dir():
        raise RgbdError(f"{path}: is a folder, expected a checkpoint file (.pt)")
    if not path.is_file():
        raise RgbdError(f"{path}: checkpoint file not found")
    try:
        with warnings.catch_warnings():
            # torch warns about a pickle protocol before refusing a foreign pickle anyway.
            warnings.simplefilter("ignore", UserWarning)
            data = torch.load(path, map_location=map_location, weights_only=True)
    except Exception as exc:  # torch raises several types for garbage / unsafe content
        # A KeyError is torch's legacy unpickler reading a stray byte as a "magic number".
        why = "it is not a torch checkpoint" if isinstance(exc, KeyError) else reason(exc)
        raise RgbdError(
            f"{path}: not a readable rgbd_rs checkpoint ({why}); "
            f"expected a file written by rgbd_rs.nn (format {FORMAT!r})"
        ) from None
    tag = data.get("format") if isinstance(data, dict) else None
    if tag != FORMAT:
        raise RgbdError(
            f"{path}: not an rgbd_rs checkpoint of this version: format tag {tag!r}, "
            f"expected {FORMAT!r}"
        )
    missing = [k for k in _REQUIRED if k not in data]
    if missing:
        raise RgbdError(f"{path}: checkpoint is missing {missing}")
    state = data["model_state"]
    if not isinstance(state, Mapping):
        raise RgbdError(f"{path}: model_state is {type(state).__name__}, expected tensors by name")
    bad = [
        k
        for k, v in state.items()
        if isinstance(v, torch.Tensor) and v.is_floating_point() and not torch.isfinite(v).all()
    ]
    if bad:
        raise RgbdError(
            f"{path}: the weights {bad[:3]}{' …' if len(bad) > 3 else ''} hold NaN or inf "
            "(a diverged training run?); expected finite weights"
        )
    if arch is not None and data["arch"] != arch:
        raise RgbdError(f"{path}: checkpoint of architecture {data['arch']!r}, expected {arch!r}")
    norm = data.get("normalisation")
    if not isinstance(norm, dict):
        raise RgbdError(
            f"{path}: checkpoint has no normalisation statistics (got {norm!r}, expected a "
            "dict); the network's inputs cannot be normalised as in training"
        )
    absent = sorted(set(normalisation_keys) - set(norm))
    if absent:
        raise RgbdError(
            f"{path}: checkpoint normalisation lacks {absent} (has {sorted(norm)}); "
            f"it was written for another version of architecture {data['arch']!r}"
        )
    known = {f.name for f in dataclasses.fields(Checkpoint)} - {"path"}
    return Checkpoint(path=path, **{k: v for k, v in data.items() if k in known})
