"""What a measurement model gives the error-state filter: its batched linearised model of one
sensor sample (:class:`Linearised`, ``z = H dx + v``), its compiled form (:class:`CompiledModel`),
and the models of one epoch stacked (:func:`stack_models`).

A compiled form is a numba kernel of one signature, beside its type's Python ``model`` in the
type's family module::

    kernel(lat, lon, h, vel, C, inp, par, cols, r0, z, H, R, valid)

``lat``, ``lon``, ``h`` ``(B,)``, ``vel`` ``(B, 3)``, ``C`` ``(B, 3, 3)``: the INS state; ``inp``
``(B, k)``: what the model reads of the sample, per run (its Python side gathers it); ``par``
``(p,)`` floats and ``cols`` ``(q,)`` ints: the model's constants and its columns in the error
state (``-1``: no such state); ``r0``: its first row in the stacked ``z`` ``(B, M)``, ``H``
``(B, M, n)`` and ``R`` ``(B, M, M)``, which arrive zeroed: a kernel writes its nonzero entries
only; ``valid`` ``(B,)``: the runs with a sample, which a kernel may narrow. The formulas are
those of the Python models, term for term (the same to rounding: a test holds them to 1e-12),
with numpy's error model: a division by zero gives inf or NaN as in the Python models.
"""

from __future__ import annotations

import warnings
from dataclasses import dataclass

import numpy as np

from navsim.navigation.estimators.error_model import Layout
from navsim.navigation.strapdown import NavState


#: the fields of :class:`Linearised`, in the order of the former ``(z, H, R, valid)`` tuple
LINEARISED_FIELDS = ("z", "H", "R", "valid")


@dataclass(frozen=True, eq=False)
class Linearised:
    """The batched linearised model of one sensor sample, what a measurement model's ``model``
    returns: ``z = H dx + v``, ``dx`` the error state (estimate minus truth), ``v ~ N(0, R)``.

    Attributes
    ----------
    z : ndarray, (B, m)
        The measured error, *INS minus sensor*.
    H : ndarray, (B, m, n)
        Its rows in the error state (``n = layout.n``).
    R : ndarray, (B, m, m)
        The noise covariance the model assumes.
    valid : ndarray of bool, (B,), or None
        The runs that have a usable sample (None: all of them).

    Unpacking it (``z, H, R, valid = m.model(...)``) or indexing it (``[0]`` for ``z``), as
    for the tuple models returned before, still works but is deprecated (a
    ``DeprecationWarning``): read the attributes.
    """

    z: np.ndarray
    H: np.ndarray
    R: np.ndarray
    valid: np.ndarray | None

    def _deprecated(self) -> tuple:
        warnings.warn("a measurement model's result is a Linearised: read .z, .H, .R, .valid "
                      "(unpacking or indexing it as a tuple is deprecated)", DeprecationWarning, stacklevel=3)
        return tuple(getattr(self, f) for f in LINEARISED_FIELDS)

    def __iter__(self):
        return iter(self._deprecated())

    def __getitem__(self, i):
        return self._deprecated()[i]


@dataclass(frozen=True, eq=False)
class CompiledModel:
    """A measurement model's compiled form for one state layout (its ``compiled(layout)``).

    Attributes
    ----------
    kernel : numba function
        ``kernel(lat, lon, h, vel, C, inp, par, cols, r0, z, H, R, valid)``, the signature of
        :mod:`navsim.navigation.estimators.measurements.model`: fills the model's rows of every run.
    rows : int
        Its rows ``m``.
    params : ndarray of float
        Its constants (``par``).
    cols : ndarray of int
        Its columns in the error state (``cols``; -1: no such state).
    inputs : callable
        ``inputs(nav, data, j)`` -> ``(inp (B, k) float array, valid (B,) bool array)``: what the
        kernel reads of sample ``j``, gathered in Python (a fresh ``valid`` the kernel may narrow).
    """

    kernel: object
    rows: int
    params: np.ndarray
    cols: np.ndarray
    inputs: object

    def fill(self, nav: NavState, data, j: int, r0: int, z, H, R) -> np.ndarray:
        """Rows ``r0:r0 + rows`` of the zeroed ``z``, ``H``, ``R``; returns the valid runs."""
        inp, valid = self.inputs(nav, data, j)
        self.kernel(nav.lat_rad, nav.lon_rad, nav.h_m, nav.vel_n_mps, nav.C_nb, np.ascontiguousarray(inp, float),
                    self.params, self.cols, r0, z, H, R, valid)
        return valid


def _compiled(kernel, rows: int, params, cols, inputs) -> CompiledModel:
    return CompiledModel(kernel, rows, np.ascontiguousarray(params, float), np.asarray(cols, np.int64), inputs)


def _own(cls: type, attr: str):
    """``cls``'s ``attr`` where the class that defines its ``model`` defines it too, else None:
    a subclass that changes ``model`` does not inherit its parent's compiled form or reads."""
    home = next((c for c in cls.__mro__ if "model" in c.__dict__), cls)
    return getattr(cls, attr) if attr in home.__dict__ else None


def compiled_form(model, layout: Layout) -> CompiledModel | None:
    """``model``'s compiled form for ``layout``, or None (a type without ``compiled``, or whose
    ``model`` is not the one its ``compiled`` mirrors)."""
    make = _own(type(model), "compiled")
    return make(model, layout) if callable(make) else None


@dataclass(frozen=True, eq=False)
class Stacked:
    """The models of one epoch stacked for :func:`navsim.navigation.estimators.kalman.update_stacked`:
    ``z`` ``(B, M)``, ``H`` ``(B, M, n)``, ``R`` ``(B, M, M)`` (block diagonal), ``valid`` ``(B, G)``
    and ``ends`` ``(G + 1,)``, model ``g`` the rows ``ends[g]:ends[g + 1]``."""

    z: np.ndarray
    H: np.ndarray
    R: np.ndarray
    valid: np.ndarray
    ends: np.ndarray


def stack_models(taken: list, nav: NavState, layout: Layout) -> Stacked:
    """The linearised models of ``taken``, a list of ``(model, compiled, data, j)`` (``compiled``
    the model's :class:`CompiledModel` or None), stacked: a compiled form fills its rows for
    every run in one call, a model without one is evaluated by its ``model``."""
    B, n = nav.lat_rad.shape[0], layout.n
    lins = [None if c is not None else m.model(nav, layout, data, j) for m, c, data, j in taken]
    rows = [c.rows if c is not None else lin.H.shape[-2] for (_, c, _, _), lin in zip(taken, lins)]
    ends = np.cumsum([0] + rows)
    M = int(ends[-1])
    z, H, R = np.zeros((B, M)), np.zeros((B, M, n)), np.zeros((B, M, M))
    valid = np.empty((B, len(taken)), bool)
    for g, ((_, c, data, j), lin) in enumerate(zip(taken, lins)):
        r = slice(ends[g], ends[g + 1])
        if c is not None:
            valid[:, g] = c.fill(nav, data, j, int(ends[g]), z, H, R)
        else:
            z[:, r], H[:, r], R[:, r, r] = lin.z, lin.H, lin.R
            valid[:, g] = True if lin.valid is None else lin.valid
    return Stacked(z, H, R, valid, ends)


def _columns(data, j: int, keys) -> np.ndarray:
    """Sample ``j`` of the values ``keys`` ``(B, len(keys))``."""
    return np.stack([data.values[k][:, j] for k in keys], -1)


def _valid(data, j: int) -> np.ndarray:
    return np.array(data.valid[:, j], bool)


def _diag(sig2: np.ndarray, B: int) -> np.ndarray:
    return np.broadcast_to(np.diag(sig2), (B, sig2.size, sig2.size)).copy()
