"""The paper's results tables (Tables 8-12 layout): a drive report as a document (:func:`report_document`,
:mod:`.document`) from its typed rows, laid out as text or Markdown by :mod:`.document`'s renderers.

Any number of estimators: the paper's layout puts the candidate estimators first and the INS DR
(the baseline) last; improvements are each candidate's over the INS DR.
"""

from __future__ import annotations

import math
from typing import Any

from .document import Document, Heading, Table, aligned, to_markdown, to_text
from .rows import BridgedRow, DriftRow, EstimatorRow, WorstRow

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


def labels_of(rep: dict[str, Any]) -> dict[str, str]:
    """Estimator name -> label, in the report's order."""
    return {e["name"]: e["label"] for e in rep["estimators"]}


def estimator_table(rows: list[EstimatorRow], distance_m: dict[str, float],
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
        out.append(["Total distance (m)" if i == 0 else "", label, _fmt(distance_m[stat])] + [""] * (2 * len(ests) - 1))
    out.append(["Number of sequences", "", str(n_outages)] + [""] * (2 * len(ests) - 1))
    return header, out


def improvement_lines(rep: dict[str, Any]) -> list[str]:
    """One line per estimator: its improvement over the INS DR, the final position error's with its
    95 % interval (``improvement_ci95_pct``) where the report has one."""
    labels = labels_of(rep)
    ci = rep.get("improvement_ci95_pct", {})

    def interval(est: str) -> str:
        lo, hi = ci.get(est, {}).get("final_position_error_m", (None, None))
        if lo is None or hi is None or not (math.isfinite(lo) and math.isfinite(hi)):
            return ""
        return f" (95 % interval {_fmt(lo, 1)} to {_fmt(hi, 1)} %)"

    return [
        f"{labels[est]} improvement over INS DR (mean): displacement CRSE {_pct(imp['crse_m'])}, "
        f"orientation-rate CRSE {_pct(imp['yaw_crse_radps'])}, final position error "
        f"{_pct(imp['final_position_error_m'])}{interval(est)}"
        for est, imp in rep.get("improvement_pct", {}).items()
    ]


def truth_line(rep: dict[str, Any]) -> str:
    """One line on what the GNSS quality checks kept out of the scores."""
    truth = rep.get("gnss_truth")
    if not truth:
        return ""
    lost = truth.get("receiver_lost_windows", 0)
    if not truth["excluded_windows"] and not lost:
        return f"GNSS truth: all {truth['windows']} windows trustworthy, none excluded"
    if truth["excluded_windows"]:
        reasons = ", ".join(f"{name} {n}" for name, n in truth["excluded_by_reason"].items())
        head = f"GNSS truth: {truth['excluded_windows']} of {truth['windows']} windows excluded ({reasons})"
    else:
        head = f"GNSS truth: all {truth['windows']} windows trustworthy"
    receiver = (f"; the receiver without a fix to trust in {lost} windows (no outage starts right after one)"
                if lost else "")
    return f"{head}{receiver}; {truth['excluded_outages']} outage(s) not placed there"


def title_of(rep: dict[str, Any], scenario: str | None = None) -> str:
    what = f"{scenario}: " if scenario else ""
    return f"{what}{rep['drive']}, {rep['outage_s']:g} s GNSS outages"


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


def worst_title(rep: dict[str, Any]) -> str:
    labels = labels_of(rep)
    return f"Worst outages by {labels.get(rep.get('worst_of', 'ins'), 'INS DR')} final position error"


def report_lines(rep: dict[str, Any]) -> list[str]:
    """A drive report's lines under its tables (``Report.to_dict``): the improvements where it has
    synthetic outages, the GNSS truth, the drives, the estimators' uncertainty, health and choices."""
    said = (improvement_lines(rep) if rep["n_sequences"] else []) + [x for x in [truth_line(rep)] if x]
    return said + drive_lines(rep) + consistency_lines(rep) + health_lines(rep) + arbiter_lines(rep) + domain_lines(rep)


def drive_lines(rep: dict[str, Any], most: int = 4) -> list[str]:
    """Where the outages went and what each drive's IMU is (for up to ``most`` drives; a fleet's
    JSON has every one)."""
    drives = rep.get("drives", [])
    placements = {d["placement"] for d in drives if d.get("placement")}
    out = [f"Outages: {p}" for p in sorted(placements)] if len(placements) <= 2 else []
    out += [f"{d['name']}: {d['imu_text']}" for d in drives[:most] if d.get("imu_text")]
    return out


def consistency_lines(rep: dict[str, Any]) -> list[str]:
    """A line per estimator that gives a position covariance: how honest it is (:mod:`.consistency`)."""
    from .consistency import consistency_line

    labels = {e["name"]: e["label"] for e in rep["estimators"]}
    return [consistency_line(labels.get(est, est), s["consistency"]) for est, s in rep["summary"].items()
            if "consistency" in s]


def health_lines(rep: dict[str, Any]) -> list[str]:
    """A line per filter of its health (:mod:`.health`), from the report's ``filter_health``."""
    from .health import health_line

    labels = {e["name"]: e["label"] for e in rep["estimators"]}
    return [health_line(labels.get(est, est), summary) for est, summary in rep.get("filter_health", {}).items()]


def arbiter_lines(rep: dict[str, Any]) -> list[str]:
    """On one drive, a line per estimator that chose per outage from its pseudo-outages over the GNSS
    before it (a history arbiter: ``gins``'s propagation, :func:`ionav_viz.nav.gins.arbitrate`; the
    IDNN's share of the INS DR's displacement, :class:`ionav_viz.learning.idnn.IdnnEstimator`): what
    it chose and why. An estimator describes the last drive it ran on, so a report of several drives
    leaves it to each drive's own run."""
    if len(rep.get("drives", [])) != 1:
        return []
    return [f"{e['label']} arbiter: {e['info']['arbiter']}" for e in rep["estimators"]
            if e.get("info", {}).get("arbiter")]


def domain_lines(rep: dict[str, Any]) -> list[str]:
    """A line per drive whose inputs lie outside what the IDNN's model was trained on (the
    estimator's ``domain`` description, :func:`ionav_viz.learning.domain.outside`): what, and how much its
    uncertainty was widened."""
    out = []
    for e in rep["estimators"]:
        for drive, note in (e.get("info", {}).get("domain") or {}).items():
            out.append(f"{e['label']} out of its training domain on {drive}: {'; '.join(note['outside'])} "
                       f"(sigma widened x{note['sigma_scale_median']:.2f} median, "
                       f"x{note['sigma_scale_max']:.2f} at most)")
    return out


def bridged_table(rows: list[BridgedRow], labels: dict[str, str],
                  several: bool) -> tuple[list[str], list[list[str]]]:
    """One row per bridged GNSS outage: where (with ``several`` drives, on which), how long, and
    each estimator's final position error."""
    header = ["#", *(["Drive"] if several else []), "Gap (s)", "From (s)", "Outage (s)", "Span (m)"]
    header += [f"{labels[e]} final err. (m)" for e in labels]
    out = [[str(b.number), *([b.drive] if several else []), f"{b.gap_s:.1f}", f"{b.gap_start_s:.1f}",
            str(b.outage_s), f"{b.span_m:.0f}", *(_fmt(b.final_error_m[e], 2) for e in labels)] for b in rows]
    return header, out


def bridged_line(rep: dict[str, Any]) -> str:
    """Mean final position error per estimator over the bridged outages, and what was left out."""
    g = rep["gnss_outages"]
    labels = labels_of(rep)
    means = ", ".join(f"{labels[e]} {_fmt(g['final_error_m'][e]['mean'], 2)} m" for e in labels)
    why = g.get("not_bridged_by_reason") or {}
    reasons = ", ".join(f"{n} with {reason}" for reason, n in why.items())
    missed = (f"; {g['not_bridged']} outage(s) not bridged" + (f" ({reasons})" if reasons else "")
              if g["not_bridged"] else "")
    return f"Mean final position error over {len(g['bridged'])} real GNSS outage(s): {means}{missed}"


def overview_rows(reports: dict[Any, dict[str, Any]], label: str = "Scenario") -> tuple[list[str], list[list[str]]]:
    """One row per scenario (or drive group): mean CRSE and final position error per estimator,
    the INS DR first, each other estimator with its improvement over the INS DR (Δ %)."""
    first = next(iter(reports.values()))
    labels = labels_of(first)
    names = [n for n in labels if n == "ins"] + [n for n in labels if n != "ins"]
    blocks = (("Disp. CRSE μ", "crse_m", "m", 2, True), ("Yaw CRSE μ", "yaw_crse_radps", "rad/s", 3, True),
              ("Final pos. err. μ", "final_position_error_m", "m", 2, False),
              ("Final err. μ", "final_error_pct", "% of distance", 1, False))
    header = [label, "Sequences"]
    for title, _key, unit, _d, delta in blocks:
        for i, est in enumerate(names):
            header.append(f"{title} {labels[est]} ({unit})" if i == 0 else f"{labels[est]} ({unit})")
            if delta and est != "ins" and "ins" in names:
                header.append("Δ %")
    rows = []
    for group, rep in reports.items():
        s, imp = rep["summary"], rep.get("improvement_pct", {})
        row = [str(group or rep["drive"]), str(rep["n_sequences"])]
        for _title, key, _unit, d, delta in blocks:
            for est in names:
                row.append(_fmt(s[est][key]["mean"], d) if est in s else "-")
                if delta and est != "ins" and "ins" in names:
                    row.append(_fmt(imp[est][key], 1) if est in imp else "-")
        rows.append(row)
    return header, rows


def render_overview(reports: dict[Any, dict[str, Any]], markdown: bool, label: str = "Scenario",
                    width: int | None = None) -> str:
    """The overview table; Δ % is an estimator's improvement over the INS DR (positive = better).

    As text wider than ``width`` it is transposed: one column per group, one row per metric and
    estimator (and split into blocks of groups if that is still too wide)."""
    header, rows = overview_rows(reports, label)
    if markdown:
        return to_markdown(Document([Table(header, rows)]))
    widths = [max(len(r[j]) for r in [header] + rows) for j in range(len(header))]
    lines = ["  ".join(c.rjust(w) if j else c.ljust(w) for j, (c, w) in enumerate(zip(r, widths)))
             for r in [header] + rows]
    if width is not None and max(map(len, lines)) > width:
        lines = aligned(*overview_transposed(reports, label), 2, width)
    return "\n".join(lines) + "\n"


def overview_transposed(reports: dict[Any, dict[str, Any]],
                        label: str = "Scenario") -> tuple[list[str], list[list[str]]]:
    """The overview with one column per group: rows are (metric, estimator) and each candidate's
    improvement over the INS DR (``Δ %``) under it."""
    header, rows = overview_rows(reports, label)
    first = next(iter(reports.values()))
    labels = labels_of(first)
    # "motorway: V-sim-motorway" -> its group
    out_header = ["Metric", "Estimator", *(r[0].split(": ")[0] for r in rows)]
    out_rows = [["Sequences", "", *(r[1] for r in rows)]]
    metric = ""
    for j in range(2, len(header)):
        name = header[j]
        est = next((lab for lab in labels.values() if name.startswith(f"{lab} (") or f" {lab} (" in name), "")
        if name == "Δ %":
            out_rows.append(["", f"{out_rows[-1][1]} Δ %", *(r[j] for r in rows)])
            continue
        title = name[: name.index(est)].strip() if est and not name.startswith(est) else ""
        unit = name[name.rindex("(") :].replace("% of distance", "% of dist.")
        if title:
            metric = f"{title} {unit}"
        out_rows.append([metric if title else "", est, *(r[j] for r in rows)])
    return out_header, out_rows


def render_lengths(summary: dict[str, Any], labels: dict[str, str], markdown: bool = False,
                   width: int | None = None) -> str:
    """Error against outage length: per estimator and length, the mean final position error (m)
    with its share of the distance (%), and the mean displacement CRSE (m)."""
    first = next(iter(summary.values()))
    header = ["Estimator", *(f"{x:g} s final (m, %)" for x in first["outage_s"]),
              *(f"{x:g} s CRSE (m)" for x in first["outage_s"])]
    rows = [[labels.get(e, e),
             *(f"{_fmt(m, 2)} ({_fmt(p, 1)} %)" for m, p in zip(r["final_position_error_m"], r["final_error_pct"])),
             *(_fmt(c, 2) for c in r["crse_m"])] for e, r in summary.items()]
    title = "Error against outage length (mean over each length's outages; " + ", ".join(
        f"{x:g} s: {n}" for x, n in zip(first["outage_s"], first["n_outages"])) + " outages)"
    doc = Document([Heading(title), Table(header, rows, 1)], spaced=False, hang=None)
    return to_markdown(doc) if markdown else to_text(doc, width)
