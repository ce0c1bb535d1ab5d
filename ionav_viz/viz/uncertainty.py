"""How sure each estimator is, in the recording: its 95 % position ellipse at the end of every
second of an outage, drawn around its current position in the map view, the local view and the
outage inspector, and a "sigma vs error" plot (the ellipse's largest radius beside the position
error, per second into each outage). For estimators that give a covariance
(:attr:`ionav_viz.nav.protocol.Estimate.pos_cov_m2`); consumes only results."""

from __future__ import annotations

import numpy as np

from ..analysis.consistency import boundary_errors_m
from ..core.geo import radii_of_curvature_m
from ..nav.kalman import CHI2_2_95
from . import columns
from . import entities as ent
from .columns import with_breaks
from .geometry import screen_xy
from .style import faded

#: Points on each ellipse's outline.
ELLIPSE_POINTS = 32


def ellipses_en_m(cov_m2: np.ndarray, scale: float = CHI2_2_95) -> np.ndarray:
    """The outlines ``(..., ELLIPSE_POINTS + 1, 2)`` (east, north m, closed) of the ellipses
    ``x^T P^-1 x = scale`` of covariances ``(..., 2, 2)``, around the origin."""
    values, vectors = np.linalg.eigh(cov_m2)
    radii = np.sqrt(np.maximum(values, 0.0) * scale)  # (..., 2)
    angle = np.linspace(0.0, 2.0 * np.pi, ELLIPSE_POINTS + 1)
    unit = np.stack([np.cos(angle), np.sin(angle)], axis=-1)  # (P, 2)
    return np.einsum("...ij,pj->...pi", vectors * radii[..., None, :], unit)


def log_uncertainty(layers, result, name: str, est, color, xy: np.ndarray, t_rows: np.ndarray,
                    t_windows: np.ndarray) -> None:
    """One estimator's ellipses (rows as its growing tracks: each outage's start, then every
    window's end) and its sigma-vs-error series (``t_windows``: each outage window's end time)."""
    import rerun as rr

    cov = est.pos_cov_m2
    if cov is None or not len(result.starts):
        return
    send = layers.send
    outline = ellipses_en_m(cov)  # (o, n+1, P+1, 2), east/north m around each boundary's estimate
    n_rows = len(t_rows)
    width = rr.Radius.ui_points(1.2)
    colors = np.tile(faded(color, 0.8), (n_rows, 1))
    local = xy[:, :, None, :] + screen_xy(outline[..., 0], outline[..., 1])
    rel = local - xy[:, :1, None, :]
    for view, pts in ((ent.LOCAL, local), (ent.INSPECT, rel)):
        flat = pts.reshape(-1, ELLIPSE_POINTS + 1, 2)
        send(ent.ellipse(view, name), t_rows, rr.LineStrips2D.columns(
            strips=columns.line_strips_2d(*columns.stacked(flat)), colors=colors, radii=np.full(n_rows, width),
            draw_order=np.full(n_rows, 25.0)))
    lat, lon = est.track.lat_deg, est.track.lon_deg
    meridian, prime = radii_of_curvature_m(lat)
    d_lat = np.degrees(outline[..., 1] / meridian[..., None])
    d_lon = np.degrees(outline[..., 0] / (prime * np.cos(np.radians(lat)))[..., None])
    ll = np.stack([lat[..., None] + d_lat, lon[..., None] + d_lon], axis=-1).reshape(-1, ELLIPSE_POINTS + 1, 2)
    send(ent.ellipse(ent.MAP, name), t_rows, rr.GeoLineStrings.columns(
        line_strings=columns.geo_line_strings(*columns.stacked(ll)), colors=colors, radii=np.full(n_rows, width)))
    # sigma vs error, per window end (as the error series): the ellipse's largest radius, and the error
    radius = np.sqrt(CHI2_2_95 * np.linalg.eigvalsh(cov[:, 1:])[..., -1])
    error = np.hypot(*np.moveaxis(boundary_errors_m(result, name)[:, 1:], -1, 0))
    for entity, values in ((ent.uncertainty_radius(name), radius), (ent.uncertainty_error(name), error)):
        t_plot, v_plot = with_breaks(t_windows, values)
        send(entity, t_plot, rr.Scalars.columns(scalars=v_plot))


def log_uncertainty_styles(rec, result, colors: dict, labels: dict[str, str]) -> None:
    """The sigma-vs-error series' names and colours (static)."""
    import rerun as rr

    for name, sol in result.estimates.items():
        if sol.pos_cov_m2 is None:
            continue
        rec.log(ent.uncertainty_error(name),
                rr.SeriesLines(colors=[colors[name]], names=[f"{labels[name]}: error"], widths=[2.0]), static=True)
        rec.log(ent.uncertainty_radius(name),
                rr.SeriesLines(colors=[faded(colors[name], 0.6)], names=[f"{labels[name]}: 95 % radius"], widths=[1.0]),
                static=True)
