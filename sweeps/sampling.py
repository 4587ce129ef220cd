"""Sampling the parameters of a sweep: full grid, random, Latin hypercube (scipy.stats.qmc).

Every parameter maps a probability ``u`` in [0, 1) to a value through its inverse cumulative
distribution (:func:`quantile`): discrete parameters (``list``, ``range``) take the level
``floor(u * n)``, continuous ones scipy.stats' ``ppf``, truncated to ``[low, high]`` by
``ppf(F(low) + u (F(high) - F(low)))``. Random sampling draws ``u`` independently
(numpy's default generator seeded with ``seed``); the Latin hypercube draws one ``u`` in each of
``runs`` equal strata per parameter (scipy.stats.qmc.LatinHypercube with the same seed); the
grid takes every combination of the levels (``list`` values, ``range`` points, or ``levels``
equal-probability quantiles ``(i + 1/2)/levels`` of a continuous distribution).
"""

from __future__ import annotations

import itertools
import math
from typing import Any

import numpy as np

from projects.schema import Problem, ProjectError
from sweeps.spec import Parameter, SweepSpec


def levels(p: Parameter) -> list[Any]:
    """The discrete levels of a parameter: its values, its range points or its quantile levels."""
    if p.distribution == "list":
        return list(p.values or [])
    if p.distribution == "range":
        pts = np.linspace(float(p.low), float(p.high), int(p.count)) if p.count and p.count > 1 else np.array([float(p.low)])
        if all(isinstance(v, int) for v in (p.low, p.high)) and np.allclose(pts, np.round(pts)):
            return [int(round(v)) for v in pts]
        return [float(v) for v in pts]
    if p.levels is None:
        raise ValueError("levels")
    u = (np.arange(p.levels) + 0.5) / p.levels
    return [float(v) for v in quantile(p, u)]


def _scipy_dist(p: Parameter) -> Any:
    from scipy import stats

    if p.distribution == "normal":
        return stats.norm(loc=float(p.mean), scale=float(p.std))
    if p.distribution == "lognormal":
        return stats.lognorm(s=float(p.std_log), scale=math.exp(float(p.mean_log)))
    return stats.uniform(loc=float(p.low), scale=float(p.high) - float(p.low))


def quantile(p: Parameter, u: np.ndarray) -> np.ndarray | list[Any]:
    """Map probabilities ``u`` in [0, 1) to parameter values (inverse CDF, truncated where set).

    Parameters
    ----------
    p : Parameter
    u : numpy.ndarray, shape (n,)

    Returns
    -------
    numpy.ndarray of float (continuous) or list (``list``/``range``: the levels' own values)
    """
    u = np.clip(np.asarray(u, dtype=float), 0.0, np.nextafter(1.0, 0.0))
    if p.distribution in ("list", "range"):
        lv = levels(p)
        idx = np.minimum((u * len(lv)).astype(int), len(lv) - 1)
        return [lv[i] for i in idx]
    dist = _scipy_dist(p)
    if p.distribution == "uniform":
        return float(p.low) + u * (float(p.high) - float(p.low))
    with np.errstate(all="ignore"):  # a std of 5e-324 overflows (x - mean) / std to inf: cdf 0 or 1, as meant
        lo = dist.cdf(float(p.low)) if p.low is not None else 0.0
        hi = dist.cdf(float(p.high)) if p.high is not None else 1.0
        values = dist.ppf(lo + u * (hi - lo))
    # ppf round-off may step a hair outside the truncation
    if p.low is not None:
        values = np.maximum(values, float(p.low))
    if p.high is not None:
        values = np.minimum(values, float(p.high))
    return values


def sample(spec: SweepSpec) -> list[dict[str, Any]]:
    """The parameter values of every run of a sweep, in run order.

    Returns
    -------
    list of dict
        One ``{key path: value}`` per run (Python scalars).

    Raises
    ------
    ProjectError
        A grid with a continuous parameter without ``levels``, or ``runs`` that contradicts the grid.
    """
    keys = list(spec.parameters)
    params = [spec.parameters[k] for k in keys]
    table = spec.sweep
    if table.sampling == "grid":
        grids = []
        for key, p in zip(keys, params):
            try:
                grids.append(levels(p))
            except ValueError:
                raise ProjectError([Problem(f'parameters."{key}"', None, f'a "{p.distribution}" parameter '
                                            'needs levels (how many quantile levels) with sampling "grid"')]) from None
        combos = list(itertools.product(*grids))
        if table.runs is not None and table.runs != len(combos):
            raise ProjectError([Problem("sweep.runs", table.runs, f"the grid has {len(combos)} runs (the product of "
                                        "the levels); remove runs or set it to that")])
        return [{k: _plain(v) for k, v in zip(keys, combo)} for combo in combos]
    n = int(table.runs)
    u = unit_samples(table.sampling, n, len(params), table.seed)
    columns = [quantile(p, u[:, j]) for j, p in enumerate(params)]
    return [{k: _plain(columns[j][i]) for j, k in enumerate(keys)} for i in range(n)]


def unit_samples(sampling: str, n: int, d: int, seed: int) -> np.ndarray:
    """``n`` points in the unit cube ``[0, 1)^d``: ``random`` or ``latin-hypercube``, seeded.

    Returns
    -------
    numpy.ndarray, shape (n, d)
    """
    if sampling == "random":
        return np.random.default_rng(seed).random((n, d))
    if sampling == "latin-hypercube":
        from scipy.stats import qmc

        return qmc.LatinHypercube(d=d, rng=np.random.default_rng(seed)).random(n)
    raise ValueError(f"unknown sampling {sampling!r}")


def _plain(value: Any) -> Any:
    if isinstance(value, np.generic):
        return value.item()
    return value
