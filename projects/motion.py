"""Whether a run's answer is final: the mass at rest at the end of the run, or still moving.

A run-out measured while the mass still moves is not the run-out: it is where the front was when
the stage's time ran out. The verdict (:func:`verdict`) is taken at the end of the run, from the
last dynamic stage that ran (:meth:`solver.simulation.Simulation.motion_at_end`):

- the **kinetic energy at the end as a fraction of its peak** (the largest kinetic energy of the
  dynamic stages) is at most the rest fraction: the stage's ``stop_when_kinetic_energy_below``,
  else the hazard's ``kinetic_energy_fraction`` (0.01 by default);
- and the **fastest particle** is no faster than the rest speed: the stage's
  ``stop_when_max_speed_below_m_s``, else :func:`default_rest_speed` (``0.1 sqrt(|g| dx)``, 0.157
  m/s at 0.25 m cells). The speed sees what the energy misses: a few particles sliding on down a
  rock face carry a negligible part of the energy at any speed.

Both hold: the mass is at rest and the measures are final. Else it is still moving, and every
measure of the run (``hazard.json``, the report, the workbench) is provisional. ``summary.json``
and ``hazard.json`` carry ``still_moving`` and the numbers (``motion_at_end``); :func:`motion_text`
says it in words for the command line, the workbench and the report.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from typing import Any

#: The default rest speed is this times ``sqrt(|g| dx)``: a particle that slow crosses a cell in
#: ``10 sqrt(dx / |g|)`` (1.6 s at 0.25 m cells) and would rise by 1/200 of a cell on its speed.
REST_SPEED_SCALE = 0.1
#: Gravity taken for the rest speed of a run without gravity (m/s2).
STANDARD_GRAVITY = 9.81


def default_rest_speed(gravity_m_s2: tuple[float, float], cell_size_m: float) -> float:
    """The rest speed where the stage gives none (m/s): ``REST_SPEED_SCALE sqrt(|g| dx)``."""
    g = math.hypot(*(float(v) for v in gravity_m_s2)) or STANDARD_GRAVITY
    return REST_SPEED_SCALE * math.sqrt(g * float(cell_size_m))


def verdict(motion: Mapping[str, Any] | None, *, kinetic_energy_fraction: float,
            rest_speed_m_s: float, status: str = "completed") -> dict[str, Any] | None:
    """The verdict on the motion at the end of a run (None when no dynamic stage ran).

    Parameters
    ----------
    motion : mapping or None
        :meth:`solver.simulation.Simulation.motion_at_end`.
    kinetic_energy_fraction, rest_speed_m_s : float
        The rest fraction and speed where the stage gives none (the hazard's
        ``kinetic_energy_fraction`` and :func:`default_rest_speed`).
    status : str
        The run's status: "stopped" ends the stage by hand (``ended_by``).

    Returns
    -------
    dict
        JSON-ready: ``still_moving`` (bool; never where ``driven``: a rigid body moves the
        material at its prescribed velocity at the end), ``driven``, ``stage``, ``time_s``, ``ended_by`` ("rest": by the
        stage's rest criterion, "duration": its time ran out, "stopped"), the kinetic energy now and
        its peak (J/m), ``kinetic_energy_fraction`` (now over peak; None where nothing moved),
        ``max_speed_m_s`` (the fastest particle now), ``rest_kinetic_energy_fraction`` and
        ``rest_speed_m_s`` (the thresholds applied).
    """
    if motion is None:
        return None
    frac_rest = motion.get("stop_when_kinetic_energy_below")
    frac_rest = float(kinetic_energy_fraction if frac_rest is None else frac_rest)
    speed_rest = motion.get("stop_when_max_speed_below_m_s")
    speed_rest = float(rest_speed_m_s if speed_rest is None else speed_rest)
    ke, peak = float(motion["kinetic_energy_J_per_m"]), float(motion["peak_kinetic_energy_J_per_m"])
    fraction = ke / peak if peak > 0.0 else None
    speed = float(motion["max_speed_m_s"])
    at_rest = (fraction is None or fraction <= frac_rest) and speed <= speed_rest
    # a rigid body driven at its velocity moves the material on purpose (a platen's test): that
    # motion is the loading, not an answer still on its way
    driven = bool(motion.get("driven"))
    ended_by = "stopped" if status == "stopped" else ("rest" if motion.get("ended_at_rest") else "duration")
    return {
        "still_moving": not (at_rest or driven), "driven": driven, "stage": motion.get("stage"),
        "time_s": float(motion["time_s"]),
        "ended_by": ended_by, "kinetic_energy_J_per_m": ke, "peak_kinetic_energy_J_per_m": peak,
        "kinetic_energy_fraction": fraction, "max_speed_m_s": speed,
        "rest_kinetic_energy_fraction": frac_rest, "rest_speed_m_s": speed_rest,
    }


def _g(value: Any, digits: int = 2) -> str:
    return "-" if value is None else f"{float(value):.{digits}g}"


def _fraction(value: Any) -> str:
    text = _g(value)
    return text + ".0" if text.isdigit() else text  # "1.0 of its peak", not "1 of its peak"


def motion_numbers(m: Mapping[str, Any]) -> str:
    """``kinetic energy 0.46 of its peak, fastest particle 3.2 m/s``."""
    return (f"kinetic energy {_fraction(m.get('kinetic_energy_fraction'))} of its peak, fastest particle "
            f"{_g(m.get('max_speed_m_s'), 3)} m/s")


def motion_text(m: Mapping[str, Any] | None) -> str:
    """The verdict in words ("" without one): ``still moving at the end (t = 2 s): kinetic energy
    0.46 of its peak, fastest particle 3.2 m/s; at rest below 0.01 and 0.157 m/s`` or ``at rest at
    the end (t = 4.6 s): ...``."""
    if not m:
        return ""
    if m.get("driven"):
        return (f"moved by a driven rigid body at the end (t = {_g(m.get('time_s'), 4)} s): {motion_numbers(m)}; "
                "the motion is the loading")
    state = "still moving" if m.get("still_moving") else "at rest"
    return (f"{state} at the end (t = {_g(m.get('time_s'), 4)} s): {motion_numbers(m)}; at rest below "
            f"{_g(m.get('rest_kinetic_energy_fraction'))} of the peak and {_g(m.get('rest_speed_m_s'), 3)} m/s")


#: What to do about a run that ended still moving (the command line and the report say it).
REMEDY = ("run the stage longer, or let it end at rest: stop_when_kinetic_energy_below and "
          "stop_when_max_speed_below_m_s with duration_s as the safety limit")


def provisional(summary: Mapping[str, Any]) -> bool:
    """Whether a run's measures are provisional: it ended with the mass still moving."""
    m = summary.get("motion_at_end")
    return bool(summary.get("still_moving")) or bool(isinstance(m, Mapping) and m.get("still_moving"))


def hazard_provisional(doc: Mapping[str, Any]) -> bool:
    """Whether the measures of ``hazard.json`` (``doc``) are provisional: the run had not completed
    when they were written, or the mass was still moving at its end."""
    m = doc.get("motion_at_end")
    still = m.get("still_moving") if isinstance(m, Mapping) else doc.get("still_moving")
    return doc.get("status") != "completed" or bool(still)
