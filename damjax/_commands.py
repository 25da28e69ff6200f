"""How damjax's commands end (``damjax ...`` and ``python -m damjax.ensemble``): an error
is one line per problem on stderr and an exit code, never a traceback."""

from __future__ import annotations

import os
import sys
from collections.abc import Callable
from typing import Any


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
        sys.stderr.write(f"damjax: error: {' '.join(str(exc).split())}\n")
        return 1
