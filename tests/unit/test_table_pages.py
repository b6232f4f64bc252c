"""A typeset table longer than its page (:func:`navsim.report.tables.layout`): on the next page
the heading it stands under again, "(continued)", and its first row, inside a group of rows
(an estimator's quantities in a metrics window), named with its group."""

from navsim.report.tables import Heading, Paragraph, Table, layout

HEADING = "Window 'outage over the straight legs' (540-839 s)"


def _lines(fig) -> list[tuple[str, bool]]:
    """The page's texts top to bottom, left to right: ``(text, bold)``."""
    texts = sorted((-t.get_position()[1], t.get_position()[0], t.get_text(), t.get_weight() == "bold")
                   for t in fig.texts if t.get_text().strip())
    return [(text, bold) for _, _, text, bold in texts]


def test_a_table_continued_on_a_page_says_under_which_heading_and_group():
    groups = [f"estimator {k}" for k in range(12)]
    rows = [[g if q == 0 else "", f"quantity {q}", f"{k}.{q}"] for k, g in enumerate(groups) for q in range(11)]
    figs = layout("report: metrics windows", [Heading(HEADING), Paragraph("What the table holds."),
                                              Table(["estimator", "quantity", "value"], rows)])
    assert len(figs) >= 2
    for fig in figs[1:]:
        lines = _lines(fig)
        assert lines[1] == (f"{HEADING} (continued)", True), lines[:3]
        first_row = lines[lines.index(("value", True)) + 1]          # under the header
        assert first_row[0] in groups, lines[:8]


def test_a_table_of_no_rows_under_a_heading_is_its_header():
    [fig] = layout("report", [Heading(HEADING), Table(["estimator", "quantity"], [])])
    assert [text for text, _ in _lines(fig)] == ["report", HEADING, "estimator", "quantity"]
