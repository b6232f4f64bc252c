"""95 % confidence intervals of Monte Carlo metrics, the runs as the independent samples.

A run's errors share its random-constant biases, its initial errors and its flight, so its
epochs are not independent; the runs are. Every interval here is therefore built from one
number (or one sum) per run, and it narrows as ``1 / sqrt(runs)``, never with the number of
epochs. The methods, by the kind of metric:

- **a mean square or RMS** over runs and epochs, ``sum_b s_b / sum_b n_b`` (``s_b`` the run's
  sum of squares, ``n_b`` its count of values): the variance of the ratio from the runs'
  influence values (the linearised ratio estimator), and the interval of a scaled chi-square
  with Satterthwaite's degrees of freedom ``nu = 2 m^2 / se^2`` (:func:`positive_interval`).
  With one value per run of a zero-mean Gaussian error this is the exact chi-square interval
  of a mean square (``nu`` = runs); an RMS's interval is the square root of its mean square's.
- **a share** (of values inside a band, of runs landed): Wilson's score interval with the
  effective number of samples from the runs' influence values (:func:`share_interval`), or
  Clopper-Pearson's exact interval where each run counts once (:func:`binomial_interval`).
- **a percentile of values pooled over runs and epochs** (``p99``, ``p95_abs``): Woodruff's
  interval: the share of values below the percentile has a run-by-run interval, and the
  percentiles at its ends are the interval (:func:`woodruff_probabilities`).
- **a percentile of one value per run** (a CEP of landing points, a calibration's 95th
  percentile): the distribution-free interval between two order statistics
  (:func:`order_statistic_interval`).
- **anything else** (a NEES share of epochs, a convergence time): the percentile interval of a
  Poisson bootstrap over runs (each run weighted by a Poisson(1) draw of its own seeded stream,
  :func:`bootstrap_weights`, so that the weights do not depend on how the runs are chunked).

A maximum has no interval (resampling never exceeds the largest value seen): none is given.
Below :data:`MIN_RUNS` runs there is no interval either.
"""

from __future__ import annotations

import functools
import math

import numpy as np
from navsim.foundations.distributions import beta_ppf, binom_cdf, chi2_ppf, norm_ppf, t_ppf

#: the confidence of every interval
CONFIDENCE = 0.95
#: the fewest runs an interval is given for
MIN_RUNS = 2
#: the replicates of the Poisson bootstrap (the (replicates, epochs) sums are kept in float32)
BOOTSTRAP_REPLICATES = 200
#: the resamples of the studentized bootstrap of a mean square, and the runs it is used for
#: (beyond, the chi-square interval it tends to)
STUDENTIZED_RESAMPLES = 999
MIN_STUDENTIZED, STUDENTIZED_MAX_RUNS = 5, 2000
#: the first entropy word of every run's bootstrap stream (the second is the run number)
BOOTSTRAP_KEY = 0x1C95


def _none() -> list[float]:
    return [math.nan, math.nan]


def positive_interval(m: float, se: float, runs: int) -> list[float]:
    """The interval of a positive mean ``m`` with standard error ``se`` over ``runs`` runs: a
    scaled chi-square with ``nu = 2 m^2 / se^2`` degrees of freedom."""
    if runs < MIN_RUNS or not (math.isfinite(m) and math.isfinite(se)):
        return _none()
    if se <= 0 or m <= 0:
        return [m, m]
    nu = 2.0 * m * m / (se * se)
    a = (1 - CONFIDENCE) / 2
    return [float(nu * m / chi2_ppf(1 - a, nu)), float(nu * m / chi2_ppf(a, nu))]


def ratio_se(s: np.ndarray, n: np.ndarray) -> tuple[float, float, int]:
    """``sum(s) / sum(n)`` over the runs (axis 0) that have values, its standard error from the
    runs' influence values, and the number of those runs."""
    s, n = np.asarray(s, float), np.asarray(n, float)
    keep = n > 0
    s, n = s[keep], n[keep]
    runs = int(keep.sum())
    if runs == 0:
        return math.nan, math.nan, 0
    total = n.sum()
    m = s.sum() / total
    if runs < MIN_RUNS:
        return float(m), math.nan, runs
    infl = (s - m * n) / total
    return float(m), float(math.sqrt(runs / (runs - 1) * np.sum(infl ** 2))), runs


def mean_square_interval(s, n) -> list[float]:
    """The interval of the mean square ``sum(s) / sum(n)`` (per-run sums of squares ``s`` and
    counts ``n``, shape ``(B,)``): the studentized bootstrap of its logarithm
    (:func:`studentized_log_ratio`), or, beyond :data:`STUDENTIZED_MAX_RUNS` runs, the
    chi-square interval (:func:`positive_interval`) that it tends to."""
    m, se, runs = ratio_se(s, n)
    if MIN_STUDENTIZED <= runs <= STUDENTIZED_MAX_RUNS and m > 0 and se > 0:
        keep = np.asarray(n, float) > 0
        out = studentized_log_ratio(np.asarray(s, float)[keep], np.asarray(n, float)[keep], m, se)
        if out is not None:
            return out
    return positive_interval(m, se, runs)


@functools.lru_cache(maxsize=4)
def _resamples(runs: int) -> np.ndarray:
    """How often each of ``runs`` runs is drawn in each of :data:`STUDENTIZED_RESAMPLES`
    resamples, ``(R, runs)``: one seeded stream per number of runs."""
    rng = np.random.default_rng([BOOTSTRAP_KEY, 1, runs])
    idx = rng.integers(0, runs, (STUDENTIZED_RESAMPLES, runs))
    rows = np.repeat(np.arange(STUDENTIZED_RESAMPLES), runs)
    w = np.bincount(rows * runs + idx.ravel(), minlength=STUDENTIZED_RESAMPLES * runs)
    return w.reshape(STUDENTIZED_RESAMPLES, runs).astype(float)


def studentized_log_ratio(s: np.ndarray, n: np.ndarray, m: float, se: float, logit: bool = False) -> list[float]:
    """The bootstrap-t interval of ``log(sum(s) / sum(n))`` (``logit`` of it for a share;
    resampling runs, each resample's standard error from its influence values), back on the
    ratio's scale: right-skewed runs (one random constant per run) are covered at small run
    counts where a symmetric or chi-square interval is not."""
    runs = s.size
    w = _resamples(runs)
    s_r, n_r = w @ s, w @ n
    m_r = s_r / n_r
    fwd = (lambda v: np.log(v / (1 - v))) if logit else np.log
    slope = (lambda v: v * (1 - v)) if logit else (lambda v: v)
    with np.errstate(invalid="ignore", divide="ignore"):
        var_r = (w @ s ** 2 - 2 * m_r * (w @ (s * n)) + m_r ** 2 * (w @ n ** 2)) * runs / (runs - 1) / n_r ** 2
        t_r = (fwd(m_r) - fwd(m)) / (np.sqrt(var_r) / slope(m_r))
    t_r = t_r[np.isfinite(t_r)]
    if t_r.size < STUDENTIZED_RESAMPLES // 2:
        return None
    a = (1 - CONFIDENCE) / 2
    q_lo, q_hi = np.quantile(t_r, [a, 1 - a])
    centre, se_t = float(fwd(m)), se / slope(m)
    ends = np.array([centre - q_hi * se_t, centre - q_lo * se_t])
    back = 1 / (1 + np.exp(-ends)) if logit else np.exp(ends)
    return [float(back[0]), float(back[1])]


def rms_interval(s, n) -> list[float]:
    """The interval of the RMS ``sqrt(sum(s) / sum(n))``: the square root of the mean square's."""
    return [math.sqrt(v) if math.isfinite(v) else math.nan for v in mean_square_interval(s, n)]


def rms_intervals(s, n) -> list[list[float]]:
    """:func:`rms_interval` of each column of ``s`` and ``n`` (shape ``(B, k)``)."""
    s, n = np.asarray(s, float), np.asarray(n, float)
    return [rms_interval(s[:, j], n[:, j]) for j in range(s.shape[1])]


def std_interval(s1, s2, n) -> list[float]:
    """The interval of the standard deviation of values pooled over runs (per-run sums ``s1``,
    sums of squares ``s2`` and counts ``n``): the variance's influence values, chi-square."""
    s1, s2, n = (np.asarray(a, float) for a in (s1, s2, n))
    keep = n > 0
    s1, s2, n = s1[keep], s2[keep], n[keep]
    runs = int(keep.sum())
    if runs < MIN_RUNS:
        return _none()
    total = n.sum()
    mu = s1.sum() / total
    var = s2.sum() / total - mu * mu
    infl = (s2 - 2 * mu * s1 + mu * mu * n - var * n) / total
    se = math.sqrt(runs / (runs - 1) * np.sum(infl ** 2))
    return [math.sqrt(max(v, 0.0)) if math.isfinite(v) else math.nan
            for v in positive_interval(float(var), se, runs)]


def mean_interval(x) -> list[float]:
    """Student's t interval of the mean of one value per run (NaN runs left out)."""
    x = np.asarray(x, float)
    x = x[np.isfinite(x)]
    if x.size < MIN_RUNS:
        return _none()
    half = t_ppf(0.5 + CONFIDENCE / 2, x.size - 1) * np.std(x, ddof=1) / math.sqrt(x.size)
    return [float(x.mean() - half), float(x.mean() + half)]


def share_interval(k, n) -> list[float]:
    """Wilson's interval of the share ``sum(k) / sum(n)`` (per-run counts ``k`` of ``n``), with
    the effective number of samples ``p (1 - p) / se^2`` of the runs' influence values (at most
    the values counted; at least the runs)."""
    p, se, runs = ratio_se(k, n)
    if runs < MIN_RUNS or not math.isfinite(se):
        return _none()
    total = float(np.sum(np.asarray(n, float)))
    n_eff = total if se <= 0 else min(max(p * (1 - p) / (se * se), runs), total)
    return wilson(p, n_eff)


def wilson(p: float, n: float) -> list[float]:
    """Wilson's score interval of a share ``p`` of ``n`` samples."""
    z = norm_ppf(0.5 + CONFIDENCE / 2)
    centre = (p + z * z / (2 * n)) / (1 + z * z / n)
    half = z / (1 + z * z / n) * math.sqrt(p * (1 - p) / n + z * z / (4 * n * n))
    return [float(max(centre - half, 0.0)), float(min(centre + half, 1.0))]


def binomial_interval(k: int, n: int) -> list[float]:
    """Clopper-Pearson's exact interval of ``k`` successes in ``n`` runs."""
    if n < MIN_RUNS:
        return _none()
    a = (1 - CONFIDENCE) / 2
    lo = 0.0 if k == 0 else float(beta_ppf(a, k, n - k + 1))
    hi = 1.0 if k == n else float(beta_ppf(1 - a, k + 1, n - k))
    return [lo, hi]


def order_statistic_interval(x, q: float) -> list[float]:
    """The distribution-free interval of the ``q``-th percentile of one value per run: the
    order statistics ``x_(l) <= x_(u)`` with ``P(x_(l) <= xi_q <= x_(u)) >= CONFIDENCE``
    (binomial), as near the percentile as that allows; NaN where the runs are too few."""
    x = np.sort(np.asarray(x, float)[np.isfinite(np.asarray(x, float))])
    n, p = x.size, q / 100.0
    if n < MIN_RUNS:
        return _none()
    from_binom = _order_ranks(n, p)
    if from_binom is None:
        return [float(x[0]) if p <= 0.5 else math.nan, float(x[-1]) if p >= 0.5 else math.nan]
    lo, hi = from_binom
    return [float(x[lo]) if lo >= 0 else math.nan, float(x[hi]) if hi < n else math.nan]


def _order_ranks(n: int, p: float):
    """0-based ranks ``(l, u)`` of the order statistics with ``P(x_(l) <= xi_p) >= 1 - a`` and
    ``P(xi_p <= x_(u)) >= 1 - a`` (``a`` half the miss): ``P(x_(l+1) <= xi_p) = 1 - F(l)`` and
    ``P(xi_p <= x_(u+1)) = F(u)`` for ``F`` the binomial(n, p) CDF; ``-1`` / ``n`` where no order
    statistic reaches that far (the interval open at that end), None at both."""
    a = (1 - CONFIDENCE) / 2
    cdf = binom_cdf(np.arange(n + 1), n, p)
    lo = int(np.searchsorted(cdf, a, side="right")) - 1     # largest j with F(j) <= a
    hi = int(np.searchsorted(cdf, 1 - a, side="left"))      # smallest j with F(j) >= 1 - a
    if lo < 0 and hi >= n:
        return None
    return lo, min(hi, n)


def woodruff_probabilities(below, n, q: float) -> tuple[float, float] | None:
    """Woodruff's interval as two cumulative shares: the share of values below the pooled
    ``q``-th percentile has a run-by-run interval (the studentized bootstrap of its logit,
    :func:`studentized_log_ratio`, asymmetric near 0 and 1; Wilson's with the runs' effective
    number of samples beyond :data:`STUDENTIZED_MAX_RUNS`); the percentiles at its ends are the
    percentile's interval (``below``: each run's count of values below the percentile, ``n``
    its count of values). None where the runs are too few."""
    below, n = np.asarray(below, float), np.asarray(n, float)
    keep = n > 0
    below, n = below[keep], n[keep]
    share, se, runs = ratio_se(below, n)
    if runs < MIN_RUNS or not math.isfinite(se):
        return None
    if MIN_STUDENTIZED <= runs <= STUDENTIZED_MAX_RUNS and 0 < share < 1 and se > 0:
        out = studentized_log_ratio(below, n, share, se, logit=True)
        if out is not None:
            return _shift(out, share, q / 100.0)
    n_eff = float(np.sum(n)) if se <= 0 else max(share * (1 - share) / (se * se), 1.0)
    return _shift(wilson(share, n_eff), share, q / 100.0)


def _shift(interval, share: float, p: float) -> tuple[float, float]:
    """The share interval moved from the share found below the percentile's bin to ``p``."""
    return max(interval[0] + p - share, 0.0), min(interval[1] + p - share, 1.0)


def bootstrap_weights(runs, replicates: int = BOOTSTRAP_REPLICATES) -> np.ndarray:
    """The Poisson(1) bootstrap weights of the run numbers ``runs``, ``(replicates, B)``
    float32: each run's column from its own stream (``BOOTSTRAP_KEY``, run), so the same run
    has the same weights whatever chunk it is scored in."""
    runs = np.asarray(runs, np.int64).ravel()
    out = np.empty((replicates, runs.size), np.float32)
    for j, r in enumerate(runs):
        out[:, j] = np.random.default_rng([BOOTSTRAP_KEY, int(r)]).poisson(1.0, replicates)
    return out


def bootstrap_interval(replicates, point: float | None = None, bounds=(-math.inf, math.inf)) -> list[float]:
    """The percentile interval of a statistic's bootstrap replicates (NaN ones left out; an
    infinite end, as a convergence that never comes, is NaN: open).

    With the statistic's ``point`` value, the interval is shifted by the replicates' median
    bias (``median - point``) and clipped to ``bounds``: a statistic that resampling biases
    (the share of epochs whose run-averaged NEES is inside its band falls as the resampled
    runs add spread) keeps its point inside its interval."""
    v = np.asarray(replicates, float)
    v = v[~np.isnan(v)]
    if v.size < 10:
        return _none()
    a = (1 - CONFIDENCE) / 2
    lo, hi = np.quantile(v, [a, 1 - a], method="inverted_cdf")
    if point is not None and math.isfinite(point):
        bias = float(np.quantile(v, 0.5, method="inverted_cdf")) - point
        if math.isfinite(bias):
            lo, hi = np.clip([lo - bias, hi - bias], *bounds)
    return [float(x) if math.isfinite(x) else math.nan for x in (lo, hi)]


def runs_needed(runs: int, value: float, interval, target: float) -> int | None:
    """The runs at which an interval around ``value`` (now from ``runs`` runs) would no longer
    reach ``target``: its half-width towards ``target`` shrinks as ``1 / sqrt(runs)``. None if
    the interval does not reach the target already (decided) or cannot be scaled."""
    lo, hi = interval
    if not all(math.isfinite(v) for v in (value, lo, hi, target)) or runs < MIN_RUNS:
        return None
    half = (hi - value) if target >= value else (value - lo)
    gap = abs(target - value)
    if half <= 0 or gap >= half:
        return None
    if gap == 0:
        return math.inf
    return int(math.ceil(runs * (half / gap) ** 2))


def student_runs(unit: float, target: float, alpha: float = 1 - CONFIDENCE, most: int = 10 ** 9) -> int | None:
    """The fewest runs ``N >= 2`` whose two-sided Student half-width ``t(1 - alpha/2, N - 1) *
    unit / sqrt(N)`` is at most ``target`` (``unit``: the spread of one run); the half-width
    falls with ``N``, so a doubling then a bisection finds it. None where it takes more than
    ``most`` or cannot be had. The quantile is :func:`~navsim.foundations.distributions.t_ppf` (1 µs a
    call, for the 20-odd calls of a search)."""
    if not (math.isfinite(unit) and math.isfinite(target) and unit > 0 and target > 0):
        return None
    ok = lambda n: float(t_ppf(1 - alpha / 2, n - 1)) * unit / math.sqrt(n) <= target
    lo, hi = 1, 2
    while not ok(hi):
        lo, hi = hi, hi * 2
        if hi > most:
            return None
    while hi - lo > 1:
        mid = (lo + hi) // 2
        lo, hi = (lo, mid) if ok(mid) else (mid, hi)
    return hi


def runs_for_precision(runs: int, value: float, interval, precision: float) -> int | None:
    """The runs at which the 95 % interval around ``value`` (now from ``runs`` runs) would be
    ``2 * precision * value`` wide (``value +- 5 %``): its half-width scales as
    ``t(N - 1) / sqrt(N)`` (Student's quantile: a few runs' interval is wider than the
    square-root law alone; :func:`student_runs`). None where there is no interval or the value
    is 0."""
    lo, hi = interval
    if not all(math.isfinite(v) for v in (value, lo, hi)) or runs < MIN_RUNS or value == 0 or precision <= 0:
        return None
    unit = (hi - lo) / 2 * math.sqrt(runs) / float(t_ppf(0.5 + CONFIDENCE / 2, runs - 1))
    return student_runs(unit, precision * abs(value))


#: the runs :class:`WeightedSums` sums in one product: fixed blocks of the runs fed, in run
#: order, so that the sums do not depend on how the runs are chunked
BOOTSTRAP_BLOCK_RUNS = 64


class WeightedSums:
    """The Poisson-bootstrap replicates of per-epoch sums over runs, fed chunk by chunk: for
    values ``x`` ``(B, epochs)`` of runs with weights ``w`` ``(R, B)``
    (:func:`bootstrap_weights`), ``sum_b w_rb x_bt`` and ``sum_b w_rb [x_bt finite]``
    (``(R, epochs)``, float32). The runs are summed in blocks of
    :data:`BOOTSTRAP_BLOCK_RUNS` in the order they are fed (the last block when the sums are
    read), whatever the chunks: the same runs give the same bits."""

    def __init__(self):
        self.s = self.n = self.s0 = self.n0 = None
        self._w: list = []             # the runs fed and not summed yet (less than a block)
        self._x: list = []

    def add(self, w: np.ndarray, x) -> None:
        self._w.append(np.asarray(w, np.float32))
        self._x.append(np.asarray(x, float))
        held = sum(len(x) for x in self._x)
        if held < BOOTSTRAP_BLOCK_RUNS:
            return
        w, x = np.concatenate(self._w, axis=1), np.concatenate(self._x)
        full = held - held % BOOTSTRAP_BLOCK_RUNS
        for a in range(0, full, BOOTSTRAP_BLOCK_RUNS):
            self._sum(w[:, a:a + BOOTSTRAP_BLOCK_RUNS], x[a:a + BOOTSTRAP_BLOCK_RUNS])
        self._w, self._x = [w[:, full:]], [x[full:]]

    def _flush(self) -> None:
        """Sum the runs held (the last block)."""
        if self._x:
            w, x = np.concatenate(self._w, axis=1), np.concatenate(self._x)
            self._w, self._x = [], []
            if len(x) or self.s is None:
                self._sum(w, x)

    def _sum(self, w: np.ndarray, x: np.ndarray) -> None:
        w, x = np.ascontiguousarray(w), np.ascontiguousarray(x)    # the same layout whatever the chunks
        finite = np.isfinite(x)
        x0 = np.where(finite, x, 0.0)
        s, n = w @ x0.astype(np.float32), w @ finite.astype(np.float32)
        s0, n0 = x0.sum(axis=0), finite.sum(axis=0)           # the unweighted sums: the point
        if self.s is None:
            self.s, self.n, self.s0, self.n0 = s, n, s0, n0
        else:
            self.s, self.n, self.s0, self.n0 = self.s + s, self.n + n, self.s0 + s0, self.n0 + n0

    def mean(self) -> np.ndarray:
        """Each replicate's per-epoch weighted mean (NaN where no weighted value)."""
        self._flush()
        with np.errstate(invalid="ignore", divide="ignore"):
            return (self.s / self.n).astype(float)

    def point(self) -> np.ndarray:
        """The per-epoch mean over the runs themselves (every weight 1), ``(1, epochs)``."""
        self._flush()
        with np.errstate(invalid="ignore", divide="ignore"):
            return (self.s0 / self.n0)[None, :]


def rounded(tree, digits: int = 4):
    """A tree of intervals (mappings, lists, numbers) with every number to ``digits``
    significant digits (an interval's ends need no more) and None for an end that is not
    finite (no interval, or open there: JSON null, as metrics.json reads back)."""
    if isinstance(tree, dict):
        return {k: rounded(v, digits) for k, v in tree.items()}
    if isinstance(tree, (list, tuple)):
        return [rounded(v, digits) for v in tree]
    if tree is None or not math.isfinite(float(tree)):
        return None
    v = float(tree)
    return v if v == 0 else float(f"{v:.{digits}g}")
