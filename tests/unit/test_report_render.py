"""The report's pages to PNGs and one PDF: a forked child draws the PNGs while the parent draws
the PDF (navsim.report.render.render); a failure in either is reported as the OutputError it is."""

import contextlib
import errno
import os

import matplotlib
import matplotlib.figure
import pytest

from navsim.foundations.errors import OutputError
from navsim.foundations.outputs import OutputFolder
from navsim.report import render as report
from navsim.report.figures import Page

matplotlib.use("Agg")


def pages():
    out = []
    for name in ("a", "b", "c"):
        fig = matplotlib.figure.Figure(figsize=(3, 2), layout="constrained")     # its labels on the page
        fig.add_subplot().plot([0, 1], [0, len(name)])
        out.append(Page(name, name, fig))
    return out


@pytest.mark.parametrize("fork", [True, False])
def test_every_page_to_a_png_and_the_pdf(tmp_path, monkeypatch, fork):
    monkeypatch.setattr(report, "_can_fork", lambda: fork)
    folder = OutputFolder(tmp_path / "out", command="run")
    files = report.render(folder, pages(), ["pdf", "png"], "t")
    assert sorted(p.name for p in files) == ["a.png", "b.png", "c.png", "report.pdf"]
    assert all(p.stat().st_size > 1000 for p in files)
    pdf = (tmp_path / "out" / "report.pdf").read_bytes()
    assert pdf.count(b"/Type /Page") - pdf.count(b"/Type /Pages") == 3           # one page each
    assert not [p for p in (tmp_path / "out").iterdir() if ".tmp" in p.name]


@pytest.mark.parametrize("fork", [True, False])
def test_a_png_that_cannot_be_written_is_reported_with_its_path_and_hint(tmp_path, monkeypatch, fork):
    monkeypatch.setattr(report, "_can_fork", lambda: fork)
    real = matplotlib.figure.Figure.savefig

    def full(self, fname, *args, **kwargs):
        if str(fname).endswith(".b.tmp.png"):
            raise OSError(errno.ENOSPC, "No space left on device", str(fname))
        return real(self, fname, *args, **kwargs)
    monkeypatch.setattr(matplotlib.figure.Figure, "savefig", full)
    folder = OutputFolder(tmp_path / "out", command="run")
    with pytest.raises(OutputError) as err:
        report.render(folder, pages(), ["pdf", "png"], "t")
    assert err.value.path.endswith("b.png") and "No space left on device" in str(err.value)
    assert "free some space" in str(err.value) and err.value.errno == errno.ENOSPC
    assert (tmp_path / "out" / "a.png").exists() and not (tmp_path / "out" / "b.png").exists()
    assert not [p for p in (tmp_path / "out").iterdir() if ".tmp" in p.name]


def test_a_fork_that_fails_falls_back_to_drawing_in_turn(tmp_path, monkeypatch):
    monkeypatch.setattr(report, "_can_fork", lambda: True)

    def no_fork():
        raise OSError(11, "Resource temporarily unavailable")
    monkeypatch.setattr(os, "fork", no_fork)
    before = _pipes()
    files = report.render(OutputFolder(tmp_path / "out", command="run"), pages(), ["pdf", "png"], "t")
    assert sorted(p.name for p in files) == ["a.png", "b.png", "c.png", "report.pdf"]
    assert _pipes() == before                                          # the pipe closed again


def _pipes() -> set:
    """This process's open pipes (not the font files matplotlib opens once, nor folder locks)."""
    out = set()
    for fd in os.listdir("/proc/self/fd"):
        with contextlib.suppress(OSError):
            target = os.readlink(f"/proc/self/fd/{fd}")
            if target.startswith("pipe:"):
                out.add(target)
    return out
