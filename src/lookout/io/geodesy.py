"""WGS-84 geodetic coordinates and local north-east-down (NED) tangent frames.

A position reference (GNSS, through :mod:`lookout.io.nmea`) reports latitude, longitude
and height on the WGS-84 ellipsoid; the vessel models work in metres in a local
north-east-down frame. :class:`LocalFrame` converts between the two exactly (no flat-
earth approximation): geodetic -> Earth-centred Earth-fixed (ECEF) -> rotation of the
ECEF offset into the tangent frame at the reference point, and back.

Precision: :meth:`LocalFrame.ned` never forms the two ECEF vectors (each ~6.4e6 m, so
each carries a rounding error of ~1e-9 m) and subtracts them; it writes the ECEF
difference with sum-to-product identities, so its rounding error scales with the
offset itself (~1e-12 m for a point 10 km away). :meth:`LocalFrame.geodetic` goes
through ECEF coordinates and is accurate to their rounding (~1e-9 m); its
ECEF -> geodetic step is Bowring's (1976) method iterated to convergence.

Everything is NumPy float64 and broadcasts like a ufunc. All angles are in degrees.

References
----------
National Imagery and Mapping Agency, *Department of Defense World Geodetic System 1984:
its definition and relationships with local geodetic systems*, Technical Report
NIMA TR8350.2, 3rd ed., amendment 1, 2000 (defining parameters, Table 3.1; geodetic
to ECEF, eq. 4-14).

B. R. Bowring, "Transformation from spatial to geographical coordinates", *Survey
Review* 23(181):323-327, 1976.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

__all__ = [
    "WGS84_FLATTENING",
    "WGS84_SEMI_MAJOR_AXIS",
    "LocalFrame",
    "geodetic_to_ecef",
]

#: Semi-major axis (equatorial radius) of the WGS-84 ellipsoid (m), NIMA TR8350.2 Table 3.1.
WGS84_SEMI_MAJOR_AXIS = 6378137.0
#: Flattening of the WGS-84 ellipsoid, NIMA TR8350.2 Table 3.1 (1/f = 298.257223563).
WGS84_FLATTENING = 1.0 / 298.257223563

_A = WGS84_SEMI_MAJOR_AXIS
_F = WGS84_FLATTENING
_E2 = _F * (2.0 - _F)  # first eccentricity squared
_B = _A * (1.0 - _F)  # semi-minor axis
_EP2 = _E2 / (1.0 - _E2)  # second eccentricity squared

# Bowring's iteration stops when no latitude moves by more than this (rad; ~6e-9 m on
# the ground). Its convergence is superlinear, so the last step's change bounds the error
# from above by a wide margin; it converges in 2 to 3 steps near the Earth's surface.
_BOWRING_TOLERANCE = 1e-15
_BOWRING_MAX_STEPS = 10


def _checked(name: str, value, bounds: tuple[float, float] | None = None, high_open: bool = False, unit: str = "") -> np.ndarray:
    """``value`` as a float64 array, or a one-line ValueError naming ``name``.

    Without ``bounds`` the entries must be finite; with ``bounds = (low, high)`` they
    must also lie in ``[low, high]`` (``[low, high)`` with ``high_open``).
    """
    if bounds is None:
        condition = "finite"
    else:
        low, high = bounds
        closing = ")" if high_open else "]"
        condition = f"finite and within [{low:g}, {high:g}{closing}{' ' + unit if unit else ''}"
    try:
        raw = np.asarray(value)
        if raw.dtype.kind not in "iufO":  # not bool, complex, str, bytes, datetime
            raise TypeError
        array = raw.astype(np.float64)
    except (TypeError, ValueError):
        raise ValueError(f"{name} must be a real number or array of them, {condition}; got {value!r}") from None
    bad = ~np.isfinite(array)
    if bounds is not None:
        low, high = bounds
        with np.errstate(invalid="ignore"):
            bad |= (array < low) | ((array >= high) if high_open else (array > high))
    if np.any(bad):
        if array.ndim == 0:
            got = f"{float(array)!r}"
        else:
            index = tuple(int(i) for i in np.argwhere(bad)[0])
            got = f"{float(array[index])!r} at index {index[0] if len(index) == 1 else index}"
            got += f" ({int(np.count_nonzero(bad))} of {array.size} entries bad)"
        raise ValueError(f"{name} must be {condition}; got {got}")
    return array


def _latitude(name: str, value) -> np.ndarray:
    return _checked(name, value, (-90.0, 90.0), unit="degrees")


def _longitude(name: str, value) -> np.ndarray:
    return _checked(name, value, (-180.0, 360.0), high_open=True, unit="degrees")


def _wrap_degrees(angle):
    """``angle`` (degrees) wrapped into [-180, 180); angles already there are unchanged.

    Leaving them unchanged matters: ``(angle + 180) % 360 - 180`` rounds a small
    longitude difference to the ulp of 180° (~3e-9 m on the ground).
    """
    angle = np.asarray(angle, dtype=np.float64)
    inside = (angle >= -180.0) & (angle < 180.0)
    return np.where(inside, angle, (angle + 180.0) % 360.0 - 180.0)


def _longitude_difference(lon, lon0):
    """``lon - lon0`` (degrees) wrapped into [-180, 180), rounded once.

    The difference is split into its rounded value and the rounding error (Knuth's
    TwoSum); adding or subtracting 360 to the rounded value is then exact (Sterbenz),
    so a point just across the antimeridian keeps the precision of one just this side
    of it, instead of the ulp of 360° (~6e-9 m).
    """
    lon = np.asarray(lon, dtype=np.float64)
    rounded = lon - lon0
    lon_part = rounded + lon0
    error = (lon - lon_part) + (-lon0 - (rounded - lon_part))
    rounded = np.where(rounded >= 180.0, rounded - 360.0, np.where(rounded < -180.0, rounded + 360.0, rounded))
    return rounded + error


def _sin_cos_degrees(lat):
    """Sine and cosine of a latitude ``lat`` in degrees, each to a few ulps.

    The cosine is taken as the sine of the colatitude, ``90 - |lat|`` being exact for
    ``|lat| >= 45``: ``cos(radians(lat))`` would carry the rounding of ``radians(lat)``
    (~2e-16 rad) as a relative error of ~2e-16 / cos(lat) near the poles.
    """
    lat = np.asarray(lat, dtype=np.float64)
    return np.sin(np.radians(lat)), np.sin(np.radians(90.0 - np.abs(lat)))


def _prime_vertical_terms(sin_lat):
    """``w = sqrt(1 - e² sin²φ)`` and the prime-vertical radius of curvature ``N = a / w``."""
    w = np.sqrt(1.0 - _E2 * sin_lat * sin_lat)
    return w, _A / w


def geodetic_to_ecef(lat_deg: npt.ArrayLike, lon_deg: npt.ArrayLike, height_m: npt.ArrayLike = 0.0) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Earth-centred Earth-fixed coordinates of WGS-84 geodetic positions.

    Parameters
    ----------
    lat_deg : array_like
        Geodetic latitude (degrees), finite, in [-90, 90].
    lon_deg : array_like
        Longitude (degrees, east positive), finite, in [-180, 360).
    height_m : array_like, optional
        Height above the ellipsoid (m), finite. Default 0.

    Returns
    -------
    x, y, z : numpy.ndarray
        ECEF coordinates (m), float64, of the inputs' broadcast shape (0-d for scalars):
        ``x`` towards (0°, 0°), ``y`` towards (0°, 90° E), ``z`` towards the north pole.

    Raises
    ------
    ValueError
        If an input is not finite or out of its range; the message names the argument.

    Notes
    -----
    NIMA TR8350.2 eq. (4-14): with ``N = a / sqrt(1 - e² sin²φ)``,
    ``x = (N + h) cos φ cos λ``, ``y = (N + h) cos φ sin λ``,
    ``z = (N (1 - e²) + h) sin φ``.

    Examples
    --------
    >>> [float(c) for c in geodetic_to_ecef(0.0, 0.0)]
    [6378137.0, 0.0, 0.0]
    """
    lat, lon, h = np.broadcast_arrays(_latitude("lat_deg", lat_deg), _longitude("lon_deg", lon_deg), _checked("height_m", height_m))
    lam = np.radians(lon)
    sin_phi, cos_phi = _sin_cos_degrees(lat)
    _, n = _prime_vertical_terms(sin_phi)
    p = (n + h) * cos_phi
    return (np.asarray(p * np.cos(lam)), np.asarray(p * np.sin(lam)), np.asarray((n * (1.0 - _E2) + h) * sin_phi))


def _ecef_to_latitude_height(p, z):
    """Geodetic latitude (rad) and height (m) from the distance to the axis ``p`` and ``z``.

    Bowring's (1976) formula, iterated to convergence: from a parametric latitude ``β``,
    ``tan φ = (z + e'² b sin³β) / (p - e² a cos³β)``, then ``tan β = (1 - f) tan φ``.
    The height ``h = p cos φ + z sin φ - a sqrt(1 - e² sin²φ)`` is well conditioned at
    every latitude (no division by ``cos φ``).
    """
    beta = np.arctan2(z, (1.0 - _F) * p)
    phi = np.arctan2(z + _EP2 * _B * np.sin(beta) ** 3, p - _E2 * _A * np.cos(beta) ** 3)
    for _ in range(_BOWRING_MAX_STEPS):
        beta = np.arctan2((1.0 - _F) * np.sin(phi), np.cos(phi))
        updated = np.arctan2(z + _EP2 * _B * np.sin(beta) ** 3, p - _E2 * _A * np.cos(beta) ** 3)
        change = np.max(np.abs(updated - phi), initial=0.0)
        phi = updated
        if change <= _BOWRING_TOLERANCE:
            break
    sin_phi = np.sin(phi)
    w, _ = _prime_vertical_terms(sin_phi)
    height = p * np.cos(phi) + z * sin_phi - _A * w
    return phi, height


@dataclass(frozen=True)
class LocalFrame:
    """A local north-east-down tangent frame on the WGS-84 ellipsoid.

    The origin is the reference point; north and east span the plane tangent to the
    ellipsoid there, down is along the inward ellipsoid normal. The conversions are exact
    (no flat-earth approximation) for points at any distance.

    Parameters
    ----------
    latitude : float
        Geodetic latitude of the reference point (degrees), finite, in [-90, 90].
    longitude : float
        Longitude of the reference point (degrees, east positive), finite, in
        [-180, 360).
    height : float, optional
        Height of the reference point above the ellipsoid (m), finite. Default 0.

    Raises
    ------
    ValueError
        If a field is not a finite real number in its range; the one-line message names
        the field and the condition, e.g. ``latitude must be finite and within [-90, 90]
        degrees; got 95.0``.

    Examples
    --------
    >>> frame = LocalFrame(63.43, 10.39)
    >>> n, e, d = frame.ned(63.44, 10.39)
    >>> round(float(n), 1), round(float(e), 6)
    (1114.7, 0.0)
    >>> [round(float(v), 9) for v in frame.geodetic(n, e, d)]
    [63.44, 10.39, 0.0]
    """

    latitude: float
    longitude: float
    height: float = 0.0

    def __post_init__(self):
        for name, value, check in (
            ("latitude", self.latitude, _latitude),
            ("longitude", self.longitude, _longitude),
            ("height", self.height, _checked),
        ):
            array = check(name, value)
            if array.ndim != 0:
                raise ValueError(f"{name} must be a scalar; got shape {array.shape}")
            object.__setattr__(self, name, float(array))

    def _reference(self):
        """Sine and cosine of the reference latitude, its ``w`` and ``N``, its ``P``
        (distance to the polar axis) and ``Z`` (ECEF z)."""
        sin0, cos0 = (float(v) for v in _sin_cos_degrees(self.latitude))
        w0, n0 = (float(v) for v in _prime_vertical_terms(sin0))
        return sin0, cos0, w0, n0, (n0 + self.height) * cos0, (n0 * (1.0 - _E2) + self.height) * sin0

    def ned(self, lat_deg: npt.ArrayLike, lon_deg: npt.ArrayLike, height_m: npt.ArrayLike = 0.0) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """North, east and down coordinates of geodetic positions in this frame.

        Parameters
        ----------
        lat_deg : array_like
            Geodetic latitude (degrees), finite, in [-90, 90].
        lon_deg : array_like
            Longitude (degrees, east positive), finite, in [-180, 360). A point across
            the antimeridian from the reference is handled (longitudes are compared
            modulo 360).
        height_m : array_like, optional
            Height above the ellipsoid (m), finite. Default 0.

        Returns
        -------
        north, east, down : numpy.ndarray
            Coordinates (m), float64, of the inputs' broadcast shape (0-d for scalars).

        Raises
        ------
        ValueError
            If an input is not finite (NaN included) or out of its range; the message
            names ``lat_deg``, ``lon_deg`` or ``height_m``.

        Notes
        -----
        The ECEF offset from the reference is rotated about the polar axis by the
        reference longitude, then into north-east-down by the reference latitude. The
        offset is written term by term, each a product of small differences
        (``cos φ - cos φ₀ = -2 sin((φ+φ₀)/2) sin((φ-φ₀)/2)``,
        ``N - N₀ = a e² (sin²φ - sin²φ₀) / (w w₀ (w + w₀))``, ...), so no two ~6.4e6 m
        numbers are subtracted and the rounding error is relative to the offset.
        """
        lat, lon, h = np.broadcast_arrays(_latitude("lat_deg", lat_deg), _longitude("lon_deg", lon_deg), _checked("height_m", height_m))
        north, east, down = self._ned(lat, lon, h)
        return np.asarray(north), np.asarray(east), np.asarray(down)

    def _ned(self, lat, lon, h):
        """:meth:`ned` without the checks, on float64 arrays of one shape."""
        sin0, cos0, w0, n0, _, _ = self._reference()
        sin_half = np.sin(np.radians(lat - self.latitude) / 2.0)  # sin((φ - φ₀) / 2)
        sin_mid, cos_mid = _sin_cos_degrees((lat + self.latitude) / 2.0)  # of (φ + φ₀) / 2
        d_sin = 2.0 * cos_mid * sin_half  # sin φ - sin φ₀
        d_cos = -2.0 * sin_mid * sin_half  # cos φ - cos φ₀
        sin_phi, cos_phi = _sin_cos_degrees(lat)
        w, n = _prime_vertical_terms(sin_phi)
        d_n = _A * _E2 * d_sin * (sin_phi + sin0) / (w * w0 * (w + w0))  # N - N₀
        d_h = h - self.height
        # ECEF offset in axes turned by the reference longitude: x' to the reference
        # meridian's equator crossing, y' 90° east of it, z to the north pole.
        d_p = (d_n + d_h) * cos_phi + (n0 + self.height) * d_cos  # P - P₀
        d_z = (d_n * (1.0 - _E2) + d_h) * sin_phi + (n0 * (1.0 - _E2) + self.height) * d_sin
        d_lam = np.radians(_longitude_difference(lon, self.longitude))
        p = (n + h) * cos_phi
        d_x = d_p - 2.0 * p * np.sin(d_lam / 2.0) ** 2  # P cos Δλ - P₀
        d_y = p * np.sin(d_lam)
        return -sin0 * d_x + cos0 * d_z, d_y, -cos0 * d_x - sin0 * d_z

    def geodetic(self, north: npt.ArrayLike, east: npt.ArrayLike, down: npt.ArrayLike = 0.0) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Geodetic positions of north-east-down coordinates in this frame.

        The exact inverse of :meth:`ned`.

        Parameters
        ----------
        north, east : array_like
            Coordinates (m), finite.
        down : array_like, optional
            Coordinate (m), finite, positive below the reference's tangent plane.
            Default 0.

        Returns
        -------
        lat_deg, lon_deg, height_m : numpy.ndarray
            Geodetic latitude (degrees), longitude (degrees, in [-180, 180)) and height
            above the ellipsoid (m), float64, of the inputs' broadcast shape.

        Raises
        ------
        ValueError
            If an input is not finite; the message names ``north``, ``east`` or
            ``down``.

        Notes
        -----
        The offset is rotated back into ECEF axes turned by the reference longitude and
        added to the reference's ECEF position; longitude follows from ``atan2``,
        latitude and height from Bowring's method iterated to convergence (its own error
        is ~1e-12 m for points within 100 km of the ellipsoid). That first estimate
        carries the rounding of the ECEF coordinates (~1e-9 m), so one Newton step
        follows: the residual ``(north, east, down) - ned(estimate)``, computed with the
        offset-relative precision of :meth:`ned`, is turned into the estimate's own
        north-east-down axes and divided by the radii of curvature. What remains is the
        rounding of the result in degrees (~1e-9 m in latitude and longitude, ~1e-12 m
        in height).
        """
        n_, e_, d_ = np.broadcast_arrays(_checked("north", north), _checked("east", east), _checked("down", down))
        sin0, cos0, _, _, p0, z0 = self._reference()
        # ECEF in axes turned by the reference longitude (as in :meth:`_ned`).
        x = p0 + (-sin0 * n_ - cos0 * d_)
        y = e_
        z = z0 + (cos0 * n_ - sin0 * d_)
        phi, height = _ecef_to_latitude_height(np.hypot(x, y), z)
        lat = np.clip(np.degrees(phi), -90.0, 90.0)
        lon0 = float(_wrap_degrees(self.longitude))
        d_lam = np.arctan2(y, x)
        lon = _wrap_degrees(lon0 + np.degrees(d_lam))

        # Newton step. Residual in the reference's NED, then in the turned ECEF axes, then
        # in the estimate's NED (turned by its longitude offset and latitude).
        r_n, r_e, r_d = (target - value for target, value in zip((n_, e_, d_), self._ned(lat, lon, height)))
        r_x = -sin0 * r_n - cos0 * r_d
        r_z = cos0 * r_n - sin0 * r_d
        d_lam = np.radians(_longitude_difference(lon, lon0))
        cos_dl, sin_dl = np.cos(d_lam), np.sin(d_lam)
        r_meridian = cos_dl * r_x + sin_dl * r_e  # towards the estimate's axis, outwards
        r_east = -sin_dl * r_x + cos_dl * r_e
        sin_phi, cos_phi = _sin_cos_degrees(lat)
        w, n = _prime_vertical_terms(sin_phi)
        r_north = -sin_phi * r_meridian + cos_phi * r_z
        r_up = cos_phi * r_meridian + sin_phi * r_z
        meridian_radius = n * (1.0 - _E2) / (w * w)  # M = a (1 - e²) / w³
        lat = np.clip(lat + np.degrees(r_north / (meridian_radius + height)), -90.0, 90.0)
        axis_distance = (n + height) * cos_phi
        with np.errstate(divide="ignore", invalid="ignore"):
            d_lon = np.where(axis_distance > 1e-6, np.degrees(r_east / axis_distance), 0.0)
        lon = _wrap_degrees(lon + d_lon)
        height = height + r_up
        return np.asarray(lat), np.asarray(lon), np.asarray(height)
