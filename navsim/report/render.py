"""A report's pages to files: all of them, in order, to ``report.pdf``, drawn once; each PNG is
its page of that PDF rasterised (PDFium, through ``pypdfium2``), not drawn a second time.

A report of :data:`SPLIT_PAGES` pages or more is drawn by two processes where the system can
fork and has two cores: a forked child writes every other page to a PDF of its own and
rasterises their PNGs while this process does the others; the two are joined into one document
by PDFium, the pages in their order (each page as it was drawn, the PNGs equal to the joined
PDF's pages). A child that fails, or gives no answer within :data:`CHILD_TIMEOUT_S`, is ended
and its pages drawn here, so a failure is reported as the sequential path reports it.
"""

from __future__ import annotations

import io
import multiprocessing
import os
import threading
import time
from pathlib import Path

from navsim.experiment.executors import die_with_parent
from navsim.foundations.outputs import OutputFolder, write_atomic
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
#: how long the child drawing the second half may take beyond this process's half, s, before
#: it is ended and its half drawn here (a child blocked on a lock another thread held at fork)
CHILD_TIMEOUT_S = 60.0
#: how long a child that sent its pages may take to end, s
CHILD_EXIT_S = 10.0


def render(folder: OutputFolder, pages: list[Page], fmts, title: str, pdf: str = "report.pdf") -> list[Path]:
    """All pages, in order, to ``pdf`` (``title`` in its metadata) and each page to
    ``<name>.png``, rasterised from that PDF at :data:`~navsim.report.tables.PNG_DPI` (the PDF
    drawn in memory where only PNGs are asked for); returns the files written."""
    out = folder.path
    pngs = [out / f"{page.name}.png" for page in pages] if "png" in fmts else []
    pdf_path = out / pdf if "pdf" in fmts else None
    folder.record(pngs + ([pdf_path] if pdf_path else []))
    if pdf_path is None and not pngs:
        return []
    if _can_split(len(pages)):
        data = _render_split(pages, pngs, title)
    else:
        data = _pdf_bytes(pages, title)
        _write_pngs(data, pngs)
    if pdf_path is not None:
        write_atomic(pdf_path, lambda p: _save_pdf(p, data))
    return pngs + ([pdf_path] if pdf_path else [])


def _can_split(n_pages: int) -> bool:
    """Whether two processes draw the report: enough pages, ``fork``, two cores, and this
    process allowed children (a daemonic one is not)."""
    cores = len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else (os.cpu_count() or 1)
    return (n_pages >= SPLIT_PAGES and cores > 1 and "fork" in multiprocessing.get_all_start_methods()
            and not multiprocessing.current_process().daemon)


def _pdf_bytes(pages: list[Page], title: str) -> bytes:
    buf = io.BytesIO()
    _write_pdf(buf, pages, title)
    return buf.getvalue()


def _save_pdf(path, data: bytes) -> None:
    """The PDF's bytes to ``path`` (a file of its own, written whole)."""
    with open(path, "wb") as f:
        f.write(data)


def _render_split(pages: list[Page], pngs: list[Path], title: str) -> bytes:
    """The PDF of all ``pages`` (returned) and their PNGs (where ``pngs``), every other page
    (the odd ones: the heavy pages of a report stand together) drawn by a forked child
    (:func:`_child`), the even ones here; the child's pages drawn here where it fails or hangs."""
    mine, theirs = slice(0, None, 2), slice(1, None, 2)
    ctx = multiprocessing.get_context("fork")
    receive, send = ctx.Pipe(duplex=False)
    child = ctx.Process(target=_child, args=(send, pages[theirs], pngs[theirs], title), daemon=True)
    child.start()
    send.close()
    second = None
    try:
        start = time.monotonic()
        first = _pdf_bytes(pages[mine], title)
        _write_pngs(first, pngs[mine])
        try:
            if receive.poll(CHILD_TIMEOUT_S + (time.monotonic() - start)):
                second = receive.recv_bytes()
        except (EOFError, OSError):             # the child ended without its pages
            second = None
    finally:
        receive.close()
        child.join(timeout=CHILD_EXIT_S if second is not None else 0)     # its pages sent: it is ending
        if child.is_alive():
            child.terminate()
            child.join()
    if second is None:
        second = _pdf_bytes(pages[theirs], title)
        _write_pngs(second, pngs[theirs])
    return _interleaved(first, second)


def _child(send, pages: list[Page], pngs: list[Path], title: str) -> None:
    """In the forked child: the pages to a PDF, their PNGs, the PDF's bytes to the parent; on
    any failure it ends quietly (the parent draws this half again and reports the failure)."""
    global _PDFIUM
    try:
        die_with_parent()
        _PDFIUM = threading.Lock()              # the parent's may have been held by another thread
        data = _pdf_bytes(pages, title)
        _write_pngs(data, pngs)
        send.send_bytes(data)
        send.close()
    except BaseException:
        os._exit(1)


def _interleaved(first: bytes, second: bytes) -> bytes:
    """Two PDFs as one, their pages taken in turn (the first's, the second's, ...; PDFium), with
    the metadata of ``first``."""
    import pypdfium2
    with _PDFIUM:
        doc, other = pypdfium2.PdfDocument(first), pypdfium2.PdfDocument(second)
        try:
            for j in range(len(other)):
                doc.import_pages(other, pages=[j], index=2 * j + 1)
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
