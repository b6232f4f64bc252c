"""Landmark fixes scored: the position error of an estimator at the end of each landmark sighting
against the camera's fix noise. The sightings ``(name, start_s, end_s, sigma_m)`` are the
camera's (:class:`navsim.sensors.camera.SightingSpan`, found on the flight by
:func:`navsim.sensors.camera.flight_sightings`): the scoring only reads them."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from navsim.records.metrics import Landmarks, Sighting, SpreadStats
from navsim.scoring.intervals import MIN_RUNS, mean_square_interval, share_interval


@dataclass(frozen=True)
class SightingEpochs:
    """The epochs of a history that :func:`sighting_metrics` reads (:func:`thin_for_sightings`)."""

    t_s: np.ndarray            #: (K,)
    pos_err_m: np.ndarray      #: (B, K, 3)
    diverged: np.ndarray       #: (B,)


def _epochs(t_s, spans) -> tuple[np.ndarray, np.ndarray]:
    """Per sighting, the epoch of its last fix and the epoch before its start."""
    E = len(t_s)
    last = np.clip(np.searchsorted(t_s, [b - 1e-6 for _, _, b, _ in spans]), 0, E - 1)
    before = np.clip(np.searchsorted(t_s, [a - 1e-6 for _, a, _, _ in spans]) - 1, 0, E - 1)
    return last.astype(int), before.astype(int)


def thin_for_sightings(h, spans) -> SightingEpochs:
    """The epochs of history ``h`` that :func:`sighting_metrics` reads (and the first and last):
    on these alone it finds the same."""
    last, before = _epochs(h.t_s, spans)
    idx = np.array(sorted({0, len(h.t_s) - 1, *last.tolist(), *before.tolist()}))
    return SightingEpochs(h.t_s[idx], h.pos_err_m[:, idx], np.asarray(h.diverged))


def sighting_metrics(h, spans, good=None) -> Landmarks | None:
    """Position error of an estimator at the last fix of each landmark sighting against the
    camera's fix noise ``sigma``: per sighting the RMS over runs of the north and east errors
    and their largest ratio to ``sigma``; over all, the share of (run, sighting, axis) inside
    3 sigma, and the RMS horizontal error just before the sightings (the growth between them).
    None without sightings or counted runs."""
    if good is None:
        good = ~np.asarray(h.diverged, bool)
    if not spans or not good.any():
        return None
    last, before_k = _epochs(h.t_s, spans)
    per, inside, before = [], [], []
    for (name, _, _, sigma), k, k0 in zip(spans, last, before_k):
        e = h.pos_err_m[good][:, k, :2]
        ratio = np.abs(e) / max(sigma, 1e-9)
        inside.append(ratio <= 3.0)
        before.append(float(np.sqrt(np.mean(np.sum(h.pos_err_m[good][:, k0, :2] ** 2, -1)))))
        per.append(Sighting(name, float(h.t_s[k]), sigma, np.sqrt(np.mean(e ** 2, axis=0)).tolist(),
                            float(ratio.max()), before[-1]))
    inside = np.concatenate([x.ravel() for x in inside])
    return Landmarks(len(spans), float(inside.mean()), float(max(p.max_ratio for p in per)),
                     float(np.sqrt(np.mean([np.mean(np.square(p.rms_ne_m)) for p in per]))),
                     SpreadStats(float(np.median(before)), float(np.max(before))), per)


def _after(h, spans, good) -> np.ndarray:
    """The north and east errors at each sighting's last fix, ``(B counted, sightings, 2)``."""
    last, _ = _epochs(h.t_s, spans)
    return h.pos_err_m[good][:, last, :2]


def sighting_sums(h, spans, good=None) -> tuple[np.ndarray, np.ndarray]:
    """Each counted run's sum of squared north and east errors after the sightings and their
    count (``rms_after_m`` is the root of their ratio), ``(B,)`` each."""
    good = ~np.asarray(h.diverged, bool) if good is None else good
    e = _after(h, spans, good)
    return np.sum(e ** 2, axis=(1, 2)), np.full(len(e), float(e[0].size if len(e) else 0))


def sighting_intervals(h, spans, good=None) -> dict:
    """The 95 % intervals of :func:`sighting_metrics`' shares and RMS, the runs as the samples:
    ``fraction_within_3sigma`` (Wilson's, with the runs' effective count) and ``rms_after_m``
    (the mean square's studentized bootstrap). Empty below two counted runs."""
    if good is None:
        good = ~np.asarray(h.diverged, bool)
    if not spans or int(np.sum(good)) < MIN_RUNS:
        return {}
    e = _after(h, spans, good)
    sigma = np.maximum([sg for *_, sg in spans], 1e-9)
    inside = np.abs(e) / sigma[None, :, None] <= 3.0
    count = np.full(len(e), float(inside[0].size))
    ms = mean_square_interval(*sighting_sums(h, spans, good))
    return {"fraction_within_3sigma": share_interval(inside.sum(axis=(1, 2)).astype(float), count),
            "rms_after_m": [float(np.sqrt(v)) if np.isfinite(v) else float("nan") for v in ms]}
