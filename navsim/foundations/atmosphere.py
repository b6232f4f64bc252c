"""International Standard Atmosphere (ICAO, 0-20 km) and the air-data relations.

Heights here are geometric (m above the ellipsoid, as JSBSim's); the ISA is defined on
geopotential height, converted with the ISA Earth radius.
"""

from __future__ import annotations

import numpy as np

R_AIR = 287.05287          #: specific gas constant of dry air, J/(kg K)
GAMMA = 1.4
G0 = 9.80665
P0_PA = 101325.0
T0_K = 288.15
RHO0 = 1.225
LAPSE = -0.0065            #: troposphere lapse rate, K/m
H_TROPO = 11000.0          #: geopotential height of the tropopause, m
R_ISA = 6356766.0          #: Earth radius of the geopotential conversion, m
A0 = np.sqrt(GAMMA * R_AIR * T0_K)
T_TROPO = T0_K + LAPSE * H_TROPO
P_TROPO = P0_PA * (T_TROPO / T0_K) ** (-G0 / (LAPSE * R_AIR))


def geopotential(h_m):
    return R_ISA * np.asarray(h_m, float) / (R_ISA + np.asarray(h_m, float))


def geometric(hp_m):
    return R_ISA * np.asarray(hp_m, float) / (R_ISA - np.asarray(hp_m, float))


def pressure(h_m):
    """ISA static pressure (Pa) at geometric height ``h_m``."""
    H = geopotential(h_m)
    tropo = P0_PA * ((T0_K + LAPSE * H) / T0_K) ** (-G0 / (LAPSE * R_AIR))
    strato = P_TROPO * np.exp(-G0 * (H - H_TROPO) / (R_AIR * T_TROPO))
    return np.where(H <= H_TROPO, tropo, strato)


def temperature(h_m):
    H = geopotential(h_m)
    return np.where(H <= H_TROPO, T0_K + LAPSE * H, T_TROPO)


def pressure_altitude(p_pa):
    """Geometric ISA height (m) of static pressure ``p_pa`` (inverse of :func:`pressure`)."""
    p = np.asarray(p_pa, float)
    tropo = T0_K / LAPSE * ((p / P0_PA) ** (-LAPSE * R_AIR / G0) - 1.0)
    strato = H_TROPO - R_AIR * T_TROPO / G0 * np.log(p / P_TROPO)
    return geometric(np.where(p >= P_TROPO, tropo, strato))


def pressure_altitude_p0_ft(p_pa):
    """P0's printed formula: ``H_p = 145442 (1 - (Ps/29.9213)^0.19026)`` ft, Ps in inHg."""
    return 145442.0 * (1.0 - (np.asarray(p_pa, float) / 3386.389 / 29.9213) ** 0.19026)


def mach_from_pressures(p_total_pa, p_static_pa):
    """Subsonic isentropic Mach number from total and static pressure."""
    ratio = np.asarray(p_total_pa, float) / np.asarray(p_static_pa, float)
    return np.sqrt(np.maximum(5.0 * (ratio ** (2.0 / 7.0) - 1.0), 0.0))


def cas_from_qc(qc_pa):
    """Calibrated airspeed (m/s) from impact pressure ``qc = pt - ps``."""
    return A0 * np.sqrt(np.maximum(5.0 * ((np.asarray(qc_pa, float) / P0_PA + 1.0) ** (2.0 / 7.0) - 1.0), 0.0))


def tas_from_air_data(p_total_pa, p_static_pa, temp_k):
    """True airspeed (m/s): Mach from the pressures times the speed of sound at ``temp_k``."""
    return mach_from_pressures(p_total_pa, p_static_pa) * np.sqrt(GAMMA * R_AIR * np.asarray(temp_k, float))


def tas_incompressible(p_total_pa, p_static_pa, temp_k):
    """P0's ``V = sqrt(2 q / rho)`` with ``q = pt - ps``, ``rho = ps / (R T)``."""
    rho = np.asarray(p_static_pa, float) / (R_AIR * np.asarray(temp_k, float))
    return np.sqrt(np.maximum(2.0 * (np.asarray(p_total_pa, float) - p_static_pa), 0.0) / rho)
