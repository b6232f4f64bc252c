"""Progress of long work that shows everywhere: :class:`Progress`.

On a terminal it is a ``tqdm`` bar. Elsewhere (a log file, a batch job, CI) a bar would print
nothing or garbage, so it logs a plain line every tenth of the work and at the end (logger
``navsim.progress``, level INFO)::

    navsim run p0_bd_sins_ads: 250/1000 runs (25 %), 12 s elapsed, about 36 s left

The library only logs; ``navsim``'s command line sends that logger to stderr.
"""

from __future__ import annotations

import logging
import sys
import time

from tqdm import tqdm

log = logging.getLogger("navsim.progress")

#: a plain line every 1 / STEPS of the work
STEPS = 10


def _seconds(s: float) -> str:
    return f"{s:.0f} s" if s < 120 else f"{s / 60:.1f} min"


class Progress:
    """``update(n)`` as work is done, ``close()`` (or a ``with`` block) at the end.

    Parameters
    ----------
    total : int
        The amount of work, in ``unit``.
    desc : str
        What is being done (the line's start).
    unit : str
        ``run``, ``point``, ``%``, ...
    stream : file, optional
        Where the bar is drawn (default ``sys.stderr``).
    tty : bool, optional
        Force the bar (True) or the logged lines (False); default: whether ``stream`` is a
        terminal.
    leave : bool
        Whether the bar stays on the terminal when closed.
    """

    def __init__(self, total: int, desc: str, unit: str = "run", stream=None, tty: bool | None = None,
                 leave: bool = True):
        self.total, self.desc, self.unit = max(int(total), 0), desc, unit
        self.stream = stream if stream is not None else sys.stderr
        self.tty = self.stream.isatty() if tty is None else tty
        self.n, self.t0, self._shown = 0, time.perf_counter(), 0      #: ``_shown``: the last step written
        self.bar = tqdm(total=self.total, desc=desc, unit=unit, file=self.stream, leave=leave) if self.tty else None

    def update(self, n: int = 1) -> None:
        self.n += n
        if self.bar is not None:
            self.bar.update(n)
        elif self.total and self.n < self.total and (self.n * STEPS) // self.total > self._shown:
            self._line()
            self._shown = (self.n * STEPS) // self.total

    def line(self) -> str:
        """The plain progress line."""
        elapsed = time.perf_counter() - self.t0
        share = self.n / self.total if self.total else 1.0
        count = f"{self.n}%" if self.unit == "%" else f"{self.n}/{self.total} {self.unit}s ({100 * share:.0f} %)"
        left = f", about {_seconds(elapsed * (1 - share) / share)} left" if 0 < share < 1 else ""
        return f"{self.desc}: {count}, {_seconds(elapsed)} elapsed{left}"

    def _line(self) -> None:
        log.info(self.line())

    def close(self) -> None:
        if self.bar is not None:
            self.bar.close()
            self.bar = None
        elif self.total and self.n:
            self._line()
        self.total = 0

    def __enter__(self):
        return self

    def __exit__(self, *exc) -> None:
        self.close()
