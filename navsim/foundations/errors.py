"""Errors that reach the user with a clear message instead of a traceback."""

from __future__ import annotations

import errno


class NavsimError(Exception):
    """Base class of the errors the command line reports without a traceback."""

    exit_code = 1


class ScenarioError(NavsimError):
    """A malformed scenario or track: names the file, the key path, what was expected, a hint."""

    exit_code = 2

    def __init__(self, message: str, *, file=None, key: str | None = None,
                 expected: str | None = None, hint: str | None = None, origin: str | None = None):
        # ``file``: a str or a path (a Scenario's ``path``), kept as text; ``origin``: what
        # wrote the key beside the file (``--set PATH=VALUE``)
        self.file = None if file is None else str(file)
        self.key, self.expected, self.hint, self.origin = key, expected, hint, origin
        self.detail = message
        super().__init__(self._format())

    def _format(self) -> str:
        where = self.file or ("" if self.origin else "<scenario>")
        if self.origin:
            where = f"{where} ({self.origin})" if where else self.origin
        if self.key:
            where += f": {self.key}"
        text = f"{where}: {self.detail}"
        if self.expected:
            text += f" (expected {self.expected})"
        if self.hint:
            text += f"\n  hint: {self.hint}"
        return text

    def with_file(self, file: str) -> "ScenarioError":
        """The same error, naming ``file``."""
        return ScenarioError(self.detail, file=file, key=self.key, expected=self.expected,
                             hint=self.hint, origin=self.origin)


class FlightError(NavsimError):
    """The aircraft could not fly the track: stall, impact, an unflyable segment, NaN."""

    exit_code = 3

    def __init__(self, reason: str, *, segment: int | None = None,
                 segment_label: str | None = None, time_s: float | None = None):
        self.reason, self.segment, self.segment_label, self.time_s = (
            reason, segment, segment_label, time_s)
        where = []
        if segment is not None:
            where.append(f"segment {segment} ({segment_label})")
        if time_s is not None:
            where.append(f"t = {time_s:.2f} s")
        prefix = "flight failed" + (" in " + ", ".join(where) if where else "")
        super().__init__(f"{prefix}: {reason}")


class LogError(NavsimError):
    """A flight log that cannot be replayed (missing, truncated, corrupt, lacking a topic or a
    field, too short): names the file, what is missing and a hint."""

    exit_code = 2

    def __init__(self, message: str, *, file: str | None = None, hint: str | None = None):
        self.file, self.detail, self.hint = file, message, hint
        text = f"{file or '<log>'}: {message}"
        super().__init__(text + (f"\n  hint: {hint}" if hint else ""))


class UsageError(NavsimError):
    """A command line that cannot be served: an unknown estimator, a parameter it does not take."""

    exit_code = 2


class OutputError(NavsimError):
    """The operating system refused an output: a folder that is a file, cannot be created or
    written, a full disk. Names the path and the system's reason."""

    exit_code = 4

    def __init__(self, path, exc: OSError | None = None, *, reason: str | None = None):
        self.path = str(path)
        self.errno = exc.errno if exc is not None else None
        why = reason or (exc.strerror if exc is not None and exc.strerror else str(exc))
        self.reason = why
        super().__init__(f"{self.path}: {why}"
                         + ("\n  hint: free some space, or write elsewhere with --out"
                            if exc is not None and exc.errno == errno.ENOSPC else ""))
