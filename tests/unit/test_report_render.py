"""The report's pages to one PDF, drawn once, and each page's PNG rasterised from it
(navsim.report.render.render): the PNG is the PDF's page at the report's resolution, pixel for
pixel what PDFium draws of it, with or without the PDF asked for; a PNG that cannot be written
is reported as the OutputError it is."""

import errno
import os

import matplotlib
import matplotlib.figure
import numpy as np
import pypdfium2
import pytest
from PIL import Image

from navsim.foundations.errors import OutputError
from navsim.foundations.outputs import OutputFolder
from navsim.report import render as report
from navsim.report.figures import Page
from navsim.report.tables import PNG_DPI

matplotlib.use("Agg")

#: the test pages' size, inches
SIZE_IN = (3, 2)


def pages():
    out = []
    for name in ("a", "b", "c"):
        fig = matplotlib.figure.Figure(figsize=SIZE_IN, layout="constrained")     # its labels on the page
        fig.add_subplot().plot([0, 1], [0, len(name)])
        out.append(Page(name, name, fig))
    return out


def test_every_page_to_the_pdf_and_its_png_is_that_page_rasterised(tmp_path):
    folder = OutputFolder(tmp_path / "out", command="run")
    files = report.render(folder, pages(), ["pdf", "png"], "t")
    assert sorted(p.name for p in files) == ["a.png", "b.png", "c.png", "report.pdf"]
    pdf = (tmp_path / "out" / "report.pdf").read_bytes()
    assert pdf.count(b"/Type /Page") - pdf.count(b"/Type /Pages") == 3           # one page each
    doc = pypdfium2.PdfDocument(pdf)
    for i, name in enumerate("abc"):
        png = np.asarray(Image.open(tmp_path / "out" / f"{name}.png"))
        assert png.shape[:2] == (round(SIZE_IN[1] * PNG_DPI), round(SIZE_IN[0] * PNG_DPI))
        page = np.asarray(doc[i].render(scale=PNG_DPI / 72).to_pil())
        assert np.array_equal(png, page)                          # the PDF's page, nothing drawn again
        assert png.std() > 10                                     # not blank: the curve and the axes
    assert not [p for p in (tmp_path / "out").iterdir() if ".tmp" in p.name]


def test_pngs_alone_are_rasterised_from_a_pdf_drawn_in_memory(tmp_path):
    files = report.render(OutputFolder(tmp_path / "out", command="run"), pages(), ["png"], "t")
    assert sorted(p.name for p in (tmp_path / "out").iterdir() if not p.name.startswith(".")) == \
        ["a.png", "b.png", "c.png"] == sorted(p.name for p in files)
    with_pdf = OutputFolder(tmp_path / "both", command="run")
    report.render(with_pdf, pages(), ["pdf", "png"], "t")
    for name in "abc":
        assert np.array_equal(np.asarray(Image.open(tmp_path / "out" / f"{name}.png")),
                              np.asarray(Image.open(tmp_path / "both" / f"{name}.png")))


def full_disk_for(monkeypatch, name: str) -> None:
    """Writing the PNG ``name`` meets a full disk (its temporary file, as write_atomic names it)."""
    real = Image.Image.save

    def full(self, fp, *args, **kwargs):
        if str(fp).endswith(f".{name}.tmp.png"):
            raise OSError(errno.ENOSPC, "No space left on device", str(fp))
        return real(self, fp, *args, **kwargs)
    monkeypatch.setattr(Image.Image, "save", full)


def test_a_png_that_cannot_be_written_is_reported_with_its_path_and_hint(tmp_path, monkeypatch):
    full_disk_for(monkeypatch, "b")
    folder = OutputFolder(tmp_path / "out", command="run")
    with pytest.raises(OutputError) as err:
        report.render(folder, pages(), ["pdf", "png"], "t")
    assert err.value.path.endswith("b.png") and "No space left on device" in str(err.value)
    assert "free some space" in str(err.value) and err.value.errno == errno.ENOSPC
    assert (tmp_path / "out" / "a.png").exists() and not (tmp_path / "out" / "b.png").exists()
    assert not [p for p in (tmp_path / "out").iterdir() if ".tmp" in p.name]


#: the tests of a report drawn by two processes (a system that cannot fork onto two cores draws alone)
split_only = pytest.mark.skipif(not report._can_split(8), reason="this system draws a report in one process")


def many_pages(n=8):
    out = []
    for i in range(n):
        fig = matplotlib.figure.Figure(figsize=SIZE_IN, layout="constrained")
        fig.add_subplot().plot([0, 1], [0, i + 1])
        fig.text(0.5, 0.02, f"page {i}")
        out.append(Page(f"p{i}", f"p{i}", fig))
    return out


def _check_split_report(out, n):
    """The joined PDF: ``n`` pages in order, the title kept; each PNG its page pixel for pixel."""
    doc = pypdfium2.PdfDocument((out / "report.pdf").read_bytes())
    assert len(doc) == n and doc.get_metadata_dict()["Title"] == "t"
    for i in range(n):
        assert doc[i].get_textpage().get_text_range().strip().endswith(f"page {i}")
        png = np.asarray(Image.open(out / f"p{i}.png"))
        assert np.array_equal(png, np.asarray(doc[i].render(scale=PNG_DPI / 72).to_pil())), i


@split_only
def test_a_long_report_is_drawn_in_two_halves_joined_in_order(tmp_path, monkeypatch):
    """Eight pages of one cost: every other one drawn by a forked child (the PNG writer called
    once here), the PDFs joined in the pages' order, every PNG the joined PDF's page."""
    writers, write = [], report._write_pngs
    monkeypatch.setattr(report, "_write_pngs", lambda data, pngs: (writers.append(os.getpid()), write(data, pngs)))
    folder = OutputFolder(tmp_path / "out", command="run")
    files = report.render(folder, many_pages(), ["pdf", "png"], "t")
    assert len(files) == 9
    _check_split_report(tmp_path / "out", 8)
    # the child's call is not seen here (its own memory): this process drew its pages only
    assert writers == [os.getpid()]


@split_only
def test_a_child_that_fails_leaves_its_half_to_this_process(tmp_path, monkeypatch):
    monkeypatch.setattr(report, "_child", lambda *args: os._exit(3))
    report.render(OutputFolder(tmp_path / "out", command="run"), many_pages(), ["pdf", "png"], "t")
    _check_split_report(tmp_path / "out", 8)


@split_only
def test_a_png_of_the_child_s_pages_that_cannot_be_written_is_reported(tmp_path, monkeypatch):
    """The child fails quietly on p5.png; this process draws its pages again and reports it."""
    full_disk_for(monkeypatch, "p5")
    with pytest.raises(OutputError) as err:
        report.render(OutputFolder(tmp_path / "out", command="run"), many_pages(), ["pdf", "png"], "t")
    assert err.value.path.endswith("p5.png") and err.value.errno == errno.ENOSPC
    out = tmp_path / "out"
    assert (out / "report.pdf").exists() and not (out / "p5.png").exists()     # the PDF first, as alone
    assert not [p for p in out.iterdir() if ".tmp" in p.name]


@split_only
def test_a_child_that_hangs_is_ended_and_its_pages_drawn_here(tmp_path, monkeypatch):
    """A child that never answers (blocked, as on a lock held at fork): after CHILD_TIMEOUT_S it
    is ended, its pages drawn here, nothing half written left behind."""
    import time
    monkeypatch.setattr(report, "CHILD_TIMEOUT_S", 0.5)
    monkeypatch.setattr(report, "_child", lambda *args: time.sleep(30))
    start = time.monotonic()
    report.render(OutputFolder(tmp_path / "out", command="run"), many_pages(), ["pdf", "png"], "t")
    assert time.monotonic() - start < 10
    _check_split_report(tmp_path / "out", 8)
    assert not [p for p in (tmp_path / "out").iterdir() if ".tmp" in p.name]


@split_only
def test_a_child_that_fails_after_its_pdf_leaves_its_pngs_to_this_process(tmp_path, monkeypatch):
    def pdf_then_fail(send, pages_, pngs, title):
        send.send_bytes(report._pdf_bytes(pages_, title))
        os._exit(1)
    monkeypatch.setattr(report, "_child", pdf_then_fail)
    report.render(OutputFolder(tmp_path / "out", command="run"), many_pages(), ["pdf", "png"], "t")
    _check_split_report(tmp_path / "out", 8)


def test_the_pages_are_shared_by_cost_and_joined_in_order():
    """The costliest pages first to the lighter share (both non-empty), the child's pages put
    back at their places; a page full of points costs more than one of text."""
    assert report.shares([5.0, 1.0, 1.0, 1.0, 1.0, 1.0]) == ([0], [1, 2, 3, 4, 5])
    assert report.shares([1.0, 3.0, 2.0, 2.0]) == ([0, 1], [2, 3])
    pages_ = many_pages(7)
    dense = pages_[3].figure.axes[0]
    dense.plot(np.arange(50_000), np.sin(np.arange(50_000)))
    costs = [report.page_cost_s(p) for p in pages_]
    assert costs[3] > 5 * max(costs[:3] + costs[4:])
    places = [0, 3, 4, 6]
    rest = [i for i in range(7) if i not in places]
    joined = report._joined(report._pdf_bytes([pages_[i] for i in rest], "t"),
                            report._pdf_bytes([pages_[i] for i in places], "t"), places)
    doc = pypdfium2.PdfDocument(joined)
    assert [doc[i].get_textpage().get_text_range().strip()[-6:] for i in range(7)] == [f"page {i}" for i in range(7)]
