"""Shared fixtures: synthetic results folders (no solver needed) and the tiny example project."""

from __future__ import annotations

import os
import re
import sys
from pathlib import Path

import numpy as np
import pytest

REPO = Path(__file__).resolve().parents[1]
EXAMPLES = REPO / "projects" / "examples"
TINY_PROJECT = EXAMPLES / "tiny_column.toml"

# Taichi's offline kernel cache (~/.cache/taichi) is capped at 100 MB by default and trimmed by a
# quarter (least recently used first) whenever a process ends above the cap. One pass of the suite
# compiles more than that (a kernel is cached per particle count and grid size), so the suite
# evicted kernels it compiled minutes before and compiled them again (measured: one engine set
# costs about 5.5 s of CPU cold against 1.6 s from the cache). A larger cap for the test processes
# and the runs they start (they inherit the environment); an explicit setting is kept.
os.environ.setdefault("TI_OFFLINE_CACHE_MAX_SIZE_OF_FILES", str(1024 ** 3))

# headless VTK without the "bad X server connection" warning (see app.render)
if sys.platform.startswith("linux") and not os.environ.get("DISPLAY"):
    os.environ.setdefault("VTK_DEFAULT_OPENGL_WINDOW", "vtkEGLRenderWindow")


#: Environment variable that runs every case of the ``matrix`` tests (default: a covering sample).
FULL_MATRIX = "RUNOUT_FULL_MATRIX"


#: The most cases of one matrix test the suite runs (each case compiles kernels of its own: most
#: of a matrix case's time with a cold kernel cache).
MATRIX_SAMPLE = 1

#: The values every matrix file runs where its cases hold them, whatever its tests' samples: the
#: schemes and the precisions (words of a case id).
ALWAYS_COVERED = frozenset({"mpm", "apic", "apic_affine", "f32", "f64"})


def case_words(item) -> set:
    """The values a parametrised case names in its id (schemes, precisions, sides, cell counts,
    stiffnesses, angle pairs...)."""
    spec = getattr(item, "callspec", None)
    if spec is None:
        return set()
    # pytest's own ids of values it cannot show (``cases3``: the fourth list of cases) name no
    # value: nothing to cover
    auto = re.compile("^(" + "|".join(re.escape(k) for k in spec.params) + r")\d+$")
    # a scheme's name holds a hyphen: "apic-affine" is one word, not "apic" and "affine"
    return {word for word in spec.id.replace("apic-affine", "apic_affine").split("-") if not auto.match(word)}


def _known_limit(item) -> bool:
    return item.get_closest_marker("xfail") is not None


def covering_sample(items: list, limit: int = MATRIX_SAMPLE, covered: frozenset = frozenset()) -> list:
    """A subset of one test's parametrised cases, at most ``limit`` of them, chosen greedily to
    hold as many of their values as they can, values not in ``covered`` (those the file's earlier
    samples hold) first: a set cover cut at ``limit``, in the cases' own order (deterministic, so
    that every pytest-xdist worker collects the same cases)."""
    # a known limit (an xfail case) is no sample of what the test claims: where a test has other
    # cases, the sample is drawn from those
    items = [i for i in items if not _known_limit(i)] or items
    wanted = set().union(*(case_words(i) for i in items)) if items else set()
    chosen: list = []
    while wanted and len(chosen) < limit:
        best = max(items, key=lambda i: (len(case_words(i) & wanted - covered), len(case_words(i) & wanted)))
        chosen.append(best)
        wanted -= case_words(best)
    return [i for i in items if i in chosen] or items[:1]


def pytest_collection_modifyitems(config, items):
    """Tests marked ``matrix`` (the solver's contact, thrust, scatter and water matrices) run a
    covering sample of their cases (:func:`covering_sample`), at most ``MATRIX_SAMPLE`` of them or
    the marker's ``sample`` (``pytest.mark.matrix(sample=3)``), known limits (xfail cases) only
    where a test has nothing else. The tests of one file share out the values: each test's sample
    prefers those the file's earlier samples left out, and where a scheme or a precision is still
    left out at the end a case holding it joins. ``RUNOUT_FULL_MATRIX=1`` (scripts/full-matrix.sh)
    runs every case (docs/validation.md says which to run when)."""
    if os.environ.get(FULL_MATRIX) == "1":
        return
    groups: dict = {}
    for item in items:
        if item.get_closest_marker("matrix") is not None:
            groups.setdefault((item.path, item.originalname), []).append(item)

    def limit(group: list) -> int:
        return int(group[0].get_closest_marker("matrix").kwargs.get("sample", MATRIX_SAMPLE))

    keep: set = set()
    files: dict = {}
    for (path, _name), group in groups.items():
        files.setdefault(path, []).append(group)
    for file_groups in files.values():
        covered: set = set()
        for group in file_groups:
            for item in covering_sample(group, limit(group), frozenset(covered)):
                keep.add(id(item))
                covered |= case_words(item)
        cases = [i for group in file_groups for i in group]
        for value in sorted(ALWAYS_COVERED & set().union(*map(case_words, cases)) - covered):
            if value not in covered:  # an earlier addition may have brought it
                # of the cases that hold it, the one that brings the most values still left out
                item = max((i for i in cases if value in case_words(i)),
                           key=lambda i: (not _known_limit(i), len(case_words(i) - covered)))
                keep.add(id(item))
                covered |= case_words(item)
    dropped = [i for group in groups.values() for i in group if id(i) not in keep]
    if dropped:
        config.hook.pytest_deselected(items=dropped)
        items[:] = [i for i in items if i.get_closest_marker("matrix") is None or id(i) in keep]


def synthetic_frames(n_frames: int = 4, *, nx: int = 40, ny: int = 20, lose_last: int = 5):
    """Frames of a 0.2 m x 0.1 m block (1 mm spacing scaled) that shears to the right.

    Two materials (lower and upper half); the last ``lose_last`` particles become inactive
    from the third frame on. Values are smooth functions of the initial position so that
    each field gives a different picture.
    """
    from solver.config import Diagnostics, Frame

    spacing = 0.2 / nx
    x, y = np.meshgrid((np.arange(nx) + 0.5) * spacing, (np.arange(ny) + 0.5) * spacing)
    p0 = np.column_stack([x.ravel(), y.ravel()])
    n = len(p0)
    material = (p0[:, 1] > 0.05).astype(np.int32)
    frames = []
    for i in range(n_frames):
        s = i / max(n_frames - 1, 1)
        shape = (p0[:, 1] / 0.1) * (p0[:, 0] / 0.2)
        disp = np.column_stack([0.3 * s * shape, -0.05 * s * shape])
        active = np.ones(n, bool)
        if i >= 2 and lose_last:
            active[-lose_last:] = False
        depth = 0.1 - p0[:, 1]
        sv = -2650.0 * 9.81 * depth
        stress = np.column_stack([0.6 * sv, sv, 200.0 * np.sin(30 * p0[:, 0]), 0.5 * sv])
        diag = Diagnostics(
            time_s=0.05 * i, stage="collapse", stage_index=1, stage_time_s=0.05 * i, step=50 * i,
            dt_s=1e-3, kinetic_energy_J_per_m=0.5 * i, momentum_x=0.1 * i, momentum_y=-0.01 * i,
            max_speed_m_s=0.2 * i, unstable_particles=0, lost_particles=int((~active).sum()),
            total_mass_kg_per_m=53.0, yielding_particles=3 * i,
        )
        fields = {
            "positions": p0 + disp,
            "active": active,
            "displacement": disp,
            "velocity": 4.0 * disp,
            "stress": stress,
            "plastic_strain": s * p0[:, 0],
            "material_id": material,
        }
        frames.append(Frame(diag, fields))
    return frames


SYNTHETIC_META = {
    "title": "Synthetic shear",
    "scheme": "apic-affine",
    "arch": "cpu",
    "precision": "f32",
    "particles": 800,
    "materials": ["lower", "upper"],
    "domain": {"origin_m": [0.0, 0.0], "size_m": [0.8, 0.15], "cell_size_m": 0.01},
    "particle_spacing_m": 0.005,
}
SYNTHETIC_PROJECT = '[runout]\nschema_version = 1\ntitle = "Synthetic shear"\n'


@pytest.fixture
def make_results(tmp_path):
    """Factory: write a closed synthetic results folder and return its path."""

    def make(name: str = "synthetic.results", n_frames: int = 4, status: str = "completed") -> Path:
        from projects.results import ResultsWriter

        writer = ResultsWriter(tmp_path / name, SYNTHETIC_PROJECT, dict(SYNTHETIC_META))
        for frame in synthetic_frames(n_frames):
            writer.write_frame(frame)
        writer.close(status, "" if status == "completed" else f"{status} on purpose")
        return tmp_path / name

    return make


@pytest.fixture
def tiny_project() -> Path:
    """The tiny example scene used by the end-to-end tests."""
    if not TINY_PROJECT.is_file():
        pytest.skip(f"{TINY_PROJECT.relative_to(REPO)} is not there yet")
    return TINY_PROJECT


# -- GUI windows outlive their tests -------------------------------------------------------------
# Deleting a window with embedded VTK (QOpenGLWidget) views under Xvfb crashed the interpreter
# at random while Qt processed the deferred deletion (twice in CI; here about one GUI-suite run in
# four with two suites running side by side). Re-checked after runs became child processes (no
# solver thread, no Taichi in the GUI process any more): creating and deleting eight windows in
# a row still corrupted PySide's object map in one try of three (horizontalHeader() returned a
# stale QOffscreenSurface), so the cause is the VTK widgets' deletion, not the solver thread.
# Tests therefore shut their windows down (runs stopped, plotters finalised: the fixtures check
# both) and keep them here instead of deleting them; the process then ends without destroying
# them (os._exit), after pytest has written its report and stopped Xvfb. Under pytest-xdist
# (scripts/test.sh) a worker has sent its results in pytest_sessionfinish before this runs. Without os._exit five
# GUI-suite runs ended cleanly, too few to rule out the one-in-four failure of that deletion.
KEPT_WIDGETS: list = []
_SESSION: dict = {}


def pytest_sessionstart(session):
    _SESSION["session"] = session


@pytest.hookimpl(trylast=True)
def pytest_unconfigure(config):
    if not KEPT_WIDGETS:
        return
    session = _SESSION.get("session")
    status = int(getattr(session, "exitstatus", 1) or 0)
    sys.stdout.flush()
    sys.stderr.flush()
    xvfb = sys.modules.get("pytest_xvfb")
    if xvfb is not None:
        xvfb.shutdown_xvfb()
    os._exit(status)
