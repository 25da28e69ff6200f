"""Progress bars: tqdm's in a terminal or a notebook; elsewhere (a log file, a batch
job's stderr) plain lines at most every `LOG_INTERVAL` seconds, without the carriage
returns that fill a log with a redrawn bar."""

from __future__ import annotations

import sys
from typing import Any

LOG_INTERVAL = 30.0  # [s] between two progress lines when stderr is not a terminal


class _Lines:
    """A stream for tqdm whose redraws ("\\r" + status) become one line each."""

    def __init__(self, stream: Any) -> None:
        self.stream = stream

    def write(self, s: str) -> None:
        text = s.replace("\r", "").strip()
        if text:
            self.stream.write(text + "\n")

    def flush(self) -> None:
        self.stream.flush()

    def isatty(self) -> bool:
        return False


def progress_bar(iterable: Any = None, **kw: Any) -> Any:
    """``tqdm(iterable, **kw)`` on stderr: the notebook widget in a notebook, the redrawn
    bar in a terminal, otherwise a line every `LOG_INTERVAL` seconds and one at the end."""
    from tqdm.auto import tqdm
    from tqdm.autonotebook import tqdm as chosen

    stderr = sys.stderr
    terminal = bool(getattr(stderr, "isatty", lambda: False)())
    if chosen.__module__ == "tqdm.std" and not terminal and "file" not in kw:
        kw["file"] = _Lines(stderr)
        kw.setdefault("mininterval", LOG_INTERVAL)
        kw.setdefault("ncols", 80)
    return tqdm(iterable, **kw)
