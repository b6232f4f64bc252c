"""The flight environment: steady wind, JSBSim turbulence, terrain or sea-surface height."""

from __future__ import annotations

import math
from dataclasses import dataclass

from navsim.foundations.config import Node
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
    the ellipsoid under the whole track."""

    wind_n_mps: tuple[float, float, float] = (0.0, 0.0, 0.0)
    turbulence: str = "none"
    turbulence_wind20_mps: float = 0.0
    turbulence_severity: int = 0
    turbulence_seed: int = 0
    surface_m: float = 0.0


#: the strongest wind a scenario may set, m/s (Beaufort 12, a hurricane, starts at 32.7 m/s)
MAX_WIND_MPS = 40.0
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


def wind_from(speed_mps: float, from_deg: float) -> tuple[float, float, float]:
    """Air-mass velocity NED of a wind of ``speed_mps`` blowing *from* ``from_deg`` (true)."""
    a = math.radians(from_deg)
    return (-speed_mps * math.cos(a), -speed_mps * math.sin(a), 0.0)


def parse_environment(data, path: str = "environment", file: str | None = None) -> Environment:
    """Read ``environment``::

        wind: {speed_mps: 4.5, from_deg: 270}     # or {north_mps, east_mps[, down_mps]}
                                                  # or {force: 3, from_deg: 270} (Beaufort mid)
        turbulence: {type: milspec, wind20_mps: 4, severity: 3, seed: 1}
        surface_m: 0                              # terrain / sea height
    """
    if data is None:
        return Environment()
    node = Node(data, path, file)
    kw: dict = {}
    wind = node.child("wind", None)
    if wind is not None:
        if wind.has("north_mps") or wind.has("east_mps"):
            lim = dict(minimum=-MAX_WIND_MPS, maximum=MAX_WIND_MPS)
            kw["wind_n_mps"] = (wind.get("north_mps", float, 0.0, **lim), wind.get("east_mps", float, 0.0, **lim),
                                wind.get("down_mps", float, 0.0, **lim))
        elif wind.has("force"):
            force = wind.get("force", int, choices=tuple(BEAUFORT_MPS))
            lo, hi = BEAUFORT_MPS[force]
            kw["wind_n_mps"] = wind_from(0.5 * (lo + hi), wind.get("from_deg", float, 0.0))
        elif wind.has("speed_mps"):
            kw["wind_n_mps"] = wind_from(wind.get("speed_mps", float, minimum=0.0, maximum=MAX_WIND_MPS),
                                         wind.get("from_deg", float, 0.0))
        else:
            raise ScenarioError("gives no wind", file=file, key=wind.path,
                                expected="speed_mps + from_deg, force + from_deg, or north_mps + east_mps")
        wind.done()
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
