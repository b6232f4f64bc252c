"""A report's pages to files: all of them, in order, to ``report.pdf``, drawn once; each PNG is
its page of that PDF rasterised (PDFium, through ``pypdfium2``), not drawn a second time.

A report of :data:`SPLIT_PAGES` pages or more is drawn by two processes where the system can
fork and has two cores: the pages are shared by their expected cost, a forked child writes its
share to a PDF of its own, hands it over and rasterises their PNGs while this process does the
others; the two PDFs are joined into one document by PDFium, the pages in their order (each
page as it was drawn, the PNGs equal to the joined PDF's pages). A child that fails, or gives
no answer within :data:`CHILD_TIMEOUT_S`, is ended and its pages drawn here, so a failure is
reported as the sequential path reports it.
"""

from __future__ import annotations

import ctypes
import io
import multiprocessing
import os
import threading
from pathlib import Path

from matplotlib.lines import Line2D
from matplotlib.text import Text

from navsim.experiment.executors import die_with_parent
from navsim.foundations.outputs import OutputFolder, temporary_name, write_atomic
from navsim.report.figures import Page
from navsim.report.tables import PNG_DPI

#: zlib's level for the PNGs and the PDF's streams: 1 instead of matplotlib's 6 writes P0's
#: report in 0.6 s less CPU for 9 % larger PNGs and a 20 % larger PDF
COMPRESS_LEVEL = 1
#: a PDF point is 1/72 inch
POINTS_PER_INCH = 72.0
#: PDFium must not be called from two threads at once, even on two documents (pypdfium2's
#: documentation): one report is rasterised at a time in a process
_PDFIUM = threading.Lock()
#: the fewest pages drawn by two processes (below, a fork costs more than it saves)
SPLIT_PAGES = 6
#: how long this process waits for each of the child's two messages (its PDF, then its PNGs
#: done) once it has done the same work itself, s, before the child is ended and its work done
#: here (a child blocked on a lock another thread held at fork)
CHILD_TIMEOUT_S = 60.0
#: how long a child that sent its pages may take to end, s
CHILD_EXIT_S = 10.0
#: a page's expected drawing time per text (its glyphs laid out in the PDF by matplotlib) and per
#: point of its lines (rasterised by PDFium), s: P0's and P4's reports, measured page by page
TEXT_COST_S, POINT_COST_S = 1e-3, 1e-5


def render(folder: OutputFolder, pages: list[Page], fmts, title: str, pdf: str = "report.pdf") -> list[Path]:
    """All pages, in order, to ``pdf`` (``title`` in its metadata), then each page to
    ``<name>.png``, rasterised from that PDF at :data:`~navsim.report.tables.PNG_DPI` (the PDF
    kept in memory where only PNGs are asked for); returns the files written."""
    out = folder.path
    pngs = [out / f"{page.name}.png" for page in pages] if "png" in fmts else []
    pdf_path = out / pdf if "pdf" in fmts else None
    folder.record(pngs + ([pdf_path] if pdf_path else []))
    if pdf_path is None and not pngs:
        return []
    save = (lambda data: write_atomic(pdf_path, lambda p: _save_pdf(p, data))) if pdf_path is not None else None
    if _can_split(len(pages)):
        _render_split(pages, pngs, title, save)
    else:
        data = _pdf_bytes(pages, title)
        if save is not None:
            save(data)
        _write_pngs(data, pngs)
    return pngs + ([pdf_path] if pdf_path else [])


def _can_split(n_pages: int) -> bool:
    """Whether two processes draw the report: enough pages and a child at hand (:func:`can_fork`)."""
    return n_pages >= SPLIT_PAGES and can_fork()


def can_fork() -> bool:
    """Whether a forked child can share the work: ``fork``, two cores, and this process allowed
    children (a daemonic one is not)."""
    cores = len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else (os.cpu_count() or 1)
    return cores > 1 and "fork" in multiprocessing.get_all_start_methods() and not multiprocessing.current_process().daemon


class ForkedWrite:
    """``write()`` (which writes ``paths``, each through a temporary name) in a forked child
    while this process goes on, where one can be had (:func:`can_fork`); :meth:`finish` waits
    for it and, where it failed or gave no word within :data:`CHILD_TIMEOUT_S`, ends it, removes
    what it left half written and calls ``write()`` here (its error then raised here); without
    a child, :meth:`finish` calls ``write()``."""

    def __init__(self, write, paths: list[Path]):
        self.write, self.paths, self.process = write, paths, None
        if can_fork():
            ctx = multiprocessing.get_context("fork")
            self.receive, send = ctx.Pipe(duplex=False)
            self.process = ctx.Process(target=_write_child, args=(send, write), daemon=True)
            self.process.start()
            send.close()

    def finish(self) -> None:
        """The files written, by the child or, failing it, here."""
        if not self.end():
            self.write()

    def end(self, abandon: bool = False) -> bool:
        """Wait for the child (once): whether it wrote the files; one that did not, or any with
        ``abandon`` (this process failed: nothing more is written), is ended and its temporary
        files removed."""
        process, self.process = self.process, None
        if process is None:
            return False
        done = False
        try:
            done = not abandon and self.receive.poll(CHILD_TIMEOUT_S) and self.receive.recv_bytes() == _DONE
        except (EOFError, OSError):
            pass
        self.receive.close()
        process.join(timeout=CHILD_EXIT_S if done else 0)
        if process.is_alive():
            process.terminate()
            process.join()
        if not done:
            for path in self.paths:
                temporary_name(path).unlink(missing_ok=True)
        return done


def _write_child(send, write) -> None:
    """In the forked child of :class:`ForkedWrite`: ``write()``, then :data:`_DONE`; on any
    failure it ends quietly (the parent writes the files and reports the failure)."""
    try:
        die_with_parent()
        write()
        send.send_bytes(_DONE)
        send.close()
    except BaseException:
        os._exit(1)


def _pdf_bytes(pages: list[Page], title: str) -> bytes:
    buf = io.BytesIO()
    _write_pdf(buf, pages, title)
    return buf.getvalue()


def _save_pdf(path, data: bytes) -> None:
    """The PDF's bytes to ``path`` (a file of its own, written whole)."""
    with open(path, "wb") as f:
        f.write(data)


class _Child:
    """The forked process drawing its share of the pages (:func:`_child`): its PDF first, then
    a word when its PNGs are written; ended, its unfinished files removed, where it fails or
    hangs."""

    def __init__(self, pages: list[Page], pngs: list[Path], title: str):
        ctx = multiprocessing.get_context("fork")
        self.receive, send = ctx.Pipe(duplex=False)
        self.pngs = pngs
        self.process = ctx.Process(target=_child, args=(send, pages, pngs, title), daemon=True)
        self.ended = False
        self.process.start()
        send.close()

    def message(self, timeout_s: float) -> bytes | None:
        """The child's next message, or None where it ended without one or gave none in time."""
        try:
            if self.receive.poll(timeout_s):
                return self.receive.recv_bytes()
        except (EOFError, OSError):
            pass
        return None

    def end(self, finished: bool) -> None:
        """Wait for a child that has ``finished`` to exit; end one that has not, and remove the
        temporary files it may have left half written. Once only (later calls do nothing)."""
        if self.ended:
            return
        self.ended = True
        self.receive.close()
        self.process.join(timeout=CHILD_EXIT_S if finished else 0)
        if self.process.is_alive():
            self.process.terminate()
            self.process.join()
        if not finished:
            for path in self.pngs:
                temporary_name(path).unlink(missing_ok=True)


def page_cost_s(page: Page) -> float:
    """A page's expected drawing time, s: its texts (laid out glyph by glyph into the PDF) and
    its lines' points (rasterised by PDFium), at :data:`TEXT_COST_S` and :data:`POINT_COST_S`."""
    fig = page.figure
    texts = sum(1 for t in fig.findobj(Text) if t.get_visible() and t.get_text())
    points = sum(len(line.get_xdata()) for line in fig.findobj(Line2D) if line.get_visible())
    return texts * TEXT_COST_S + points * POINT_COST_S


def shares(costs: list[float]) -> tuple[list[int], list[int]]:
    """The pages' indices for this process and for the child, each in order: the costliest page
    first to the share with less so far (both shares have a page)."""
    totals, out = [0.0, 0.0], ([], [])
    for i in sorted(range(len(costs)), key=lambda i: -costs[i]):
        k = 0 if totals[0] <= totals[1] else 1
        out[k].append(i)
        totals[k] += costs[i]
    return sorted(out[0]), sorted(out[1])


def _render_split(pages: list[Page], pngs: list[Path], title: str, save) -> None:
    """The report drawn by two processes, the pages shared by their expected cost
    (:func:`shares`): a forked child draws its share, this process the other; the two PDFs
    joined in the pages' order and saved (``save(data)``, None: not asked for) before the PNGs
    are rasterised, each process its own. What the child fails to do, or does not do in time,
    is done here."""
    mine, theirs = shares([page_cost_s(p) for p in pages])
    pick = lambda xs, idx: [xs[i] for i in idx] if xs else []          # no PNGs asked: none
    child, finished = _Child(pick(pages, theirs), pick(pngs, theirs), title), False
    try:
        first = _pdf_bytes(pick(pages, mine), title)
        second = child.message(CHILD_TIMEOUT_S)
        if second is None:
            child.end(False)
            second = _pdf_bytes(pick(pages, theirs), title)
        if save is not None:
            save(_joined(first, second, theirs))
        _write_pngs(first, pick(pngs, mine))
        finished = not child.ended and child.message(CHILD_TIMEOUT_S) == _DONE
    finally:
        child.end(finished)
    if not finished:
        _write_pngs(second, pick(pngs, theirs))


#: the child's last message: its PNGs are written
_DONE = b"done"


def _child(send, pages: list[Page], pngs: list[Path], title: str) -> None:
    """In the forked child: the pages to a PDF whose bytes go to the parent, then their PNGs,
    then :data:`_DONE`; on any failure it ends quietly (the parent does its work again and
    reports the failure)."""
    global _PDFIUM
    try:
        die_with_parent()
        _PDFIUM = threading.Lock()              # the parent's may have been held by another thread
        data = _pdf_bytes(pages, title)
        send.send_bytes(data)
        _write_pngs(data, pngs)
        send.send_bytes(_DONE)
        send.close()
    except BaseException:
        os._exit(1)


def _joined(first: bytes, second: bytes, places: list[int]) -> bytes:
    """Two PDFs as one: the pages of ``second`` at the indices ``places`` (increasing), those of
    ``first`` in order around them, with the metadata of ``first`` (PDFium: the second's pages
    imported in one call, so their shared fonts once, then each moved to its place)."""
    import pypdfium2
    import pypdfium2.raw as pdfium_c
    with _PDFIUM:
        doc, other = pypdfium2.PdfDocument(first), pypdfium2.PdfDocument(second)
        try:
            k = len(doc)
            doc.import_pages(other)
            for j, place in enumerate(places):      # the earlier ones in place: page k + j is next
                if not pdfium_c.FPDF_MovePages(doc.raw, (ctypes.c_int * 1)(k + j), 1, place):
                    raise RuntimeError(f"PDFium could not move page {k + j} to {place}")
            buf = io.BytesIO()
            doc.save(buf)
        finally:
            other.close()
            doc.close()
    return buf.getvalue()


def _write_pdf(target, pages: list[Page], title: str) -> None:
    """The pages to one PDF at ``target`` (a path or a binary file)."""
    from matplotlib import rc_context
    from matplotlib.backends.backend_pdf import PdfPages
    with rc_context({"pdf.compression": COMPRESS_LEVEL}), PdfPages(target) as pdf:
        for page in pages:
            pdf.savefig(page.figure)
        pdf.infodict()["Title"] = title


def _write_pngs(data: bytes, pngs: list[Path]) -> None:
    """Page ``i`` of the PDF ``data`` to ``pngs[i]``."""
    if not pngs:
        return
    import pypdfium2
    with _PDFIUM:
        doc = pypdfium2.PdfDocument(data)
        try:
            images = [doc[i].render(scale=PNG_DPI / POINTS_PER_INCH).to_pil() for i in range(len(pngs))]
        finally:
            doc.close()
    for path, image in zip(pngs, images):
        write_atomic(path, lambda p, image=image: image.save(p, format="PNG", compress_level=COMPRESS_LEVEL,
                                                             dpi=(PNG_DPI, PNG_DPI)))
