"""Typeset text pages: headings, paragraphs and tables laid out on A4 pages (:func:`layout`).

A table is drawn as in a paper (a rule above and below the header and under the last row, no
grid), each column as wide as its widest cell measured with the renderer's font metrics, numbers
right-aligned. A table wider than the text block is split into column groups stacked one under
the other, its first column repeated in each; a column wider than its table's ``max_column``
share of the block has its cells wrapped; a table longer than the page continues on the next
with its header repeated. Nothing is drawn outside the page's margins.
"""

from __future__ import annotations

import dataclasses
import functools
import math
import re
from dataclasses import dataclass
from typing import NamedTuple

from matplotlib.backends.backend_agg import FigureCanvasAgg, RendererAgg
from matplotlib.figure import Figure
from matplotlib.font_manager import FontProperties
from matplotlib.lines import Line2D

PAGE_IN = (8.27, 11.69)        #: A4 portrait, inches
MARGIN_IN = 0.55               #: left, right, top and bottom
CELL_PAD_IN = 0.13             #: space between two columns
SMALLER = (7.0, 6.5)           #: the font sizes a table too wide for the block tries before it is split
LINE = 1.3                     #: line height, in font sizes
ASCENT = 0.8                   #: the first baseline below a line's top, in font sizes
PASS, FAIL, WARN = "#1a7f37", "#c62828", "#b45309"     #: verdict and warning colours
#: the PNGs' resolution, dots per inch; text is measured at it (hinted glyphs at a small pixel
#: size are wider than the font's metrics scale to: 8 % at 110 dpi against 100)
PNG_DPI = 110


@dataclass
class Heading:
    text: str
    size: float = 11.0


@dataclass
class Paragraph:
    """Text wrapped to the text block (``pre``: its lines kept as they are)."""

    text: str
    size: float = 8.5
    colour: str = "black"
    family: str = "sans-serif"
    pre: bool = False


@dataclass
class Table:
    """``rows`` of strings under ``headers`` (a header may hold a line break); ``colours`` the
    text colour per cell (None: black); ``align`` ``"l"`` or ``"r"`` per column (default: the
    first left, the others right)."""

    headers: list[str]
    rows: list[list[str]]
    colours: list[list[str | None]] | None = None
    align: list[str] | None = None
    size: float = 7.5
    max_column: float = 0.42       #: the share of the text block a column may take before it wraps


@dataclass
class _Page:
    fig: Figure
    y_in: float = MARGIN_IN                  #: the cursor, from the top


class _Style(NamedTuple):
    """How a text is drawn: its font size (points), horizontal alignment, colour, weight and
    family."""

    size: float
    ha: str = "left"
    colour: str = "black"
    weight: str = "normal"
    family: str = "sans-serif"


def _new_page(title: str, continued: bool) -> _Page:
    fig = Figure(figsize=PAGE_IN, dpi=PNG_DPI)
    FigureCanvasAgg(fig)
    page = _Page(fig)
    _draw_text(page, title + (" (continued)" if continued else ""), MARGIN_IN, _Style(14, weight="bold"))
    page.y_in += 14 * LINE / 72 + 0.1
    return page


def _width_in(page: _Page, text: str, size: float, weight: str = "normal", family: str = "sans-serif") -> float:
    return text_width_in(text, size, weight, family, page.fig.dpi)


def text_width_in(text: str, size: float, weight: str = "normal", family: str = "sans-serif",
                  dpi: float = PNG_DPI) -> float:
    """The width of ``text``'s widest line at ``size`` points, inches, as Agg draws it at ``dpi``
    (:func:`_line_width_px`: 0-1.5 % over, never under); 0 for no text."""
    if not text:
        return 0.0
    return max(_line_width_px(line, size, weight, family, dpi) for line in text.split("\n")) / dpi


def _line_width_px(line: str, size: float, weight: str, family: str, dpi: float) -> float:
    """One line's width in pixels at ``dpi``: the sum of its characters' widths as Agg draws
    each alone. Kerning is left out, so a line comes out 0-1.5 % wider than Agg draws it (the
    report's fonts, measured on its table cells; 4 % on a line of kerned pairs such as AV and
    Ty), not narrower on any line measured (``tests/unit/test_report_text.py``). Measuring every
    trial line of a wrap whole took 0.2 ms plus 11 us a character, most of the time of building
    P0's report pages."""
    return sum(_char_width_px(c, size, weight, family, dpi) for c in line)


@functools.lru_cache(maxsize=1 << 14)
def _char_width_px(char: str, size: float, weight: str, family: str, dpi: float) -> float:
    prop = FontProperties(size=size, weight=weight, family=family)
    return _renderer(dpi).get_text_width_height_descent(char, prop, ismath=False)[0]


@functools.lru_cache(maxsize=4)
def _renderer(dpi: float) -> RendererAgg:
    """An Agg renderer at ``dpi``, for measuring text (a page's size does not change it)."""
    return RendererAgg(1, 1, dpi)


def _draw_text(page: _Page, text: str, x_in: float, style: _Style) -> None:
    W, H = PAGE_IN
    size = style.size
    for k, line in enumerate(text.split("\n")):            # each line on its own baseline
        baseline_in = page.y_in + (ASCENT + k * LINE) * size / 72
        page.fig.text(x_in / W, 1 - baseline_in / H, line, fontsize=size, ha=style.ha, va="baseline",
                      color=style.colour, weight=style.weight, family=style.family)


def _rule(page: _Page, x0_in: float, x1_in: float, lw: float) -> None:
    W, H = PAGE_IN
    y = 1 - page.y_in / H
    page.fig.add_artist(Line2D([x0_in / W, x1_in / W], [y, y], lw=lw, color="black"))


def _block_width() -> float:
    return PAGE_IN[0] - 2 * MARGIN_IN


def _room(page: _Page) -> float:
    return PAGE_IN[1] - MARGIN_IN - page.y_in


def _pieces(dpi: float, word: str, width_in: float, size: float, family: str) -> list[str]:
    """A word too long for the line cut after its dots, underscores and slashes (a metric's
    path), where it has them."""
    if text_width_in(word, size, family=family, dpi=dpi) <= width_in:
        return [word]
    parts, out = re.findall(r"[^._/]+[._/]?|[._/]", word), [""]
    # a piece still too long is cut between characters
    parts = [q for p in parts for q in ([p] if text_width_in(p, size, family=family, dpi=dpi) <= width_in else list(p))]
    for part in parts:
        if out[-1] and text_width_in(out[-1] + part, size, family=family, dpi=dpi) > width_in:
            out.append(part)
        else:
            out[-1] += part
    return out


def wrap_text(text: str, width_in: float, size: float, family: str = "sans-serif", dpi: float = PNG_DPI) -> list[str]:
    """``text``'s lines wrapped to ``width_in`` at ``size`` points (each paragraph of it,
    measured as Agg draws it at ``dpi``; a word too long cut after its dots, underscores and
    slashes)."""
    out = []
    for para in text.split("\n"):
        words, line = [p for w in para.split(" ") for p in _pieces(dpi, w, width_in, size, family)], ""
        for w in words:
            trial = f"{line} {w}" if line else w
            if line and text_width_in(trial, size, family=family, dpi=dpi) > width_in:
                out.append(line)
                line = w
            else:
                line = trial
        out.append(line)
    return out


class _Layout:
    """The pages so far and the cursor on the last."""

    def __init__(self, title: str):
        self.title = title
        self.pages = [_new_page(title, False)]

    def new(self) -> _Page:
        self.pages.append(_new_page(self.title, True))
        return self.pages[-1]

    def page(self, height_in: float) -> _Page:
        """The last page, or a new one if ``height_in`` does not fit on what is left of it."""
        last = self.pages[-1]
        return self.new() if _room(last) < height_in and last.y_in > MARGIN_IN + 0.5 else last


def layout(title: str, blocks: list) -> list[Figure]:
    """The pages holding ``blocks`` (:class:`Heading`, :class:`Paragraph`, :class:`Table`) in
    order under ``title``."""
    lay = _Layout(title)
    heading = None                                  # the last heading and its page
    for b in blocks:
        if isinstance(b, Heading):
            p = _heading(lay, b.text, b.size)
            heading = (b, p)
        elif isinstance(b, Paragraph):
            lines = (b.text.split("\n") if b.pre
                     else wrap_text(b.text, _block_width(), b.size, b.family, lay.pages[-1].fig.dpi))
            step = b.size * LINE / 72
            for line in lines:
                p = lay.page(step)
                _draw_text(p, line, MARGIN_IN, _Style(b.size, colour=b.colour, family=b.family))
                p.y_in += step
            lay.pages[-1].y_in += 0.06
        else:
            _table(lay, b, heading)
    return [p.fig for p in lay.pages]


def _heading(lay: _Layout, text: str, size: float) -> _Page:
    """Draw a heading where it keeps two lines of what follows; returns its page."""
    lines = wrap_text(text, 0.93 * _block_width(), size, dpi=lay.pages[-1].fig.dpi)      # bold is wider
    p = lay.page(size * LINE / 72 * (len(lines) + 2))
    p.y_in += 0.08
    _draw_text(p, "\n".join(lines), MARGIN_IN, _Style(size, weight="bold"))
    p.y_in += len(lines) * size * LINE / 72 + 0.04
    return p


def _cell_lines(page: _Page, table: Table, caps: list[float]) -> list[list[list[str]]]:
    """Each row's cells as lines, wrapped where a column is wider than its cap (inches)."""
    out = []
    for row in table.rows:
        cells = []
        for text, cap in zip(row, caps):
            text = str(text)
            wide = _width_in(page, text, table.size) > cap
            cells.append(wrap_text(text, cap, table.size, dpi=page.fig.dpi) if wide else text.split("\n"))
        out.append(cells)
    return out


def _column_widths(page: _Page, table: Table, cells) -> list[float]:
    n = len(table.headers)
    return [max([_width_in(page, table.headers[j], table.size, weight="bold")]
                + [_width_in(page, "\n".join(r[j]), table.size) for r in cells]) for j in range(n)]


def _groups(widths: list[float]) -> list[list[int]]:
    """Columns in groups that fit the text block, the first column in each."""
    room = _block_width()
    groups, cur, used = [], [0], widths[0] + CELL_PAD_IN
    for j in range(1, len(widths)):
        if used + widths[j] > room and len(cur) > 1:
            groups.append(cur)
            cur, used = [0], widths[0] + CELL_PAD_IN
        cur.append(j)
        used += widths[j] + CELL_PAD_IN
    groups.append(cur)
    return groups


_NUMERIC = re.compile(r"[-+0-9.e %±<>=]*")


def numeric(cell: str) -> bool:
    """Whether a cell holds numbers only (a vector, a percentage, a bound): set right."""
    return bool(_NUMERIC.fullmatch(cell)) and (any(c.isdigit() for c in cell) or cell.strip() == "-")


def _alignment(table: Table) -> list[str]:
    if table.align:
        return table.align
    return ["l"] + ["r" if table.rows and all(numeric(str(r[j])) for r in table.rows) else "l"
                    for j in range(1, len(table.headers))]


#: the widths (inches) a table too wide for the block wraps its text columns to, in turn
TEXT_CAPS_IN = (2.0, 1.6, 1.3)


def _measured(page: _Page, table: Table):
    """``(table, cells, widths)``: the first layout that fits the text block whole, trying the
    table's size, then :data:`SMALLER` sizes, each with its text columns (left-aligned) wrapped
    to :data:`TEXT_CAPS_IN`; else the table's own, to be split in column groups."""
    cap = table.max_column * _block_width()
    text = [a == "l" for a in _alignment(table)]
    first = None
    for size in (table.size, *(s for s in SMALLER if s < table.size)):
        t = dataclasses.replace(table, size=size)
        for narrow in (cap, *(c for c in TEXT_CAPS_IN if c < cap)):
            caps = [min(cap, narrow) if is_text else cap for is_text in text]
            cells = _cell_lines(page, t, caps)
            widths = [min(w, c) for w, c in zip(_column_widths(page, t, cells), caps)]
            first = first or (t, cells, widths)
            if sum(widths) + CELL_PAD_IN * (len(widths) - 1) <= _block_width():
                return t, cells, widths
    return first


def _table(lay: _Layout, table: Table, heading=None) -> None:
    """Draw ``table`` from the cursor on, over as many pages as it takes; on a page after
    ``heading``'s (``(Heading, its page)``), the heading again, "(continued)", and a first row
    whose first cell is empty (a row of a group) with the group's name."""
    table, cells, widths = _measured(lay.pages[-1], table)
    line_in = table.size * LINE / 72
    head_lines = max(h.count("\n") + 1 for h in table.headers)
    grid = _Grid(table, widths, _alignment(table), table.colours or [[None] * len(table.headers) for _ in table.rows],
                 head_lines, line_in)
    for cols in _groups(widths):
        rows = list(range(len(cells)))
        while True:
            p = lay.page((head_lines + min(3, len(rows)) + 1) * line_in)
            if heading is not None and p is not heading[1]:
                p = _heading(lay, f"{heading[0].text} (continued)", heading[0].size)
                heading = (heading[0], p)
            shown = _named_group(cells, rows[0]) if rows else cells      # a table of no rows: its header
            fit = max(1, int(math.floor((_room(p) - (head_lines + 0.6) * line_in) / line_in)))
            taken, used = [], 0
            for r in rows:
                n = max(len(shown[r][j]) for j in cols)
                if taken and used + n > fit:
                    break
                taken.append(r)
                used += n
            _draw_rows(p, grid, cols, shown, taken)
            rows = rows[len(taken):]
            if not rows:
                break
            lay.new()
        lay.pages[-1].y_in += 0.12


def _named_group(cells: list, first: int) -> list:
    """``cells`` with row ``first``'s empty first cell given the last first cell above it (a
    table continued on a new page starts inside a group of rows: its name again)."""
    if first == 0 or any(line.strip() for line in cells[first][0]):
        return cells
    name = next((cells[r][0] for r in range(first - 1, -1, -1) if any(line.strip() for line in cells[r][0])), None)
    if name is None:
        return cells
    shown = list(cells)
    shown[first] = [name] + cells[first][1:]
    return shown


class _Grid(NamedTuple):
    """A table as measured for drawing: its column widths (inches), alignments and cell
    colours, the lines of its header and the height of a line (inches)."""

    table: Table
    widths: list
    align: list
    colours: list
    head_lines: int
    line_in: float


def _draw_rows(p: _Page, grid: _Grid, cols, cells, rows) -> None:
    """The columns ``cols`` of the header and of the rows ``rows`` of ``cells`` (their lines),
    between rules, from the cursor of ``p`` on."""
    table, widths, align, colours, line_in = grid.table, grid.widths, grid.align, grid.colours, grid.line_in
    xs, x = [], MARGIN_IN
    for j in cols:
        xs.append(x)
        x += widths[j] + CELL_PAD_IN
    right = x - CELL_PAD_IN
    _rule(p, MARGIN_IN, right, 0.9)
    p.y_in += 0.04
    for j, x0 in zip(cols, xs):
        ha, xa = ("right", x0 + widths[j]) if align[j] == "r" else ("left", x0)
        _draw_text(p, table.headers[j], xa, _Style(table.size, ha=ha, weight="bold"))
    p.y_in += grid.head_lines * line_in + 0.02
    _rule(p, MARGIN_IN, right, 0.5)
    p.y_in += 0.04
    for r in rows:
        for j, x0 in zip(cols, xs):
            ha, xa = ("right", x0 + widths[j]) if align[j] == "r" else ("left", x0)
            _draw_text(p, "\n".join(cells[r][j]), xa, _Style(table.size, ha=ha, colour=colours[r][j] or "black"))
        p.y_in += max(len(cells[r][j]) for j in cols) * line_in
    p.y_in += 0.02
    _rule(p, MARGIN_IN, right, 0.9)


def monospace_block(lines: list[str], size: float = 6.5) -> Paragraph:
    """Preformatted lines (a YAML file) as one paragraph, each line kept as it is (cut at the
    text block's width at ``size``)."""
    width = int(_block_width() * 72 / (0.62 * size))       # DejaVu Sans Mono: 0.6 em per character
    return Paragraph("\n".join(line if len(line) <= width else line[:width - 4] + " ..." for line in lines),
                     size=size, family="monospace", pre=True)
