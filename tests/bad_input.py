"""Shared by the tests/test_bad_input*.py files (not a test module itself): a bad-input case
states, for one public callable, the call, the exact RgbdError subclass it must raise
(ShapeMismatchError for shapes, InvalidArgumentError for other arguments, RgbdError itself for
a file whose content is bad) and a pattern the message must contain (the argument or file).

Calls that would allocate absurd sizes run in a child interpreter (:func:`isolated`), so a
missing check aborts the child ("memory allocation of N bytes failed"), not the test run.
"""

from __future__ import annotations

import re
import subprocess
import sys
import textwrap
from collections.abc import Callable
from dataclasses import dataclass

import pytest

from rgbd_rs import RgbdError


@dataclass(frozen=True)
class Case:
    #: The public callable covered, as the meta-test names it: ``func``, ``Class``,
    #: ``Class.method``.
    name: str
    call: Callable[[], object]
    error: type[RgbdError]
    #: Regular expression searched in the message (names the argument or the file).
    match: str
    #: Tells several cases of one callable apart.
    label: str = ""

    @property
    def id(self) -> str:
        return f"{self.name}[{self.label}]" if self.label else self.name


def check(case: Case) -> None:
    """The call raises exactly ``case.error`` with a message matching ``case.match``."""
    with pytest.raises(RgbdError) as info:
        case.call()
    exc = info.value
    assert type(exc) is case.error, f"raised {type(exc).__name__}: {exc}"
    assert re.search(case.match, str(exc)), f"{case.match!r} not in {str(exc)!r}"


def public_cases(cases: list[Case]) -> list[Case]:
    """The cases of names the package exports: what the coverage meta-test counts (cases of
    private helpers still run in their own file; their checks guard the package's calls)."""
    from test_bad_input_coverage import public_callables

    public = set(public_callables())
    return [c for c in cases if c.name in public]


def params(cases: list[Case]) -> list[object]:
    return [pytest.param(c, id=c.id) for c in cases]


def isolated(code: str, timeout: float = 120.0) -> Callable[[], object]:
    """A call that runs ``code`` (which must raise) in a child interpreter and re-raises the
    RgbdError it printed in this process; a child that dies (abort, segfault) fails the test
    with its exit status and stderr."""

    def call() -> object:
        script = textwrap.dedent(
            """
            import sys
            import numpy as np
            import rgbd_rs
            from rgbd_rs import RgbdError
            try:
            {body}
            except RgbdError as exc:
                print(type(exc).__name__ + "\\n" + str(exc))
                sys.exit(0)
            print("no error")
            """
        ).format(body=textwrap.indent(textwrap.dedent(code).strip(), "    "))
        res = subprocess.run(
            [sys.executable, "-c", script],
            capture_output=True,
            text=True,
            timeout=timeout,
            check=False,
        )
        assert res.returncode == 0, (
            f"the child interpreter died with status {res.returncode}: {res.stderr[-2000:]}"
        )
        kind, _, message = res.stdout.partition("\n")
        if kind == "no error":
            return None
        import rgbd_rs

        raise getattr(rgbd_rs, kind.strip())(message.strip())

    return call
