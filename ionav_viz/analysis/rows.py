"""A drive report's typed rows and values (:class:`~ionav_viz.analysis.report.Report`): what its
tables and the lines under them (:mod:`.tables`, as text and Markdown) and its JSON (``Report.to_dict``,
docs/report-schema.md) are all built from; a fleet's own rows are in :mod:`.fleet`. Every number
carries its unit in its name; times are seconds on the drive's clock.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass, field
from typing import Any, Generic, TypeVar

#: The metrics whose means are compared with the baseline's (:class:`Improvement`), each to its field.
IMPROVEMENT_METRICS = ("crse_m", "yaw_crse_radps", "final_position_error_m")
T = TypeVar("T")


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


class Improvement(dict[str, T], Generic[T]):
    """How much lower one estimator's means are than the INS DR's (%; positive: better): of the
    displacement CRSE, the orientation-rate CRSE and the final position error; as an interval, each
    its 95 % ``[low, high]`` (%). A dict by metric name (:data:`IMPROVEMENT_METRICS`), the JSON's
    ``improvement_pct`` (or ``improvement_ci95_pct``) entry, with its values as attributes too:
    ``improvement["crse_m"]`` is ``improvement.crse_pct``."""

    def __init__(self, crse_pct: T, yaw_crse_pct: T, final_position_error_pct: T) -> None:
        super().__init__(zip(IMPROVEMENT_METRICS, (crse_pct, yaw_crse_pct, final_position_error_pct), strict=True))

    @property
    def crse_pct(self) -> T:
        return self[IMPROVEMENT_METRICS[0]]

    @property
    def yaw_crse_pct(self) -> T:
        return self[IMPROVEMENT_METRICS[1]]

    @property
    def final_position_error_pct(self) -> T:
        return self[IMPROVEMENT_METRICS[2]]

    def to_dict(self) -> dict[str, T]:
        return dict(self)


@dataclass(frozen=True)
class LengthRow:
    """One estimator's error against outage length (``evaluate --outage 10s,30s,60s``; the JSON's
    ``by_length`` entry, :meth:`to_dict`): per length (``outage_s``, increasing) its outages, the mean
    final position error with its share of the distance (%), the mean displacement CRSE and the
    final error's 90th percentile (NaN where a length has no outage)."""

    name: str
    label: str
    outage_s: list[float]
    n_outages: list[int]
    final_position_error_m: list[float]
    final_error_pct: list[float]
    crse_m: list[float]
    final_error_p90_m: list[float]

    def to_dict(self) -> dict[str, list[float]]:
        return {k: v for k, v in asdict(self).items() if k not in ("name", "label")}


@dataclass(frozen=True)
class GnssTruth:
    """What the GNSS quality checks kept out of the scores, on one drive or summed over a report's
    (the JSON's ``gnss_truth``): of ``windows``, the ``excluded_windows`` of bad truth
    (``excluded_by_reason``: windows per fault name), ``receiver_lost_windows`` (beside a reference:
    the estimators' receiver had no fix to trust; no outage starts right after one) and the
    ``excluded_outages`` not placed for either."""

    windows: int
    excluded_windows: int
    excluded_by_reason: dict[str, int]
    receiver_lost_windows: int
    excluded_outages: int


@dataclass(frozen=True)
class DriveEntry:
    """One drive of a report (the JSON's ``drives`` entry): its ``name`` as the report names it, the
    file it was read from, its :class:`GnssTruth`, where its outages went (``placement``; empty when
    unknown), what the reader found of its IMU (``imu``: ``ImuCharacter.to_dict``, and ``imu_text``;
    None and empty for a drive without one) and each filter's health on it, by estimator."""

    name: str
    source: str
    gnss_truth: GnssTruth
    placement: str = ""
    imu: dict[str, Any] | None = None
    imu_text: str = ""
    filter_health: dict[str, dict[str, Any]] = field(default_factory=dict)

    def to_dict(self) -> dict[str, Any]:
        return {"name": self.name, "source": self.source, "gnss_truth": asdict(self.gnss_truth),
                **({"placement": self.placement} if self.placement else {}),
                **({"imu": self.imu, "imu_text": self.imu_text} if self.imu is not None else {}),
                **({"filter_health": self.filter_health} if self.filter_health else {})}


@dataclass(frozen=True)
class DomainNote:
    """Where one drive's inputs lie outside what an estimator's model was trained on, as the
    estimator describes it (its own ``info.domain``, :func:`ionav_viz.learning.domain.outside`): what
    lies ``outside``, and by how much its sigma was widened (median and most)."""

    estimator: str
    drive: str
    outside: list[str]
    sigma_scale_median: float
    sigma_scale_max: float


@dataclass(frozen=True)
class GnssOutages:
    """The log's own GNSS losses in a report (``--on gnss-outage``; the JSON's ``gnss_outages``,
    :func:`~dataclasses.asdict` of it): the ``bridged`` ones, how many were ``not_bridged`` in all and
    by reason, and per estimator the :class:`Spread` of its final position error over the bridged (m)."""

    bridged: list[BridgedRow]
    not_bridged: int
    not_bridged_by_reason: dict[str, int]
    final_error_m: dict[str, Spread]
