"""The paper's results tables (Tables 8-12 layout) from an ``evaluate`` report dict, as text or Markdown.

Any number of estimators: the paper's layout puts the candidate estimators first and the INS DR
(the baseline) last; improvements are each candidate's over the INS DR.
"""

from __future__ import annotations

import math
from typing import Any

_STATS = (("max", "max"), ("min", "min"), ("mean", "μ"), ("std", "σ"))
_BLOCKS = (("CRSE", "crse_m", "yaw_crse_radps"), ("CAE", "cae_m", "yaw_cae_radps"), ("AEPS (/s)", "aeps_m", "yaw_aeps_radps"))


def _fmt(x: float, decimals: int = 2) -> str:
    return "nan" if x is None or (isinstance(x, float) and math.isnan(x)) else f"{x:.{decimals}f}"


def labels_of(rep: dict[str, Any]) -> dict[str, str]:
    """Estimator name -> label, in the report's order."""
    return {e["name"]: e["label"] for e in rep["estimators"]}


def table_order(rep: dict[str, Any]) -> list[str]:
    """Candidates first, the INS DR baseline last (the paper's column order)."""
    names = list(labels_of(rep))
    return [n for n in names if n != "ins"] + [n for n in names if n == "ins"]


def table_rows(rep: dict[str, Any]) -> tuple[list[str], list[list[str]]]:
    """Header and rows: displacement (m) and orientation rate (rad/s) per estimator."""
    ests, labels = table_order(rep), labels_of(rep)
    header = ["Metric", ""] + [f"{labels[e]} (m)" for e in ests] + [f"{labels[e]} (rad/s)" for e in ests]
    rows = []
    for title, disp_key, yaw_key in _BLOCKS:
        for i, (stat, label) in enumerate(_STATS):
            row = [title if i == 0 else "", label]
            row += [_fmt(rep["summary"][e][disp_key][stat]) for e in ests]
            row += [_fmt(rep["summary"][e][yaw_key][stat], 3) for e in ests]
            rows.append(row)
    for i, (stat, label) in enumerate(_STATS):
        row = ["Final position error" if i == 0 else "", label]
        row += [_fmt(rep["summary"][e]["final_position_error_m"][stat]) for e in ests] + [""] * len(ests)
        rows.append(row)
    for i, (stat, label) in enumerate(_STATS[:3]):
        rows.append(["Total distance (m)" if i == 0 else "", label, _fmt(rep["distance_m"][stat])] + [""] * (2 * len(ests) - 1))
    rows.append(["Number of sequences", "", str(rep["n_sequences"])] + [""] * (2 * len(ests) - 1))
    return header, rows


def improvement_lines(rep: dict[str, Any]) -> list[str]:
    labels = labels_of(rep)
    return [
        f"{labels[est]} improvement over INS (mean): displacement CRSE {_fmt(imp['crse_m'], 1)} %, "
        f"orientation-rate CRSE {_fmt(imp['yaw_crse_radps'], 1)} %, final position error {_fmt(imp['final_position_error_m'], 1)} %"
        for est, imp in rep.get("improvement_pct", {}).items()
    ]


def truth_line(rep: dict[str, Any]) -> str:
    """One line on what the GNSS quality checks kept out of the scores."""
    truth = rep.get("gnss_truth")
    if not truth:
        return ""
    if not truth["excluded_windows"]:
        return f"GNSS truth: all {truth['windows']} windows trustworthy, none excluded"
    reasons = ", ".join(f"{name} {n}" for name, n in truth["excluded_by_reason"].items())
    return (f"GNSS truth: {truth['excluded_windows']} of {truth['windows']} windows excluded ({reasons}); "
            f"{truth['excluded_outages']} outage(s) not placed there")


def title_of(rep: dict[str, Any], scenario: str | None = None) -> str:
    what = f"{scenario}: " if scenario else ""
    return f"{what}{rep['drive']}, {rep['outage_s']:g} s GNSS outages"


def render_markdown(rep: dict[str, Any], scenario: str | None = None) -> str:
    header, rows = table_rows(rep)
    lines = [f"**{title_of(rep, scenario)}**", "", "| " + " | ".join(header) + " |", "|" + "---|" * len(header)]
    lines += ["| " + " | ".join(f"**{c}**" if j == 0 and c else c for j, c in enumerate(r)) + " |" for r in rows]
    extra = improvement_lines(rep) + [x for x in [truth_line(rep)] if x]
    return "\n".join(lines + ([""] + extra if extra else [])) + "\n"


def render_text(rep: dict[str, Any], scenario: str | None = None) -> str:
    header, rows = table_rows(rep)
    widths = [max(len(r[j]) for r in [header] + rows) for j in range(len(header))]
    def line(r: list[str]) -> str:
        return "  ".join(c.ljust(w) if j < 2 else c.rjust(w) for j, (c, w) in enumerate(zip(r, widths))).rstrip()
    out = [title_of(rep, scenario), line(header), "  ".join("-" * w for w in widths)]
    out += [line(r) for r in rows]
    out += improvement_lines(rep) + [x for x in [truth_line(rep)] if x]
    return "\n".join(out) + "\n"


def overview_rows(reports: dict[Any, dict[str, Any]], label: str = "Scenario") -> tuple[list[str], list[list[str]]]:
    """One row per scenario (or drive group): mean CRSE and final position error per estimator,
    the INS DR first, each other estimator with its improvement over the INS DR (Δ %)."""
    first = next(iter(reports.values()))
    labels = labels_of(first)
    names = [n for n in labels if n == "ins"] + [n for n in labels if n != "ins"]
    blocks = (("Disp. CRSE μ", "crse_m", "m", 2, True), ("Yaw CRSE μ", "yaw_crse_radps", "rad/s", 3, True),
              ("Final pos. err. μ", "final_position_error_m", "m", 2, False))
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


def render_overview(reports: dict[Any, dict[str, Any]], markdown: bool, label: str = "Scenario") -> str:
    """The overview table; Δ % is an estimator's improvement over the INS DR (positive = better)."""
    header, rows = overview_rows(reports, label)
    if markdown:
        lines = ["| " + " | ".join(header) + " |", "|" + "---|" * len(header)] + ["| " + " | ".join(r) + " |" for r in rows]
        return "\n".join(lines) + "\n"
    widths = [max(len(r[j]) for r in [header] + rows) for j in range(len(header))]
    lines = ["  ".join(c.rjust(w) if j else c.ljust(w) for j, (c, w) in enumerate(zip(r, widths))) for r in [header] + rows]
    return "\n".join(lines) + "\n"
