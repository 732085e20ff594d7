"""WGS-84 geodetic <-> local north-east-down conversions (lookout.io.geodesy)."""

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.integrate import quad

from lookout.io.geodesy import WGS84_FLATTENING, WGS84_SEMI_MAJOR_AXIS, LocalFrame, geodetic_to_ecef

A = WGS84_SEMI_MAJOR_AXIS
E2 = WGS84_FLATTENING * (2.0 - WGS84_FLATTENING)

latitudes = st.floats(-89.9, 89.9)
longitudes = st.floats(-180.0, 180.0, exclude_max=True)
heights = st.floats(-100.0, 3000.0)
bearings = st.floats(0.0, 2.0 * math.pi)
distances = st.floats(0.0, 10_000.0)


def nearby(pymap3d, lat0, lon0, h0, bearing, distance):
    """Latitude and longitude of the point ``distance`` m from the reference along ``bearing``
    in its tangent plane."""
    lat, lon, _ = pymap3d.ned2geodetic(distance * math.cos(bearing), distance * math.sin(bearing), 0.0, lat0, lon0, h0)
    return float(lat), float(lon)


def longitude_gap(a, b):
    """|a - b| in degrees, modulo 360."""
    return abs((float(a) - float(b) + 180.0) % 360.0 - 180.0)


@settings(max_examples=200)
@given(lat0=latitudes, lon0=longitudes, h0=heights, bearing=bearings, distance=distances, h=heights)
def test_ned_agrees_with_pymap3d(lat0, lon0, h0, bearing, distance, h):
    pymap3d = pytest.importorskip("pymap3d")
    lat, lon = nearby(pymap3d, lat0, lon0, h0, bearing, distance)
    ours = np.array(LocalFrame(lat0, lon0, h0).ned(lat, lon, h))
    theirs = np.array(pymap3d.geodetic2ned(lat, lon, h, lat0, lon0, h0), dtype=float)
    # Measured over 3000 random cases of this kind: max |ours - pymap3d| = 3.3e-9 m. That is
    # pymap3d's rounding (it subtracts two ~6.4e6 m ECEF vectors, ~1e-9 m each); ours
    # agrees with an 80-bit long-double evaluation of the same definitions to 5e-12 m.
    assert np.max(np.abs(ours - theirs)) < 1e-3
    assert np.max(np.abs(ours - theirs)) < 1e-7  # 30x the measured disagreement


@settings(max_examples=200)
@given(
    lat0=latitudes,
    lon0=st.floats(-180.0, 360.0, exclude_max=True),
    h0=heights,
    near=st.booleans(),
    bearing=bearings,
    distance=distances,
    far_lat=latitudes,
    far_lon=longitudes,
    h=heights,
)
def test_geodetic_inverts_ned(lat0, lon0, h0, near, bearing, distance, far_lat, far_lon, h):
    frame = LocalFrame(lat0, lon0, h0)
    if near:
        pymap3d = pytest.importorskip("pymap3d")
        lat, lon = nearby(pymap3d, lat0, lon0 if lon0 < 180.0 else lon0 - 360.0, h0, bearing, distance)
    else:  # anywhere on Earth, up to the antipode
        lat, lon = far_lat, far_lon
    back_lat, back_lon, back_h = frame.geodetic(*frame.ned(lat, lon, h))
    assert -180.0 <= back_lon < 180.0
    assert abs(back_lat - lat) < 1e-9
    assert longitude_gap(back_lon, lon) < 1e-9
    assert abs(back_h - h) < 1e-6


@settings(max_examples=200)
@given(
    lat0=latitudes,
    lon0=longitudes,
    h0=heights,
    north=st.floats(-10_000.0, 10_000.0),
    east=st.floats(-10_000.0, 10_000.0),
    down=st.floats(-3000.0, 100.0),
)
def test_ned_inverts_geodetic(lat0, lon0, h0, north, east, down):
    frame = LocalFrame(lat0, lon0, h0)
    again = np.array(frame.ned(*frame.geodetic(north, east, down)))
    assert np.max(np.abs(again - [north, east, down])) < 1e-6


def test_reference_point_is_the_origin():
    frame = LocalFrame(63.4305, 10.3951, 12.5)
    assert [float(v) for v in frame.ned(63.4305, 10.3951, 12.5)] == [0.0, 0.0, 0.0]
    lat, lon, h = frame.geodetic(0.0, 0.0, 0.0)
    assert abs(lat - 63.4305) < 1e-12 and abs(lon - 10.3951) < 1e-12 and abs(h - 12.5) < 1e-9


def test_one_arc_minute_north_on_the_equator_is_the_meridional_arc():
    dphi = math.radians(1.0 / 60.0)
    arc, _ = quad(lambda phi: A * (1.0 - E2) / (1.0 - E2 * math.sin(phi) ** 2) ** 1.5, 0.0, dphi, epsabs=1e-10, epsrel=1e-13)
    assert arc == pytest.approx(1842.9, abs=0.05)
    north, east, down = LocalFrame(0.0, 25.0).ned(1.0 / 60.0, 25.0)
    # The chord's projection on the tangent falls short of the arc by ~arc³ / (6 R²) ~ 3e-5 m.
    assert abs(north - arc) < 1e-3
    assert abs(east) < 1e-12
    # Exactly: at the equator, north is ECEF z and down is a - (distance to the axis).
    w = math.sqrt(1.0 - E2 * math.sin(dphi) ** 2)
    assert north == pytest.approx(A * (1.0 - E2) * math.sin(dphi) / w, abs=1e-9)
    assert down == pytest.approx(A - A * math.cos(dphi) / w, abs=1e-9)


def test_geodetic_to_ecef_axes():
    b = A * (1.0 - WGS84_FLATTENING)
    np.testing.assert_allclose(geodetic_to_ecef(0.0, 0.0), [A, 0.0, 0.0], atol=1e-9)
    np.testing.assert_allclose(geodetic_to_ecef(0.0, 90.0, 100.0), [0.0, A + 100.0, 0.0], atol=1e-9)
    np.testing.assert_allclose(geodetic_to_ecef(90.0, 0.0), [0.0, 0.0, b], atol=1e-9)
    np.testing.assert_allclose(geodetic_to_ecef(-90.0, 0.0, -10.0), [0.0, 0.0, -b + 10.0], atol=1e-9)


def test_antimeridian_and_longitude_conventions():
    # Binary fractions, so that the longitude differences are exactly 0.5 degrees.
    east_across = LocalFrame(0.0, 179.75).ned(0.0, -179.75)[1]
    east_here = LocalFrame(0.0, 0.0).ned(0.0, 0.5)[1]
    assert east_across == pytest.approx(east_here, abs=1e-9) and east_across > 55_000.0
    point = (59.5, -9.7, 40.0)
    np.testing.assert_allclose(LocalFrame(60.0, 350.0).ned(*point), LocalFrame(60.0, -10.0).ned(*point), atol=1e-9)
    np.testing.assert_allclose(LocalFrame(60.0, -10.0).ned(59.5, 350.3, 40.0), LocalFrame(60.0, -10.0).ned(59.5, -9.7, 40.0), atol=1e-9)
    down = LocalFrame(0.0, 0.0).ned(0.0, 0.5)[2]
    lat, lon, _ = LocalFrame(0.0, 179.75).geodetic(0.0, east_across, down)
    assert abs(lat) < 1e-12 and lon == pytest.approx(-179.75, abs=1e-12)


def test_arrays_broadcast():
    frame = LocalFrame(45.0, 5.0)
    lat = np.array([[45.0], [45.01]])
    north, east, down = frame.ned(lat, [5.0, 5.01, 5.02], 10.0)
    assert north.shape == east.shape == down.shape == (2, 3)
    assert north.dtype == np.float64
    for i in range(2):
        for j, lon in enumerate([5.0, 5.01, 5.02]):
            single = frame.ned(float(lat[i, 0]), lon, 10.0)
            assert [north[i, j], east[i, j], down[i, j]] == [float(v) for v in single]
    back = frame.geodetic(north, east, down)
    np.testing.assert_allclose(back[0], np.broadcast_to(lat, (2, 3)), atol=1e-12)
    x, y, z = geodetic_to_ecef([0.0, 10.0], 0.0)
    assert x.shape == y.shape == z.shape == (2,)


@pytest.mark.parametrize(
    ("arguments", "message"),
    [
        ((95.0, 0.0), r"^latitude must be finite and within \[-90, 90\] degrees; got 95\.0$"),
        ((float("nan"), 0.0), r"^latitude must be finite .*; got nan$"),
        ((0.0, 360.0), r"^longitude must be finite and within \[-180, 360\) degrees; got 360\.0$"),
        ((0.0, -180.5), r"^longitude must be finite"),
        ((0.0, float("inf")), r"^longitude must be finite"),
        ((0.0, 0.0, float("nan")), r"^height must be finite; got nan$"),
        (("63", 0.0), r"^latitude must be a real number"),
        (([1.0, 2.0], 0.0), r"^latitude must be a scalar"),
    ],
)
def test_bad_reference_is_refused(arguments, message):
    with pytest.raises(ValueError, match=message):
        LocalFrame(*arguments)


@pytest.mark.parametrize(
    ("arguments", "message"),
    [
        ((float("nan"), 0.0), r"^lat_deg must be finite and within \[-90, 90\] degrees; got nan$"),
        ((-90.5, 0.0), r"^lat_deg must be finite"),
        (([0.0, 91.0], 0.0), r"^lat_deg must be finite .*got 91\.0 at index 1"),
        ((0.0, float("nan")), r"^lon_deg must be finite and within \[-180, 360\) degrees"),
        ((0.0, [1.0, 400.0]), r"^lon_deg must be finite"),
        ((0.0, 0.0, float("inf")), r"^height_m must be finite"),
    ],
)
def test_bad_positions_are_refused(arguments, message):
    frame = LocalFrame(0.0, 0.0)
    with pytest.raises(ValueError, match=message):
        frame.ned(*arguments)
    with pytest.raises(ValueError, match=message):
        geodetic_to_ecef(*arguments)


@pytest.mark.parametrize(
    ("arguments", "name"),
    [((float("nan"), 0.0), "north"), ((0.0, float("inf")), "east"), ((0.0, 0.0, float("nan")), "down")],
)
def test_bad_offsets_are_refused(arguments, name):
    with pytest.raises(ValueError, match=rf"^{name} must be finite; got"):
        LocalFrame(0.0, 0.0).geodetic(*arguments)
