"""Validation studies: ``runout study NAME [--out DIR] [--quick]``.

Each study runs its scenes through the normal project/solver path, writes ``report.md`` with
tables and PNG plots plus the raw numbers (CSV/JSON) into its folder and returns a
:class:`~studies.common.StudyResult` whose ``verdict`` lines the command line prints.

=============  ===============================================================================
name           what
=============  ===============================================================================
sand-column    paper section 2.4: stable particles against step for the three schemes; the
               largest stable time step (:mod:`studies.sand_column`)
bui2008        paper section 2.5: final surface against the experiment, energy curves, apic
               against apic-affine wall time (:mod:`studies.bui2008`)
bui2008-choices what each model choice (base, cone match, damping, initial stress, mu(I)) does
               to toe, reach, centroid, failure line and surface (:mod:`studies.bui2008_choices`)
slope          paper section 3: initial stress, energy peak, speeds, displacement, final
               angle beside the paper's (:mod:`studies.slope`)
tradeoff       error against cost over schemes, cell sizes, particles per cell and time steps;
               Pareto front and the presets (:mod:`studies.tradeoff`)
presets        the part of the tradeoff sweep the presets are chosen from, on the shipped scene,
               against a 1.25 mm reference (:mod:`studies.presets`)
extremes       runs at the edges of the parameter space: stable or stopped with a message,
               never NaN, hang or traceback (:mod:`studies.extremes`)
fos            factor of safety by strength reduction against the cell size and Bishop's
               method; its cost in equilibrium runs; the infinite slope (:mod:`studies.fos`)
softening      a strain-softening clay bank's failure time, run-out and retrogression against
               the cell size with and without a softening length; run-out against the
               brittleness (:mod:`studies.softening`)
=============  ===============================================================================
"""

from __future__ import annotations

import importlib
import shutil
from pathlib import Path

from studies.common import Note, StudyError, StudyResult, quiet

#: Study name -> module under ``studies`` with a ``run(out_dir, quick, note)`` function.
STUDIES: dict[str, str] = {
    "sand-column": "sand_column",
    "bui2008": "bui2008",
    "bui2008-choices": "bui2008_choices",
    "slope": "slope",
    "tradeoff": "tradeoff",
    "presets": "presets",
    "extremes": "extremes",
    "fos": "fos",
    "softening": "softening",
}

#: Default output folder of ``runout study NAME``: ``study-results/NAME`` (``-quick`` appended).
DEFAULT_ROOT = Path("study-results")


def default_out_dir(name: str, quick: bool) -> Path:
    """``study-results/NAME`` or ``study-results/NAME-quick`` in the working folder."""
    return DEFAULT_ROOT / (name + ("-quick" if quick else ""))


def run_study(name: str, out_dir: Path | None = None, quick: bool = False, note: Note = quiet,
              budget_s: float | None = None) -> StudyResult:
    """Run one study by name.

    Parameters
    ----------
    name : str
        A key of :data:`STUDIES`.
    out_dir : Path, optional
        Folder for the report and data (default :func:`default_out_dir`). Created; files of an
        earlier run of the same study are overwritten.
    quick : bool
        The reduced version (a few minutes on 2 CPU cores); the report says what is reduced.
    note : callable
        Receives one progress line at a time (the command line prints them on stderr).
    budget_s : float, optional
        Wall-clock budget of a sweep (``tradeoff`` only): runs that would not fit are left out
        and listed in the report; cached runs are always used.

    Returns
    -------
    StudyResult

    Raises
    ------
    StudyError
        Unknown study name, or the study's input data is missing.
    """
    if name not in STUDIES:
        raise StudyError(f"unknown study {name!r}; choose one of: {', '.join(STUDIES)}")
    if budget_s is not None:
        if name != "tradeoff":
            raise StudyError(f"a budget applies to the tradeoff sweep only, not to {name!r}")
        if not budget_s > 0:
            raise StudyError(f"the budget must be a positive number of seconds, not {budget_s!r}")
    out = Path(out_dir) if out_dir is not None else default_out_dir(name, quick)
    if out.exists() and not out.is_dir():
        raise StudyError(f"{out} exists and is not a folder")
    out.mkdir(parents=True, exist_ok=True)
    module = importlib.import_module(f"studies.{STUDIES[name]}")
    if budget_s is not None:
        return module.run(out, quick=quick, note=note, budget_s=budget_s)
    return module.run(out, quick=quick, note=note)


#: Files of a study folder that make its published report (the runs' results folders are left out).
PUBLISHED = ("report.md", "*.png", "*.csv", "*.json")


def publish(study_dir: Path, dest_dir: Path) -> list[Path]:
    """Copy a study's report, plots and raw numbers (not its runs) to ``dest_dir``.

    Used to put the reports of full runs into ``docs/validation/NAME/``.

    Parameters
    ----------
    study_dir : Path
        A study's output folder.
    dest_dir : Path
        Created if needed; files of the same names are replaced.

    Returns
    -------
    list of Path
        The copied files.
    """
    study_dir, dest_dir = Path(study_dir), Path(dest_dir)
    if not (study_dir / "report.md").is_file():
        raise StudyError(f"{study_dir} holds no report.md")
    dest_dir.mkdir(parents=True, exist_ok=True)
    copied = []
    for pattern in PUBLISHED:
        for path in sorted(study_dir.glob(pattern)):
            if path.is_file():
                copied.append(Path(shutil.copy2(path, dest_dir / path.name)))
    return copied


__all__ = ["STUDIES", "StudyError", "StudyResult", "default_out_dir", "publish", "run_study"]
