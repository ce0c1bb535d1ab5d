"""The paper's results tables (Tables 8-12 layout) and the lines under them: the parts of a drive
report's document (:meth:`ionav_viz.analysis.report.Report.document`), each from the report's typed
values (:mod:`.rows`), never from its JSON; laid out as text or Markdown by :mod:`.document`'s renderers.

Any number of estimators: the paper's layout puts the candidate estimators first and the INS DR
(the baseline) last; improvements are each candidate's over the INS DR.
"""

from __future__ import annotations

import math
from collections.abc import Mapping

from .document import Document, Heading, Table, to_markdown, to_text
from .rows import (
    BridgedRow,
    DomainNote,
    DriftRow,
    DriveEntry,
    EstimatorRow,
    GnssOutages,
    GnssTruth,
    Improvement,
    LengthRow,
    Spread,
    WorstRow,
)

_STATS = (("max", "max"), ("min", "min"), ("mean", "μ"), ("std", "σ"))
_BLOCKS = (("CRSE", "crse_m", "yaw_crse_radps"), ("CAE", "cae_m", "yaw_cae_radps"),
           ("AEPS (/s)", "aeps_m", "yaw_aeps_radps"))


def _fmt(x: float, decimals: int = 2) -> str:
    """A table cell: ``-`` where the report leaves the value undefined (None, NaN: e.g. the final
    error as a % of under 10 m driven), as the fleet's tables write it, not ``nan``; a value that
    rounds to zero is ``0.000``, not ``-0.000``."""
    # no "-0.000"
    return ("-" if x is None or (isinstance(x, float) and math.isnan(x))
            else f"{round(x, decimals) + 0.0:.{decimals}f}")


def _pct(x: float) -> str:
    # no "-0.0 %"
    return "n/a" if x is None or (isinstance(x, float) and math.isnan(x)) else f"{round(x, 1) + 0.0:.1f} %"


def estimator_table(rows: list[EstimatorRow], distance_m: Spread,
                    n_outages: int) -> tuple[list[str], list[list[str]]]:
    """Header and rows of the paper's table: displacement (m) and orientation rate (rad/s) per
    estimator (candidates first, the INS DR baseline last), the distance driven and the outages."""
    ests = [r for r in rows if r.name != "ins"] + [r for r in rows if r.name == "ins"]
    header = ["Metric", ""] + [f"{e.label} (m)" for e in ests] + [f"{e.label} (rad/s)" for e in ests]
    out = []
    blocks = [*((title, disp, yaw, 2) for title, disp, yaw in _BLOCKS),
              ("Final position error", "final_position_error_m", None, 2),
              ("Final error, % of distance", "final_error_pct", None, 1)]
    for title, disp_key, yaw_key, decimals in blocks:
        for i, (stat, label) in enumerate(_STATS):
            row = [title if i == 0 else "", label]
            row += [_fmt(getattr(getattr(e, disp_key), stat), decimals) for e in ests]
            row += [_fmt(getattr(getattr(e, yaw_key), stat), 3) if yaw_key else "" for e in ests]
            out.append(row)
    for i, (stat, label) in enumerate(_STATS[:3]):
        out.append(["Total distance (m)" if i == 0 else "", label, _fmt(getattr(distance_m, stat))]
                   + [""] * (2 * len(ests) - 1))
    out.append(["Number of sequences", "", str(n_outages)] + [""] * (2 * len(ests) - 1))
    return header, out


def improvement_lines(labels: Mapping[str, str], improvement: Mapping[str, Improvement[float]],
                      ci95: Mapping[str, Improvement[list[float]]]) -> list[str]:
    """One line per estimator of ``improvement``: its improvement over the INS DR, the final
    position error's with its 95 % interval where ``ci95`` has a finite one."""

    def interval(est: str) -> str:
        lo, hi = ci95[est].final_position_error_pct if est in ci95 else (None, None)
        if lo is None or hi is None or not (math.isfinite(lo) and math.isfinite(hi)):
            return ""
        return f" (95 % interval {_fmt(lo, 1)} to {_fmt(hi, 1)} %)"

    return [
        f"{labels[est]} improvement over INS DR (mean): displacement CRSE {_pct(imp.crse_pct)}, "
        f"orientation-rate CRSE {_pct(imp.yaw_crse_pct)}, final position error "
        f"{_pct(imp.final_position_error_pct)}{interval(est)}"
        for est, imp in improvement.items()
    ]


def truth_line(truth: GnssTruth) -> str:
    """One line on what the GNSS quality checks kept out of the scores."""
    lost = truth.receiver_lost_windows
    if not truth.excluded_windows and not lost:
        return f"GNSS truth: all {truth.windows} windows trustworthy, none excluded"
    if truth.excluded_windows:
        reasons = ", ".join(f"{name} {n}" for name, n in truth.excluded_by_reason.items())
        head = f"GNSS truth: {truth.excluded_windows} of {truth.windows} windows excluded ({reasons})"
    else:
        head = f"GNSS truth: all {truth.windows} windows trustworthy"
    receiver = (f"; the receiver without a fix to trust in {lost} windows (no outage starts right after one)"
                if lost else "")
    return f"{head}{receiver}; {truth.excluded_outages} outage(s) not placed there"


def title_of(drive: str, outage_s: float, scenario: str | None = None) -> str:
    what = f"{scenario}: " if scenario else ""
    return f"{what}{drive}, {outage_s:g} s GNSS outages"


def worst_table(rows: list[WorstRow], labels: dict[str, str], several: bool) -> tuple[list[str], list[list[str]]]:
    """The worst outages: number, (with ``several`` drives, the drive,) span and each estimator's
    final position error."""
    header = ["Outage", *(["Drive"] if several else []), "Span (s)"] + [f"{labels[e]} final err. (m)" for e in labels]
    out = [[f"#{w.number}", *([w.drive] if several else []), f"{w.start_s:.0f}-{w.end_s:.0f}",
            *(_fmt(w.final_error_m[e], 2) for e in labels)] for w in rows]
    return header, out


def drift_table(rows: list[DriftRow]) -> tuple[list[str], list[list[str]]]:
    """Position error against seconds since the outage began (about five points, the end always):
    per estimator the mean with the 10-90 % range; then the final-error percentiles."""
    t = rows[0].t_s
    step = max(1, round((len(t) - 1) / 5))
    picks = sorted({*range(step, len(t), step), len(t) - 1})
    header = ["Estimator", *(f"{t[k]:g} s" for k in picks), "p50", "p90", "p95", "max"]
    out = [[d.label, *(f"{_fmt(d.mean_m[k], 1)} [{_fmt(d.p10_m[k], 1)}-{_fmt(d.p90_m[k], 1)}]" for k in picks),
            *(_fmt(x, 1) for x in (d.final_p50_m, d.final_p90_m, d.final_p95_m, d.final_max_m))] for d in rows]
    return header, out


DRIFT_TITLE = "Position error since the outage began (m): mean [10-90 %], and final-error percentiles (m)"


def drive_lines(drives: list[DriveEntry], most: int = 4) -> list[str]:
    """Where the outages went and what each drive's IMU is (for up to ``most`` drives; the JSON has
    every one)."""
    placements = {d.placement for d in drives if d.placement}
    out = [f"Outages: {p}" for p in sorted(placements)] if len(placements) <= 2 else []
    return out + [f"{d.name}: {d.imu_text}" for d in drives[:most] if d.imu_text]


def domain_detail(note: DomainNote) -> str:
    """What of a drive lies outside an estimator's training domain, and how much its uncertainty was widened."""
    return (f"{'; '.join(note.outside)} (sigma widened x{note.sigma_scale_median:.2f} median, "
            f"x{note.sigma_scale_max:.2f} at most)")


def bridged_table(rows: list[BridgedRow], labels: dict[str, str],
                  several: bool) -> tuple[list[str], list[list[str]]]:
    """One row per bridged GNSS outage: where (with ``several`` drives, on which), how long, and
    each estimator's final position error."""
    header = ["#", *(["Drive"] if several else []), "Gap (s)", "From (s)", "Outage (s)", "Span (m)"]
    header += [f"{labels[e]} final err. (m)" for e in labels]
    out = [[str(b.number), *([b.drive] if several else []), f"{b.gap_s:.1f}", f"{b.gap_start_s:.1f}",
            str(b.outage_s), f"{b.span_m:.0f}", *(_fmt(b.final_error_m[e], 2) for e in labels)] for b in rows]
    return header, out


def bridged_line(real: GnssOutages, labels: Mapping[str, str]) -> str:
    """Mean final position error per estimator over the bridged outages, and what was left out."""
    means = ", ".join(f"{labels[e]} {_fmt(real.final_error_m[e].mean, 2)} m" for e in labels)
    reasons = ", ".join(f"{n} with {reason}" for reason, n in real.not_bridged_by_reason.items())
    missed = (f"; {real.not_bridged} outage(s) not bridged" + (f" ({reasons})" if reasons else "")
              if real.not_bridged else "")
    return f"Mean final position error over {len(real.bridged)} real GNSS outage(s): {means}{missed}"


def render_lengths(lengths: list[LengthRow], markdown: bool = False, width: int | None = None) -> str:
    """Error against outage length: per estimator and length, the mean final position error (m)
    with its share of the distance (%), and the mean displacement CRSE (m)."""
    first = lengths[0]
    header = ["Estimator", *(f"{x:g} s final (m, %)" for x in first.outage_s),
              *(f"{x:g} s CRSE (m)" for x in first.outage_s)]
    rows = [[r.label, *(f"{_fmt(m, 2)} ({_fmt(p, 1)} %)" for m, p in zip(r.final_position_error_m, r.final_error_pct)),
             *(_fmt(c, 2) for c in r.crse_m)] for r in lengths]
    title = "Error against outage length (mean over each length's outages; " + ", ".join(
        f"{x:g} s: {n}" for x, n in zip(first.outage_s, first.n_outages)) + " outages)"
    doc = Document([Heading(title), Table(header, rows, 1)], spaced=False, hang=None)
    return to_markdown(doc) if markdown else to_text(doc, width)
