"""A drive report's typed rows (:class:`~ionav_viz.analysis.report.Report`): what its tables
(:mod:`.tables`, as text and Markdown) and its JSON (``Report.to_dict``, docs/report-schema.md) are
both built from. Every number carries its unit in its name; times are seconds on the drive's clock.
"""

from __future__ import annotations

from dataclasses import dataclass


@dataclass(frozen=True)
class Spread:
    """One metric across a report's outages, in the metric's unit: ``max``, ``min``, ``mean`` and
    population ``std`` over the outages where it is defined (all NaN where none is)."""

    max: float
    min: float
    mean: float
    std: float


@dataclass(frozen=True)
class EstimatorRow:
    """One estimator's metrics across a report's outages (:data:`~ionav_viz.analysis.metrics.METRICS`,
    a field each): a column pair of the paper's table and the JSON's ``summary`` entry."""

    name: str
    label: str
    crse_m: Spread
    cae_m: Spread
    aeps_m: Spread
    yaw_crse_radps: Spread
    yaw_cae_radps: Spread
    yaw_aeps_radps: Spread
    final_position_error_m: Spread
    final_error_pct: Spread


@dataclass(frozen=True)
class WorstRow:
    """One of the worst outages: its ``drive``, ``number`` (1-based within its drive, as the
    recording's "outage N"), ``start_s`` and ``end_s`` on the drive's time (rounded to the
    millisecond) and each estimator's ``final_error_m``; the JSON's ``worst`` entry."""

    drive: str
    number: int
    start_s: float
    end_s: float
    final_error_m: dict[str, float]


@dataclass(frozen=True)
class DriftRow:
    """How one estimator's position error grows through the outages (:mod:`.drift`): at ``t_s``
    seconds since each outage began the ``mean_m``, ``p10_m`` and ``p90_m`` over the outages; and
    the final position error's percentiles (m). The JSON's ``drift`` and ``final_error_percentiles``."""

    name: str
    label: str
    t_s: list[float]
    mean_m: list[float]
    p10_m: list[float]
    p90_m: list[float]
    final_p50_m: float
    final_p90_m: float
    final_p95_m: float
    final_max_m: float


@dataclass(frozen=True)
class BridgedRow:
    """One of the log's own GNSS losses, bridged (:class:`~ionav_viz.analysis.bridging.BridgedOutage`,
    as its JSON rounds it): the last good fix (``gap_start_s``) and the first after it
    (``gap_end_s``), the outage run from ``outage_start_s`` for ``outage_s`` whole seconds, the
    straight-line ``span_m`` and each estimator's ``final_error_m``; the JSON's ``gnss_outages.bridged`` entry."""

    drive: str
    number: int
    gap_start_s: float
    gap_end_s: float
    gap_s: float
    outage_start_s: float
    outage_s: int
    span_m: float
    final_error_m: dict[str, float]
