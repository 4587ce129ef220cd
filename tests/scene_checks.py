"""Checks that hold for any run of a scene no material leaves (shared by the contact tests)."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from projects.results import open_results, read_contacts
from solver.structures import signed_distance

G = 9.81


def check_kept_balanced_and_outside(folder: Path, structures: dict[str, list[list[float]]]) -> dict:
    """Assert, of the results in ``folder`` (vertical gravity, equal particle masses):

    - every particle is kept (none lost, none removed by the guard, the mass unchanged);
    - no particle is inside a structure (name -> polygon) in any frame;
    - impulse balance: the impulse recorded on every contact in ``contacts.csv`` (mean force times
      interval) equals the material's change of momentum less gravity's impulse, within 2 %;
    - no energy gained: kinetic plus potential energy at the end at most the start's.

    Returns ``contacts.csv`` as :func:`projects.results.read_contacts` reads it."""
    results = open_results(folder)
    series = results.series
    assert series["lost_particles"].max() == 0 and series["unstable_particles"].max() == 0
    mass = series["total_mass_kg_per_m"]
    assert np.allclose(mass, mass[0], rtol=1e-6)
    for i in range(len(results.times)):
        frame = results.frame(i, ["positions", "active"])
        assert frame["active"].all()
        for name, polygon in structures.items():
            depth = signed_distance(frame["positions"], polygon).min()
            assert depth >= -1e-6, f"frame {i}: a particle {-depth:.4f} m inside {name}"
    first, last = results.frame(0), results.frame(-1)
    m = mass[0] / len(first["positions"])
    v0 = first["velocity"][:, :2].astype(float)
    v1 = last["velocity"][:, :2].astype(float)
    duration = float(results.times[-1] - results.times[0])
    change = m * (v1.sum(0) - v0.sum(0)) - np.array([0.0, -G]) * mass[0] * duration  # less gravity's impulse
    impulse = np.zeros(2)
    contacts = read_contacts(folder)
    for columns in contacts.values():
        dt = np.diff(columns["time_s"])
        impulse += [(columns["force_x_N_per_m"][1:] * dt).sum(), (columns["force_y_N_per_m"][1:] * dt).sum()]
    # the material's change is the reaction of what it exerted on the contacts
    assert np.linalg.norm(change + impulse) <= 0.02 * np.linalg.norm(impulse), (change, impulse)
    y0, y1 = first["positions"][:, 1], last["positions"][:, 1]
    start = m * np.sum(G * y0 + 0.5 * (v0 ** 2).sum(1))
    end = m * np.sum(G * y1 + 0.5 * (v1 ** 2).sum(1))
    assert end <= start
    return contacts
