"""The flight environment: steady wind, JSBSim turbulence, terrain or sea-surface height."""

from __future__ import annotations

import math
from dataclasses import dataclass

from navsim.foundations.config import MAX_DURATION_S, MAX_WIND_MPS, Node
from navsim.foundations.errors import ScenarioError

#: Beaufort force -> (low, high) mean wind speed, m/s (WMO).
BEAUFORT_MPS = {0: (0.0, 0.2), 1: (0.3, 1.5), 2: (1.6, 3.3), 3: (3.4, 5.4), 4: (5.5, 7.9),
                5: (8.0, 10.7), 6: (10.8, 13.8)}


@dataclass(frozen=True)
class Environment:
    """``wind_n_mps``: air-mass velocity NED (a wind *from* the west blows towards +east).
    ``turbulence``: ``none``, ``milspec`` or ``tustin`` (JSBSim's MIL-F-8785C / MIL-HDBK-1797
    models) with ``turbulence_wind20_mps`` (wind at 20 ft) and ``turbulence_severity`` (0..7);
    ``turbulence_seed`` picks the realisation. ``surface_m``: terrain or sea-surface height above
    the ellipsoid under the whole track. ``wind_changes``: ``(time_s, wind_n_mps)`` points in
    time order the steady wind goes through after the start (:func:`steady_wind_n_mps`)."""

    wind_n_mps: tuple[float, float, float] = (0.0, 0.0, 0.0)
    wind_changes: tuple[tuple[float, tuple[float, float, float]], ...] = ()
    turbulence: str = "none"
    turbulence_wind20_mps: float = 0.0
    turbulence_severity: int = 0
    turbulence_seed: int = 0
    surface_m: float = 0.0


#: the largest turbulence seed (JSBSim's random seed is a 32-bit integer)
MAX_TURBULENCE_SEED = 2**31 - 1


def turbulence_sigma_mps(wind20_mps: float, h_agl_m: float) -> tuple[float, float]:
    """The gusts' std (horizontal, vertical), m/s, of MIL-HDBK-1797's low-altitude model (below
    1000 ft, as JSBSim's ``milspec`` and ``tustin`` use it) for the wind ``wind20_mps`` at 20 ft:
    ``sigma_w = 0.1 W20``, ``sigma_u = sigma_v = sigma_w / (0.177 + 0.000823 h)^0.4`` with ``h``
    in feet (at least 10 ft)."""
    h_ft = max(h_agl_m / 0.3048, 10.0)
    sigma_w = 0.1 * wind20_mps
    return sigma_w / (0.177 + 0.000823 * h_ft) ** 0.4, sigma_w


def turbulence_scale_m(h_agl_m: float) -> tuple[float, float, float]:
    """The gusts' scale lengths (along the wind ``L_u``, across it ``L_v``, vertical ``L_w``), m,
    of MIL-HDBK-1797's low-altitude model, as JSBSim's ``milspec`` uses them: ``L_u = 2 L_v =
    h / (0.177 + 0.000823 h)^1.2``, ``L_w = h / 2``, ``h`` in feet (at least 10 ft). Dryden's
    first-order gust over an airspeed ``V`` has the correlation time ``L / V``."""
    h_ft = max(h_agl_m / 0.3048, 10.0)
    L_u = 0.3048 * h_ft / (0.177 + 0.000823 * h_ft) ** 1.2
    return L_u, L_u / 2.0, 0.3048 * h_ft / 2.0


def steady_wind_n_mps(env: Environment, t_s: float) -> tuple[float, float, float]:
    """The steady wind NED at ``t_s``, m/s: ``wind_n_mps`` at 0 s, then through each point of
    ``wind_changes`` in turn, the last held after it; between two points the speed and the
    direction it blows to are interpolated linearly (the shorter way round: a wind veering from
    270 to 320 deg turns through 295), and the vertical wind too. A wind held and then changed
    is the start wind repeated as a point; a gust front is two points a few seconds apart."""
    points = ((0.0, env.wind_n_mps),) + env.wind_changes
    if t_s <= points[0][0] or len(points) == 1:
        return points[0][1]
    for (t0, w0), (t1, w1) in zip(points, points[1:]):
        if t_s < t1:
            f = (t_s - t0) / (t1 - t0)
            s0, s1 = math.hypot(w0[0], w0[1]), math.hypot(w1[0], w1[1])
            a0 = math.atan2(w0[1], w0[0]) if s0 > 0 else math.atan2(w1[1], w1[0])
            a1 = math.atan2(w1[1], w1[0]) if s1 > 0 else a0
            a = a0 + f * ((a1 - a0 + math.pi) % (2.0 * math.pi) - math.pi)
            speed = s0 + f * (s1 - s0)
            return (speed * math.cos(a), speed * math.sin(a), w0[2] + f * (w1[2] - w0[2]))
    return points[-1][1]


def wind_from(speed_mps: float, from_deg: float) -> tuple[float, float, float]:
    """Air-mass velocity NED of a wind of ``speed_mps`` blowing *from* ``from_deg`` (true)."""
    a = math.radians(from_deg)
    return (-speed_mps * math.cos(a), -speed_mps * math.sin(a), 0.0)


def parse_environment(data, path: str = "environment", file: str | None = None) -> Environment:
    """Read ``environment``::

        wind: {speed_mps: 4.5, from_deg: 270}     # or {north_mps, east_mps[, down_mps]}
                                                  # or {force: 3, from_deg: 270} (Beaufort mid)
        wind_changes:                             # the steady wind later (steady_wind_n_mps)
          - {at_s: 300, force: 5, from_deg: 320}  # each a wind as above, at a time
        turbulence: {type: milspec, wind20_mps: 4, severity: 3, seed: 1}
        surface_m: 0                              # terrain / sea height
    """
    if data is None:
        return Environment()
    node = Node(data, path, file)
    kw: dict = {}
    wind = node.child("wind", None)
    if wind is not None:
        kw["wind_n_mps"] = _wind(wind, file)
    if node.has("wind_changes"):
        kw["wind_changes"] = _wind_changes(node, file)
    turb = node.child("turbulence", None)
    if turb is not None:
        kw["turbulence"] = turb.get("type", str, "milspec", choices=("none", "milspec", "tustin"))
        kw["turbulence_wind20_mps"] = turb.get("wind20_mps", float, 0.0, minimum=0.0, maximum=MAX_WIND_MPS)
        kw["turbulence_severity"] = turb.get("severity", int, 3, minimum=0, maximum=7)
        kw["turbulence_seed"] = turb.get("seed", int, 0, minimum=0, maximum=MAX_TURBULENCE_SEED)
        turb.done()
    kw["surface_m"] = node.get("surface_m", float, 0.0, minimum=-400.0, maximum=8000.0)
    node.done()
    return Environment(**kw)


def _wind(wind: Node, file: str | None) -> tuple[float, float, float]:
    """One wind (``speed_mps + from_deg``, ``force + from_deg`` or ``north_mps + east_mps``),
    NED m/s."""
    if wind.has("north_mps") or wind.has("east_mps"):
        lim = dict(minimum=-MAX_WIND_MPS, maximum=MAX_WIND_MPS)
        out = (wind.get("north_mps", float, 0.0, **lim), wind.get("east_mps", float, 0.0, **lim),
               wind.get("down_mps", float, 0.0, **lim))
    elif wind.has("force"):
        force = wind.get("force", int, choices=tuple(BEAUFORT_MPS))
        lo, hi = BEAUFORT_MPS[force]
        out = wind_from(0.5 * (lo + hi), wind.get("from_deg", float, 0.0))
    elif wind.has("speed_mps"):
        out = wind_from(wind.get("speed_mps", float, minimum=0.0, maximum=MAX_WIND_MPS),
                        wind.get("from_deg", float, 0.0))
    else:
        raise ScenarioError("gives no wind", file=file, key=wind.path,
                            expected="speed_mps + from_deg, force + from_deg, or north_mps + east_mps")
    wind.done()
    return out


def _wind_changes(node: Node, file: str | None) -> tuple:
    """``wind_changes``: a list of winds, each with its time ``at_s`` (after 0, increasing)."""
    raw = node.items("wind_changes", 1, "a list of winds, each with its time: [{at_s: 300, force: 5, from_deg: 320}]")
    out, last = [], 0.0
    for i, data in enumerate(raw):
        item = Node(data, node.key(f"wind_changes[{i}]"), file)
        at = item.get("at_s", float, exclusive_minimum=last, maximum=MAX_DURATION_S)
        out.append((at, _wind(item, file)))
        last = at
    return tuple(out)
