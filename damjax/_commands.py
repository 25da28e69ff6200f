"""How damjax's commands end (``damjax ...`` and ``python -m damjax.ensemble``): an error
is one line per problem on stderr and an exit code, never a traceback."""

from __future__ import annotations

import argparse
import errno
import os
import re
import sys
from collections.abc import Callable
from typing import Any

# a value that starts with "-" is read as a flag unless it looks like a number; argparse's
# own pattern knows "-5" and "-0.5" but not "-1e3", "-inf" or "-nan", which then failed as
# "expected one argument" instead of reaching the range check
_NEGATIVE_NUMBER = re.compile(r"^-(\d+\.?\d*|\.\d+)([eE][-+]?\d+)?$|^-(inf|infinity|nan)$", re.I)


class Parser(argparse.ArgumentParser):
    """The commands' parser: an error is one ``damjax: error:`` line and exit code 2 (no
    usage dump), and negative numbers in any notation are values, not flags."""

    def __init__(self, *args: Any, **kwargs: Any) -> None:
        super().__init__(*args, **kwargs)
        self._negative_number_matcher = _NEGATIVE_NUMBER

    def error(self, message: str) -> Any:  # one line, exit 2, no usage dump
        sys.stderr.write(f"damjax: error: {message}\n")
        sys.exit(2)


def dispatch(func: Callable[[Any], int], ns: Any, interrupted: str = "damjax: interrupted") -> int:
    """``func(ns)``, its exit code, or that of what stopped it: 2 for invalid input
    (a ValueError, one ``damjax: error:`` line per line of its message), 130 after
    Ctrl-C (the line ``interrupted``), 0 when the reader of stdout left (``damjax show
    DIR | head``), 1 for an unreadable input, an unwritable output folder or a full disk
    (an OSError)."""
    try:
        return func(ns)
    except ValueError as exc:  # validation: one line per problem
        for line in str(exc).splitlines():
            sys.stderr.write(f"damjax: error: {line}\n")
        return 2
    except KeyboardInterrupt:
        sys.stderr.write(interrupted + "\n")
        return 130
    except BrokenPipeError:  # the reader left, not an error
        devnull = os.open(os.devnull, os.O_WRONLY)
        os.dup2(devnull, sys.stdout.fileno())  # no second error when Python flushes stdout
        return 0
    except OSError as exc:  # unreadable input, unwritable output folder, full disk
        text = str(exc)
        if exc.strerror:  # without Python's "[Errno 28]"
            text = exc.strerror + (f": {exc.filename}" if exc.filename else "")
        if exc.errno == errno.ENOSPC:
            text += (
                " (free some space, or give another --out; a checkpoint already written is kept)"
            )
        sys.stderr.write(f"damjax: error: {' '.join(text.split())}\n")
        return 1


def add_set_flag(p: Any) -> None:
    """``--set KEY=VALUE`` (repeatable): a scenario key changed for this run."""
    p.add_argument(
        "--set",
        action="append",
        metavar="KEY=VALUE",
        default=None,
        help="change a scenario key for this run, e.g. --set setup.duration=0.5 --set "
        "strength.seed=3 (a TOML value; a bare word is a string; nothing after = removes "
        "the key; a relative file path is taken from the working directory; repeatable)",
    )
