"""A filter's health over a drive, from its update log (:class:`ionav_viz.nav.protocol.FilterHealth`).

Per kind of measurement (GNSS position, NHC, ...): how many boundaries it was measured at, how
many its gate left out and the longest such run (s), and its normalised innovation squared (NIS,
``innovation^2 / S`` per scalar update): a filter whose noise model matches its data averages 1,
and about 1 % of the updates lie above the chi-square's 99 % point (6.63, one degree of freedom).
Much more means the filter is surer than it should be (it will gate good fixes out), much less
that its noise is too wide.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from ..nav.protocol import SAFEGUARD_KINDS, FilterHealth

#: The 99 % point of a chi-square of one degree of freedom: a scalar NIS above it is a 1 % event.
NIS_99 = 6.635


def _longest_run(flags: np.ndarray) -> int:
    """The longest run of True in ``flags``."""
    if not flags.any():
        return 0
    edges = np.diff(np.concatenate([[0], flags.astype(np.int8), [0]]))
    return int((np.flatnonzero(edges == -1) - np.flatnonzero(edges == 1)).max())


def summarise_health(health: FilterHealth) -> dict[str, dict[str, Any]]:
    """Per measurement kind, in the order of ``health.kinds``: ``updates`` (boundaries where it was
    measured), ``gated`` (where its gate left it out), ``longest_gated_s``, ``mean_nis`` (over the
    scalar updates used; 1 when the noise model is right), ``nis_above_99_pct`` (% of them above
    :data:`NIS_99`; 1 % expected) and ``n_nis`` (how many)."""
    nis = health.nis()
    status = np.asarray(health.status)
    step_s = float(np.median(np.diff(health.t_s))) if len(health.t_s) > 1 else 1.0
    out: dict[str, dict[str, Any]] = {}
    for kind in dict.fromkeys(health.kinds):
        cols = [i for i, k in enumerate(health.kinds) if k == kind]
        st = status[:, cols]
        if kind in SAFEGUARD_KINDS:  # its acts: how often, never a NIS
            out[kind] = {"updates": int((st > 0).any(axis=1).sum()), "gated": 0, "longest_gated_s": 0.0,
                         "mean_nis": float("nan"), "nis_above_99_pct": float("nan"), "n_nis": 0}
            continue
        used = nis[:, cols][st == 1]
        gated = (st == 2).any(axis=1)
        out[kind] = {"updates": int((st > 0).any(axis=1).sum()), "gated": int(gated.sum()),
                     "longest_gated_s": round(_longest_run(gated) * step_s, 3),
                     "mean_nis": float(used.mean()) if used.size else float("nan"),
                     "nis_above_99_pct": float(100.0 * (used > NIS_99).mean()) if used.size else float("nan"),
                     "n_nis": int(used.size)}
    return out


def pooled_health(summaries: list[dict[str, dict[str, Any]]]) -> dict[str, dict[str, Any]]:
    """Several drives' :func:`summarise_health` as one (counts summed, means weighted by ``n_nis``,
    the longest run the longest of any drive)."""
    out: dict[str, dict[str, Any]] = {}
    for summary in summaries:
        for kind, s in summary.items():
            p = out.setdefault(kind,
                               {"updates": 0, "gated": 0, "longest_gated_s": 0.0, "_nis": 0.0, "_above": 0.0,
                                "n_nis": 0})
            p["updates"] += s["updates"]
            p["gated"] += s["gated"]
            p["longest_gated_s"] = max(p["longest_gated_s"], s["longest_gated_s"])
            if s["n_nis"]:
                p["_nis"] += s["mean_nis"] * s["n_nis"]
                p["_above"] += s["nis_above_99_pct"] * s["n_nis"]
                p["n_nis"] += s["n_nis"]
    for p in out.values():
        total, nis, above = p["n_nis"], p.pop("_nis"), p.pop("_above")
        p["mean_nis"] = nis / total if total else float("nan")
        p["nis_above_99_pct"] = above / total if total else float("nan")
    return {k: {key: p[key] for key in ("updates", "gated", "longest_gated_s", "mean_nis", "nis_above_99_pct", "n_nis")}
            for k, p in out.items()}


def health_line(label: str, summary: dict[str, dict[str, Any]]) -> str:
    """One line of a filter's health for the text report, e.g. ``GNSS/INS 3D health: GNSS position
    used at 290 of 302 boundaries (12 gated out, longest 5 s); mean NIS (1 expected): GNSS position
    1.31, NHC 0.42, ...``."""
    parts = []
    for kind, s in summary.items():
        if s["gated"]:
            parts.append(f"{kind} used at {s['updates'] - s['gated']} of {s['updates']} boundaries "
                         f"({s['gated']} gated out, longest {s['longest_gated_s']:g} s)")
    nis = ", ".join(f"{kind} {s['mean_nis']:.2f}" for kind, s in summary.items()
                    if s["n_nis"] and kind not in SAFEGUARD_KINDS)
    gated = "; ".join(parts) if parts else "no measurement gated out"
    gated += "".join(f"; {kind} at {s['updates']} boundar{'y' if s['updates'] == 1 else 'ies'}"
                     for kind, s in summary.items() if kind in SAFEGUARD_KINDS and s["updates"])
    return f"{label} health: {gated}; mean NIS (1 expected): {nis or 'no updates'}"
