"""WGS-84 geodesy: the hoisted constants and the one-pass surface iteration give the written-out formulas'
results bit for bit (a GNSS fix runs them four times, so they were restructured for speed)."""

from __future__ import annotations

import math

from hypothesis import given, settings
from hypothesis import strategies as st

from dpbase.geodesy import WGS84_A_M, WGS84_B_M, WGS84_E2, WGS84_EP2, LocalFrame, ecef_to_geodetic, geodetic_to_ecef


def heikkinen(x_m: float, y_m: float, z_m: float) -> tuple[float, float, float]:
    """ECEF → geodetic as the formula is written (Heikkinen / Zhu), every product of constants evaluated in place."""
    a, b, e2, ep2 = WGS84_A_M, WGS84_B_M, WGS84_E2, WGS84_EP2
    p = math.hypot(x_m, y_m)
    lon = math.atan2(y_m, x_m)
    if p < 1e-9:
        return math.degrees(math.copysign(math.pi / 2.0, z_m)), math.degrees(lon), abs(z_m) - b
    f_ = 54.0 * b * b * z_m * z_m
    g = p * p + (1.0 - e2) * z_m * z_m - e2 * (a * a - b * b)
    c = e2 * e2 * f_ * p * p / (g * g * g)
    s = (1.0 + c + math.sqrt(c * c + 2.0 * c)) ** (1.0 / 3.0)
    k = s + 1.0 + 1.0 / s
    pp = f_ / (3.0 * k * k * g * g)
    q = math.sqrt(1.0 + 2.0 * e2 * e2 * pp)
    r0 = -(pp * e2 * p) / (1.0 + q) + math.sqrt(
        max(0.5 * a * a * (1.0 + 1.0 / q) - pp * (1.0 - e2) * z_m * z_m / (q * (1.0 + q)) - 0.5 * pp * p * p, 0.0))
    u = math.hypot(p - e2 * r0, z_m)
    v = math.sqrt((p - e2 * r0) ** 2 + (1.0 - e2) * z_m * z_m)
    z0 = b * b * z_m / (a * v)
    alt = u * (1.0 - b * b / (a * v))
    return math.degrees(math.atan((z_m + ep2 * z0) / p)), math.degrees(lon), alt


def surface_by_iteration(frame: LocalFrame, north_m: float, east_m: float, alt_m: float) -> tuple[float, float]:
    """The surface point found with :meth:`LocalFrame.to_geodetic` at each step (three corrections of down)."""
    down = 0.0
    for _ in range(3):
        _, _, alt = frame.to_geodetic(north_m, east_m, down)
        down += alt - alt_m
    lat, lon, _ = frame.to_geodetic(north_m, east_m, down)
    return lat, lon


ecef = st.floats(-7.0e6, 7.0e6, allow_nan=False)


@settings(max_examples=1000, deadline=None)
@given(lat=st.floats(-90.0, 90.0), lon=st.floats(-180.0, 180.0), alt=st.floats(-1e4, 1e5))
def test_ecef_to_geodetic_is_the_written_out_formula(lat: float, lon: float, alt: float) -> None:
    point = geodetic_to_ecef(lat, lon, alt)
    assert ecef_to_geodetic(*point) == heikkinen(*point)


@settings(max_examples=1000, deadline=None)
@given(x=ecef, y=ecef, z=ecef)
def test_ecef_to_geodetic_anywhere_is_the_written_out_formula(x: float, y: float, z: float) -> None:
    try:
        expected: object = heikkinen(x, y, z)
    except (ValueError, TypeError) as exc:  # deep inside the Earth the closed form leaves its domain (a negative
        expected = type(exc)  # sqrt, a complex cube root): so must the fast one, the same way
    try:
        got: object = ecef_to_geodetic(x, y, z)
    except (ValueError, TypeError) as exc:
        got = type(exc)
    assert got == expected


def test_ecef_to_geodetic_on_the_axis_is_the_written_out_formula() -> None:
    for point in ((0.0, 0.0, 6.35e6), (0.0, 0.0, -6.35e6), (1e-10, -1e-10, 1.0), (0.0, 0.0, 0.0)):
        assert ecef_to_geodetic(*point) == heikkinen(*point)


@settings(max_examples=1000, deadline=None)
@given(lat0=st.floats(-90.0, 90.0), lon0=st.floats(-180.0, 360.0), alt0=st.floats(-100.0, 100.0),
       north=st.floats(-5e4, 5e4), east=st.floats(-5e4, 5e4), alt=st.floats(-50.0, 500.0))
def test_surface_to_geodetic_is_the_plain_iteration(lat0: float, lon0: float, alt0: float, north: float, east: float,
                                                    alt: float) -> None:
    frame = LocalFrame(lat0, lon0, alt0)
    assert frame.surface_to_geodetic(north, east, alt) == surface_by_iteration(frame, north, east, alt)
