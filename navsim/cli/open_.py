"""``navsim open``: a result's interactive page (``report.html``, ``compare.html``, ...) in the
user's web browser; its path printed where there is none (a server, a terminal over SSH)."""

from __future__ import annotations

import argparse
import os
import sys
import webbrowser
from pathlib import Path

from navsim.cli.command import Command
from navsim.foundations.errors import UsageError

#: the interactive pages a result folder may hold, looked for in this order
PAGES = ("report.html", "compare.html", "budget.html", "sweep.html", "tune.html")


def page_of(target: Path) -> Path:
    """The page to open: ``target`` itself when it is an ``.html`` file, else the first of
    :data:`PAGES` in the folder ``target``; a :class:`UsageError` naming what was looked for."""
    if target.is_file() and target.suffix == ".html":
        return target
    if not target.exists():
        raise UsageError(f"{target}: no such folder\n  hint: give the output folder of navsim run, compare, budget, "
                         "sweep or tune (reports/<name> by default)")
    if not target.is_dir():
        raise UsageError(f"{target}: not a folder nor an .html page")
    for name in PAGES:
        if (target / name).is_file():
            return target / name
    raise UsageError(f"{target}: no interactive page in it (looked for {', '.join(PAGES)})\n  hint: a result of an "
                     "older navsim, or of a scenario whose report.formats leave out html, has none: add html to "
                     "report.formats (or take the line out) and run again, or write a run's report again: python -c "
                     f"\"import navsim; navsim.write_report(navsim.open_result('{target}'))\"")


def can_show() -> bool:
    """Whether a graphical browser can be at hand: always on macOS and Windows, on other systems
    only with a display (else ``webbrowser`` would start a text browser in this terminal)."""
    return sys.platform in ("darwin", "win32") or bool(os.environ.get("DISPLAY") or os.environ.get("WAYLAND_DISPLAY"))


def arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("folder", type=Path, help="a result folder (navsim run, compare, budget, sweep, tune) or an .html "
                   "page")
    p.add_argument("--print", dest="only_print", action="store_true",
                   help="print the page's path, open nothing")


def handle(args) -> int:
    page = page_of(args.folder).resolve()
    opened = False
    if not args.only_print and can_show():
        try:
            opened = webbrowser.open(page.as_uri())
        except webbrowser.Error:
            opened = False
    print(page if opened or args.only_print else f"{page}\n(no web browser here: open it in one; the file stands alone, "
          "it can be copied)")
    return 0


COMMAND = Command(
    "open", "open a result's interactive page in the web browser", usage="FOLDER",
    description="Open the interactive page of a result folder (report.html of navsim run; compare.html, "
    "budget.html, sweep.html, tune.html) in the web browser; print its path where there is none.",
    arguments=arguments, handler=handle)
