"""Progress off a terminal: a plain line every tenth of the work and at the end, logged (the
command line shows the log on stderr)."""

import io
import logging

from navsim.foundations.progress import Progress


def test_plain_lines_every_tenth_and_at_the_end(caplog):
    out = io.StringIO()
    with caplog.at_level(logging.INFO, logger="navsim.progress"):
        with Progress(20, "p0: 20 runs", stream=out) as p:
            for _ in range(20):
                p.update()
    lines = [r.getMessage() for r in caplog.records]
    assert [ln.split(": ")[2].split(",")[0] for ln in lines] == [f"{n}/20 runs ({5 * n} %)" for n in range(2, 21, 2)]
    assert all("elapsed" in ln for ln in lines) and all("left" in ln for ln in lines[:-1])
    assert "left" not in lines[-1]                       # done: nothing left to estimate
    assert out.getvalue() == ""                          # the library logs, it does not print


def test_uneven_updates_and_an_interrupted_run(caplog):
    out = io.StringIO()
    with caplog.at_level(logging.INFO, logger="navsim.progress"):
        p = Progress(1000, "big", stream=out)
        for n in (250, 5, 500):                          # chunks of runs finish unevenly
            p.update(n)
        p.close()                                        # interrupted at 755 of 1000
    lines = [r.getMessage() for r in caplog.records]
    assert [ln.split(": ")[1].split(",")[0] for ln in lines] == ["250/1000 runs (25 %)", "755/1000 runs (76 %)",
                                                                 "755/1000 runs (76 %)"]


def test_a_terminal_gets_the_bar_and_no_lines():
    out = io.StringIO()
    with Progress(5, "tty", stream=out, tty=True) as p:
        p.update(5)
    assert "5/5" in out.getvalue() and "elapsed" not in out.getvalue()
