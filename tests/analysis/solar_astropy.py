#!/usr/bin/env python3
"""Oracle for tests/analysis/test_solar_position.cpp: the Sun by astropy (ERFA, IAU 2006/2000A).

Reads requests from stdin, one a line, and writes one answer a line in the same order:

  pos <id> <unix_seconds> <fraction> <lat_deg> <lon_deg> <elevation_m>
    -> pos <id> <zenith_deg> <azimuth_deg> <ra_deg> <dec_deg> <eot_min> <delta_t_s> <delta_ut1_s>
       Topocentric AltAz without refraction (pressure 0), azimuth clockwise from north; the
       geocentric apparent right ascension and declination (true equator and equinox of date, TETE);
       the equation of time (apparent minus mean solar time); and the ΔT = TT - UT1 and
       ΔUT1 = UT1 - UTC astropy used, for the caller to give SPA the same time scales.

  rts <id> <day_start_unix> <lat_deg> <lon_deg> <h0_deg>
    -> rts <id> <transit_unix> <rise_unix> <set_unix> <delta_t_s> <delta_ut1_s>
       Within [day_start, day_start + 86400) UTC: the first time the local hour angle of the
       geocentric apparent Sun is 0, and the first upward and downward crossings of h0 by its
       geocentric altitude (the definitions of SPA's A.2); "nan" where there is none.

Nothing is downloaded: astropy's bundled IERS-B table gives ΔUT1 and polar motion from 1962 to its
end; outside it astropy carries on with degraded accuracy (the table's nearest values), which the
caller receives in the answer and matches.
"""
import sys
import warnings

import numpy as np

warnings.simplefilter("ignore")

from astropy.utils import iers  # noqa: E402

iers.conf.auto_download = False
iers.conf.auto_max_age = None
iers.conf.iers_degraded_accuracy = "warn"  # warnings are ignored above

import astropy.units as u  # noqa: E402
from astropy.coordinates import AltAz, EarthLocation, TETE, get_sun  # noqa: E402
from astropy.time import Time  # noqa: E402


def time_scales(t):
    """ΔT = TT - UT1 and ΔUT1 = UT1 - UTC in seconds."""
    tt, ut1, utc = t.tt, t.ut1, t.utc
    delta_t = ((tt.jd1 - ut1.jd1) + (tt.jd2 - ut1.jd2)) * 86400.0
    delta_ut1 = ((ut1.jd1 - utc.jd1) + (ut1.jd2 - utc.jd2)) * 86400.0
    return delta_t, delta_ut1


def apparent_geocentric(t):
    """Right ascension, declination of date (TETE), Greenwich apparent sidereal time; degrees."""
    sun = get_sun(t).transform_to(TETE(obstime=t))
    gast = t.sidereal_time("apparent", longitude=0 * u.deg).to_value(u.deg)
    return sun.ra.to_value(u.deg), sun.dec.to_value(u.deg), gast


def positions(req):
    ids = [r[1] for r in req]
    secs = np.array([float(r[2]) for r in req])
    frac = np.array([float(r[3]) for r in req])
    lat = np.array([float(r[4]) for r in req])
    lon = np.array([float(r[5]) for r in req])
    elev = np.array([float(r[6]) for r in req])
    t = Time(secs, frac, format="unix", scale="utc")
    loc = EarthLocation.from_geodetic(lon * u.deg, lat * u.deg, elev * u.m)
    altaz = get_sun(t).transform_to(AltAz(obstime=t, location=loc, pressure=0 * u.hPa))
    ra, dec, gast = apparent_geocentric(t)
    delta_t, delta_ut1 = time_scales(t)
    # Apparent solar time at Greenwich is the Sun's hour angle + 12 h; mean solar time is UT1.
    ut1_hours = (((t.ut1.jd1 - 0.5) % 1.0) + t.ut1.jd2) * 24.0
    eot_hours = ((gast - ra) / 15.0 + 12.0 - ut1_hours + 12.0) % 24.0 - 12.0
    out = []
    for i, ident in enumerate(ids):
        out.append(
            f"pos {ident} {90.0 - altaz.alt.deg[i]:.9f} {altaz.az.deg[i]:.9f} {ra[i]:.9f} "
            f"{dec[i]:.9f} {eot_hours[i] * 60.0:.6f} {delta_t[i]:.6f} {delta_ut1[i]:.6f}"
        )
    return out


def geocentric_state(t, lat, lon):
    """Local hour angle (wrapped to -180..180) and geocentric altitude of the Sun, degrees."""
    ra, dec, gast = apparent_geocentric(t)
    ha = (gast + lon - ra + 180.0) % 360.0 - 180.0
    phi, d, h = np.radians(lat), np.radians(dec), np.radians(ha)
    alt = np.degrees(np.arcsin(np.sin(phi) * np.sin(d) + np.cos(phi) * np.cos(d) * np.cos(h)))
    return ha, alt


def first_crossing(values, rising):
    """Index i of the first sign change of values between samples i and i+1, or None."""
    s = np.sign(values)
    idx = np.nonzero((s[:-1] < 0) & (s[1:] >= 0) if rising else (s[:-1] >= 0) & (s[1:] < 0))[0]
    return int(idx[0]) if len(idx) else None


def event_function(ts, lat, lon, h0, is_transit):
    """Hour angle (transit) or altitude - h0 (rise, set) at unix times ts; all arrays alike."""
    ha, alt = geocentric_state(Time(ts, format="unix", scale="utc"), lat, lon)
    return np.where(is_transit, ha, alt - h0)


def rise_transit_sets(reqs):
    """All rts requests at once: one astropy evaluation per grid or refinement step."""
    start = np.array([float(r[2]) for r in reqs])
    lat = np.array([float(r[3]) for r in reqs])
    lon = np.array([float(r[4]) for r in reqs])
    h0 = np.array([float(r[5]) for r in reqs])
    grid = start[:, None] + 300.0 * np.arange(0, 289)[None, :]
    shape = grid.shape
    ha, alt = geocentric_state(
        Time(grid.ravel(), format="unix", scale="utc"),
        np.broadcast_to(lat[:, None], shape).ravel(),
        np.broadcast_to(lon[:, None], shape).ravel(),
    )
    ha, alt = ha.reshape(shape), alt.reshape(shape)
    # Events (request, column, first grid time): transit where the hour angle passes 0 upwards
    # (its -180/+180 wrap passes downwards), rise and set where the altitude crosses h0.
    events = []
    for k in range(len(reqs)):
        for col, values, rising in ((0, ha[k], True), (1, alt[k] - h0[k], True),
                                    (2, alt[k] - h0[k], False)):
            i = first_crossing(values, rising)
            if i is not None:
                events.append((k, col, grid[k, i]))
    times = np.full((len(reqs), 3), np.nan)
    if events:
        ks = np.array([e[0] for e in events])
        transit = np.array([e[1] == 0 for e in events])
        # Secant steps from the bracketing grid interval, all events together.
        a = np.array([e[2] for e in events])
        b = a + 300.0
        for _ in range(4):
            f = event_function(np.concatenate([a, b]), np.tile(lat[ks], 2), np.tile(lon[ks], 2),
                               np.tile(h0[ks], 2), np.tile(transit, 2))
            fa, fb = f[: len(a)], f[len(a):]
            root = np.where(fb != fa, b - fb * (b - a) / np.where(fb != fa, fb - fa, 1.0), b)
            a, b = root - 0.5, root + 0.5
        for (k, col, _), t in zip(events, (a + b) / 2.0):
            times[k, col] = t if start[k] <= t < start[k] + 86400.0 else np.nan
    delta_t, delta_ut1 = time_scales(Time(start, format="unix", scale="utc"))
    return [
        f"rts {r[1]} {times[k, 0]:.3f} {times[k, 1]:.3f} {times[k, 2]:.3f} "
        f"{delta_t[k]:.6f} {delta_ut1[k]:.6f}"
        for k, r in enumerate(reqs)
    ]


def main():
    lines = [ln.split() for ln in sys.stdin.read().splitlines() if ln.strip()]
    unknown = [ln[0] for ln in lines if ln[0] not in ("pos", "rts")]
    if unknown:
        sys.exit(f"solar_astropy.py: unknown request '{unknown[0]}'")
    answers = {}
    for kind, solve in (("pos", positions), ("rts", rise_transit_sets)):
        reqs = [ln for ln in lines if ln[0] == kind]
        if reqs:
            answers.update(zip((id(ln) for ln in reqs), solve(reqs)))
    for ln in lines:
        print(answers[id(ln)])


if __name__ == "__main__":
    main()
