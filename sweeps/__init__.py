"""Sweeps, Monte Carlo and back-analysis of projects on Ray (``runout sweep``, ``runout calibrate``).

The package drives many ``runout run`` processes through Ray tasks (:mod:`sweeps.engine`); it never
imports Taichi, Qt or pyvista in the driver process. Entry points:

- :func:`sweeps.spec.load_spec`: read a sweep or calibration file (ProjectError on bad input).
- :func:`sweeps.sweep.run_sweep` / :func:`sweeps.folder.read_sweep`: run a sweep into a folder,
  read it back (live or finished: ``progress.json`` and ``sweep.csv`` are rewritten after each run).
- :func:`sweeps.calibrate.run_calibration` / :func:`sweeps.calibrate.read_calibration`.
- :func:`sweeps.report.write_report`: report.html of a sweep or calibration folder.
"""
