"""The checks of a page a person reads, shared by the suite: no text drawn outside its figure
(:func:`text_outside`), no two tick labels of an axis printed over each other
(:func:`overprinted_ticks`).

``tests/conftest.py`` applies them to every figure a test saves (:func:`check_saved`, through
its wrapper of :meth:`matplotlib.figure.Figure.savefig`, which ``PdfPages.savefig`` calls too);
a test of a page can call them on a figure it drew itself (:func:`page_problems`).
"""

from __future__ import annotations

import os
import re
from pathlib import Path

from matplotlib import rc_context, rcParams
from matplotlib.text import Text

from navsim.report.tables import text_width_in

#: pixels a text may stand over the figure's edge (antialiasing)
EDGE_PX = 1.0


def _axes(ax):
    return [a for a in (ax.xaxis, ax.yaxis, getattr(ax, "zaxis", None)) if a is not None]


def _tick_labels(axis) -> tuple[list, list]:
    """``(every tick label axis holds, those it draws)``: the drawn are those of ticks inside its
    view interval (matplotlib keeps labels for ticks beyond it, which are not drawn)."""
    lo, hi = sorted(axis.get_view_interval())
    pad = 1e-9 * max(abs(hi - lo), 1e-300)
    ticks = axis.get_major_ticks() + axis.get_minor_ticks()
    drawn = [lab for tick in ticks if lo - pad <= tick.get_loc() <= hi + pad
             for lab in (tick.label1, tick.label2) if lab.get_visible() and lab.get_text().strip()]
    return [lab for tick in ticks for lab in (tick.label1, tick.label2)], drawn


def drawn_tick_labels(axis) -> list:
    """The tick labels ``axis`` draws (:func:`_tick_labels`)."""
    return _tick_labels(axis)[1]


def _all_tick_labels(fig) -> dict:
    """:func:`_tick_labels` of every axis of ``fig``'s axes."""
    return {axis: _tick_labels(axis) for ax in fig.axes for axis in _axes(ax)}


#: the margin on a text's width measured character by character, and a line's height and the
#: room below a baseline at most, in font sizes: measuring a text costs a millisecond, so a text
#: that cannot reach an edge, or another label, is not measured
WIDTH_MARGIN, EM_PER_LINE, EM_DESCENT = 1.15, 1.25, 0.3


def _box_px(t, dpi: float):
    """Where a plain text can lie at most, pixels ``(x0, x1, y0, y1)``: its lines' widths
    (:func:`~navsim.report.tables.text_width_in`, mathtext's markup counted as characters:
    wider) and heights laid out as its alignment lays them out; None for a text placed or
    turned otherwise (an annotation, a slanted text)."""
    angle = t.get_rotation() % 180
    if type(t) is not Text or angle not in (0, 90) or t.get_rotation_mode() not in (None, "default"):
        return None
    x, y = t.get_transform().transform(t.get_unitless_position())
    em = t.get_fontsize() * dpi / 72
    w = WIDTH_MARGIN * text_width_in(t.get_text(), t.get_fontsize(), t.get_weight(), t.get_family()[0], dpi) * dpi
    h = EM_PER_LINE * em * (t.get_text().count("\n") + 1) + EM_DESCENT * em
    w, h = (w, h) if angle == 0 else (h, w)
    ha, va = t.get_ha(), t.get_va()
    x0 = {"left": x, "right": x - w}.get(ha, x - w / 2)
    y0 = {"top": y - h, "bottom": y, "baseline": y - EM_DESCENT * em}.get(va, y - h / 2)
    return x0, x0 + w, y0, y0 + h


def _surely_inside(t, W: float, H: float, dpi: float) -> bool:
    box = _box_px(t, dpi)
    return box is not None and box[0] >= 0 and box[1] <= W and box[2] >= 0 and box[3] <= H


def _apart(a, b, dpi: float) -> bool:
    """Whether two plain texts surely do not overlap (where each can lie does not)."""
    ba, bb = _box_px(a, dpi), _box_px(b, dpi)
    return ba is not None and bb is not None and (ba[1] <= bb[0] or bb[1] <= ba[0] or ba[3] <= bb[2] or bb[3] <= ba[2])


def text_outside(fig, renderer, tick_labels: dict | None = None) -> list[str]:
    """The visible texts of ``fig`` that are drawn and whose extent leaves the figure
    (``tick_labels``: :func:`_all_tick_labels` of ``fig``, if at hand)."""
    W, H = fig.bbox.width, fig.bbox.height
    tick_labels = tick_labels or _all_tick_labels(fig)
    ticks = {id(t) for held, _ in tick_labels.values() for t in held}
    drawn = {id(t) for _, shown in tick_labels.values() for t in shown}
    out = []
    hidden = {id(t) for ax in fig.axes if not ax.get_visible() for t in ax.findobj(Text)}
    for t in fig.findobj(Text):
        if (not t.get_visible() or not t.get_text().strip() or id(t) in hidden
                or (id(t) in ticks and id(t) not in drawn) or _surely_inside(t, W, H, fig.dpi)):
            continue
        e = t.get_window_extent(renderer)
        if e.x0 < -EDGE_PX or e.y0 < -EDGE_PX or e.x1 > W + EDGE_PX or e.y1 > H + EDGE_PX:
            out.append(f"{t.get_text()!r} at x {e.x0:.0f}-{e.x1:.0f}, y {e.y0:.0f}-{e.y1:.0f} of {W:.0f}x{H:.0f}")
    return out


def overprinted_ticks(fig, renderer, tick_labels: dict | None = None) -> list[str]:
    """Pairs of drawn tick labels of one axis whose extents overlap (``tick_labels``:
    :func:`_all_tick_labels` of ``fig``, if at hand)."""
    out = []
    tick_labels = tick_labels or _all_tick_labels(fig)
    for ax in fig.axes:
        if not ax.get_visible():
            continue
        for axis in _axes(ax):
            labels = tick_labels[axis][1]
            for i in range(len(labels)):
                for j in range(i + 1, len(labels)):
                    a, b = labels[i], labels[j]
                    if _apart(a, b, fig.dpi):
                        continue
                    ba, bb = a.get_window_extent(renderer), b.get_window_extent(renderer)
                    if ba.overlaps(bb) and min(ba.width, bb.width) > 0:
                        out.append(f"{ax.get_title() or ax.get_ylabel()!r}: {a.get_text()!r} and {b.get_text()!r}")
    return out


def page_problems(fig, renderer) -> list[str]:
    """What :func:`text_outside` and :func:`overprinted_ticks` find on ``fig`` as ``renderer``
    measures it, each prefixed ``outside:`` or ``overprinted:``."""
    ticks = _all_tick_labels(fig)
    return ([f"outside: {p}" for p in text_outside(fig, renderer, ticks)]
            + [f"overprinted: {p}" for p in overprinted_ticks(fig, renderer, ticks)])


def saved_name(fname) -> str:
    """The file a ``savefig`` target stands for: a path, or a ``PdfPages`` (its file and the
    page just added); navsim's temporary name (``.report.tmp.pdf``) as the file it becomes."""
    page = ""
    if hasattr(fname, "get_pagecount"):                    # PdfPages
        page, fname = f", page {fname.get_pagecount()}", getattr(fname, "_filename", fname)
    if isinstance(fname, (str, os.PathLike)):
        p = Path(fname)
        m = re.fullmatch(r"\.(.+)\.tmp(\.\w+)?", p.name)
        return str(p.with_name(m.group(1) + (m.group(2) or "")) if m else p) + page
    return f"{type(fname).__name__}{page}"


#: the resolution matplotlib draws a PDF at (points): the pixels of its layout
PDF_DPI = 72


def check_saved(fig, fname, kwargs: dict) -> list[str]:
    """The problems of ``fig`` just saved by ``savefig(fname, **kwargs)``, in its state as drawn
    for the file and at the dpi it was drawn at (a PDF's :data:`PDF_DPI`): an axis label is
    placed in that draw's pixels, so measuring it at another dpi moves it; no second draw.
    A figure cropped to its contents (``bbox_inches="tight"``) keeps every text and is not
    measured."""
    if kwargs.get("bbox_inches") == "tight":
        return []
    fmt = kwargs.get("format") or Path(str(getattr(fname, "_filename", fname))).suffix.lstrip(".")
    dpi = PDF_DPI if fmt == "pdf" else kwargs.get("dpi", rcParams["savefig.dpi"])
    keep = fig.dpi
    if isinstance(dpi, (int, float)) and dpi != keep:
        fig.dpi = dpi
    try:
        # a PDF's text is as wide as its font's metrics scale to, not as hinted glyphs at 72 pixels
        # an inch (7 % wider at 6.5 points)
        with rc_context({"text.hinting": "none"} if fmt == "pdf" else {}):
            return page_problems(fig, fig._get_renderer())
    finally:
        if fig.dpi != keep:
            fig.dpi = keep
