"""The verb *compare*: :func:`compare` sets two estimators side by side over the runs as the
samples (``B - A`` per metric with its 95 % interval and a verdict,
:mod:`navsim.scoring.compare`), paired run by run where the two results flew the same flights
and sensor data; :func:`write_comparison` writes ``compare.json``, ``compare.csv`` and the
pages."""

from __future__ import annotations

import csv
import io
from pathlib import Path

import yaml

from navsim import report
from navsim.api.arguments import checked_path
from navsim.api.results import Result, resolved_scenario
from navsim.experiment.options import check_flags, shown
from navsim.experiment.results import ResultFiles, check_comparable, pairing, read_result
from navsim.experiment.scenario import REPORT_FORMATS
from navsim.foundations.errors import UsageError
from navsim.foundations.outputs import OutputFolder
from navsim.foundations.provenance import provenance
from navsim.report.compare import CSV_HEADERS, compare_page, csv_rows
from navsim.report.figures import pyplot
from navsim.report.render import render
from navsim.scoring.compare import DEFAULT_MARGIN_PCT, Comparison, Side, check_margin, check_margin_paths
from navsim.scoring.compare import compare_samples
from navsim.scoring.intervals import MIN_RUNS


def compare(a, b=None, estimators=None, *, partial: bool = False, unpaired: bool = False,
            margin=DEFAULT_MARGIN_PCT) -> list[Comparison]:
    """Compare two estimators over the runs as the samples: ``B - A`` per metric with its 95 %
    interval and a verdict (:mod:`navsim.scoring.compare`); nothing is written.

    Parameters
    ----------
    a, b : path or Result
        Result folders (``navsim run``'s ``--out``) or :class:`Result` objects (:func:`run`,
        :func:`open_result`); ``b`` None: two estimators of ``a``.
    estimators : sequence of str, optional
        ``(A, B)``: the estimator of ``a`` and of ``b``; one label: the same on both sides.
        Default: every label the two results share (one comparison each), or each one's only
        estimator; required for two estimators of one result.
    partial : bool
        Compare an interrupted result as it is (its finished runs), else refuse it.
    unpaired : bool
        Compare side against side even where the runs pair (what pairing gains).
    margin : float or mapping, optional
        The practical-equivalence margin, per cent of the larger of the two values: a
        difference whose 95 % interval lies within it is ``negligible``, and none within it is
        offered a run count (:mod:`navsim.scoring.compare`). A mapping gives it per metric path
        (``{"rms.pos_m": 5, "": 1}``: the longest matching start; ``""`` the others).
        Default :data:`navsim.scoring.compare.DEFAULT_MARGIN_PCT`.

    Returns
    -------
    list of Comparison
        One per estimator pair. Paired run by run when both results flew the same flights and
        sensor data (:func:`navsim.experiment.results.pairing`), else unpaired.

    Raises
    ------
    UsageError
        A folder that is not a result, a damaged file of one (named with its key or array), a
        result an older or a newer navsim wrote, two different tracks or
        metric settings, an interrupted result without ``partial``, an unknown estimator.
    """
    for name, x in (("a", a), ("b", b)):
        if not isinstance(x, Result) and (x is not None or name == "a"):
            checked_path(name, x, "result folder")
    estimators = _labels(estimators)
    check_flags(dict(partial=partial, unpaired=unpaired))
    margin = check_margin(margin)
    ra = _result_files(a)
    rb = ra if b is None or b is a else _result_files(b)
    check_comparable(ra, rb)
    for r in {id(ra): ra, id(rb): rb}.values():
        if r.record.interrupted and not partial:
            raise UsageError(f"{r.folder}: interrupted after {r.record.runs_done} of {r.record.runs} runs; hint: "
                             "complete it with navsim run --resume, or compare what finished with --partial")
    paired, why = pairing(ra, rb)
    if unpaired:
        paired, why = False, "unpaired (asked): side against side"
    out = [_compare_pair(ra, rb, pair, (paired, why), margin)
           for pair in _estimator_pairs(ra, rb, b is None, estimators)]
    check_margin_paths(margin, {d.metric for c in out for d in c.differences})
    return out


def _compare_pair(ra: ResultFiles, rb: ResultFiles, pair: tuple, pairing_: tuple, margin) -> Comparison:
    """The comparison of the estimators ``pair`` = ``(A's, B's)``, ``pairing_`` = ``(paired, why)``;
    a :class:`UsageError` where they share no metric or too few runs."""
    (la, lb), (paired, why) = pair, pairing_
    side = lambda r, label: Side(str(r.folder), label, len(r.samples[label].runs), r.record.runs_done,
                                 r.record.runs, bool(r.record.interrupted), r.record.seed)
    c = compare_samples(side(ra, la), ra.samples[la], side(rb, lb), rb.samples[lb], paired, why, margin)
    if not c.differences:
        raise UsageError(f"{ra.folder} '{la}' and {rb.folder} '{lb}' share no metric to compare")
    if c.runs_compared < MIN_RUNS:
        raise UsageError(f"'{la}' ({c.a.runs} counted runs) against '{lb}' ({c.b.runs}): "
                         f"{c.runs_compared} runs to compare{' in common' if paired else ''}, at least "
                         f"{MIN_RUNS} needed (a diverged run is not counted)")
    return c


def _result_files(x) -> ResultFiles:
    """A result folder's files (:func:`~navsim.experiment.results.read_result`), or the same
    of a :class:`Result` at hand (its scenario resolved as a folder would hold it)."""
    if not isinstance(x, Result):
        return read_result(x)
    if x.metrics is None or not x.samples:
        raise UsageError(f"result of '{x.scenario.name}': not scored, or scored by an older navsim (no per-run samples)")
    resolved = yaml.safe_load(yaml.safe_dump(resolved_scenario(x), sort_keys=False))
    return ResultFiles(x.folder or f"{x.scenario.name} (in memory)", x.metrics, x.record, resolved, x.samples)


def _estimator_pairs(ra: ResultFiles, rb: ResultFiles, one: bool, estimators) -> list[tuple[str, str]]:
    """The ``(A, B)`` labels compared (see :func:`compare`)."""
    la, lb = list(ra.samples), list(rb.samples)
    if estimators:
        names = list(estimators)
        if len(names) > 2:
            raise UsageError(f"--estimators takes one or two labels, not {len(names)}")
        pair = (names[0], names[-1])
        for r, label in zip((ra, rb), pair):
            if label not in r.samples:
                raise UsageError(f"{r.folder}: no estimator '{label}'; it has: " + ", ".join(r.samples))
        if one and pair[0] == pair[1]:
            raise UsageError(f"{ra.folder}: one estimator against itself; name two: --estimators A B")
        return [pair]
    if one:
        raise UsageError(f"{ra.folder}: one result: name the two estimators to compare, --estimators A B "
                         "(it has: " + ", ".join(la) + ")")
    common = [x for x in la if x in lb]
    if common:
        return [(x, x) for x in common]
    if len(la) == len(lb) == 1:
        return [(la[0], lb[0])]
    raise UsageError(f"{ra.folder} and {rb.folder} share no estimator label; name them: --estimators A B "
                     f"(A has: {', '.join(la)}; B has: {', '.join(lb)})")


def write_comparison(comparisons: list[Comparison], folder: OutputFolder, fmts=REPORT_FORMATS) -> list[Path]:
    """``compare.json``, ``compare.csv``, the page of each comparison (``compare.pdf``, a PNG
    each, its runs' differences drawn) and ``compare.html`` (the tables, sortable, and the
    differences with their intervals, to explore).

    Parameters
    ----------
    comparisons : list of Comparison
        What :func:`compare` returned.
    folder : navsim.foundations.outputs.OutputFolder
        The open output folder written into.
    fmts : sequence of {"pdf", "png", "html"}
        The page formats.

    Returns
    -------
    list of Path
        The files written.
    """
    folder.json("compare.json", {"comparisons": [c.to_dict() for c in comparisons], **provenance()})
    buf = io.StringIO()
    w = csv.writer(buf, lineterminator="\n")
    w.writerow(CSV_HEADERS)
    for c in comparisons:
        w.writerows(csv_rows(c))
    folder.text("compare.csv", buf.getvalue())
    pages = [compare_page(c, "compare" if j == 0 else f"compare_{j + 1}") for j, c in enumerate(comparisons)]
    try:
        files = render(folder, pages, fmts, "navsim compare", pdf="compare.pdf")
    finally:
        for p in pages:
            pyplot().close(p.figure)
    if "html" in fmts:                          # Bokeh imported here, on first use
        files.append(folder.write("compare.html", lambda p: p.write_text(report.html.compare_html(comparisons),
                                                                          encoding="utf-8")))
    return [folder.path / "compare.json", folder.path / "compare.csv", *files]




def _labels(estimators) -> list[str] | None:
    """:func:`compare`'s ``estimators``: None, one label or a sequence of one or two."""
    if estimators is None or isinstance(estimators, str):
        return None if estimators is None else [estimators]
    names = list(estimators) if isinstance(estimators, (list, tuple)) else None
    if names is None or not all(isinstance(x, str) for x in names) or len(names) > 2:
        raise UsageError(f"estimators: {shown(estimators)}: expected one or two estimator labels (str)")
    return names
