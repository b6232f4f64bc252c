"""An INS/GNSS log as navsim reads it, whatever its format: :class:`NavLog`.

A log holds the IMU as increments (:class:`ImuLog`: ``dtheta_b_rad``, ``dv_b_mps`` over
``(t[j-1], t[j]]``, body front-right-down), the GNSS fixes with their 1-sigma
(:class:`GnssLog`), optionally a reference trajectory (:class:`Trajectory`: the truth the
estimators are scored against) and the start the filters are initialised at (:class:`Start`).
Times are seconds from the log's start ``t0_s`` (its own clock, a GNSS second of week for
KF-GINS files). Everything is SI; the units of a file are converted where it is read
(:mod:`navsim.replay.kfgins`, :mod:`navsim.replay.csvlog`).

Every problem with a file raises :class:`~navsim.foundations.errors.LogError` naming the file and
the line (``file:line``), what was expected and a hint: :func:`read_rows` (columns, numbers, NaN),
:func:`check_times` (time not increasing), :func:`check_imu` (rates or degrees where increments in
radians belong), :func:`check_gnss` (latitude, longitude, sigmas out of range; no fix at all).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from navsim.foundations.errors import LogError
from navsim.foundations.transform import euler_from_dcm

#: the largest rotation rate and specific force an IMU log may hold (above: not increments in
#: rad and m/s, or the wrong unit): 2000 deg/s and 50 g
MAX_RATE_RPS = math.radians(2000.0)
MAX_FORCE_MPS2 = 50 * 9.80665
#: the IMU times are uniform when every interval is within this fraction of the median
UNIFORM_TOL = 1e-6


@dataclass
class ImuLog:
    """The IMU as increments on its own times: row ``j`` is the increment over
    ``(t_s[j-1], t_s[j]]``; row 0, at the start, is zero."""

    t_s: np.ndarray               #: (N,)
    dtheta_b_rad: np.ndarray      #: (N, 3) rotation increments, body FRD
    dv_b_mps: np.ndarray          #: (N, 3) velocity increments, body FRD

    @property
    def dt_s(self) -> float:
        """The median interval."""
        return float(np.median(np.diff(self.t_s)))

    @property
    def uniform(self) -> bool:
        d = np.diff(self.t_s)
        return bool(np.all(np.abs(d - self.dt_s) <= UNIFORM_TOL * self.dt_s))


@dataclass
class GnssLog:
    """GNSS fixes: position, its 1-sigma north-east-down, and the velocity when the log has it."""

    t_s: np.ndarray               #: (G,)
    lat_rad: np.ndarray           #: (G,)
    lon_rad: np.ndarray           #: (G,)
    h_m: np.ndarray               #: (G,) ellipsoidal height
    sigma_ned_m: np.ndarray       #: (G, 3)
    vel_n_mps: np.ndarray | None = None       #: (G, 3) NED, or None
    sigma_vel_mps: np.ndarray | None = None   #: (G, 3), or None


@dataclass
class Trajectory:
    """A navigation solution or a reference: position, NED velocity and roll, pitch, yaw."""

    t_s: np.ndarray               #: (R,)
    lat_rad: np.ndarray
    lon_rad: np.ndarray
    h_m: np.ndarray
    vel_n_mps: np.ndarray         #: (R, 3)
    euler_rad: np.ndarray         #: (R, 3) roll, pitch, yaw (true heading)


@dataclass
class Start:
    """The state the filters start from and its 1-sigma (None: the scenario's ``initial_errors``)."""

    lat_rad: float
    lon_rad: float
    h_m: float
    vel_n_mps: np.ndarray         #: (3,)
    euler_rad: np.ndarray         #: (3,)
    sigma_pos_m: np.ndarray | None = None      #: (3,) north, east, down
    sigma_vel_mps: np.ndarray | None = None    #: (3,)
    sigma_att_rad: np.ndarray | None = None    #: (3,) roll, pitch, yaw


@dataclass
class NavLog:
    """An INS/GNSS log, SI, times from ``t0_s``: the IMU, the GNSS, and optionally the reference
    and the start; ``files`` names what was read (role -> path), ``notes`` what the replay works
    around."""

    name: str
    format: str
    t0_s: float
    imu: ImuLog
    gnss: GnssLog
    reference: Trajectory | None = None
    start: Start | None = None
    files: dict = field(default_factory=dict)
    notes: list = field(default_factory=list)

    @property
    def duration_s(self) -> float:
        return float(self.imu.t_s[-1] - self.imu.t_s[0])


@dataclass
class Rows:
    """A numeric table read from a text file: its values and each row's line in the file."""

    path: Path
    values: np.ndarray            #: (R, C)
    lines: np.ndarray             #: (R,) 1-based line numbers

    def where(self, row: int) -> str:
        """``file:line`` of row ``row``."""
        return f"{self.path}:{int(self.lines[row])}"

    def subset(self, keep: np.ndarray) -> "Rows":
        """The rows ``keep`` (a mask or indices)."""
        return Rows(self.path, self.values[keep], self.lines[keep])


def rows_text(a: np.ndarray, sep: str = " ") -> str:
    """Rows of numbers as text lines that read back bit for bit (``repr`` of each float)."""
    return "\n".join(sep.join(repr(float(x)) for x in row) for row in a) + "\n"


def log_name(imu_path) -> str:
    """A log's name: its IMU file's, or its folder's where the file is just ``imu``."""
    path = Path(str(imu_path))
    return path.parent.resolve().name if path.stem.lower() == "imu" else path.stem


def read_rows(path, widths: tuple, what: str, sep: str | None = None, skip: int = 0, hint: str = "") -> Rows:
    """The numbers of a text table, one row a line: blank lines and lines starting with ``#`` or
    ``%`` are skipped, as are the first ``skip`` lines (a header). Every row has one of
    ``widths`` columns (the first row's), every value is a finite number.

    Raises
    ------
    LogError
        ``file:line``: a missing file, a row of another width, a value that is not a number,
        NaN or infinite, or no row at all.
    """
    path = Path(path)
    try:
        text = path.read_text(encoding="utf-8-sig", errors="replace")     # -sig: a spreadsheet's BOM
    except OSError as exc:
        raise LogError(f"cannot be read ({exc.strerror or exc})", file=str(path), hint=hint or None) from None
    numbered = [(i + 1, line) for i, line in enumerate(text.splitlines()) if i >= skip]
    numbered = [(n, line) for n, line in numbered if line.strip() and line.lstrip()[0] not in "#%"]
    if not numbered:
        raise LogError(f"holds no {what} (an empty file)", file=str(path), hint=hint or None)
    tokens = [line.split(sep) if sep else line.split() for _, line in numbered]
    width = len(tokens[0])
    if width not in widths:
        raise LogError(f"has {width} columns, not {' or '.join(map(str, widths))} ({what})",
                       file=f"{path}:{numbered[0][0]}", hint=hint or None)
    for (n, _), row in zip(numbered, tokens):
        if len(row) != width:
            raise LogError(f"has {len(row)} columns where the rows before have {width} ({what})",
                           file=f"{path}:{n}", hint="a row cut short or joined to the next: mend or drop it")
    try:
        values = np.array([float(x) for row in tokens for x in row]).reshape(len(tokens), width)
    except ValueError:
        n, col, x = _not_a_number(numbered, tokens)
        raise LogError(f"column {col}: {x!r} is not a number ({what})", file=f"{path}:{n}", hint=hint or None) from None
    rows = Rows(path, values, np.array([n for n, _ in numbered]))
    bad = ~np.isfinite(values)
    if bad.any():
        r, c = np.argwhere(bad)[0]
        raise LogError(f"column {c + 1} is {values[r, c]} ({what}): every value must be a finite number",
                       file=rows.where(r), hint="drop the rows where the sensor gave nothing")
    return rows


def _not_a_number(numbered, tokens):
    """The first (line, column, text) that is not a number."""
    for (n, _), row in zip(numbered, tokens):
        for c, x in enumerate(row):
            try:
                float(x)
            except ValueError:
                return n, c + 1, x
    raise AssertionError("every value parsed")


def check_times(rows: Rows, t: np.ndarray, what: str) -> None:
    """Refuse times that do not increase, naming the first line where one goes back or repeats."""
    back = np.flatnonzero(np.diff(t) <= 0)
    if back.size:
        r = int(back[0]) + 1
        raise LogError(f"time {t[r]:.6f} s does not follow {t[r - 1]:.6f} s of the line before ({what}): "
                       "times must increase", file=rows.where(r),
                       hint="sort the file by time and drop repeated rows")


def check_imu(rows: Rows, imu: ImuLog) -> None:
    """Refuse increments no IMU gives: a rotation faster than :data:`MAX_RATE_RPS` or a specific
    force above :data:`MAX_FORCE_MPS2` (the file holds rates, or degrees, or another unit).
    ``rows`` are the file's rows of ``imu``'s rows 1, 2, ..."""
    dt = np.diff(imu.t_s)[:, None]
    bad = np.flatnonzero(~np.isfinite(imu.dtheta_b_rad[1:] + imu.dv_b_mps[1:]).all(axis=1))
    if bad.size:
        raise LogError("an increment is not a finite number", file=rows.where(int(bad[0])),
                       hint="drop the rows where the IMU gave nothing")
    rate = np.linalg.norm(imu.dtheta_b_rad[1:], axis=1) / dt[:, 0]
    force = np.linalg.norm(imu.dv_b_mps[1:], axis=1) / dt[:, 0]
    for name, x, limit, unit in (("rotation", rate, MAX_RATE_RPS, "rad"), ("velocity", force, MAX_FORCE_MPS2, "m/s")):
        over = np.flatnonzero(x > limit)
        if over.size:
            r = int(over[0])
            raise LogError(f"the {name} increment is {x[over[0]] * dt[over[0], 0]:.4g} {unit} over "
                           f"{dt[over[0], 0]:.4g} s, more than any IMU measures ({x[over[0]]:.4g} {unit}/s)",
                           file=rows.where(r), hint=f"the IMU columns must be increments in {unit}, not rates "
                           "or degrees: multiply rates by the sample interval, degrees by pi/180")


def start_time(start_s, t: np.ndarray) -> float:
    """The log's start: the last IMU sample at or before ``start_s`` (a configuration's
    ``starttime``; None: not given), so that the first increment replayed is a whole sample
    interval; one interval before the first sample where ``start_s`` is before it or not given."""
    if start_s is not None:
        at = int(np.searchsorted(t, start_s + 1e-9 * max(abs(start_s), 1.0), side="right")) - 1
        if at >= 0:
            return float(t[at])
    return float(t[0] - (t[1] - t[0]))


def imu_from(rows: Rows, t: np.ndarray, dtheta: np.ndarray, dv: np.ndarray, t0: float, end_s=None) -> ImuLog:
    """The IMU after the start ``t0`` (and up to ``end_s``, when given) as increments from
    ``t0``, checked (:func:`check_imu`); a :class:`LogError` when fewer than two samples are left."""
    keep = (t > t0) & ((t <= end_s) if end_s is not None else True)
    if keep.sum() < 2:
        raise LogError(f"holds {int(keep.sum())} IMU sample(s) after the start ({t0:.6f} s)"
                       + (f" and before the end ({end_s} s)" if end_s is not None else ""), file=str(rows.path),
                       hint="the start file's starttime and endtime must leave the IMU samples replayed")
    zero = np.zeros((1, 3))
    imu = ImuLog(np.r_[0.0, t[keep] - t0], np.r_[zero, dtheta[keep]], np.r_[zero, dv[keep]])
    check_imu(rows.subset(keep), imu)
    return imu


def check_gnss(rows: Rows, g: GnssLog) -> None:
    """Refuse a latitude or longitude outside its range and a negative 1-sigma."""
    for name, x, limit in (("latitude", g.lat_rad, math.pi / 2), ("longitude", g.lon_rad, math.pi)):
        bad = np.flatnonzero(np.abs(x) > limit)
        if bad.size:
            raise LogError(f"the {name} {math.degrees(x[bad[0]]):.6g} deg is out of range",
                           file=rows.where(int(bad[0])), hint="latitude and longitude in degrees")
    for name, s in (("position", g.sigma_ned_m), ("velocity", g.sigma_vel_mps)):
        bad = np.flatnonzero(np.any(s < 0, axis=1)) if s is not None else []
        if len(bad):
            raise LogError(f"a {name} 1-sigma is negative", file=rows.where(int(bad[0])),
                           hint="each fix's standard deviations north, east, down, at least 0")


def trim_gnss(g: GnssLog, t_end_s: float, notes: list) -> GnssLog:
    """The fixes inside ``[0, t_end_s]``, a note for those left out; a :class:`LogError` when none
    is left (the caller names the file)."""
    keep = (g.t_s >= 0) & (g.t_s <= t_end_s)
    if not keep.any():
        raise ValueError(f"no GNSS fix falls inside the IMU record (0-{t_end_s:.1f} s from its start; "
                         f"the fixes span {g.t_s[0]:.1f}-{g.t_s[-1]:.1f} s)")
    if not keep.all():
        notes.append(f"{int((~keep).sum())} GNSS fix(es) outside the IMU record left out")
    pick = lambda a: None if a is None else a[keep]
    return GnssLog(g.t_s[keep], g.lat_rad[keep], g.lon_rad[keep], g.h_m[keep], g.sigma_ned_m[keep],
                   pick(g.vel_n_mps), pick(g.sigma_vel_mps))


def start_of(nav0, sigma) -> Start:
    """A :class:`Start` from a one-run :class:`~navsim.navigation.strapdown.NavState` and
    the 1-sigma of an :class:`~navsim.experiment.driver.InitialErrors` (``pos_m``, ``vel_mps``,
    ``att_rad``)."""
    return Start(float(nav0.lat_rad[0]), float(nav0.lon_rad[0]), float(nav0.h_m[0]), np.array(nav0.vel_n_mps[0]),
                 euler_from_dcm(nav0.C_nb[0]), np.array(sigma.pos_m, float), np.array(sigma.vel_mps, float),
                 np.array(sigma.att_rad, float))
