"""Hazard results of a run: settings, run-out measures and the files ``hazard.json``,
``hazard_profile.csv``, ``targets.csv`` and ``hazard.vti`` (docs/project-format.md, "Hazard").

The envelopes themselves are accumulated on the device by :mod:`solver.envelopes`; this module
resolves the ``[hazard]`` and ``[[targets]]`` keys of a project into the solver's
:class:`~solver.config.EnvelopeConfig` and the thresholds of the measures (:func:`settings`),
computes the measures from an envelope snapshot (:func:`measures`, numpy only) and writes the
files (atomically; :class:`HazardOutput` writes them with every frame and at the end).

Definitions (all thresholds are in ``hazard.json`` under ``thresholds``):

- **release**: the start of the first dynamic stage. The *ground* is the material surface then
  (or the grid's bottom where there is no material); heights are measured along y.
- **mobilised** particles: those that moved more than ``mobilised_displacement_m`` between the
  release and now (and are still in the domain). Mobilised area: their area at the release (m2
  per m of width); its centroid's travel from the release to now.
- **run-out direction**: the sign of the mobilised particles' mean (volume-weighted) displacement
  along x: +1 (towards +x) or -1.
- **source**: the mobilised particles that also descended (along gravity) by more than
  ``mobilised_displacement_m``, at the release (all mobilised particles when none descended, as in
  motion along the level); material pushed along or heaved up in front of a slide is mobilised but
  not source. Its *front* is their outermost edge along the run-out direction; its *top* (the crown) is the highest point of their squares (of the tops
  level with it within a quarter of a particle, the rearmost, at its rear edge).
- **deposit**: the surface now less the ground (m; negative where material left).
  ``runout_x_m``: the outermost particle edge, along the run-out direction, of the farthest
  raster column whose deposit exceeds ``deposit_threshold_m``; ``runout_distance_m`` its distance
  from the source front along the run-out direction (Lube et al. 2005's ``L_inf - L_0`` for a
  column). The same from the peak-flow-height envelope (columns ever thicker than
  ``flow_height_threshold_m``): ``runout_x_envelope_m``, ``runout_distance_envelope_m``.
- **travel angle** (Fahrboeschung): the angle below the horizontal of the line from the source top
  to the run-out point (``runout_x_m`` on the ground); ``drop_height_m`` H and
  ``travel_length_m`` L are measured along and across gravity; ``h_over_l`` = H / L.
- **slide duration**: from the release to the first update after the kinetic-energy peak at
  which the kinetic energy is below ``kinetic_energy_fraction`` of the peak (null: still moving).
"""

from __future__ import annotations

import csv
import functools
import io
import json
import logging
import math
import threading
from collections.abc import Callable, Mapping
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from projects.atomic import write_atomic
from projects.results import _encode_array, runout_version
from solver import config as sc

if TYPE_CHECKING:  # pragma: no cover - typing only
    from projects.schema import Project

logger = logging.getLogger(__name__)

HAZARD_JSON = "hazard.json"
PROFILE_CSV = "hazard_profile.csv"
TARGETS_CSV = "targets.csv"
HAZARD_VTI = "hazard.vti"

#: Columns of ``hazard_profile.csv`` (one row per raster column along x).
PROFILE_COLUMNS: tuple[str, ...] = (
    "x_m", "x_lo_m", "x_hi_m", "floor_m", "ground_m", "surface_m", "peak_flow_height_m", "deposit_m",
    "arrival_s", "max_speed_m_s", "max_energy_J_m3", "max_pressure_pa",
)

DIRECTION_RULE = ("sign of the volume-weighted mean displacement along x of the mobilised particles "
                  "(+1: towards +x, -1: towards -x)")


@dataclass(frozen=True)
class HazardSettings:
    """The resolved ``[hazard]`` keys (defaults filled in from the scene).

    Attributes
    ----------
    enabled : bool
    cell_size_m : float
        Raster cell (default: the grid's cell).
    update_every_steps : int
    flow_height_threshold_m : float
        Flow height above which a column counts as reached (default: half the particle spacing,
        i.e. any material).
    deposit_threshold_m : float
        Deposit thickness above which a column counts for the run-out (default: half the particle
        spacing).
    mobilised_displacement_m : float
        Displacement above which a particle counts as mobilised (default: one grid cell).
    kinetic_energy_fraction : float
        Fraction of the peak kinetic energy that ends the slide (default 0.01).
    """

    enabled: bool
    cell_size_m: float
    update_every_steps: int
    flow_height_threshold_m: float
    deposit_threshold_m: float
    mobilised_displacement_m: float
    kinetic_energy_fraction: float


def settings(project: Project) -> HazardSettings:
    """Resolve the ``[hazard]`` table of a project (presets applied) with its scene defaults."""
    h = project.hazard
    dx = project.domain.cell_size_m
    half_spacing = 0.5 * dx / project.particles.per_cell
    return HazardSettings(
        enabled=h.enabled,
        cell_size_m=h.cell_size_m if h.cell_size_m is not None else dx,
        update_every_steps=h.update_every_steps,
        flow_height_threshold_m=h.flow_height_threshold_m if h.flow_height_threshold_m is not None else half_spacing,
        deposit_threshold_m=h.deposit_threshold_m if h.deposit_threshold_m is not None else half_spacing,
        mobilised_displacement_m=h.mobilised_displacement_m if h.mobilised_displacement_m is not None else dx,
        kinetic_energy_fraction=h.kinetic_energy_fraction,
    )


def envelope_config(project: Project) -> sc.EnvelopeConfig | None:
    """The solver's envelope configuration of a project (None when ``hazard.enabled`` is false)."""
    s = settings(project)
    if not s.enabled:
        return None
    targets = tuple(sc.Target(t.name, *t.xy) for t in project.targets)
    if project.structures and not _raster_cells(project, s.cell_size_m) <= _raster_limit():
        # a raster past the size limits (projects.limits: hazard raster cells), which refuse the run
        # unless forced: its floor, one value per column, is not built while a live estimate or a
        # refused run resolves the project (1e-9 m cells took minutes and gigabytes)
        logger.warning("a hazard raster past the size limits: the floor of the structures under it is left out")
        return sc.EnvelopeConfig(cell_size_m=s.cell_size_m, every_steps=s.update_every_steps,
                                 flow_height_threshold_m=s.flow_height_threshold_m, targets=targets, ground_m=None)
    floor = structure_floor_m(project, s.cell_size_m)
    return sc.EnvelopeConfig(cell_size_m=s.cell_size_m, every_steps=s.update_every_steps,
                             flow_height_threshold_m=s.flow_height_threshold_m, targets=targets,
                             ground_m=None if floor is None else tuple(float(v) for v in floor))


def _raster_cells(project: Project, cell_size_m: float) -> float:
    """Cells of the hazard raster at ``cell_size_m`` over the grid (as solver.envelopes.Envelopes)."""
    d = project.domain
    grid = sc.Grid(tuple(d.origin_m), tuple(d.size_m), d.cell_size_m)
    try:
        return math.prod(math.ceil(n * d.cell_size_m / cell_size_m - 1e-9) for n in grid.cells)
    except (OverflowError, ValueError):
        return math.inf


def _raster_limit() -> float:
    from projects.limits import LIMITS

    return next(limit.maximum for limit in LIMITS if limit.estimate_key == "hazard_cells")


def structure_floor_m(project: Project, cell_size_m: float) -> np.ndarray | None:
    """The rigid floor under each raster column (m, (nx,)): the top of the highest
    ``[[structures]]`` entry on the vertical line through the column's centre, or the grid's
    bottom where no structure is; None for a project without structures.

    Material flows over a structure (a platform, bedrock, a barrier's crest): its flow height and
    the ground of a column it never covered are measured from the structure's top there.
    """
    if not project.structures:
        return None
    d = project.domain
    grid = sc.Grid(tuple(d.origin_m), tuple(d.size_m), d.cell_size_m)
    width = grid.cells[0] * grid.cell_size_m
    nx = max(1, math.ceil(width / cell_size_m - 1e-9))  # as solver.envelopes.Envelopes
    xc = d.origin_m[0] + (np.arange(nx) + 0.5) * cell_size_m
    floor = np.full(nx, float(d.origin_m[1]))
    for structure in project.structures:
        pts = np.asarray(structure.polygon_m, dtype=float)
        a, b = pts, np.roll(pts, -1, axis=0)
        lo, hi = np.minimum(a[:, 0], b[:, 0]), np.maximum(a[:, 0], b[:, 0])
        for (ax, ay), (bx, by), x0, x1 in zip(a, b, lo, hi):
            on = (xc >= x0) & (xc <= x1)
            if bx == ax:  # a vertical edge exactly on a column centre: its top
                y = np.full(nx, max(ay, by))
            else:
                y = ay + (xc - ax) * (by - ay) / (bx - ax)
            floor = np.where(on, np.maximum(floor, y), floor)
    return floor


# --------------------------------------------------------------------------------------------
# measures


def _f(value: Any) -> float | None:
    """A finite float or None (JSON has no NaN)."""
    if value is None:
        return None
    value = float(value)
    return value if math.isfinite(value) else None


def profile(snap: Mapping[str, Any]) -> dict[str, np.ndarray]:
    """The profiles along x (``PROFILE_COLUMNS``) of an envelope snapshot."""
    nx, _ = snap["shape"]
    c = snap["cell_size_m"]
    x0 = snap["origin_m"][0]
    lo = x0 + c * np.arange(nx)
    floor = snap["floor_m"]
    # the surface now, never below the rigid floor: where a structure stands on the vertical
    # through a column's centre, particles whose centres lie in the column beside it (against a
    # check dam's face) are no ground under its top, and the deposit there is measured on the
    # structure's top, not as a pit of its height (2.5 m under a 2.5 m dam)
    surface = np.where(np.isnan(snap["surface_m"]), floor, np.maximum(snap["surface_m"], floor))
    return {
        "x_m": lo + 0.5 * c,
        "x_lo_m": lo,
        "x_hi_m": lo + c,
        "floor_m": floor,
        "ground_m": snap["ground_m"],
        "surface_m": surface,
        "peak_flow_height_m": snap["peak_height_m"],
        "deposit_m": surface - snap["ground_m"],
        "arrival_s": snap["arrival_s"],
        "max_speed_m_s": snap["max_speed_m_s"].max(axis=1),
        "max_energy_J_m3": snap["max_energy_J_m3"].max(axis=1),
        "max_pressure_pa": snap["max_pressure_pa"].max(axis=1),
    }


def measures(snap: Mapping[str, Any], hs: HazardSettings, gravity_m_s2: tuple[float, float],
             targets: tuple[sc.Target, ...] = ()) -> dict[str, Any]:
    """The run-out measures of an envelope snapshot (see the module docstring for definitions).

    Parameters
    ----------
    snap : mapping
        :meth:`solver.envelopes.Envelopes.snapshot`.
    hs : HazardSettings
    gravity_m_s2 : (gx, gy)
    targets : tuple of solver.config.Target
        In the order of the envelopes' targets.

    Returns
    -------
    dict
        JSON-ready: every length in m, time in s, angle in degrees; None where undefined.
    """
    out: dict[str, Any] = {
        "release_time_s": _f(snap["release_time_s"]), "time_s": _f(snap["time_s"]),
        "direction": None, "direction_rule": DIRECTION_RULE,
        "runout_distance_m": None, "runout_x_m": None, "runout_point_m": None,
        "runout_distance_envelope_m": None, "runout_x_envelope_m": None,
        "travel_angle_deg": None, "h_over_l": None, "drop_height_m": None, "travel_length_m": None,
        "source_top_m": None, "source_front_x_m": None,
        "mobilised_area_m2_per_m": 0.0, "mobilised_particles": 0,
        "source_area_m2_per_m": 0.0, "source_particles": 0,
        "centroid_start_m": None, "centroid_end_m": None, "centroid_travel_m": None,
        "centroid_travel_angle_deg": None,
        "slide_duration_s": None, "slide_end_time_s": None, "still_moving": None,
        "peak_kinetic_energy_J_per_m": None, "peak_kinetic_energy_time_s": None,
        "max_speed_m_s": None, "max_pressure_pa": None, "max_flow_height_m": None,
        "note": "",
    }
    out["thresholds"] = {
        "deposit_threshold_m": hs.deposit_threshold_m,
        "flow_height_threshold_m": hs.flow_height_threshold_m,
        "mobilised_displacement_m": hs.mobilised_displacement_m,
        "kinetic_energy_fraction": hs.kinetic_energy_fraction,
        "cell_size_m": hs.cell_size_m,
        "update_every_steps": hs.update_every_steps,
    }
    out["targets"] = {
        t.name: {"kind": "point" if t.y_m is not None else "line", "x_m": t.x_m, "y_m": t.y_m,
                 "arrival_time_s": None, "arrival_after_release_s": None, "max_height_m": None,
                 "max_speed_m_s": None, "max_pressure_pa": None}
        for t in targets
    }
    if not snap.get("started"):
        out["note"] = "no dynamic stage ran: nothing was released"
        return out

    prof = profile(snap)
    out["max_speed_m_s"] = _f(snap["max_speed_m_s"].max(initial=0.0))
    out["max_pressure_pa"] = _f(snap["max_pressure_pa"].max(initial=0.0))
    out["max_flow_height_m"] = _f(snap["peak_height_m"].max(initial=0.0))
    release = float(snap["release_time_s"])
    for k, t in enumerate(targets):
        arrival = _f(snap["target_arrival_s"][k])
        peak = snap["target_max"][k]
        out["targets"][t.name].update(
            arrival_time_s=arrival,
            arrival_after_release_s=None if arrival is None else arrival - release,
            max_height_m=_f(peak[0]), max_speed_m_s=_f(peak[1]), max_pressure_pa=_f(peak[2]))

    series = np.asarray(snap["series"])
    if len(series):
        t_s, ke = series[:, 0], series[:, 1]
        ipk = int(np.argmax(ke))
        peak_ke = float(ke[ipk])
        out["peak_kinetic_energy_J_per_m"] = _f(peak_ke)
        out["peak_kinetic_energy_time_s"] = _f(t_s[ipk])
        below = np.flatnonzero(ke[ipk:] < hs.kinetic_energy_fraction * peak_ke) if peak_ke > 0 else np.array([])
        if below.size:
            end = float(t_s[ipk + below[0]])
            out.update(slide_end_time_s=end, slide_duration_s=end - release, still_moving=False)
        else:
            out["still_moving"] = peak_ke > 0

    init, cur = snap["initial"], snap["current"]
    x0 = np.asarray(init["positions_m"], float)
    x1 = np.asarray(cur["positions_m"], float)
    vol0 = np.asarray(init["volumes_m2"], float)
    both = np.asarray(init["active"], bool) & np.asarray(cur["active"], bool)
    disp = x1 - x0
    mob = both & (np.linalg.norm(disp, axis=1) > hs.mobilised_displacement_m)
    out["mobilised_particles"] = int(mob.sum())
    if not mob.any():
        out["note"] = "no particle moved more than the mobilised displacement"
        return out
    w = vol0[mob]
    area = float(w.sum())
    out["mobilised_area_m2_per_m"] = area
    mean_dx = float((w * disp[mob, 0]).sum())
    direction = 1 if mean_dx >= 0.0 else -1
    out["direction"] = direction
    c0 = (w[:, None] * x0[mob]).sum(axis=0) / area
    c1 = (w[:, None] * x1[mob]).sum(axis=0) / area
    g = np.asarray(gravity_m_s2, float)
    gdir = g / np.linalg.norm(g) if np.linalg.norm(g) > 0 else np.array([0.0, -1.0])

    def drop_and_length(a: np.ndarray, b: np.ndarray) -> tuple[float, float]:
        d = a - b
        along = float(d @ gdir)  # positive where b lies below a
        return -along, float(np.linalg.norm(d - along * gdir))

    hc, lc = drop_and_length(c0, c1)
    out["centroid_start_m"] = [float(c0[0]), float(c0[1])]
    out["centroid_end_m"] = [float(c1[0]), float(c1[1])]
    out["centroid_travel_m"] = {"dx_m": float(c1[0] - c0[0]), "dy_m": float(c1[1] - c0[1]),
                                "distance_m": float(np.linalg.norm(c1 - c0)), "drop_m": hc,
                                "horizontal_m": lc}
    out["centroid_travel_angle_deg"] = math.degrees(math.atan2(hc, lc)) if lc > 0 else None

    # the source: mobilised material that descended (along gravity) by more than the mobilised
    # displacement; material pushed along or heaved up in front of a slide is mobilised but no source
    drop = disp @ gdir
    src = mob & (drop > hs.mobilised_displacement_m)
    if not src.any():
        src = mob  # nothing descended (motion along the level): the mobilised material
    out["source_particles"] = int(src.sum())
    out["source_area_m2_per_m"] = float(vol0[src].sum())
    half0 = 0.5 * np.sqrt(vol0[src])
    xs, ys = x0[src, 0], x0[src, 1]
    front = float((xs + half0).max()) if direction > 0 else float((xs - half0).min())
    out["source_front_x_m"] = front
    # the crown: the highest particle top; among tops level with it (within a quarter of a particle)
    # the rearmost, at its rear edge (the back of a flat-topped source, where the scarp starts)
    tops = np.stack([xs - direction * half0, ys + half0], axis=1)
    elevation = -(tops @ gdir)
    level = np.flatnonzero(elevation >= elevation.max() - 0.25 * float(np.median(2 * half0)))
    crown = tops[level[np.argmin(direction * tops[level, 0])]]
    out["source_top_m"] = [float(crown[0]), float(crown[1])]

    deposit = prof["deposit_m"]
    thick = np.flatnonzero(deposit > hs.deposit_threshold_m)
    if thick.size:
        i = int(thick[-1] if direction > 0 else thick[0])
        edge = snap["edge_hi_m"][i] if direction > 0 else snap["edge_lo_m"][i]
        if not np.isfinite(edge):
            edge = prof["x_hi_m"][i] if direction > 0 else prof["x_lo_m"][i]
        xr = float(edge)
        yr = float(snap["ground_m"][i])
        out["runout_x_m"] = xr
        out["runout_point_m"] = [xr, yr]
        out["runout_distance_m"] = direction * (xr - front)
        H, L = drop_and_length(crown, np.array([xr, yr]))
        out["drop_height_m"] = H
        out["travel_length_m"] = L
        if L > 0:
            out["travel_angle_deg"] = math.degrees(math.atan2(H, L))
            out["h_over_l"] = H / L
    else:
        out["note"] = "no deposit thicker than the deposit threshold"
    env_front = snap["front_hi_m"] if direction > 0 else snap["front_lo_m"]
    if np.isfinite(env_front):
        out["runout_x_envelope_m"] = float(env_front)
        out["runout_distance_envelope_m"] = direction * (float(env_front) - front)
    return out


# --------------------------------------------------------------------------------------------
# files


def _csv_text(columns: tuple[str, ...], table: np.ndarray) -> str:
    """CSV with a header row; numbers with 9 significant digits (the envelopes are float32 or
    better), empty fields for NaN (never reached)."""
    buf = io.StringIO()
    csv.writer(buf, lineterminator="\n").writerow(columns)
    if len(table):
        body = io.StringIO()
        np.savetxt(body, np.asarray(table, float), fmt="%.9g", delimiter=",")
        buf.write(body.getvalue().replace("nan", ""))
    return buf.getvalue()


def profile_csv(snap: Mapping[str, Any]) -> str:
    prof = profile(snap)
    return _csv_text(PROFILE_COLUMNS, np.column_stack([prof[c] for c in PROFILE_COLUMNS]))


def targets_csv(snap: Mapping[str, Any]) -> str:
    return _csv_text(tuple(snap["series_columns"]), np.asarray(snap["series"]))


def vti_bytes(snap: Mapping[str, Any]) -> bytes:
    """The envelopes as VTK XML ImageData: cell arrays on the raster (z = 0 plane).

    Per cell: ``max_speed_m_s``, ``max_kinetic_energy_J_m3``, ``max_pressure_pa``,
    ``first_arrival_s`` (-1: never reached); per column, repeated up the rows:
    ``peak_flow_height_m``, ``deposit_m``, ``flow_arrival_s`` (-1: never).
    """
    nx, ny = snap["shape"]
    c = snap["cell_size_m"]
    ox, oy = snap["origin_m"]
    prof = profile(snap)

    def cells(a2d: np.ndarray) -> np.ndarray:  # (nx, ny) -> VTK order (x fastest)
        return np.ascontiguousarray(np.asarray(a2d, "<f4").T).ravel()

    def column(a1d: np.ndarray) -> np.ndarray:
        return cells(np.repeat(np.asarray(a1d, float)[:, None], ny, axis=1))

    arrays = {
        "max_speed_m_s": cells(snap["max_speed_m_s"]),
        "max_kinetic_energy_J_m3": cells(snap["max_energy_J_m3"]),
        "max_pressure_pa": cells(snap["max_pressure_pa"]),
        "first_arrival_s": cells(np.nan_to_num(snap["cell_arrival_s"], nan=-1.0)),
        "peak_flow_height_m": column(prof["peak_flow_height_m"]),
        "deposit_m": column(prof["deposit_m"]),
        "flow_arrival_s": column(np.nan_to_num(prof["arrival_s"], nan=-1.0)),
    }
    blobs, tags, offset = [], [], 0
    for name, arr in arrays.items():
        blob = _encode_array(arr, 1)
        tags.append(f'<DataArray type="Float32" Name="{name}" NumberOfComponents="1" format="appended" '
                    f'offset="{offset}"/>')
        blobs.append(blob)
        offset += len(blob)
    head = "\n".join([
        '<?xml version="1.0"?>',
        '<VTKFile type="ImageData" version="1.0" byte_order="LittleEndian" header_type="UInt64" '
        'compressor="vtkZLibDataCompressor">',
        f'<ImageData WholeExtent="0 {nx} 0 {ny} 0 0" Origin="{ox!r} {oy!r} 0" Spacing="{c!r} {c!r} 1">',
        "<FieldData>",
        f'<DataArray type="Float64" Name="TimeValue" NumberOfTuples="1" format="ascii">{float(snap["time_s"])!r}'
        "</DataArray>",
        f'<DataArray type="Float64" Name="release_time_s" NumberOfTuples="1" format="ascii">'
        f'{float(snap["release_time_s"])!r}</DataArray>',
        "</FieldData>",
        f'<Piece Extent="0 {nx} 0 {ny} 0 0">',
        "<CellData>",
        *tags,
        "</CellData>",
        "</Piece>",
        "</ImageData>",
        '<AppendedData encoding="raw">',
        "_",
    ]).encode("ascii")
    return head + b"".join(blobs) + b"\n</AppendedData>\n</VTKFile>\n"


@functools.lru_cache(maxsize=1)
def _version() -> str:
    return runout_version()


def hazard_document(snap: Mapping[str, Any], hs: HazardSettings, gravity_m_s2: tuple[float, float],
                    targets: tuple[sc.Target, ...], status: str,
                    motion: Mapping[str, Any] | None = None) -> dict[str, Any]:
    """The content of ``hazard.json``. ``motion`` is the verdict at the end of the run
    (:func:`projects.motion.verdict`): it decides ``still_moving`` (a slide still moving has no
    end time) and is written as ``motion_at_end``."""
    doc = {"status": status, "runout_version": _version()}
    doc.update(measures(snap, hs, gravity_m_s2, targets))
    if motion is not None:
        doc["still_moving"] = bool(motion["still_moving"])
        if motion["still_moving"]:
            doc["slide_end_time_s"] = doc["slide_duration_s"] = None
        doc["motion_at_end"] = dict(motion)
    nx, ny = snap["shape"]
    doc["raster"] = {"origin_m": list(snap["origin_m"]), "cell_size_m": snap["cell_size_m"], "shape": [nx, ny]}
    doc["settings"] = asdict(hs)
    doc["sampling"] = {
        "every_steps": int(snap.get("every_steps", hs.update_every_steps)), "updates": int(len(snap["series"])),
        "note": "envelopes are updated every `every_steps` steps and at every output frame; a peak between "
                "updates is missed by at most its change over that interval, an arrival is late by less than it",
    }
    doc["files"] = {"profile": PROFILE_CSV, "targets": TARGETS_CSV, "raster": HAZARD_VTI}
    return doc


def write_files(out_dir: Path, snap: Mapping[str, Any], hs: HazardSettings, gravity_m_s2: tuple[float, float],
                targets: tuple[sc.Target, ...], status: str, motion: Mapping[str, Any] | None = None) -> None:
    """Write the four hazard files into ``out_dir``, each atomically (hazard.json last)."""
    out_dir = Path(out_dir)
    write_atomic(out_dir / HAZARD_VTI, vti_bytes(snap))
    write_atomic(out_dir / PROFILE_CSV, profile_csv(snap))
    write_atomic(out_dir / TARGETS_CSV, targets_csv(snap))
    doc = hazard_document(snap, hs, gravity_m_s2, targets, status, motion)
    doc["structures"] = structure_forces(out_dir)
    write_atomic(out_dir / HAZARD_JSON, json.dumps(doc, indent=2) + "\n")


def structure_forces(out_dir: Path) -> dict[str, dict[str, Any]]:
    """The force history of each rigid structure so far, summed up for ``hazard.json``.

    Read from the run's ``contacts.csv`` (the history itself, one row per output interval):
    per structure ``peak_force_N_per_m`` (largest single-step force magnitude) and its
    ``peak_time_s`` (the end of the interval that held it), ``max_mean_force_N_per_m`` (largest
    interval mean, magnitude), ``max_normal_force_N_per_m`` and ``max_tangential_force_N_per_m``
    (the largest interval-mean parts on the loaded face, :mod:`projects.structure_forces`) with
    their times, and ``history`` (the file). The closed sides are left out (their forces are in
    ``contacts.csv`` and ``summary.json``).
    """
    from projects.results import CONTACTS_NAME, read_contacts
    from projects.structure_forces import contact_peaks
    from solver.config import SIDES

    out: dict[str, dict[str, Any]] = {}
    keys = ("peak_force_N_per_m", "peak_time_s", "max_mean_force_N_per_m", "max_normal_force_N_per_m",
            "max_normal_force_time_s", "max_tangential_force_N_per_m", "max_tangential_force_time_s")
    for name, cols in read_contacts(out_dir).items():
        if name in SIDES or not len(cols["time_s"]):
            continue
        peaks = contact_peaks(cols)
        out[name] = {**{k: peaks[k] for k in keys}, "history": CONTACTS_NAME}
    return out


class HazardOutput:
    """Writes the hazard files of a running simulation with every frame and at the end.

    The snapshot is taken in the calling (solver) thread; encoding and writing happen in
    ``submit`` (the results writer's thread when given), so the files follow the frames.
    """

    def __init__(self, out_dir: Path, sim: Any, hs: HazardSettings,
                 submit: Callable[[Callable[[], None]], None] | None = None):
        self.out_dir = Path(out_dir)
        self.sim = sim
        self.hs = hs
        self.gravity = tuple(sim.config.gravity_m_s2)
        self.targets = tuple(sim.config.envelopes.targets) if sim.config.envelopes is not None else ()
        self.submit = submit if submit is not None else (lambda job: job())
        self._lock = threading.Lock()

    @property
    def active(self) -> bool:
        return self.sim.envelopes is not None and self.sim.envelopes.started

    def write(self, status: str = "running", motion: Mapping[str, Any] | None = None) -> None:
        """Write the files now; at the end with the run's ``status`` and the verdict on its
        motion (:func:`projects.motion.verdict`)."""
        if not self.active:
            return
        snap = self.sim.envelopes.snapshot()

        def job() -> None:
            with self._lock:
                write_files(self.out_dir, snap, self.hs, self.gravity, self.targets, status, motion)

        self.submit(job)


def read_hazard(results_dir: str | Path) -> dict[str, Any]:
    """``hazard.json`` of a results folder, with ``profile`` (dict of arrays from
    ``hazard_profile.csv``) and ``series`` (dict of arrays from ``targets.csv``, the rows up to
    ``hazard.json``'s time) added."""
    path = Path(results_dir)
    doc = json.loads((path / HAZARD_JSON).read_text(encoding="utf-8"))
    profile = _read_csv(path / PROFILE_CSV)
    if all(k in profile for k in ("floor_m", "ground_m", "surface_m")):
        # files written before the surface was held at the floor: the same rule on reading
        surface = np.fmax(profile["surface_m"], profile["floor_m"])
        profile["surface_m"] = surface
        profile["deposit_m"] = surface - profile["ground_m"]
    doc["profile"] = profile
    series = _read_csv(path / TARGETS_CSV)
    # hazard.json is written last: a run killed between the files leaves targets.csv a frame
    # ahead of it. The rows hazard.json was made from are its first `sampling.updates`.
    rows = doc.get("sampling", {}).get("updates")
    if rows is not None:
        series = {name: col[: int(rows)] for name, col in series.items()}
    doc["series"] = series
    return doc


def _read_csv(path: Path) -> dict[str, np.ndarray]:
    with open(path, newline="", encoding="utf-8") as fh:
        rows = list(csv.reader(fh))
    if not rows:
        return {}
    head, body = rows[0], rows[1:]
    data = np.array([[float(v) if v != "" else np.nan for v in r] for r in body], float).reshape(len(body), len(head))
    return {name: data[:, k] for k, name in enumerate(head)}
