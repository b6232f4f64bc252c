"""A report's pages to files: each to its PNG and all, in order, to ``report.pdf``."""

from __future__ import annotations

import os
import signal
import sys
import threading
from pathlib import Path

from navsim.foundations.errors import OutputError
from navsim.foundations.outputs import OutputFolder, write_atomic
from navsim.report.figures import Page
from navsim.report.tables import PNG_DPI


#: the share of the PNGs this process draws after the PDF while a forked child draws the others:
#: a page's PNG costs about 1.4 times its PDF page (P0's report, 15 pages: 2.4 s and 1.6-1.8 s),
#: and P0's report measured 3.2-3.4 s with a fifth of them here, 3.4-3.5 s with 15 % or 10 %
PARENT_PNG_SHARE = 0.2

#: zlib's level for the PNGs and the PDF's streams: 1 instead of matplotlib's 6 writes P0's
#: report in 0.6 s less CPU for 9 % larger PNGs and a 20 % larger PDF
COMPRESS_LEVEL = 1


def render(folder: OutputFolder, pages: list[Page], fmts, title: str, pdf: str = "report.pdf") -> list[Path]:
    """Each page to ``<name>.png`` and all of them, in order, to ``pdf`` (``title`` in
    its metadata); returns the files written. Where the machine has a second core and ``fork``
    (Linux), a forked child draws most PNGs while this process draws the PDF and the rest
    (:data:`PARENT_PNG_SHARE`)."""
    out = folder.path
    pngs = [(out / f"{page.name}.png", page.figure) for page in pages] if "png" in fmts else []
    pdf_path = out / pdf if "pdf" in fmts else None
    folder.record([p for p, _ in pngs] + ([pdf_path] if pdf_path else []))
    split = len(pngs) - round(PARENT_PNG_SHARE * len(pngs))
    child = _fork_writer(pngs[:split]) if pngs and pdf_path and _can_fork() else None
    here = pngs[split:] if child is not None else pngs
    try:
        if pdf_path is not None:
            write_atomic(pdf_path, lambda p: _write_pdf(p, pages, title))
        _write_pngs(here)
    except BaseException:
        if child is not None:                 # this error is the one reported
            _join_writer(*child, report=False)
        raise
    if child is not None:
        _join_writer(*child)
    return [p for p, _ in pngs] + ([pdf_path] if pdf_path else [])


def _write_pngs(pngs: list) -> None:
    for path, fig in pngs:
        write_atomic(path, lambda p, fig=fig: fig.savefig(p, dpi=PNG_DPI,
                                                         pil_kwargs={"compress_level": COMPRESS_LEVEL}))


def _write_pdf(path: Path, pages: list[Page], title: str) -> None:
    from matplotlib import rc_context
    from matplotlib.backends.backend_pdf import PdfPages
    with rc_context({"pdf.compression": COMPRESS_LEVEL}), PdfPages(path) as pdf:
        for page in pages:
            pdf.savefig(page.figure)
        pdf.infodict()["Title"] = title


def _can_fork() -> bool:
    return (sys.platform == "linux" and hasattr(os, "fork") and len(os.sched_getaffinity(0)) > 1
            and threading.current_thread() is threading.main_thread())


def _fork_writer(pngs: list):
    """Fork a child that writes the PNGs ``(path, figure)``; returns its pid and the pipe on
    which it reports a failure (errno, path and reason of an OS error, or an exception's
    name and message; nothing on success), or None when the fork fails. Ctrl-C is held back
    across the fork, so it reaches the child inside its ``try``."""
    r, w = os.pipe()
    held = signal.pthread_sigmask(signal.SIG_BLOCK, {signal.SIGINT})
    try:
        pid = os.fork()
    except OSError:                          # no process to spare: drawn one after the other
        signal.pthread_sigmask(signal.SIG_SETMASK, held)
        os.close(r)
        os.close(w)
        return None
    if pid:
        signal.pthread_sigmask(signal.SIG_SETMASK, held)
        os.close(w)
        return pid, r
    code = 0
    try:
        signal.pthread_sigmask(signal.SIG_SETMASK, held)
        os.close(r)
        _write_pngs(pngs)
    except OutputError as exc:
        os.write(w, f"{exc.errno or 0}\n{exc.path}\n{exc.reason}".encode())
        code = 4
    except KeyboardInterrupt:
        code = 130
    except BaseException as exc:              # the parent reports it; never return into it
        os.write(w, f"\n\n{type(exc).__name__}: {exc}".encode())
        code = 1
    finally:
        os._exit(code)


def _join_writer(pid: int, pipe: int, report: bool = True) -> None:
    """Wait for the PNG writer and, with ``report``, raise its failure here."""
    try:
        with os.fdopen(pipe, "rb") as f:
            message = f.read().decode(errors="replace")
    finally:                                  # never a zombie, even on Ctrl-C
        _, status = os.waitpid(pid, 0)
    code = os.waitstatus_to_exitcode(status)
    if code == 0 or not report:
        return
    if code == 130:
        raise KeyboardInterrupt
    number, path, why = (message.split("\n", 2) + ["", ""])[:3]
    if path:
        number = int(number or 0)
        raise OutputError(path, OSError(number, why)) if number else OutputError(path, reason=why)
    raise RuntimeError(f"the PNG writer failed: {why or f'exit code {code}'}")


# --- attitude estimators (P4): the summary's attitude table and the roll/pitch/yaw pages ---

