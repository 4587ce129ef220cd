"""``runout report RESULTS``: a self-contained HTML hazard report with its pictures beside it.

The report reads a results folder only (``summary.json``, ``series.csv``, ``project.toml``, the
frames and the hazard files of ``projects.hazard``; ``contacts.csv`` when a run wrote one) and
writes ``report/report.html`` with the PNGs it shows next to it (the HTML embeds them too, so the
one file can be handed on). Pictures are drawn headless: matplotlib's Agg canvas for the plots,
:func:`app.render.render_frame` (offscreen VTK) for the scene.

Contents: the run's settings and provenance; the scene before and after; the envelope profiles
along the section (surfaces, peak flow height, speed, impact pressure, arrival time, deposit) with
the targets and run-out points marked; the measures with their thresholds; the targets' table and
time series; the energy curves (``series.csv`` and the envelope updates); the peak and mean
forces on the sides and structures (``contacts.csv``); and context from experience
(:func:`context`), which is context, not a verdict.
"""

from __future__ import annotations

import base64
import csv
import html
import logging
import math
import os
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

import numpy as np

from projects.hazard import HAZARD_JSON, read_hazard
from projects.motion import hazard_provisional
from app.render import structure_patches  # noqa: F401 - drawn in the report's profiles; the views take it here too
from projects.results import Results, ResultsError

logger = logging.getLogger(__name__)

REPORT_DIR = "report"
REPORT_HTML = "report.html"
CONTACTS_CSV = "contacts.csv"

#: Lube, Huppert, Sparks & Freundt (2005), "Collapses of two-dimensional granular columns",
#: Phys. Rev. E 72, 041301: dry granular columns released in a channel (planar), aspect ratio
#: a = H0 / L0. Run-out (L_inf - L0) / L0 = 1.2 a, fitted for a < 1.8, and 1.9 a^(2/3), fitted for
#: a > 2.8 (as cited by later column-collapse studies); between the two fits (a transition the
#: paper leaves open) the report switches at a = 2.3. Final height H_inf / L0 = a for a < 1.15,
#: a^(2/5) above. Empirical fits; the branches do not meet exactly.
LUBE_2005 = {
    "source": "Lube, Huppert, Sparks & Freundt (2005), Phys. Rev. E 72, 041301 (planar granular columns)",
    "runout_break": 2.3, "runout_low": (1.2, 1.0), "runout_high": (1.9, 2.0 / 3.0),
    "height_break": 1.15, "height_high": (1.0, 2.0 / 5.0),
}
#: Corominas (1996), "The angle of reach as a mobility index for small and large landslides",
#: Can. Geotech. J. 33, 260-271: regression over all landslide types of the inventory,
#: log10(H/L) = 0.047 - 0.085 log10(V), V in m3 (natural landslides, about 1e1 to 1e10 m3).
COROMINAS_1996 = {
    "source": "Corominas (1996), Can. Geotech. J. 33, 260-271 (all landslide types)",
    "intercept": 0.047, "slope": -0.085, "volume_range_m3": (1.0e1, 1.0e10),
}


# --------------------------------------------------------------------------------------------
# context from experience


def lube_runout(a: float) -> float:
    """(L_inf - L0) / L0 of a planar granular column of aspect ratio ``a`` (Lube et al. 2005)."""
    c, e = LUBE_2005["runout_low"] if a < LUBE_2005["runout_break"] else LUBE_2005["runout_high"]
    return c * a ** e


def lube_height(a: float) -> float:
    """H_inf / L0 of a planar granular column of aspect ratio ``a`` (Lube et al. 2005)."""
    if a < LUBE_2005["height_break"]:
        return a
    c, e = LUBE_2005["height_high"]
    return c * a ** e


def corominas_h_over_l(volume_m3: float) -> float:
    """H/L of the Corominas (1996) regression for a landslide of ``volume_m3``."""
    return 10.0 ** (COROMINAS_1996["intercept"] + COROMINAS_1996["slope"] * math.log10(volume_m3))


def _column_geometry(project: Any, domain: Mapping[str, Any]) -> dict[str, float] | None:
    """L0, H0 of a planar column collapse: one rectangular body standing on the grid's bottom
    against a side of the grid box; None for any other scene."""
    if project is None or len(project.bodies) != 1:
        return None
    pts = np.asarray(project.bodies[0].polygon_m, float)
    if len(pts) > 4 and np.allclose(pts[0], pts[-1]):
        pts = pts[:-1]
    if len(pts) != 4:
        return None
    x0, y0 = pts.min(axis=0)
    x1, y1 = pts.max(axis=0)
    on_box = np.all((np.isclose(pts[:, 0], x0) | np.isclose(pts[:, 0], x1))
                    & (np.isclose(pts[:, 1], y0) | np.isclose(pts[:, 1], y1)))
    ox, oy = domain["origin_m"]
    width = domain["size_m"][0]
    tol = 1e-9 * max(1.0, width)
    against_wall = abs(x0 - ox) < tol or abs(x1 - (ox + width)) < tol
    if not on_box or abs(y0 - oy) > tol or not against_wall:
        return None
    return {"L0": float(x1 - x0), "H0": float(y1 - y0)}


def context(doc: Mapping[str, Any], project: Any, summary: Mapping[str, Any]) -> list[dict[str, Any]]:
    """Empirical relations to read the run against, each with its source and assumptions.

    Returns
    -------
    list of dict
        ``name``, ``source``, ``assumption``, ``rows`` (label, this run, relation), ``applies``
        (bool) and ``note``.
    """
    out = []
    domain = summary.get("domain") or {}
    col = _column_geometry(project, domain) if domain else None
    if col is not None:
        a = col["H0"] / col["L0"]
        runout = doc.get("runout_distance_m")
        final_h = None
        prof = doc.get("profile") or {}
        if "surface_m" in prof and len(prof["surface_m"]):
            final_h = float(np.nanmax(prof["surface_m"] - prof["floor_m"]))
        rows = [
            ("aspect ratio a = H0 / L0", f"{a:.3g}", ""),
            ("run-out (L_inf - L0) / L0", "-" if runout is None else f"{runout / col['L0']:.3g}",
             f"{lube_runout(a):.3g}"),
            ("final height H_inf / L0", "-" if final_h is None else f"{final_h / col['L0']:.3g}",
             f"{lube_height(a):.3g}"),
        ]
        out.append({
            "name": "Planar granular column collapse", "source": LUBE_2005["source"], "applies": True,
            "points": {"a": a, "runout": None if runout is None else runout / col["L0"],
                       "height": None if final_h is None else final_h / col["L0"]},
            "assumption": (f"the scene is a column {col['L0']:g} m long and {col['H0']:g} m high against a wall; "
                           "the laws were fitted to dry, cohesionless grains on a rough horizontal bed "
                           "(independent of friction angle within their data); L0 is the column's length "
                           "from the wall, the run-out is measured from its front"),
            "rows": rows,
            "note": "run-out fits hold for a < 1.8 and a > 2.8 (the report switches at a = 2.3 in between); "
                    "height fits change at a = 1.15",
        })
    area = doc.get("source_area_m2_per_m") or doc.get("mobilised_area_m2_per_m") or 0.0
    hl = doc.get("h_over_l")
    if area > 0 and hl is not None:
        source_len = None
        if doc.get("source_top_m") is not None and doc.get("source_front_x_m") is not None:
            source_len = abs(doc["source_front_x_m"] - doc["source_top_m"][0])
        widths = [("1 m (per metre of section)", 1.0)]
        if source_len and source_len > 0:
            widths.append((f"{source_len:.3g} m (the source's length: a square plan)", source_len))
        lo, hi = COROMINAS_1996["volume_range_m3"]
        rows = [("H/L of this run (travel angle)", f"{hl:.3g} ({doc['travel_angle_deg']:.1f} deg)", "")]
        applies = False
        points = []
        for label, w in widths:
            v = area * w
            inside = lo <= v <= hi
            applies = applies or inside
            rel = corominas_h_over_l(v)
            points.append((f"W = {w:.3g} m", v))
            rows.append((f"V = A x W, W = {label}: V = {v:.3g} m3", "",
                         f"{rel:.3g} ({math.degrees(math.atan(rel)):.1f} deg)"
                         + ("" if inside else " - outside the data")))
        out.append({
            "name": "Volume and travel angle of landslides", "source": COROMINAS_1996["source"],
            "applies": applies, "points": points, "area_m2_per_m": area,
            "assumption": (f"a 2D section has no width: the volume is the source's area "
                           f"({area:.3g} m2/m) times an assumed width W, shown for the widths listed; "
                           "the regression spans natural landslides of about 1e1 to 1e10 m3 and its "
                           "scatter is large (a factor of about 2 in H/L)"),
            "rows": rows,
            "note": "" if applies else "this run's volume lies outside the data of the regression: not applicable",
        })
    return out


# --------------------------------------------------------------------------------------------
# pictures


def _figure(width_in: float, height_in: float):
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    fig = Figure(figsize=(width_in, height_in), dpi=110, layout="constrained")
    FigureCanvasAgg(fig)
    return fig


def _target_lines(ax, doc: Mapping[str, Any], label: bool = False) -> None:
    for name, t in (doc.get("targets") or {}).items():
        ax.axvline(t["x_m"], color="tab:red", lw=0.9, ls="--", alpha=0.8)
        if label:
            y = ax.get_ylim()[1]
            ax.annotate(name, (t["x_m"], y), xytext=(2, -10), textcoords="offset points", color="tab:red",
                        fontsize=8, rotation=90, va="top")


def water_lines(project: Any, summary: Mapping[str, Any]) -> list[tuple[str, Any, Any]]:
    """The water lines a report draws on the section: (label, phreatic line, free-water line or
    None), each (K, 2) m: at the start, at the end of the run where a stage moved it, and at the
    failure where ``summary.json`` has ``water_at_failure``."""
    if project is None or getattr(project, "water", None) is None:
        return []
    from projects.build import solver_water

    waters = solver_water(project)
    out = [("water at the start", waters[0].phreatic_line_m, waters[0].free_water_line_m)]
    failure = summary.get("water_at_failure")
    if isinstance(failure, Mapping) and failure.get("phreatic_line_m"):
        out.append((f"water at the failure (t = {_fmt(failure.get('time_s'), 's')})", failure["phreatic_line_m"],
                    failure.get("free_water_line_m")))
    if waters[-1] != waters[0]:
        out.append(("water at the end", waters[-1].phreatic_line_m, waters[-1].free_water_line_m))
    return out


#: How each of :func:`water_lines` is drawn: colour and line style.
_WATER_STYLES = (("#1565c0", "-"), ("#c2185b", "-."), ("#1565c0", "--"))


def _water_on(ax, water: Sequence[tuple[str, Any, Any]], x_range: tuple[float, float],
              ground: tuple[Any, Any] | None = None) -> None:
    """Draw the water lines on a section's axes; the first one's free water shaded above ``ground``
    (x, y of the ground surface)."""
    from app.render import water_line_across

    x0, x1 = x_range
    for k, (label, phreatic, free) in enumerate(water):
        color, style = _WATER_STYLES[min(k, len(_WATER_STYLES) - 1)]
        line = water_line_across(phreatic, x0, x1)
        ax.plot(line[:, 0], line[:, 1], color=color, ls=style, lw=1.6, label=f"phreatic line, {label}")
        if free is not None:
            level = water_line_across(free, x0, x1)
            ax.plot(level[:, 0], level[:, 1], color="#0b8fd6", ls=style, lw=1.0, label=f"free-water line, {label}")
        else:
            level = line
        if k == 0 and ground is not None:
            gx, gy = (np.asarray(v, dtype=float) for v in ground)
            wy = np.interp(gx, level[:, 0], level[:, 1])
            ax.fill_between(gx, gy, wy, where=wy > gy, color="#a9d8f7", alpha=0.8, step="mid", lw=0,
                            label="free water")


def profiles_png(doc: Mapping[str, Any], path: Path,
                 structures: Sequence[Mapping[str, Any]] | None = None,
                 water: Sequence[tuple[str, Any, Any]] | None = None) -> Path:
    """Envelope profiles along the section, targets and run-out points marked; ``structures``
    (``summary.json``'s) drawn on the surfaces, and the ``water`` lines (:func:`water_lines`)."""
    p = doc["profile"]
    x = p["x_m"]
    fig = _figure(9.0, 10.5)
    axes = fig.subplots(5, 1, sharex=True)
    ax = axes[0]
    ax.fill_between(x, p["floor_m"], p["ground_m"], color="0.85", step="mid", label="material at the release")
    structure_patches(ax, structures)
    if water:
        _water_on(ax, water, (float(x[0]), float(x[-1])), (x, p["ground_m"]))
    ax.step(x, p["ground_m"] + p["peak_flow_height_m"], where="mid", color="tab:orange",
            label="ground + peak flow height")
    ax.step(x, p["surface_m"], where="mid", color="tab:brown", lw=1.6, label="surface at the end")
    for key, marker, lab in (("runout_point_m", "v", "run-out (deposit)"),):
        if doc.get(key):
            ax.plot(*doc[key], marker=marker, color="k", ms=8, ls="none", label=lab)
    if doc.get("runout_x_envelope_m") is not None:
        ax.axvline(doc["runout_x_envelope_m"], color="tab:orange", lw=0.8, ls=":", label="run-out (peak height)")
    if doc.get("source_top_m"):
        ax.plot(*doc["source_top_m"], marker="^", color="k", ms=7, ls="none", label="source top")
        if doc.get("runout_point_m"):
            (xa, ya), (xb, yb) = doc["source_top_m"], doc["runout_point_m"]
            ax.plot([xa, xb], [ya, yb], color="k", lw=0.8, ls="--",
                    label=f"travel angle {doc['travel_angle_deg']:.1f} deg" if doc.get("travel_angle_deg") else None)
    ax.set_ylabel("height y (m)")
    ax.set_title("Surfaces")
    # above the plots, not in them: in the upper right corner it covered the names of the targets
    # downstream, where they usually are
    fig.legend(*ax.get_legend_handles_labels(), fontsize=7, loc="outside upper center", ncols=4)
    _target_lines(ax, doc, label=True)
    panels = [
        (axes[1], p["peak_flow_height_m"], "peak flow height (m)", "tab:orange", 1.0),
        (axes[2], p["max_speed_m_s"], "max speed (m/s)", "tab:blue", 1.0),
        (axes[3], p["max_pressure_pa"], "max impact pressure (kPa)", "tab:purple", 1e-3),
    ]
    for a, values, label, colour, scale in panels:
        a.step(x, np.asarray(values) * scale, where="mid", color=colour)
        a.fill_between(x, 0, np.asarray(values) * scale, step="mid", color=colour, alpha=0.25)
        a.set_ylabel(label)
        _target_lines(a, doc)
    a = axes[4]
    deposit = p["deposit_m"]
    a.bar(x, deposit, width=x[1] - x[0] if len(x) > 1 else 1.0,
          color=np.where(deposit >= 0, "tab:green", "tab:gray"))
    a.axhline(doc["thresholds"]["deposit_threshold_m"], color="tab:green", lw=0.8, ls=":",
              label=f"threshold {doc['thresholds']['deposit_threshold_m']:.3g} m")
    a.set_ylabel("deposit (m)")
    a.legend(fontsize=7, loc="upper right")
    a2 = a.twinx()
    arr = p["arrival_s"]
    a2.plot(x, arr, color="k", marker=".", ms=3, lw=0.8)
    a2.set_ylabel("arrival time (s)")
    _target_lines(a, doc)
    a.set_xlabel("x (m)")
    fig.savefig(path)
    return path


def energy_png(series: Mapping[str, np.ndarray], doc: Mapping[str, Any], path: Path) -> Path:
    """Kinetic energy and the fastest particle against time (frames and envelope updates)."""
    fig = _figure(9.0, 4.2)
    ax = fig.subplots()
    env = doc.get("series") or {}
    if len(env.get("time_s", [])):
        ax.plot(env["time_s"], env["kinetic_energy_J_per_m"], color="tab:blue", lw=1.0,
                label="kinetic energy (envelope updates)")
    if len(series.get("time_s", [])):
        ax.plot(series["time_s"], series["kinetic_energy_J_per_m"], "o", color="tab:blue", ms=3,
                label="kinetic energy (frames, series.csv)")
    if doc.get("peak_kinetic_energy_time_s") is not None:
        ax.axvline(doc["peak_kinetic_energy_time_s"], color="tab:blue", ls=":", lw=0.8, label="peak")
    if doc.get("slide_end_time_s") is not None:
        ax.axvline(doc["slide_end_time_s"], color="k", ls="--", lw=0.8,
                   label=f"slide ended ({doc['thresholds']['kinetic_energy_fraction']:g} of the peak)")
    ax.set_xlabel("time (s)")
    ax.set_ylabel("kinetic energy (J/m)")
    ax2 = ax.twinx()
    if len(env.get("time_s", [])):
        ax2.plot(env["time_s"], env["max_speed_m_s"], color="tab:orange", lw=1.0, label="fastest particle")
    elif len(series.get("time_s", [])):
        ax2.plot(series["time_s"], series["max_speed_m_s"], color="tab:orange", lw=1.0, label="fastest particle")
    ax2.set_ylabel("speed (m/s)", color="tab:orange")
    h1, l1 = ax.get_legend_handles_labels()
    h2, l2 = ax2.get_legend_handles_labels()
    ax.legend(h1 + h2, l1 + l2, fontsize=7, loc="upper right")
    fig.savefig(path)
    return path


def targets_png(doc: Mapping[str, Any], path: Path) -> Path | None:
    """Each target's height, speed and pressure against time."""
    names = list(doc.get("targets") or {})
    env = doc.get("series") or {}
    if not names or not len(env.get("time_s", [])):
        return None
    fig = _figure(9.0, 6.5)
    axes = fig.subplots(3, 1, sharex=True)
    t = env["time_s"]
    for name in names:
        for ax, q, scale in zip(axes, ("height_m", "speed_m_s", "pressure_pa"), (1.0, 1.0, 1e-3)):
            ax.plot(t, env[f"{name}:{q}"] * scale, label=name)
        arrival = doc["targets"][name]["arrival_time_s"]
        if arrival is not None:
            axes[0].axvline(arrival, ls=":", lw=0.8, color=axes[0].lines[-1].get_color())
    axes[0].set_ylabel("flow height (m)")
    axes[1].set_ylabel("speed (m/s)")
    axes[2].set_ylabel("impact pressure (kPa)")
    axes[2].set_xlabel("time (s)")
    axes[0].legend(fontsize=8, loc="upper right")
    fig.savefig(path)
    return path


def contacts_png(contacts: Mapping[str, Mapping[str, np.ndarray]], path: Path,
                 structures: Sequence[str] = ()) -> Path | None:
    """The forces against time, one plot per structure that took any (in ``structures``' order)
    and one for the closed sides together, each with its own scale (a base carrying the whole
    weight, MN per metre, no longer flattens a dam's kN): the interval-mean normal and tangential
    parts (on the face that carries the force; a side's along its axes) and the largest force of
    a step in each interval, kN/m, drawn as steps over the interval each value belongs to."""
    from app.render import CONTACT_COLORS
    from solver.config import SIDES

    def took(cols: Mapping[str, np.ndarray]) -> bool:
        peak = np.nan_to_num(np.asarray(cols.get("peak_force_N_per_m", []), dtype=float))
        return len(peak) > 0 and float(np.abs(peak).max(initial=0.0)) > 0.0

    names = [n for n in structures if n in contacts and took(contacts[n])]
    names += [n for n in contacts if n not in SIDES and n not in names and took(contacts[n])]
    sides = [n for n in SIDES if n in contacts and took(contacts[n])]
    panels = [(n, [n]) for n in names] + ([("closed sides: " + ", ".join(sides), sides)] if sides else [])
    if not panels:
        return None
    fig = _figure(9.0, 1.0 + 2.1 * len(panels))
    axes = np.atleast_1d(fig.subplots(len(panels), 1, sharex=True))
    colours = {n: CONTACT_COLORS[i % len(CONTACT_COLORS)] for i, n in enumerate(contacts)}
    for ax, (title, group) in zip(axes, panels, strict=True):
        for name in group:
            cols = contacts[name]
            t = np.asarray(cols["time_s"], dtype=float)
            colour = colours[name]
            label = name if len(group) > 1 else ""
            normal = np.asarray(cols.get("force_normal_N_per_m", np.full(len(t), np.nan)), dtype=float)
            tangential = np.asarray(cols.get("force_tangential_N_per_m", np.full(len(t), np.nan)), dtype=float)
            peak = np.asarray(cols["peak_force_N_per_m"], dtype=float)
            ax.plot(t, peak * 1e-3, color=colour, lw=0.8, alpha=0.45, drawstyle="steps-pre",
                    label=f"{label + ': ' if label else ''}peak |F| of a step")
            if np.isfinite(normal).any():
                ax.plot(t, normal * 1e-3, color=colour, lw=1.5, drawstyle="steps-pre",
                        label=f"{label + ': ' if label else ''}mean normal")
                ax.plot(t, tangential * 1e-3, color=colour, lw=1.2, ls="--", drawstyle="steps-pre",
                        label=f"{label + ': ' if label else ''}mean tangential")
        ax.set_title(title, fontsize=9, loc="left")
        ax.set_ylabel("kN/m")
        ax.axhline(0.0, color="#9aa0a6", lw=0.6)
        ax.grid(alpha=0.3)
        ax.legend(fontsize=7, loc="upper left", ncol=3 if len(group) == 1 else 2, framealpha=0.8)
    axes[-1].set_xlabel("time (s)")
    fig.savefig(path)
    return path


def context_png(ctx: list[dict[str, Any]], doc: Mapping[str, Any], path: Path) -> Path | None:
    """The empirical relations as curves, this run as a point."""
    if not ctx:
        return None
    fig = _figure(9.0, 3.8)
    axes = fig.subplots(1, len(ctx), squeeze=False)[0]
    for ax, item in zip(axes, ctx):
        pts = item["points"]
        if isinstance(pts, dict):  # Lube et al.
            aa = np.geomspace(0.2, 20.0, 200)
            ax.loglog(aa, [lube_runout(v) for v in aa], color="k", lw=1, label="(L_inf - L0)/L0, Lube et al.")
            ax.loglog(aa, [lube_height(v) for v in aa], color="0.5", lw=1, label="H_inf/L0, Lube et al.")
            if pts["runout"] is not None and pts["runout"] > 0:
                ax.loglog([pts["a"]], [pts["runout"]], "o", color="tab:red", label="this run: run-out")
            if pts["height"] is not None and pts["height"] > 0:
                ax.loglog([pts["a"]], [pts["height"]], "s", color="tab:orange", label="this run: final height")
            ax.set_xlabel("aspect ratio a = H0 / L0")
            ax.legend(fontsize=7)
        else:  # Corominas
            lo, hi = COROMINAS_1996["volume_range_m3"]
            vmin = min([1e-3] + [v / 10 for _, v in pts])
            v = np.geomspace(vmin, hi, 200)
            ax.loglog(v, [corominas_h_over_l(x) for x in v], color="k", lw=1, label="Corominas (1996)")
            ax.axvspan(vmin, lo, color="0.9", label="outside the data")
            for label, vol in pts:
                ax.loglog([vol], [doc["h_over_l"]], "o", label=f"this run, {label}")
            ax.set_xlabel(f"volume V = {item['area_m2_per_m']:.3g} m2/m x W (m3)")
            ax.set_ylabel("H / L")
            ax.legend(fontsize=7)
        ax.set_title(item["name"], fontsize=9)
    fig.savefig(path)
    return path


# --------------------------------------------------------------------------------------------
# HTML


def _fmt(value: Any, unit: str = "", digits: int = 4) -> str:
    if value is None:
        return "-"
    if isinstance(value, bool):
        return "yes" if value else "no"
    if isinstance(value, (int, float)):
        if isinstance(value, float) and not math.isfinite(value):
            return "-"
        text = f"{value:.{digits}g}"
        return f"{text} {unit}".strip()
    if isinstance(value, (list, tuple)):
        return "(" + ", ".join(_fmt(v, "", digits) for v in value) + ")" + (f" {unit}" if unit else "")
    return str(value)


def _table(header: list[str], rows: list[list[str]]) -> str:
    head = "".join(f"<th>{html.escape(h)}</th>" for h in header)
    body = "".join("<tr>" + "".join(f"<td>{html.escape(str(c))}</td>" for c in r) + "</tr>" for r in rows)
    return f"<table><thead><tr>{head}</tr></thead><tbody>{body}</tbody></table>"


def _img(path: Path | None, alt: str) -> str:
    if path is None:
        return ""
    data = base64.b64encode(path.read_bytes()).decode("ascii")
    return (f'<figure><img alt="{html.escape(alt)}" src="data:image/png;base64,{data}">'
            f"<figcaption>{html.escape(alt)} ({html.escape(path.name)})</figcaption></figure>")


def _read_contacts(path: Path) -> dict[str, dict[str, np.ndarray]]:
    """``contacts.csv`` of the results (empty where there is none or it does not read)."""
    from projects.results import read_contacts

    if not path.is_file():
        return {}
    try:
        return read_contacts(path)
    except (OSError, ValueError, KeyError, IndexError) as err:
        logger.warning("contacts.csv not read: %s", err)
        return {}


def _contacts(results_dir: Path, peaks: Mapping[str, Mapping[str, Any]]) -> list[list[str]]:
    """Per contact that took any force, the structures first (:func:`projects.results.force_table`):
    the largest single-step force with its normal and tangential parts and time,
    the largest interval-mean normal and tangential forces with their times, and a point of the
    largest mean force's line of action (``summary.json``, where the run wrote one)."""
    from projects.results import force_table

    try:
        rows = force_table(results_dir)
    except (OSError, ValueError, KeyError, IndexError) as err:
        logger.warning("contacts.csv not read: %s", err)
        return []
    def scale(value: Any) -> tuple[float, str]:  # kN/m from 1 kN/m up, else N/m (a laboratory's forces)
        v = float(value) if value is not None else math.nan
        return (1e3, "kN/m") if math.isfinite(v) and abs(v) >= 1e3 else (1.0, "N/m")

    def number(value: Any, factor: float) -> str:
        return "-" if value is None or not math.isfinite(float(value)) else f"{float(value) / factor:.3g}"

    def force(value: Any) -> str:
        factor, unit = scale(value)
        text = number(value, factor)
        return text if text == "-" else f"{text} {unit}"

    out = []
    for r in rows:
        name = str(r["contact"])
        point = (peaks.get(name) or {}).get("max_mean_force_point_m")
        factor, _unit = scale(r["peak_force_N_per_m"])
        out.append([name if r["kind"] == "structure" else f"{name} (side)",
                    f"{force(r['peak_force_N_per_m'])} (N {number(r['peak_force_normal_N_per_m'], factor)}, "
                    f"T {number(r['peak_force_tangential_N_per_m'], factor)})", _fmt(r["peak_time_s"], "s", 3),
                    force(r["max_normal_force_N_per_m"]),
                    _fmt(r["max_normal_force_time_s"], "s", 3) if r["max_normal_force_N_per_m"] is not None else "-",
                    force(r["max_tangential_force_N_per_m"]),
                    _fmt(r["max_tangential_force_time_s"], "s", 3) if r["max_tangential_force_N_per_m"] is not None
                    else "-", _fmt(point, "m") if point else "-"])
    return out


_CSS = """
body { font-family: sans-serif; max-width: 1000px; margin: 2em auto; color: #222; }
h1 { font-size: 1.5em; } h2 { font-size: 1.2em; border-bottom: 1px solid #ccc; margin-top: 1.6em; }
table { border-collapse: collapse; margin: 0.5em 0; font-size: 0.9em; }
th, td { border: 1px solid #ccc; padding: 3px 8px; text-align: left; }
th { background: #f2f2f2; } img { max-width: 100%; } figure { margin: 0.6em 0; }
figcaption { font-size: 0.8em; color: #666; } .note { font-size: 0.85em; color: #555; }
.scene { display: flex; gap: 1%; } .scene figure { width: 49.5%; }
.provisional { border: 2px solid #e37400; background: #fff4e5; padding: 0.5em 0.8em; }
.final { border-left: 4px solid #188038; padding: 0.2em 0.8em; }
"""

MEASURES = [
    ("runout_distance_m", "run-out distance (deposit, from the source front)", "m", "deposit_threshold_m"),
    ("runout_x_m", "run-out point x (deposit)", "m", "deposit_threshold_m"),
    ("runout_distance_envelope_m", "run-out distance (peak-height envelope)", "m", "flow_height_threshold_m"),
    ("travel_angle_deg", "travel angle (Fahrboeschung)", "deg", "deposit_threshold_m"),
    ("h_over_l", "H / L", "", "deposit_threshold_m"),
    ("drop_height_m", "drop height H (source top to run-out point)", "m", ""),
    ("travel_length_m", "travel length L", "m", ""),
    ("mobilised_area_m2_per_m", "mobilised area", "m2/m", "mobilised_displacement_m"),
    ("source_area_m2_per_m", "source area (mobilised and descended)", "m2/m", "mobilised_displacement_m"),
    ("centroid_travel_angle_deg", "centroid travel angle", "deg", "mobilised_displacement_m"),
    ("slide_duration_s", "slide duration (from the release)", "s", "kinetic_energy_fraction"),
    ("peak_kinetic_energy_J_per_m", "peak kinetic energy", "J/m", ""),
    ("max_flow_height_m", "largest flow height", "m", ""),
    ("max_speed_m_s", "largest speed", "m/s", ""),
    ("max_pressure_pa", "largest impact pressure", "kPa", ""),
]


def measure_value(doc: Mapping[str, Any], key: str, unit: str) -> Any:
    """The value of measure ``key`` of ``hazard.json`` in the unit :data:`MEASURES` shows it in
    (pressures are stored in Pa and shown in kPa, as in every plot)."""
    value = doc.get(key)
    if unit == "kPa" and isinstance(value, (int, float)) and not isinstance(value, bool):
        return value * 1e-3
    return value


def project_source(summary: Mapping[str, Any]) -> str:
    """The project a run stands for, as its ``summary.json`` records it: the file, with a note
    when the workbench ran edits not saved in it, or "unsaved project" (never the temporary copy
    the workbench starts its runs from); "-" for a folder that records nothing."""
    path = summary.get("project_file")
    if summary.get("project_unsaved"):
        return f"{path}, with edits not saved in it" if path else "unsaved project"
    return str(path) if path else "-"


def line_text(line: Any) -> str:
    """A water line in words: ``level at y = 5 m`` or ``from y = 8 m at x = 0 m to y = 2 m at x = 40 m
    (points (0, 8), (20, 5), (40, 2))``."""
    pts = np.asarray(line, dtype=float).reshape(-1, 2)
    if not len(pts):
        return "-"
    if np.allclose(pts[:, 1], pts[0, 1], rtol=0.0, atol=1e-9):
        return f"level at y = {_fmt(pts[0, 1], 'm')}"
    listed = ", ".join(f"({pt[0]:.4g}, {pt[1]:.4g})" for pt in pts[:12]) + (", ..." if len(pts) > 12 else "")
    return (f"from y = {_fmt(pts[0, 1], 'm')} at x = {_fmt(pts[0, 0], 'm')} to y = {_fmt(pts[-1, 1], 'm')} at "
            f"x = {_fmt(pts[-1, 0], 'm')} (points {listed} m)")


def _stage_text(stage: Any, project: Any) -> str:
    stages = list(getattr(project, "stages", []) or [])
    if isinstance(stage, bool):
        return str(stage)
    if isinstance(stage, int) and 0 <= stage < len(stages):
        return f"stage {stage + 1} ({stages[stage].name or stages[stage].type})"
    if isinstance(stage, str):
        for i, st in enumerate(stages):
            if st.name == stage:
                return f"stage {i + 1} ({stage})"
        return f"stage {stage}"
    return "an unknown stage"


def water_sentences(project: Any, summary: Mapping[str, Any]) -> list[str]:
    """The report's words on the ground water: where it was at the start, where each stage moved
    it, and where it was when the slope failed (``summary.json`` ``water_at_failure``)."""
    out = []
    water = getattr(project, "water", None) if project is not None else None
    if water is not None:
        text = f"At the start the phreatic line is {line_text(water.phreatic_line_m)}"
        if water.free_water_line_m is not None:
            text += f", the free water {line_text(water.free_water_line_m)}"
        out.append(text + f" (unit weight of water {_fmt(water.unit_weight_n_m3 / 1000.0, 'kN/m3')}"
                   + (", inclined-line correction" if water.inclined_line_correction else "") + ").")
        for i, stage in enumerate(project.stages):
            move = stage.water
            if move is None:
                continue
            what = []
            if move.phreatic_line_m is not None:
                what.append(f"the phreatic line to {line_text(move.phreatic_line_m)}")
            if move.free_water_line_m is not None:
                what.append(f"the free water to {line_text(move.free_water_line_m)}")
            over = "at once" if stage.type == "k0" or not stage.duration_s else f"over {_fmt(stage.duration_s, 's')}"
            out.append(f"{_stage_text(i, project).capitalize()} moves {' and '.join(what)}, {over}.")
    if "water_at_failure" in summary:
        failure = summary.get("water_at_failure")
        if isinstance(failure, Mapping):
            text = (f"The slope failed at t = {_fmt(failure.get('time_s'), 's')}, in "
                    f"{_stage_text(failure.get('stage'), project)}, with the phreatic line "
                    f"{line_text(failure.get('phreatic_line_m') or [])}")
            if failure.get("free_water_line_m"):
                text += f" and the free water {line_text(failure['free_water_line_m'])}"
            out.append(text + ".")
        else:
            out.append("The slope did not fail under the water of this run.")
    return out


def load_rows(project: Any) -> list[list[str]]:
    """The loads of each stage for the report's table (projects.loads.describe): stage, load, where,
    pressure, resultant, how it is applied; one row per surcharge in force and one per stage's
    seismic coefficients. Empty for a project without loads."""
    if project is None:
        return []
    from projects.loads import describe

    try:
        stages = describe(project)
    except ValueError:
        return []
    if not any(row["surcharges"] or row["seismic"] for row in stages):
        return []
    rows = []
    for k, row in enumerate(stages):
        label = f"{k + 1}. {row['stage']}"
        kind = project.stages[k].type
        for load in row["surcharges"]:
            start, end = load["pressure_pa"]
            pressure = _fmt(start / 1e3, "kPa") if start == end else \
                f"{_fmt(start / 1e3)} to {_fmt(end / 1e3, 'kPa')}"
            how = ("ramped up with gravity" if kind == "gravity" else
                   "grows over the stage from the load in force before" if load["ramp"] else
                   "full value in the trials" if kind == "strength-reduction" else "at once")
            rows.append([label, f"surcharge {load['name']}", f"x = {_fmt(load['from_m'])} to {_fmt(load['to_m'], 'm')}",
                         pressure, _fmt(load["force_n_per_m"] / 1e3, "kN/m"), how])
        quake = row["seismic"]
        if quake is not None:
            rows.append([label, "seismic", f"k_h {_fmt(quake['k_h'])} towards {quake['direction']}"
                         + (" (out of the slope)" if quake["towards"] == "out-of-slope" else ""),
                         f"k_v {_fmt(quake['k_v'])}", "-", "this stage only"])
    return rows


def headline(doc: Mapping[str, Any], summary: Mapping[str, Any]) -> str:
    """The report's headline, whether its answer is final (HTML): provisional where the mass was
    still moving at the end of the run or the run did not complete (projects.motion), with the
    kinetic energy at the end as a fraction of its peak and the fastest particle; final where it
    came to rest."""
    from projects.motion import REMEDY, motion_text

    motion = doc.get("motion_at_end") or summary.get("motion_at_end")
    words = motion_text(motion) if isinstance(motion, Mapping) else ""
    if hazard_provisional(doc):
        if doc.get("status") != "completed":
            why = f"the run did not complete (status {doc.get('status')})"
        else:
            why = words or "the mass was still moving at the end of the run"
        return (f"<p class='provisional'><b>Provisional answer:</b> {html.escape(why)}. Every measure below is "
                "where the slide had got to when the run ended, not its run-out; "
                f"{html.escape(REMEDY)}.</p>")
    if words:
        return f"<p class='final'><b>Final answer:</b> the mass came to rest; {html.escape(words)}.</p>"
    return ""


def write_report(results: str | os.PathLike[str], out_dir: str | os.PathLike[str] | None = None,
                 *, scene_size: tuple[int, int] = (1200, 560)) -> Path:
    """Write the hazard report of a results folder.

    Parameters
    ----------
    results : path-like
        The results folder.
    out_dir : path-like, optional
        Where ``report.html`` and its PNGs go (default: ``RESULTS/report``).
    scene_size : (int, int)
        Pixel size of the scene pictures.

    Returns
    -------
    Path
        ``report.html``.

    Raises
    ------
    ResultsError
        The folder is not a results folder, or has no hazard files (``[hazard] enabled = false``,
        or no dynamic stage ran).
    """
    res = Results(results)
    if not (res.path / HAZARD_JSON).is_file():
        raise ResultsError(f"{res.path} has no {HAZARD_JSON}: the run wrote no hazard envelopes "
                           "(hazard.enabled = false, or no dynamic stage ran)")
    doc = read_hazard(res.path)
    summary = res.summary
    project = None
    if res.project_text:
        from projects.document import loads_project
        from projects.schema import ProjectError

        try:
            project = loads_project(res.project_text)
        except ProjectError as err:
            logger.warning("the results' project.toml does not load: %s", err)
    out = Path(out_dir) if out_dir is not None else res.path / REPORT_DIR
    from projects.results_folder import check_writable

    check_writable(out / "report.html")  # a read-only results folder: one line before any picture

    pictures: dict[str, Path | None] = {}
    if len(res):
        from app.render import render_frame

        have = set(res.frame(0).keys())
        before = "material" if "material_id" in have else ("displacement" if "displacement" in have else "velocity")
        after = "displacement" if "displacement" in have else before
        pictures["scene_before"] = render_frame(res, 0, before, out / "scene_before.png", size=scene_size)
        pictures["scene_after"] = render_frame(res, -1, after, out / "scene_after.png", size=scene_size)
    water = water_lines(project, summary)
    pictures["profiles"] = profiles_png(doc, out / "profiles.png", summary.get("structures"), water)
    pictures["energy"] = energy_png(res.series, doc, out / "energy.png")
    pictures["targets"] = targets_png(doc, out / "targets.png")
    contact_table = _read_contacts(res.path / CONTACTS_CSV)
    pictures["contacts"] = contacts_png(contact_table, out / "contacts.png",
                                        [st.get("name") for st in summary.get("structures") or []
                                         if isinstance(st, dict)])
    ctx = context(doc, project, summary)
    pictures["context"] = context_png(ctx, doc, out / "context.png")

    th = doc["thresholds"]
    title = summary.get("title") or res.path.name
    parts = [f"<!DOCTYPE html><html><head><meta charset='utf-8'><title>{html.escape(title)} - hazard report"
             f"</title><style>{_CSS}</style></head><body>",
             f"<h1>{html.escape(title)}: hazard report</h1>",
             f"<p>Results folder <code>{html.escape(str(res.path))}</code>; run status "
             f"<b>{html.escape(res.status)}</b>: {html.escape(res.message or '')}</p>"]

    parts.append(headline(doc, summary))

    parts.append("<h2>Measures</h2>")
    rows = []
    mark = " (provisional)" if hazard_provisional(doc) else ""
    for key, label, unit, thr in MEASURES:
        value = _fmt(measure_value(doc, key, unit), unit)
        rows.append([label, value + (mark if value != "-" else ""), f"{thr} = {_fmt(th[thr])}" if thr else ""])
    direction = doc.get("direction")
    rows.append(["run-out direction", {1: "+x", -1: "-x"}.get(direction, "-"), doc.get("direction_rule", "")])
    rows.append(["source top (crown)", _fmt(doc.get("source_top_m"), "m"), ""])
    rows.append(["source front x", _fmt(doc.get("source_front_x_m"), "m"), ""])
    ct = doc.get("centroid_travel_m") or {}
    rows.append(["centroid travel dx, dy", _fmt([ct.get("dx_m"), ct.get("dy_m")], "m"), ""])
    parts.append(_table(["measure", "value", "threshold / rule"], rows))
    if doc.get("note"):
        parts.append(f"<p class='note'>{html.escape(doc['note'])}</p>")
    parts.append("<p class='note'>Definitions: docs/project-format.md, \"Hazard files\". The release is the start "
                 f"of the first dynamic stage (t = {_fmt(doc.get('release_time_s'), 's')}); heights are along y "
                 "above the surface at the release. Envelopes are updated every "
                 f"{doc['sampling']['every_steps']} steps and at every frame ({doc['sampling']['updates']} updates): "
                 "a peak between updates is missed by at most its change over one interval, an arrival is late by "
                 "less than one interval.</p>")

    water_text = water_sentences(project, summary)
    if water_text:
        parts.append("<h2>Ground water</h2>")
        parts.extend(f"<p>{html.escape(t)}</p>" for t in water_text)
        parts.append("<p class='note'>The phreatic line is drawn blue in the pictures (dashed: at the end of the "
                     "run, dash-dotted: at the failure), the free water shaded light blue where it stands above "
                     "the ground; the scene pictures show the water of their frame's time.</p>")

    loads = load_rows(project)
    if loads:
        parts.append("<h2>Loads</h2>")
        parts.append(_table(["stage", "load", "where", "pressure / k_v", "resultant", "applied"], loads))
        parts.append("<p class='note'>Surcharges act along gravity on the ground's top particles under them, per "
                     "unit length of x, and stay in force until a stage changes them; seismic coefficients act in "
                     "their stage only: a horizontal force k_h W and a weight (1 - k_v) W on every mass "
                     "(docs/project-format.md, loads).</p>")

    parts.append("<h2>Scene before and after</h2><div class='scene'>")
    parts.append(_img(pictures.get("scene_before"), "the scene at the first frame"))
    parts.append(_img(pictures.get("scene_after"), "the scene at the last frame"))
    parts.append("</div>")

    parts.append("<h2>Envelopes along the section</h2>")
    parts.append(_img(pictures["profiles"], "surfaces, peak flow height, speed, impact pressure, deposit and "
                                            "arrival time along x; targets dashed red"))

    parts.append("<h2>Targets</h2>")
    trows = [[name, t["kind"], _fmt(t["x_m"], "m") + ("" if t["y_m"] is None else f", y {_fmt(t['y_m'], 'm')}"),
              _fmt(t["arrival_time_s"], "s") if t["arrival_time_s"] is not None else "never reached",
              _fmt(t["max_height_m"], "m"), _fmt(t["max_speed_m_s"], "m/s"),
              _fmt(measure_value(t, "max_pressure_pa", "kPa"), "kPa")]
             for name, t in (doc.get("targets") or {}).items()]
    if trows:
        parts.append(_table(["target", "kind", "place", "arrival", "max height", "max speed", "max pressure"], trows))
        parts.append(_img(pictures.get("targets"), "the targets' time series (targets.csv)"))
    else:
        parts.append("<p class='note'>No targets in the project ([[targets]]).</p>")
    contacts = _contacts(res.path, summary.get("contacts") or {}) if contact_table else []
    if contacts:
        parts.append("<h3>Forces on the structures and sides (contacts.csv)</h3>")
        parts.append("<p class='note'>The force the material exerts on each structure and closed side, N per "
                     "metre out of plane, as its normal part N (pressing on the face that carries it, positive) "
                     "and tangential part T (along that face: up a steep face, along +x a flat one; a side's along "
                     "its axes): the largest force of a single step with its parts, and the largest mean over an "
                     "output interval (the impulse over the interval divided by its length) of each part, with "
                     "the point of the largest mean force's line of action where it meets a side (the centre of "
                     "pressure) or nearest a structure's vertex mean (from its moment in contacts.csv).</p>")
        parts.append(_table(["contact", "peak force of a step (N, T)", "at", "largest mean normal", "at",
                             "largest mean tangential", "at", "acts through"], contacts))
        parts.append(_img(pictures.get("contacts"), "the forces against time, each structure on its own scale, "
                                                    "the closed sides together (contacts.csv)"))

    parts.append("<h2>Energy</h2>")
    parts.append(_img(pictures["energy"], "kinetic energy and the fastest particle (series.csv and the envelope "
                                          "updates)"))

    parts.append("<h2>Context from experience</h2>")
    parts.append("<p class='note'>Empirical relations engineers check a run against. Context, not a verdict: "
                 "they hold for the conditions of their data, stated with each.</p>")
    if not ctx:
        parts.append("<p class='note'>None applies to this run (not a column collapse, nothing mobilised).</p>")
    for item in ctx:
        parts.append(f"<h3>{html.escape(item['name'])}</h3><p class='note'>Source: {html.escape(item['source'])}. "
                     f"Assumption: {html.escape(item['assumption'])}.</p>")
        parts.append(_table(["quantity", "this run", "relation"], [list(r) for r in item["rows"]]))
        if item["note"]:
            parts.append(f"<p class='note'>{html.escape(item['note'])}</p>")
    parts.append(_img(pictures.get("context"), "this run against the relations"))

    parts.append("<h2>Settings and provenance</h2>")
    dom = summary.get("domain") or {}
    prov = [
        ["Runout version", summary.get("runout_version", "-")],
        ["scheme", summary.get("scheme", "-")],
        ["arch / precision", f"{summary.get('arch', '-')} / {summary.get('precision', '-')}"],
        ["particles", _fmt(summary.get("particles"))],
        ["grid cell", _fmt(dom.get("cell_size_m"), "m")],
        ["particle spacing", _fmt(summary.get("particle_spacing_m"), "m")],
        ["domain", f"origin {_fmt(dom.get('origin_m'), 'm')}, size {_fmt(dom.get('size_m'), 'm')}"],
        ["steps", _fmt(summary.get("steps"))],
        ["simulated time", _fmt(summary.get("simulated_time_s"), "s")],
        ["wall time", _fmt(summary.get("wall_time_s"), "s")],
        ["started / finished", f"{summary.get('started_at', '-')} / {summary.get('finished_at', '-')}"],
        ["stages", ", ".join(summary.get("stages") or [])],
        ["materials", ", ".join(summary.get("materials") or [])],
        ["project file", project_source(summary)],
        ["hazard raster", f"{doc['raster']['shape'][0]} x {doc['raster']['shape'][1]} cells of "
                          f"{_fmt(doc['raster']['cell_size_m'], 'm')}"],
        ["thresholds", ", ".join(f"{k} = {_fmt(v)}" for k, v in th.items())],
    ]
    parts.append(_table(["setting", "value"], [[a, str(b)] for a, b in prov]))
    if res.project_text:
        parts.append("<details><summary>project.toml (the resolved project that ran)</summary><pre>"
                     f"{html.escape(res.project_text)}</pre></details>")
    parts.append("</body></html>")
    path = out / REPORT_HTML
    from projects.atomic import write_atomic

    write_atomic(path, "\n".join(parts))
    logger.info("wrote %s", path)
    return path
