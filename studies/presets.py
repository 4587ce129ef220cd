"""``runout study presets``: the numerics presets measured afresh on the aluminium-bar scene.

The part of the tradeoff sweep (:mod:`studies.tradeoff`) that the presets are chosen from:
apic-affine at 2 x 2 particles per cell over the cell sizes, two time steps and one particle per
cell, against a reference at 1.25 mm cells (:func:`studies.tradeoff.preset_settings`), run twice:
on the shipped scene (its mu(I) law) and on the source paper's rate-independent model
(:func:`studies.bui2008_choices.paper`), whose thin tail converges more slowly. Each preset is the
cheapest setting (by the shipped scene's wall time, time step at most
:data:`studies.tradeoff.PRESET_MAX_CFL` of the critical one) within
:data:`studies.tradeoff.PRESET_CRITERIA` of its reference in both, so that a preset holds for
rate-independent materials too. Writes both sweeps' reports (the second under
``rate-independent/``) and ``presets.json`` of both; copy it to ``projects/presets.json`` to ship
what it chose.
"""

from __future__ import annotations

import json
import math
from pathlib import Path
from typing import Any

from studies.bui2008_choices import paper
from studies.common import Note, StudyResult, fmt, quiet, write_json
from studies.tradeoff import PRESET_CRITERIA, PRESET_MAX_CFL, PRESET_SCHEMES
from studies.tradeoff import run as run_tradeoff

_ERRORS = ("rms_vs_ref_m", "reach_vs_ref_m", "crest_vs_ref_m", "toe_vs_ref_m")


def combine(shipped: list[dict[str, Any]], rate_independent: list[dict[str, Any]]) -> dict[str, dict[str, Any] | None]:
    """The presets over both sweeps: per preset the cheapest shipped-scene row whose errors, and
    those of the same setting on the rate-independent model, are within the criteria."""
    other = {r["label"]: r for r in rate_independent}
    out: dict[str, dict[str, Any] | None] = {}
    for name, limits in PRESET_CRITERIA.items():
        ok = []
        for r in shipped:
            o = other.get(r["label"])
            if (o is None or r["scheme"] not in PRESET_SCHEMES or r["cfl"] > PRESET_MAX_CFL + 1e-12
                    or r.get("is_reference") or r["status"] != "completed" or o["status"] != "completed"):
                continue
            if all(max(r.get(k, math.inf), o.get(k, math.inf)) <= v for k, v in limits.items()):
                ok.append((r, o))
        out[name] = None
        if ok:
            r, o = min(ok, key=lambda pair: pair[0]["wall_s"])
            out[name] = {"row": r, "rate_independent": o}
    return out


def run(out_dir: Path, quick: bool = False, note: Note = quiet) -> StudyResult:
    """Run both presets sweeps (``quick`` has no smaller version) and choose the presets."""
    out_dir = Path(out_dir)
    first = run_tradeoff(out_dir, note=note, presets_only=True)
    second = run_tradeoff(out_dir / "rate-independent", note=note, presets_only=True, change=paper)
    rows = json.loads((out_dir / "tradeoff.json").read_text())["rows"]
    other = json.loads((out_dir / "rate-independent" / "tradeoff.json").read_text())["rows"]
    chosen = combine(rows, other)
    std = (chosen.get("standard") or {}).get("row")
    presets: dict[str, Any] = {
        "format": 1,
        "source": ("runout study presets: aluminium-bar collapse (Bui et al. 2008), the shipped scene and the "
                   "source paper's rate-independent model, errors against the finest apic-affine run of each"),
        "resolution": "cells_per_height = height of the smallest body / cell size (the block is 0.1 m high)",
        "criteria_m": PRESET_CRITERIA,
        "presets": {},
    }
    lines = ["", "## Presets over both scenes", "",
             "The presets shipped (`presets.json`): each the cheapest setting within its criteria against the "
             "reference in both sweeps, this one and `rate-independent/report.md` (the source paper's "
             "rate-independent model). The table \"Presets\" above is this sweep's choice alone.", "",
             "| preset | cells per height | ppc | cfl | RMS vs ref (mm): shipped / rate-independent | "
             "reach vs ref (mm) | toe vs ref (mm) | RMS vs experiment (mm) | wall (s) | relative wall time |",
             "|---|---|---|---|---|---|---|---|---|---|"]
    for name, pick in chosen.items():
        if pick is None:
            presets["presets"][name] = None
            lines.append(f"| {name} | none meets the criteria | | | | | | | | |")
            continue
        r, o = pick["row"], pick["rate_independent"]
        presets["presets"][name] = {
            "scheme": r["scheme"], "per_cell": int(r["per_cell"]), "cfl": r["cfl"],
            "cells_per_height": r["cells_per_height"], "cell_size_m_in_study": r["cell_mm"] / 1e3,
            "measured": {
                **{f"{k[:-2]}_mm": 1e3 * max(r[k], o[k]) for k in _ERRORS},
                "rms_vs_experiment_mm": 1e3 * r["rms_vs_exp_m"], "toe_m": r.get("toe_m"), "reach_m": r.get("reach_m"),
                "crest_m": r.get("crest_m"), "wall_s": r["wall_s"], "particle_steps": r["particle_steps"],
                "rate_independent": {f"{k[:-2]}_mm": 1e3 * o[k] for k in _ERRORS} | {
                    "rms_vs_experiment_mm": 1e3 * o["rms_vs_exp_m"], "toe_m": o.get("toe_m")},
                "relative_wall_time": r["wall_s"] / std["wall_s"] if std else None,
                "relative_particle_steps": r["particle_steps"] / std["particle_steps"] if std else None,
            },
        }
        lines.append(f"| {name} | {r['cells_per_height']:g} | {int(r['per_cell']) ** 2} | {r['cfl']:g} | "
                     f"{fmt(1e3 * r['rms_vs_ref_m'])} / {fmt(1e3 * o['rms_vs_ref_m'])} | "
                     f"{fmt(1e3 * max(r['reach_vs_ref_m'], o['reach_vs_ref_m']))} | "
                     f"{fmt(1e3 * max(r['toe_vs_ref_m'], o['toe_vs_ref_m']))} | {fmt(1e3 * r['rms_vs_exp_m'])} | "
                     f"{fmt(r['wall_s'])} | {fmt(r['wall_s'] / std['wall_s'] if std else math.nan)} |")
    write_json(out_dir / "presets.json", presets)
    report = out_dir / "report.md"
    report.write_text(report.read_text() + "\n".join(lines) + "\n")
    passed = first.passed and second.passed and all(v is not None for v in chosen.values())
    verdict = [f"presets {'PASS' if passed else 'FAIL'} (two sweeps of 8 runs)"] + [
        f"{n}: " + (f"{p['row']['cells_per_height']:g} cells per height, cfl {p['row']['cfl']:g}" if p else "none")
        for n, p in chosen.items()]
    return StudyResult("presets", passed, verdict, report, first.wall_s + second.wall_s,
                       {"presets": presets})
