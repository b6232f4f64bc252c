"""What the commands share to show their work: aligned text tables, a progress bar for work
measured in simulated seconds, and the output folders a command holds until it ends."""

from __future__ import annotations

from pathlib import Path

from navsim.foundations.outputs import OutputFolder
from navsim.foundations.progress import Progress


def _numeric(text: str) -> bool:
    try:
        float(text)
        return True
    except ValueError:
        return False


def table(headers: list[str], rows: list[list[str]]) -> str:
    """``rows`` under ``headers`` in aligned columns, numbers to the right."""
    widths = [max(len(h), *(len(r[i]) for r in rows)) if rows else len(h)
              for i, h in enumerate(headers)]
    line = "  ".join(h.ljust(w) for h, w in zip(headers, widths))
    out = [line, "  ".join("-" * w for w in widths)]
    out += ["  ".join(c.rjust(w) if _numeric(c) else c.ljust(w) for c, w in zip(r, widths))
            for r in rows]
    return "\n".join(out)


def progress(desc: str):
    """A :class:`Progress` in percent and ``update(t_s, nominal_s)`` for work measured in
    simulated seconds (a flight, a replay)."""
    bar = Progress(100, desc, unit="%", leave=False)

    def update(t_s, nominal_s):
        target = min(int(100 * t_s / max(nominal_s, 1.0)), 99)
        if target > bar.n:
            bar.update(target - bar.n)
    return bar, update


#: the output folders the command being run holds (closed by :func:`navsim.cli.main` however
#: it ends)
OPEN: list = []


def open_folder(args, default: Path) -> OutputFolder:
    """The command's output folder (``--out``, else ``default``), locked until the command
    ends; ``--force`` writes into a folder that is not navsim's."""
    folder = OutputFolder(Path(args.out) if args.out else default, command=args.command, force=args.force)
    OPEN.append(folder)
    return folder


def close_folders() -> None:
    """Close every folder the command held (the last opened first)."""
    while OPEN:
        OPEN.pop().close()
