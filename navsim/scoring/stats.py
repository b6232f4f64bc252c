"""Statistics of values fed in pieces (chunk by chunk), and the chi-square bands and the
convergence time the scores use.

Sums, counts, extremes and per-epoch sums over the runs accumulate as the pieces go by, each
run's part summed alone and added in run order (:func:`run_nansums`, :func:`fold_runs`), so that
the figures do not depend on how the runs are cut into pieces, bit for bit; the standard
deviations combine the runs' means and squared deviations in run order (Chan et al.); the
percentiles of absolute values are exact, in two passes over the pieces: the first counts the
values in fixed logarithmic bins (:data:`BINS_PER_DECADE`), the second keeps only the values in
the bins that hold the wanted ranks and picks them (numpy's linear interpolation).
"""

from __future__ import annotations

import warnings

import numpy as np

from navsim.foundations.distributions import chi2_ppf
from navsim.scoring.intervals import woodruff_probabilities

#: the resolution of the first pass of :class:`AbsPercentiles`: bins per decade, from 1e-15 to 1e15
BINS_PER_DECADE = 400
_LOG_MIN, _LOG_MAX = -15.0, 15.0
_NBINS = int((_LOG_MAX - _LOG_MIN) * BINS_PER_DECADE) + 2


def _bins(v):
    """Bin of each absolute value (0: below 1e-15 or zero; last: above 1e15 or inf)."""
    with np.errstate(divide="ignore", invalid="ignore"):
        x = (np.log10(v) - _LOG_MIN) * BINS_PER_DECADE + 1
    return np.clip(np.nan_to_num(x, nan=0.0, neginf=0.0, posinf=_NBINS - 1), 0, _NBINS - 1).astype(np.int64)


def _lerp(a, b, t):
    """numpy's linear interpolation between neighbouring order statistics (elementwise)."""
    diff = b - a
    return np.where(t >= 0.5, b - diff * (1 - t), a + diff * t)


class AbsPercentiles:
    """Exact ``np.nanpercentile(np.abs(x), q)`` of values fed in pieces, in two passes.

    Feed every piece with :meth:`add` (pass 1), call :meth:`second_pass`, feed the same pieces
    again, then read :meth:`value`. Each key has its own percentile ``q``.
    """

    def __init__(self):
        self.q: dict = {}
        self.hist: dict = {}
        self.window: dict | None = None      # key -> (first bin, last bin, values below, ranks, t)
        self.kept: dict = {}
        self.per_run: dict = {}             # key -> [(each run's values below, its values)]

    def add(self, key, x, q: float) -> None:
        """Feed the values ``x``, ``(runs, ...)``: a run per row (the second pass counts each
        run's values below the percentile's bin, for :meth:`interval`)."""
        x = np.asarray(x, float)
        rows = np.abs(x).reshape((x.shape[0], int(np.prod(x.shape[1:]))) if x.ndim else (1, 1))
        valid = ~np.isnan(rows)
        b_rows = _bins(rows)                 # binned once: the pooled values and each run's
        v, b = rows[valid], b_rows[valid]
        if self.window is None:
            self.q[key] = q
            counts = np.bincount(b, minlength=_NBINS)
            self.hist[key] = self.hist[key] + counts if key in self.hist else counts
        elif key in self.window and self.window[key] is not None:
            lo, hi = self.window[key][:2]
            self.kept.setdefault(key, []).append(v[(b >= lo) & (b <= hi)])
            self.per_run.setdefault(key, []).append(
                (np.sum(valid & (b_rows < lo), axis=1), np.sum(valid, axis=1)))

    def second_pass(self) -> None:
        self.window = {}
        for key, hist in self.hist.items():
            n = int(hist.sum())
            if n == 0:
                self.window[key] = None
                continue
            pos = self.q[key] / 100.0 * (n - 1)
            r_lo = int(np.floor(pos))
            r_hi = min(r_lo + 1, n - 1)              # numpy interpolates with the next value even at t = 0
            cum = np.cumsum(hist)
            b_lo, b_hi = (int(np.searchsorted(cum, r, side="right")) for r in (r_lo, r_hi))
            below = int(cum[b_lo - 1]) if b_lo > 0 else 0
            self.window[key] = (b_lo, b_hi, below, (r_lo, r_hi), pos - r_lo)

    def value(self, key) -> float:
        w = self.window.get(key)
        if w is None:
            return float("nan")
        _, _, below, (r_lo, r_hi), t = w
        vals = np.sort(np.concatenate(self.kept.get(key, [np.empty(0)])))
        return float(_lerp(vals[r_lo - below], vals[r_hi - below], t))


    def interval(self, key) -> list[float]:
        """Woodruff's 95 % interval of the percentile (the runs as the samples,
        :func:`navsim.scoring.intervals.woodruff_probabilities`), read from the first pass's
        histogram (to a bin, 0.6 %); NaN where the runs are too few."""
        w, pieces = self.window.get(key), self.per_run.get(key)
        if w is None or not pieces:
            return [float("nan")] * 2
        below, n = (np.concatenate([p[i] for p in pieces]) for i in range(2))
        shares = woodruff_probabilities(below, n, self.q[key])
        if shares is None:
            return [float("nan")] * 2
        return [self._at_share(key, p) for p in shares]

    def _at_share(self, key, share: float) -> float:
        """The value at cumulative ``share`` of the first pass's histogram (log-linear in a bin)."""
        hist = self.hist[key]
        cum = np.cumsum(hist)
        rank = share * (cum[-1] - 1)
        k = int(np.searchsorted(cum, rank, side="right"))
        if k == 0:
            return 0.0
        k = min(k, _NBINS - 1)
        f = (rank - cum[k - 1]) / max(hist[k], 1)
        return float(10.0 ** (_LOG_MIN + (k - 1 + min(max(f, 0.0), 1.0)) / BINS_PER_DECADE))


def run_nansums(x, keep: int = 0) -> tuple[np.ndarray, np.ndarray]:
    """Each run's ``np.nansum`` and non-NaN count over the axes after the run axis (axis 0)
    but the last ``keep``: ``(B, epochs, 3)`` -> ``(B, 3)`` with ``keep=1``.

    A run's sum has the same bits whatever runs share its array: numpy's reductions follow the
    memory layout (a boolean index over epochs leaves the runs innermost, and a pairwise sum
    then becomes a sequential one), so each run's values of each kept index are summed as one
    contiguous row, from a C-contiguous ``(B, kept, values)`` copy."""
    x = np.asarray(x, float)
    kept = x.shape[x.ndim - keep:] if keep else ()
    rows = (x.shape[0], int(np.prod(x.shape[1:x.ndim - keep])), int(np.prod(kept)))
    y = np.ascontiguousarray(np.swapaxes(x.reshape(rows), 1, 2))
    nan = np.isnan(y)
    s, n = np.sum(np.where(nan, 0.0, y), axis=2), np.sum(~nan, axis=2)
    return s.reshape(x.shape[:1] + kept), n.reshape(x.shape[:1] + kept)


def fold_runs(total, rows) -> np.ndarray:
    """``total + rows[0] + rows[1] + ...``, added left to right (``np.add.accumulate``: never
    regrouped), so that a sum over runs fed in pieces has the bits of the same sum fed whole;
    ``total`` None: from zero (also when ``rows`` holds no run)."""
    rows = np.asarray(rows)
    start = np.zeros(rows.shape[1:], rows.dtype) if total is None else np.asarray(total, rows.dtype)
    return np.add.accumulate(np.concatenate([start[None], rows]), axis=0)[-1]


class RunSums:
    """Each run's ``np.nansum`` and non-NaN count over the axes after the run axis (its last
    axes kept: ``(B, epochs, 3)`` -> ``(B, 3)``), run after run: what an interval with the
    runs as the samples needs (:mod:`navsim.scoring.intervals`); :func:`run_nansums`, so a
    run's sums do not depend on its chunk."""

    def __init__(self, keep: int = 0):
        self.keep = keep             # trailing axes kept
        self.s: list = []
        self.n: list = []

    def add(self, x) -> None:
        s, n = run_nansums(x, self.keep)
        self.s.append(s)
        self.n.append(n)

    def arrays(self) -> tuple[np.ndarray, np.ndarray]:
        """The runs' sums and counts, run axis first."""
        return np.concatenate(self.s), np.concatenate(self.n)


class Moments:
    """Count, mean and squared deviations of the non-NaN values of runs ``(B, values)``: each
    run's (:func:`run_nansums`), combined run after run in run order (Chan et al.), so that
    the result does not depend on how the runs are chunked."""

    def __init__(self):
        self.n, self.mean, self.m2 = 0, 0.0, 0.0

    def add(self, x) -> None:
        s, n = run_nansums(x)
        with np.errstate(invalid="ignore", divide="ignore"):
            mean = s / n
        m2, _ = run_nansums((np.asarray(x, float) - mean[:, None]) ** 2)
        for n_b, mean_b, m2_b in zip(n.tolist(), mean.tolist(), m2.tolist()):
            if n_b == 0:
                continue
            delta = mean_b - self.mean
            tot = self.n + n_b
            self.mean += delta * n_b / tot
            self.m2 += m2_b + delta ** 2 * self.n * n_b / tot
            self.n = tot

    def std(self) -> float:
        return float(np.sqrt(self.m2 / self.n)) if self.n else float("nan")


class Sum:
    """``np.nansum`` and the non-NaN count over the run axis (and more leading axes): each
    run's sum (:func:`run_nansums`), added in run order (:func:`fold_runs`), so that the sums
    do not depend on how the runs are chunked."""

    def __init__(self):
        self.s = self.n = None

    def add(self, x, axis) -> None:
        """Feed ``x`` (runs first), summed over ``axis``: 0 or the leading axes ``(0, 1, ...)``."""
        x = np.asarray(x, float)
        s, n = run_nansums(x, x.ndim - len(np.atleast_1d(axis)))
        n = np.sum(n, axis=0)
        self.s, self.n = fold_runs(self.s, s), (n if self.n is None else self.n + n)

    def mean(self):
        with np.errstate(invalid="ignore", divide="ignore"):
            return self.s / self.n


class Extreme:
    def __init__(self, fn):
        self.fn, self.v = fn, None

    def value(self, shape=()):
        """The extreme; NaN (of ``shape``) where every value was NaN, as ``np.nanmax``."""
        return np.full(shape, np.nan) if self.v is None else self.v

    def add(self, x, axis=None) -> None:
        if np.all(np.isnan(x)):
            return
        v = self.fn(x, axis=axis)
        self.v = v if self.v is None else self.fn(np.stack([self.v, v]), axis=0)


def last_finite(finite: np.ndarray) -> np.ndarray:
    """Each row's last ``True`` column of ``finite`` ``(B, E)``: a run's last record (a
    closed-loop run's records end at its landing); the last column for a row with none."""
    return finite.shape[1] - 1 - np.argmax(finite[:, ::-1], axis=1)


def chi2_band(dim: int, runs: int, p: float = 0.95) -> tuple[float, float]:
    """Two-sided band of the average of ``runs`` NEES/NIS of dimension ``dim``."""
    a = (1 - p) / 2
    lo, hi = chi2_ppf(np.array([a, 1 - a]), dim * runs) / runs
    return float(lo), float(hi)


#: :func:`convergence_time`'s defaults: the factor over the steady error, and how long it holds
CONVERGENCE_FACTOR, CONVERGENCE_HOLD_S = 2.0, 60.0


def convergence_time(t_s, err, factor: float = CONVERGENCE_FACTOR, hold_s: float = CONVERGENCE_HOLD_S):
    """First time from which ``err`` (the Monte Carlo RMS of the position error norm) stays
    below ``factor`` times its steady value (the median over the second half of the run) for
    ``hold_s`` (or to the end of the run), so that a later fault window does not count as
    a failure to converge; None if it never does, or if the steady error is not below the
    initial one (an error that grows, as free inertial navigation's, has not converged)."""
    t = convergence_times(t_s, np.asarray(err, float)[None, :], factor, hold_s)[0]
    return None if np.isinf(t) else float(t)


def convergence_times(t_s, err, factor: float = CONVERGENCE_FACTOR, hold_s: float = CONVERGENCE_HOLD_S,
                      own_end: bool = False) -> np.ndarray:
    """:func:`convergence_time` of each row of ``err`` ``(B, E)``, vectorised: ``(B,)``, ``inf``
    where a row never converges. ``own_end``: each row is one run whose records end at its last
    finite epoch (a closed-loop run's landing): its steady value is over the second half of its
    own epochs, and the hold may reach its end; otherwise a NaN epoch is a bad one."""
    t_s, err = np.asarray(t_s, float), np.asarray(err, float)
    B, E = err.shape
    out = np.full(B, np.inf)
    if E == 0:
        return out
    cols = np.arange(E)[None, :]
    end = (last_finite(np.isfinite(err)) + 1)[:, None] if own_end else np.full((B, 1), E)
    late = np.where((cols >= end // 2) & (cols < end), err, np.nan)
    has = np.isfinite(late).any(axis=1)
    with warnings.catch_warnings():                       # a row without a finite late value: left inf
        warnings.simplefilter("ignore", RuntimeWarning)
        steady = np.nanmedian(late, axis=1)
    ok = (err <= factor * steady[:, None]) | (cols >= end)
    bad_t = np.where(ok, np.inf, t_s[None, :])
    # each epoch's next bad time after it: the running minimum from the end, shifted by one
    nxt = np.concatenate([np.minimum.accumulate(bad_t[:, ::-1], axis=1)[:, ::-1][:, 1:], np.full((B, 1), np.inf)],
                         axis=1)
    good = ok & (cols < end) & (nxt - t_s[None, :] >= hold_s)
    first = np.argmax(good, axis=1)
    found = good.any(axis=1) & has & (steady < err[:, 0])
    out[found] = t_s[first[found]]
    return out


def row_percentiles(x, q: float) -> np.ndarray:
    """Each run's ``np.nanpercentile(np.abs(x[b]), q, axis=0)`` of ``x`` ``(B, E, ...)``, over
    its epochs (axis 1): ``(B, ...)``; NaN for a run without a finite value there. One sort of
    the whole array (NaN sorts last), each row's ranks read at its own count of values."""
    a = np.sort(np.abs(np.asarray(x, float)), axis=1)
    n = np.sum(~np.isnan(a), axis=1)                       # (B, ...)
    pos = q / 100.0 * np.maximum(n - 1, 0)
    lo = np.floor(pos).astype(np.int64)
    hi = np.minimum(lo + 1, np.maximum(n - 1, 0))
    t = pos - lo
    take = lambda i: np.take_along_axis(a, i[:, None], axis=1)[:, 0] if a.shape[1] else np.full(i.shape, np.nan)
    return np.where(n > 0, _lerp(take(lo), take(hi), t), np.nan)


def chi2_bands(dim: int, counts, p: float = 0.95) -> tuple[np.ndarray, np.ndarray]:
    """:func:`chi2_band` of each of ``counts`` (the runs behind each epoch's average)."""
    counts = np.asarray(counts)
    a = (1 - p) / 2
    return chi2_ppf(a, dim * counts) / counts, chi2_ppf(1 - a, dim * counts) / counts
