"""The paper's results tables (Tables 8-12 layout) from an ``evaluate`` report, as text or Markdown."""

from __future__ import annotations

import math
from typing import Any

LABELS = {"ins": "INS DR", "idnn": "IDNN"}
_STATS = (("max", "max"), ("min", "min"), ("mean", "μ"), ("std", "σ"))
_BLOCKS = (("CRSE", "crse_m", "yaw_crse_radps"), ("CAE", "cae_m", "yaw_cae_radps"), ("AEPS (/s)", "aeps_m", "yaw_aeps_radps"))


def _fmt(x: float, decimals: int = 2) -> str:
    return "nan" if x is None or (isinstance(x, float) and math.isnan(x)) else f"{x:.{decimals}f}"


def table_rows(rep: dict[str, Any]) -> tuple[list[str], list[list[str]]]:
    """Header and rows: displacement (m) and orientation rate (rad/s) per estimator."""
    ests = [e for e in ("idnn", "ins") if e in rep["summary"]]
    header = ["Metric", ""] + [f"{LABELS[e]} (m)" for e in ests] + [f"{LABELS[e]} (rad/s)" for e in ests]
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
    imp = rep.get("improvement_pct")
    if not imp:
        return []
    return [
        f"IDNN improvement over INS (mean): displacement CRSE {_fmt(imp['crse_m'], 1)} %, "
        f"orientation-rate CRSE {_fmt(imp['yaw_crse_radps'], 1)} %, final position error {_fmt(imp['final_position_error_m'], 1)} %"
    ]


def title_of(rep: dict[str, Any], scenario: str | None = None) -> str:
    what = f"{scenario}: " if scenario else ""
    return f"{what}{rep['drive']}, {rep['outage_s']:g} s GNSS outages"


def render_markdown(rep: dict[str, Any], scenario: str | None = None) -> str:
    header, rows = table_rows(rep)
    lines = [f"**{title_of(rep, scenario)}**", "", "| " + " | ".join(header) + " |", "|" + "---|" * len(header)]
    lines += ["| " + " | ".join(f"**{c}**" if j == 0 and c else c for j, c in enumerate(r)) + " |" for r in rows]
    extra = improvement_lines(rep)
    return "\n".join(lines + ([""] + extra if extra else [])) + "\n"


def render_text(rep: dict[str, Any], scenario: str | None = None) -> str:
    header, rows = table_rows(rep)
    widths = [max(len(r[j]) for r in [header] + rows) for j in range(len(header))]
    def line(r: list[str]) -> str:
        return "  ".join(c.ljust(w) if j < 2 else c.rjust(w) for j, (c, w) in enumerate(zip(r, widths))).rstrip()
    out = [title_of(rep, scenario), line(header), "  ".join("-" * w for w in widths)]
    out += [line(r) for r in rows]
    out += improvement_lines(rep)
    return "\n".join(out) + "\n"


def overview_rows(reports: dict[Any, dict[str, Any]], label: str = "Scenario") -> tuple[list[str], list[list[str]]]:
    """One row per scenario (or drive group): mean CRSE and final position error, INS vs IDNN."""
    header = [label, "Sequences", "Disp. CRSE μ INS (m)", "IDNN (m)", "Δ %",
              "Yaw CRSE μ INS (rad/s)", "IDNN (rad/s)", "Δ %", "Final pos. err. μ INS (m)", "IDNN (m)"]
    rows = []
    for group, rep in reports.items():
        s = rep["summary"]
        idnn = "idnn" in s
        imp = rep.get("improvement_pct", {})

        def val(est: str, key: str, d: int = 2) -> str:
            return _fmt(s[est][key]["mean"], d) if est in s else "-"

        rows.append([
            str(group or rep["drive"]), str(rep["n_sequences"]),
            val("ins", "crse_m"), val("idnn", "crse_m"), _fmt(imp["crse_m"], 1) if idnn else "-",
            val("ins", "yaw_crse_radps", 3), val("idnn", "yaw_crse_radps", 3), _fmt(imp["yaw_crse_radps"], 1) if idnn else "-",
            val("ins", "final_position_error_m"), val("idnn", "final_position_error_m"),
        ])  # fmt: skip
    return header, rows


def render_overview(reports: dict[Any, dict[str, Any]], markdown: bool, label: str = "Scenario") -> str:
    """The overview table; Δ % is the IDNN's improvement over the INS (positive = IDNN better)."""
    header, rows = overview_rows(reports, label)
    if markdown:
        lines = ["| " + " | ".join(header) + " |", "|" + "---|" * len(header)] + ["| " + " | ".join(r) + " |" for r in rows]
        return "\n".join(lines) + "\n"
    widths = [max(len(r[j]) for r in [header] + rows) for j in range(len(header))]
    lines = ["  ".join(c.rjust(w) if j else c.ljust(w) for j, (c, w) in enumerate(zip(r, widths))) for r in [header] + rows]
    return "\n".join(lines) + "\n"
