"""What every pipeline's commands share (private): the parser class that reports a bad command
line in one line, argparse types that reject nonsense values while parsing, the registry each
pipeline adds its commands to, and the wrapper that names the flag when its file is bad."""

from __future__ import annotations

import argparse
import hashlib
import os
import re
import shutil
import sys
import tempfile
import warnings
from collections.abc import Callable, Mapping, Sequence
from pathlib import Path
from typing import Any, NoReturn, TypeVar

from rgbd_rs.errors import RgbdError

T = TypeVar("T")
Run = Callable[[argparse.Namespace], int]


#: What reads as a negative number, so ``--min-depth -inf`` or ``--offset -1e-3`` give the flag its
#: value (argparse's own pattern knows only ``-1`` and ``-1.5`` and takes ``-inf`` for a flag);
#: also any word of a dash and a digit (``--shard -1/2``, ``--size -80x60``), so that the flag's
#: own check says what it got instead of "expected one argument".
NEGATIVE_NUMBER = re.compile(
    r"^-(?:\d+\.?\d*|\.\d+)(?:[eE][-+]?\d+)?$|^-(?:inf|infinity|nan)$|^-\d\S*$", re.IGNORECASE
)


class Parser(argparse.ArgumentParser):
    """An ArgumentParser whose errors are one line: ``rgbd: error: ... (see `PROG --help`)``,
    and that reads ``-inf``, ``-nan`` and ``-1e3`` as values (:data:`NEGATIVE_NUMBER`)."""

    def __init__(self, *args: Any, **kwargs: Any) -> None:
        super().__init__(*args, **kwargs)
        # argparse consults this (a private attribute since Python 3.2) before taking a word
        # that starts with "-" for an option; no rgbd flag looks like a number.
        self._negative_number_matcher = NEGATIVE_NUMBER

    def error(self, message: str) -> NoReturn:
        self.exit(2, f"rgbd: error: {one_line(message)} (see `{self.prog} --help`)\n")


def one_line(message: str) -> str:
    """``message`` with its line breaks folded, so an error is always one line."""
    return " ".join(message.split())


def fail(message: str) -> int:
    """Print ``rgbd: error: MESSAGE`` (one line) on stderr; the exit status of a failed run."""
    print(f"rgbd: error: {one_line(message)}", file=sys.stderr)
    return 2


def integer(minimum: int, maximum: int | None = None) -> Callable[[str], int]:
    """An argparse type: an integer in ``[minimum, maximum]``."""

    def parse(text: str) -> int:
        try:
            v = int(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"got {text!r}, expected an integer") from None
        if v < minimum or (maximum is not None and v > maximum):
            hi = "" if maximum is None else f" and <= {maximum}"
            raise argparse.ArgumentTypeError(f"got {v}, expected an integer >= {minimum}{hi}")
        return v

    return parse


def device(*, auto: bool) -> Callable[[str], str]:
    """An argparse type: a torch device that exists here (``cpu``, ``cuda``, ``cuda:N``; also
    ``auto`` when ``auto``), so ``--device tpu`` or ``cuda`` without a GPU fail while parsing."""
    from rgbd_rs import _validate

    def parse(text: str) -> str:
        try:
            return _validate.device("device", text, auto=auto)
        except RgbdError as exc:
            raise argparse.ArgumentTypeError(str(exc).removeprefix("device: ")) from None

    return parse


def _bound(x: float) -> str:
    """``x`` short where that is exact (``0.9``, ``1e+06``), else every digit it needs
    (``0.014814814814814815``): a bound copied from a message must pass."""
    short = f"{x:g}"
    return short if float(short) == x else repr(float(x))


def real(minimum: float, maximum: float, *, low_open: bool = True) -> Callable[[str], float]:
    """An argparse type: a finite number in ``(minimum, maximum]`` (``[minimum, ...`` when not
    ``low_open``)."""

    def parse(text: str) -> float:
        try:
            v = float(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"got {text!r}, expected a number") from None
        low_ok = v > minimum if low_open else v >= minimum
        if not (low_ok and v <= maximum):  # also refuses nan
            lo = f"> {_bound(minimum)}" if low_open else f">= {_bound(minimum)}"
            raise argparse.ArgumentTypeError(
                f"got {text}, expected a number {lo} and <= {_bound(maximum)}"
            )
        return v

    return parse


def shard(text: str) -> tuple[int, int]:
    """Parse ``--shard i/n`` (shard i of n, 0 <= i < n): the flag long dataset jobs share."""
    try:
        i, n = (int(v) for v in text.split("/"))
    except ValueError:
        raise argparse.ArgumentTypeError(f"got {text!r}, expected i/n (e.g. 0/4)") from None
    if not 0 <= i < n:
        raise argparse.ArgumentTypeError(f"got {text!r}, expected 0 <= i < n")
    return i, n


def without_name(flag: str, message: str) -> str:
    """``message`` without a leading ``"name: "`` when ``name`` is the flag's own parameter
    (``--data`` and ``"data: got ..."``), so that the flag is not followed by its name."""
    bare = flag.lstrip("-").replace("-", "_")
    return message[len(bare) + 1 :].lstrip() if message.startswith(f"{bare}:") else message


def named(flag: str, load: Callable[[], T]) -> T:
    """``load()``, with a bad file's error prefixed by the ``flag`` that named the file."""
    try:
        return load()
    except RgbdError as exc:
        raise type(exc)(f"{flag}: {without_name(flag, str(exc))}") from None
    except OSError as exc:
        raise RgbdError(f"{flag}: {os_message(exc)}") from None


def flagged(
    names: Mapping[str, str],
    call: Callable[[], T],
    amend: Callable[[str], str] | None = None,
    *,
    warnings_too: bool = True,
) -> T:
    """``call()``, with its errors and warnings about a library parameter worded for the
    command line: a message that starts ``"name:"`` (a key of ``names``) starts with that
    parameter's flag instead (``"camera: got a 640x480 camera ..."`` -> ``"--calib: got a
    640x480 camera ..."``). The call's warnings are shown once it has returned or failed; they
    and its error are first passed through ``amend`` (e.g. to add the flag value that fixes
    it). ``warnings_too=False`` words the error only and lets warnings show as they come (for
    a long call such as a training, whose warnings must not wait for its end)."""

    def worded(msg: str) -> str | None:
        for name, flag in names.items():
            if msg.startswith(f"{name}:"):
                return f"{flag}{msg[len(name) :]}"
        return None

    seen: list[warnings.WarningMessage] = []
    try:
        if not warnings_too:
            return call()
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            try:
                return call()
            finally:
                seen = list(caught)
    except (RgbdError, MemoryError) as exc:  # the native core's MemoryError names its argument
        text = str(exc) if amend is None else amend(str(exc))
        msg = worded(text)
        if msg is None:
            if text == str(exc):
                raise
            msg = text
        raise type(exc)(msg) from None
    finally:
        for w in seen:
            text = str(w.message) if amend is None else amend(str(w.message))
            warnings.warn(worded(text) or text, w.category, stacklevel=2)


def folder(text: str) -> Path:
    """An argparse type: an output folder, which must not be an existing file (checked while
    parsing, before minutes of work)."""
    if not text.strip():
        # Path("") is the working folder, whose files a command may then replace.
        raise argparse.ArgumentTypeError("got an empty path, expected a folder")
    path = Path(text)
    if path.exists() and not path.is_dir():
        raise argparse.ArgumentTypeError(f"got {text}, a file; expected a folder")
    return path


def input_paths(args: argparse.Namespace) -> dict[str, Path]:
    """The command's file arguments (every :class:`~pathlib.Path` but ``--out``), by flag."""
    return {
        "--" + k.replace("_", "-"): v
        for k, v in vars(args).items()
        if isinstance(v, Path) and k != "out"
    }


def output_folder(
    out: Path,
    outputs: Sequence[str],
    flag: str = "--out",
    inputs: Mapping[str, Path] | None = None,
) -> Path:
    """Create the output folder ``out`` and set aside the files a previous run of the command
    left there (in ``out/.rgbd-previous-<command>``, put back by :func:`finish_outputs` if this
    run does not finish): ``outputs`` are glob patterns (relative to ``out``) of everything the
    command may write, so a run that writes fewer files (no ``--undistort``, fit-only instead
    of the ConvNet) does not leave the other run's files beside its own. Other files are kept.
    ``inputs`` (flag -> path, e.g. :func:`input_paths`) are refused where the command would
    delete or overwrite one of them, before anything is touched."""
    refuse_overwriting(out, outputs, flag, inputs or {})
    try:  # a file at ``out`` (the ``folder`` type refused one while parsing) fails in mkdir
        out.mkdir(parents=True, exist_ok=True)
        backup = _backup(out, outputs)
        if backup.is_dir():  # a run that died before it finished: the last complete outputs
            _restore(out, outputs)
        for old in _outputs(out, outputs):
            dest = backup / old.relative_to(out)
            dest.parent.mkdir(parents=True, exist_ok=True)
            os.replace(old, dest)
    except OSError as exc:
        raise RgbdError(f"{flag}: {os_message(exc)}") from None
    _STAGED.append((out, tuple(outputs)))
    return out


#: Where :func:`output_folder` keeps a previous run's outputs until the new run has finished
#: (one folder per command, named by its outputs: commands sharing an --out never mix them).
PREVIOUS = ".rgbd-previous"


def _backup(out: Path, outputs: Sequence[str]) -> Path:
    """The folder of ``out`` that keeps the previous outputs of the command writing ``outputs``."""
    tag = hashlib.sha1("\n".join(outputs).encode()).hexdigest()[:8]
    return out / f"{PREVIOUS}-{tag}"


#: The output folders of the running command (``main`` finishes them).
_STAGED: list[tuple[Path, tuple[str, ...]]] = []


def _outputs(out: Path, outputs: Sequence[str]) -> list[Path]:
    """The files of ``out`` that match ``outputs`` (never those kept in :data:`PREVIOUS`)."""
    found = []
    for pattern in outputs:
        for p in out.glob(pattern):
            rel = p.relative_to(out).parts
            if (p.is_file() or p.is_symlink()) and not rel[0].startswith(PREVIOUS):
                found.append(p)
    return found


def _restore(out: Path, outputs: Sequence[str]) -> None:
    """Put the outputs kept aside for this command back, in place of a run's partial ones."""
    backup = _backup(out, outputs)
    if not backup.is_dir():
        return
    for new in _outputs(out, outputs):
        new.unlink()
    for f in sorted(backup.rglob("*")):
        if f.is_file() or f.is_symlink():
            dest = out / f.relative_to(backup)
            dest.parent.mkdir(parents=True, exist_ok=True)
            os.replace(f, dest)
    shutil.rmtree(backup, ignore_errors=True)


def finish_outputs(finished: bool) -> None:
    """End the running command's output folders: a command that finished drops the previous
    run's outputs it kept; one interrupted or failed puts them back (its partial outputs go),
    so a re-run into the same ``--out`` never loses the last complete result. Best effort."""
    while _STAGED:
        out, outputs = _STAGED.pop()
        try:
            if finished:
                shutil.rmtree(_backup(out, outputs), ignore_errors=True)
            else:
                _restore(out, outputs)
        except OSError:
            pass


def refuse_overwriting(
    out: Path, outputs: Sequence[str], flag: str, inputs: Mapping[str, Path]
) -> None:
    """An :class:`RgbdError` where an output of the command in ``out`` is one of ``inputs``."""
    if not out.is_dir():
        return
    written = {p.resolve(): p.name for pattern in outputs for p in out.glob(pattern)}
    for name, path in inputs.items():
        if path.exists() and path.resolve() in written:
            raise RgbdError(
                f"{flag}: the folder {out} would get a new {written[path.resolve()]}, but that "
                "file is the "
                f"input {name} ({path}): expected an output folder that does not hold the "
                "inputs under the names the command writes (choose another --out, or rename "
                "the input)"
            )


def writable_out(out: Path, flag: str = "--out") -> None:
    """Refuse, before any work, an output path nothing can be written to: the nearest folder
    that exists at or above ``out`` must take a new file (probed with a temporary file, removed
    at once), and no file may stand where ``out`` needs a folder."""
    path = out.absolute()
    have = path
    while not have.exists() and have.parent != have:
        if have.is_symlink():  # a link to nowhere: nothing can be created through it
            raise RgbdError(
                f"{flag}: got {out}, but {have} is a link to {os.readlink(have)}, which does not "
                "exist: expected a path in a folder"
            )
        have = have.parent
    if have != path and not have.is_dir():
        raise RgbdError(f"{flag}: got {out}, but {have} is a file: expected a path in a folder")
    target = have if have.is_dir() else have.parent
    try:
        with tempfile.TemporaryFile(dir=target):
            pass
    except OSError as exc:
        reason = exc.strerror or str(exc)
        raise RgbdError(
            f"{flag}: got {out}, but nothing can be written in {target} ({reason}): expected a "
            "writable location"
        ) from None


def os_message(exc: OSError) -> str:
    """``FILE: reason`` of an OSError (permission denied, a folder where a file belongs, ...)."""
    reason = exc.strerror or str(exc)
    return f"{exc.filename}: {reason}" if exc.filename else reason


#: The shared command groups: name -> (help, description). A group appears in ``rgbd --help``
#: once a pipeline adds a ``WHAT`` to it.
GROUPS: dict[str, tuple[str, str]] = {
    "eval": (
        "evaluate a pipeline against ground truth",
        "Evaluate a pipeline; each WHAT is one pipeline's evaluation protocol.",
    ),
    "train": (
        "train a pipeline's network",
        "Train a pipeline's network; each WHAT is one pipeline's trainer.",
    ),
}


class Commands:
    """What a pipeline registers its commands with: top-level commands (``rgbd fuse``) and the
    ``WHAT`` of a shared group (``rgbd eval fusion``, ``rgbd train segmentation``)."""

    def __init__(self, sub: argparse._SubParsersAction[Parser]) -> None:
        self._sub = sub
        self._groups: dict[str, argparse._SubParsersAction[Parser]] = {}

    def command(self, name: str, run: Run, *, help: str, description: str) -> Parser:
        """Add ``rgbd NAME``; ``run(args)`` returns the exit status."""
        p = self._sub.add_parser(name, help=help, description=description)
        p.set_defaults(run=run)
        return p

    def group_command(
        self, group: str, what: str, run: Run, *, help: str, description: str
    ) -> Parser:
        """Add ``rgbd GROUP WHAT`` (``group`` is ``"eval"`` or ``"train"``)."""
        if group not in self._groups:
            group_help, group_description = GROUPS[group]
            g = self._sub.add_parser(group, help=group_help, description=group_description)
            self._groups[group] = g.add_subparsers(dest=group, metavar="WHAT", required=True)
        p = self._groups[group].add_parser(what, help=help, description=description)
        p.set_defaults(run=run)
        return p


def training_run_options(
    p: argparse.ArgumentParser,
    init_help: str = "start from this checkpoint's weights (fine-tune)",
) -> None:
    """The options every ``rgbd train WHAT`` of the shared trainer takes after its own: seed,
    checkpoint period, data-loader workers, device, ``--init``, ``--ship``, ``--no-resume`` and
    ``--quiet`` (one wording for all; ``init_help`` says what ``--init`` takes from a network)."""
    from pathlib import Path

    p.add_argument("--seed", type=integer(0, 2**32 - 1), default=0, metavar="N", help="seed (0)")
    p.add_argument(
        "--checkpoint-steps",
        type=integer(0),
        default=50,
        metavar="N",
        help="also save every N steps (50)",
    )
    p.add_argument(
        "--workers", type=integer(0, 64), default=0, metavar="N", help="data-loader processes (0)"
    )
    p.add_argument(
        "--device",
        type=device(auto=True),
        default="auto",
        metavar="DEV",
        help="auto, cpu, cuda or cuda:N (auto; under torchrun auto or cuda: GPU LOCAL_RANK)",
    )
    p.add_argument(
        "--init",
        type=Path,
        metavar="FILE",
        help=init_help,
    )
    p.add_argument("--ship", action="store_true", help="copy the best checkpoint into the package")
    p.add_argument(
        "--no-resume",
        action="store_true",
        help="start afresh, overwriting --out's checkpoints (default: resume from its last.pt)",
    )
    p.add_argument(
        "--quiet",
        action="store_true",
        help="no progress (a bar on a terminal, otherwise one line per epoch on stderr)",
    )
