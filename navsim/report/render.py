"""A report's pages to files: all of them, in order, to ``report.pdf``, drawn once; each PNG is
its page of that PDF rasterised (PDFium, through ``pypdfium2``), not drawn a second time."""

from __future__ import annotations

import io
import threading
from pathlib import Path

from navsim.foundations.outputs import OutputFolder, write_atomic
from navsim.report.figures import Page
from navsim.report.tables import PNG_DPI

#: zlib's level for the PNGs and the PDF's streams: 1 instead of matplotlib's 6 writes P0's
#: report in 0.6 s less CPU for 9 % larger PNGs and a 20 % larger PDF
COMPRESS_LEVEL = 1
#: a PDF point is 1/72 inch
POINTS_PER_INCH = 72.0
#: PDFium must not be called from two threads at once, even on two documents (pypdfium2's
#: documentation): one report is rasterised at a time
_PDFIUM = threading.Lock()


def render(folder: OutputFolder, pages: list[Page], fmts, title: str, pdf: str = "report.pdf") -> list[Path]:
    """All pages, in order, to ``pdf`` (``title`` in its metadata) and each page to
    ``<name>.png``, rasterised from that PDF at :data:`~navsim.report.tables.PNG_DPI` (the PDF
    drawn in memory where only PNGs are asked for); returns the files written."""
    out = folder.path
    pngs = [out / f"{page.name}.png" for page in pages] if "png" in fmts else []
    pdf_path = out / pdf if "pdf" in fmts else None
    folder.record(pngs + ([pdf_path] if pdf_path else []))
    if pdf_path is not None:
        write_atomic(pdf_path, lambda p: _write_pdf(p, pages, title))
    if pngs:
        if pdf_path is not None:
            source = pdf_path
        else:
            source = io.BytesIO()
            _write_pdf(source, pages, title)
        _write_pngs(source, pngs)
    return pngs + ([pdf_path] if pdf_path else [])


def _write_pdf(target, pages: list[Page], title: str) -> None:
    """The pages to one PDF at ``target`` (a path or a binary file)."""
    from matplotlib import rc_context
    from matplotlib.backends.backend_pdf import PdfPages
    with rc_context({"pdf.compression": COMPRESS_LEVEL}), PdfPages(target) as pdf:
        for page in pages:
            pdf.savefig(page.figure)
        pdf.infodict()["Title"] = title


def _write_pngs(source, pngs: list[Path]) -> None:
    """Page ``i`` of the PDF ``source`` (a path or a binary file) to ``pngs[i]``."""
    import pypdfium2
    data = source.getvalue() if isinstance(source, io.BytesIO) else Path(source).read_bytes()
    with _PDFIUM:
        doc = pypdfium2.PdfDocument(data)
        try:
            images = [doc[i].render(scale=PNG_DPI / POINTS_PER_INCH).to_pil() for i in range(len(pngs))]
        finally:
            doc.close()
    for path, image in zip(pngs, images):
        write_atomic(path, lambda p, image=image: image.save(p, format="PNG", compress_level=COMPRESS_LEVEL,
                                                             dpi=(PNG_DPI, PNG_DPI)))
