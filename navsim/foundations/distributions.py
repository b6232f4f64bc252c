"""The quantiles and tail probabilities navsim's statistics take, as ``scipy.stats`` computes them.

``scipy.stats`` costs about 0.35 s to import (its whole distribution zoo), a third of a
command's start, and 60-80 us a call in argument handling; every quantile navsim needs is one
``scipy.special`` function that ``scipy.stats`` itself calls (scipy 1.17: ``chi2._ppf``,
``t._ppf``, ``t._sf``, ``norm._ppf``; ``beta._ppf`` is Boost's beta quantile, which
``betaincinv`` is too). Each function below gives ``scipy.stats``' number to the bit on every
argument it is called with, NaN where ``scipy.stats`` gives NaN (a degree of freedom of 0), and
takes scalars or arrays (numpy broadcasting); ``tests/unit/test_distributions.py`` holds them to
``scipy.stats``. The one exception is :func:`binom_cdf`, ``scipy.stats.binom.cdf``'s formula
(Boost's: the complemented incomplete beta function) through scipy's public ``betaincc``,
within a few units of 1e-15 of it: what it decides (the order statistics of an interval) is
tested equal.

Notation: ``q`` a probability, ``nu``/``df`` degrees of freedom, ``a``/``b`` the beta shapes.
"""

from __future__ import annotations

import numpy as np
from scipy.special import betaincc, betaincinv, gammaincinv, ndtri, stdtr, stdtrit


def chi2_ppf(q, nu):
    """``scipy.stats.chi2.ppf(q, nu)``: ``2 gammaincinv(nu / 2, q)``."""
    return 2 * gammaincinv(np.divide(nu, 2), q)


def t_ppf(q, df):
    """``scipy.stats.t.ppf(q, df)``: Student's quantile ``stdtrit(df, q)``."""
    return stdtrit(df, q)


def t_sf(x, df):
    """``scipy.stats.t.sf(x, df)``: Student's upper tail ``stdtr(df, -x)``."""
    return stdtr(df, np.negative(x))


def norm_ppf(q):
    """``scipy.stats.norm.ppf(q)``: the standard normal quantile ``ndtri(q)``."""
    return ndtri(q)


def beta_ppf(q, a, b):
    """``scipy.stats.beta.ppf(q, a, b)``: the inverse regularised incomplete beta function."""
    return betaincinv(a, b, q)


def binom_cdf(k, n, p):
    """``scipy.stats.binom.cdf(k, n, p)`` for whole ``0 <= k`` and ``n >= 1``: ``P(X <= k)`` of
    a binomial(n, p), ``betaincc(k + 1, n - k, p)`` (1 from ``k = n`` on)."""
    k, n = np.asarray(k, float), np.asarray(n, float)
    return np.where(k >= n, 1.0, betaincc(k + 1.0, np.maximum(n - k, 1.0), p))
