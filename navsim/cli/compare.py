"""``navsim compare``: two results' (or one result's two estimators') metrics, ``B - A`` with
95 % intervals and a verdict per metric."""

from __future__ import annotations

from pathlib import Path

from navsim import api
from navsim.cli.command import Command
from navsim.cli.options import NOTHING_RESUMED, out_option
from navsim.cli.output import open_folder, table
from navsim.foundations.errors import UsageError
from navsim.report.compare import HEADERS as COMPARE_HEADERS, headline, text_rows
from navsim.scoring.compare import DEFAULT_MARGIN_PCT, check_margin


def arguments(p) -> None:
    """The result folders, the estimators, how they are compared and ``--out``."""
    p.add_argument("a", help="result folder A")
    p.add_argument("b", nargs="?", help="result folder B (default: A, comparing two of its estimators)")
    p.add_argument("--estimators", nargs="+", metavar="LABEL",
                   help="the estimator of A and of B (one label: the same on both; default: every label both "
                   "have, or each one's only estimator)")
    p.add_argument("--partial", action="store_true",
                   help="compare an interrupted result's finished runs (each side's count is printed)")
    p.add_argument("--unpaired", action="store_true",
                   help="compare side against side even where the runs pair (to see what pairing gains)")
    p.add_argument("--margin", action="append", metavar="[PATH=]PCT",
                   help="the practical-equivalence margin, per cent of the larger value: a difference whose "
                   f"95 %% interval lies within it is 'negligible', and none within it is offered a run count "
                   f"(default {DEFAULT_MARGIN_PCT:g}); PATH=PCT sets it for a metric path (rms.pos_m=5); repeatable")
    out_option(p, "reports/compare_<A>_vs_<B>")


def handle(args) -> int:
    """Compare, print each comparison's table, write compare.json, .csv and .pdf/.png; an
    ``--out`` inside or holding a compared result is refused before anything is written."""
    comparisons = api.compare(args.a, args.b, args.estimators, partial=args.partial, unpaired=args.unpaired,
                              margin=parse_margins(args.margin))
    name = lambda p: Path(p).resolve().name
    default = Path("reports") / (f"compare_{name(args.a)}" + (f"_vs_{name(args.b)}" if args.b else ""))
    out = (Path(args.out) if args.out else default).resolve()
    for given in filter(None, (args.a, args.b)):
        held = Path(given).resolve()
        if out == held or held in out.parents or out in held.parents:
            raise UsageError(f"--out {out}: inside or holding the result {given} it compares; hint: write the "
                             "comparison to a folder of its own (default reports/compare_<A>_vs_<B>)")
    folder = open_folder(args, default)      # only now: a refused comparison writes nothing
    for j, c in enumerate(comparisons):
        print(("\n" if j else "") + headline(c) + "\n\n" + table(list(COMPARE_HEADERS), text_rows(c)))
    folder.clear_earlier()
    files = api.write_comparison(comparisons, folder)
    print(f"\nwrote {folder.path}/: " + ", ".join(f.name for f in files))
    return 0


def parse_margins(items: list[str] | None):
    """``--margin`` strings (``PCT`` or ``PATH=PCT``) as :func:`navsim.compare`'s ``margin``: one
    number, or a mapping of metric path -> per cent (``""`` the default)."""
    out = {}
    for item in items or []:
        path, sep, value = item.rpartition("=")
        try:
            out[path.strip()] = float(value)
        except ValueError:
            raise UsageError(f"--margin {item!r}: expected PCT or PATH=PCT, a number of per cent "
                             "(--margin 2, --margin rms.pos_m=5)") from None
    margin = DEFAULT_MARGIN_PCT if not out else out[""] if list(out) == [""] else out
    try:
        return check_margin(margin)
    except UsageError as exc:                   # in the option's words: margin[...] -> --margin[...]
        raise UsageError(f"--{exc}") from None


COMMAND = Command(
    "compare", "compare two estimators' metrics: B - A with 95 %% intervals", usage="A B [--estimators LA LB]",
    description="Compare the metrics of two results (navsim run's folders), or of two estimators of one "
    "result: for each metric A, B, B - A with its 95 % interval and a verdict (better / worse / no significant "
    "difference at N runs, with the runs that would resolve it; NEES: higher / lower). When both flew the same "
    "flights and sensor data (the resolved scenarios equal but for their estimators and run counts, the same "
    "seed and flight) the runs are paired by number, which cancels the noise they share; else side against "
    "side. Writes compare.json, compare.csv and compare.pdf/.png. Refused with exit 2, nothing written: a "
    "folder that is not a result, damaged, or that an older or newer navsim wrote, two different tracks or "
    "metric settings, an interrupted result (unless --partial).",
    arguments=arguments, handler=handle, kept=NOTHING_RESUMED)
