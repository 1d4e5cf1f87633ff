"""Planet models: ellipsoid shape, rotation and normal gravity (Groves 2013, ch. 2).

Earth is WGS84. Mars (IAU 2000 ellipsoid, MGS-derived GM) and the Moon (IAU mean radius,
flattening of the lunar figure, sidereal rotation) use the same formulas; their equatorial and
polar normal gravity come from Clairaut's theorem, which reproduces WGS84's published values to
1e-4 m/s^2 (a test checks that).
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from functools import cached_property

import numpy as np


@dataclass(frozen=True)
class Planet:
    """Reference ellipsoid and gravity of a planet.

    Attributes
    ----------
    name : planet name.
    R0_m : equatorial radius, m.
    flattening : ellipsoid flattening f.
    omega_ie_rps : rotation rate w.r.t. inertial space, rad/s.
    GM_m3ps2 : gravitational constant times mass, m^3/s^2.
    g_equator_mps2, g_pole_mps2 : normal gravity on the ellipsoid at equator / pole, m/s^2.
    """

    name: str
    R0_m: float
    flattening: float
    omega_ie_rps: float
    GM_m3ps2: float
    g_equator_mps2: float
    g_pole_mps2: float

    # Derived constants are computed once per planet (the INS evaluates the formulas below at
    # every IMU sample); cached_property writes the instance dict, which a frozen dataclass
    # allows.
    @cached_property
    def e2(self) -> float:
        """Eccentricity squared."""
        return self.flattening * (2.0 - self.flattening)

    @cached_property
    def RP_m(self) -> float:
        """Polar radius, m."""
        return self.R0_m * (1.0 - self.flattening)

    @cached_property
    def meridian_numerator_m(self) -> float:
        """``R0 (1 - e2)``, the numerator of the meridian radius of curvature, m."""
        return self.R0_m * (1.0 - self.e2)

    @cached_property
    def somigliana_k(self) -> float:
        """``k = R_P g_pole / (R0 g_equator) - 1`` of Somigliana's formula."""
        return self.RP_m * self.g_pole_mps2 / (self.R0_m * self.g_equator_mps2) - 1.0

    @cached_property
    def gravity_height_coefficient(self) -> float:
        """First-order height coefficient of normal gravity (Groves eq. 2.139), 1/m."""
        R0 = self.R0_m
        return (2.0 / R0) * (1.0 + self.flattening + self.omega_ie_rps ** 2 * R0 ** 2
                             * self.RP_m / self.GM_m3ps2)

    @cached_property
    def strapdown_constants(self) -> tuple[float, ...]:
        """``(omega_ie, e2, R0, R0^2, R0 (1 - e2), g_equator, k, height coefficient)``: what
        the strapdown step reads, in one attribute."""
        return (self.omega_ie_rps, self.e2, self.R0_m, self.R0_m * self.R0_m,
                self.meridian_numerator_m, self.g_equator_mps2, self.somigliana_k,
                self.gravity_height_coefficient)


def clairaut_normal_gravity(R0_m: float, flattening: float, omega_ie_rps: float,
                            GM_m3ps2: float) -> tuple[float, float]:
    """Equatorial and polar normal gravity (m/s^2) by Clairaut's theorem (first order in f, m).

    ``g_e = GM/(a b) (1 - 3/2 m)``, ``g_p = g_e (1 + 5/2 m - f)`` with ``m = w^2 a^2 b / GM``.
    """
    b = R0_m * (1.0 - flattening)
    m = omega_ie_rps ** 2 * R0_m ** 2 * b / GM_m3ps2
    g_e = GM_m3ps2 / (R0_m * b) * (1.0 - 1.5 * m)
    return g_e, g_e * (1.0 + 2.5 * m - flattening)


EARTH = Planet('earth', 6378137.0, 1.0 / 298.257223563, 7.292115e-5, 3.986004418e14,
               9.7803253359, 9.8321849378)
MARS = Planet('mars', 3396190.0, 1.0 / 169.8944, 7.088218e-5, 4.282837e13,
              *clairaut_normal_gravity(3396190.0, 1.0 / 169.8944, 7.088218e-5, 4.282837e13))
MOON = Planet('moon', 1737400.0, 0.0012, 2.6616995e-6, 4.9028001e12,
              *clairaut_normal_gravity(1737400.0, 0.0012, 2.6616995e-6, 4.9028001e12))
PLANETS = {p.name: p for p in (EARTH, MARS, MOON)}


def radii_of_curvature(planet: Planet, L_rad: float) -> tuple[float, float]:
    """Meridian and transverse radii of curvature ``(R_N, R_E)``, m (Groves eq. 2.105-2.106)."""
    s2 = math.sin(L_rad) ** 2
    d = 1.0 - planet.e2 * s2
    return planet.meridian_numerator_m / d ** 1.5, planet.R0_m / math.sqrt(d)


def surface_gravity(planet: Planet, L_rad: float) -> float:
    """Somigliana normal gravity on the ellipsoid g0(L), m/s^2 (Groves eq. 2.134)."""
    s2 = math.sin(L_rad) ** 2
    return (planet.g_equator_mps2 * (1.0 + planet.somigliana_k * s2)
            / math.sqrt(1.0 - planet.e2 * s2))


def gravity_down(planet: Planet, L_rad: float, h_m: float) -> float:
    """Down component of gravity (gravitation plus centrifugal) at L, h, m/s^2 (Groves eq.
    2.139); the small north component (< 1e-5 m/s^2 below 1 km) is neglected."""
    R0 = planet.R0_m
    scale = 1.0 - planet.gravity_height_coefficient * h_m + 3.0 * h_m * h_m / (R0 * R0)
    return surface_gravity(planet, L_rad) * scale


def gravity_n(planet: Planet, L_rad: float, h_m: float) -> np.ndarray:
    """Gravity vector in NED at latitude L and height h, m/s^2 (see :func:`gravity_down`)."""
    return np.array([0.0, 0.0, gravity_down(planet, L_rad, h_m)])


def earth_rate_n(planet: Planet, L_rad: float) -> np.ndarray:
    """``omega_ie_n``: planet rotation resolved in NED, rad/s (Groves eq. 5.41)."""
    w = planet.omega_ie_rps
    return np.array([w * math.cos(L_rad), 0.0, -w * math.sin(L_rad)])


def _llh_to_ecef_xyz(planet: Planet, L_rad: float, lambda_rad: float,
                     h_m: float) -> tuple[float, float, float]:
    _, R_E = radii_of_curvature(planet, L_rad)
    cL, sL = math.cos(L_rad), math.sin(L_rad)
    return ((R_E + h_m) * cL * math.cos(lambda_rad), (R_E + h_m) * cL * math.sin(lambda_rad),
            ((1.0 - planet.e2) * R_E + h_m) * sL)


def ecef_to_enu_dcm(L_rad: float, lambda_rad: float) -> np.ndarray:
    """``C_e_enu``: takes planet-fixed vectors to the local ENU frame at (L, lambda)."""
    sL, cL = math.sin(L_rad), math.cos(L_rad)
    sl, cl = math.sin(lambda_rad), math.cos(lambda_rad)
    return np.array([[-sl, cl, 0.0], [-sL * cl, -sL * sl, cL], [cL * cl, cL * sl, sL]])


class LocalEnu:
    """Positions in the ENU frame at a fixed origin ``llh0`` (rad, rad, m): the origin's
    planet-fixed position and rotation are computed once, not per position."""

    def __init__(self, planet: Planet, llh0: np.ndarray) -> None:
        self.planet = planet
        self.llh0 = np.array(llh0, dtype=float)
        L0, lambda0, h0 = self.llh0.tolist()
        self._r0_e = _llh_to_ecef_xyz(planet, L0, lambda0, h0)
        self._C_e_enu = ecef_to_enu_dcm(L0, lambda0).tolist()

    def __call__(self, llh: np.ndarray) -> np.ndarray:
        """Position (m, ENU axes at the origin) of ``llh`` relative to the origin."""
        return np.array(self.enu(*np.asarray(llh, dtype=float).tolist()))

    def enu(self, L_rad: float, lambda_rad: float, h_m: float) -> tuple[float, float, float]:
        """:meth:`__call__` on floats."""
        x, y, z = _llh_to_ecef_xyz(self.planet, L_rad, lambda_rad, h_m)
        x0, y0, z0 = self._r0_e
        dx, dy, dz = x - x0, y - y0, z - z0
        (a, b, c), (d, e, f), (g, h, i) = self._C_e_enu
        return a * dx + b * dy + c * dz, d * dx + e * dy + f * dz, g * dx + h * dy + i * dz


def llh_to_local_enu(planet: Planet, llh: np.ndarray, llh0: np.ndarray) -> np.ndarray:
    """Position (m, ENU axes at ``llh0``) of ``llh`` relative to ``llh0`` (both rad, rad, m)."""
    return LocalEnu(planet, llh0)(llh)
