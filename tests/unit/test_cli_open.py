"""``navsim open``: the result's page handed to the web browser where one can show it, its path
printed where none can; a folder without a page or a missing one refused (exit 2) with a hint."""

import webbrowser

import pytest

from navsim.cli import main


@pytest.fixture
def opened(monkeypatch):
    """The URIs handed to the web browser (none is started)."""
    calls = []
    monkeypatch.setattr(webbrowser, "open", lambda uri, *a, **k: calls.append(uri) or True)
    return calls


def test_a_result_page_is_opened_in_the_browser_where_there_is_a_display(tmp_path, opened, monkeypatch, capsys):
    (tmp_path / "compare.html").write_text("<html></html>")
    (tmp_path / "report.html").write_text("<html></html>")
    monkeypatch.setenv("DISPLAY", ":0")
    assert main(["open", str(tmp_path)]) == 0
    assert opened == [(tmp_path / "report.html").resolve().as_uri()]       # a run's report first
    assert capsys.readouterr().out.strip() == str((tmp_path / "report.html").resolve())
    assert main(["open", str(tmp_path / "compare.html")]) == 0 and opened[-1].endswith("/compare.html")


def test_without_a_display_or_with_print_only_the_path_is_printed(tmp_path, opened, monkeypatch, capsys):
    (tmp_path / "sweep.html").write_text("<html></html>")
    monkeypatch.delenv("DISPLAY", raising=False)
    monkeypatch.delenv("WAYLAND_DISPLAY", raising=False)
    monkeypatch.setattr("sys.platform", "linux")
    assert main(["open", str(tmp_path)]) == 0
    out = capsys.readouterr().out
    assert opened == [] and str((tmp_path / "sweep.html").resolve()) in out and "no web browser here" in out
    monkeypatch.setenv("DISPLAY", ":0")
    assert main(["open", str(tmp_path), "--print"]) == 0 and opened == []
    assert capsys.readouterr().out.strip() == str((tmp_path / "sweep.html").resolve())


def test_a_folder_without_a_page_or_no_folder_is_refused_with_a_hint(tmp_path, opened, capsys):
    (tmp_path / "notes.txt").write_text("x")
    assert main(["open", str(tmp_path)]) == 2
    err = capsys.readouterr().err
    assert "no interactive page" in err and "report.html" in err and "write_report" in err
    assert main(["open", str(tmp_path / "missing")]) == 2
    assert "no such folder" in capsys.readouterr().err and opened == []
