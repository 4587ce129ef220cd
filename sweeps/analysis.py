"""Statistics of a sweep: exceedance curves, probability profiles, sensitivity ranking.

- **Exceedance** of a measure ``X`` from ``n`` completed runs: the empirical survival function
  ``P(X > x) = #{x_i > x} / n`` at each distinct sampled value, with the Dvoretzky-Kiefer-Wolfowitz
  band ``P +- eps``, ``eps = sqrt(ln(2/alpha) / (2 n))`` (Massart 1990's constant; a simultaneous
  ``1 - alpha`` band over all ``x``), clipped to [0, 1].
- **Probability profile** along the section: at each station ``x``, the fraction of completed
  runs whose profile (envelope or final surface) exceeds the threshold, with the Wilson score
  interval (Wilson 1927) of a binomial proportion at ``1 - alpha`` (pointwise). Runs are put on
  one grid by linear interpolation, zero outside a run's own stations (no flow there).
- **Sensitivity**: Spearman's rank correlation (scipy.stats.spearmanr) between each numeric
  parameter and each measure over the completed runs, ranked by ``|rho|``. It measures monotone
  association and needs no special sampling design (SALib's Sobol or Morris indices would need
  their own sample plans, which a sweep of given runs does not have).
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class Exceedance:
    """``P(X > x)`` at the sorted distinct sample values, with the DKW band.

    Attributes
    ----------
    x : numpy.ndarray, shape (k,)
    p : numpy.ndarray, shape (k,)
    lower, upper : numpy.ndarray, shape (k,)
    n : int
        Number of finite samples.
    eps : float
        Half-width of the DKW band.
    samples : numpy.ndarray, shape (n,)
        The sorted finite values.
    """

    x: np.ndarray
    p: np.ndarray
    lower: np.ndarray
    upper: np.ndarray
    n: int
    eps: float
    samples: np.ndarray

    def at(self, x: float) -> float:
        """``P(X > x)`` of the empirical distribution (a right-continuous step function)."""
        return float(np.mean(self.samples > x)) if self.n else math.nan


def dkw_epsilon(n: int, alpha: float = 0.05) -> float:
    """Half-width of the Dvoretzky-Kiefer-Wolfowitz band for ``n`` samples: ``sqrt(ln(2/alpha)/(2n))``."""
    return math.sqrt(math.log(2.0 / alpha) / (2.0 * n)) if n > 0 else math.nan


def exceedance(values: Sequence[float], alpha: float = 0.05) -> Exceedance:
    """Empirical exceedance curve of the finite values, with the DKW band at ``1 - alpha``."""
    v = np.asarray(values, dtype=float)
    v = np.sort(v[np.isfinite(v)])
    n = int(v.size)
    x = np.unique(v)
    p = (n - np.searchsorted(v, x, side="right")) / n if n else np.empty(0)
    eps = dkw_epsilon(n, alpha)
    return Exceedance(x, p, np.clip(p - eps, 0, 1), np.clip(p + eps, 0, 1), n, eps, v)


def wilson_interval(k: np.ndarray | int, n: int, alpha: float = 0.05) -> tuple[np.ndarray, np.ndarray]:
    """Wilson score interval of a binomial proportion ``k/n`` at ``1 - alpha`` (two-sided).

    ``(p + z^2/2n -+ z sqrt(p(1-p)/n + z^2/4n^2)) / (1 + z^2/n)`` with ``z`` the normal quantile.
    """
    from scipy.stats import norm

    k = np.asarray(k, dtype=float)
    if n <= 0:
        return np.full(k.shape, np.nan), np.full(k.shape, np.nan)
    z = float(norm.ppf(1 - alpha / 2))
    p = k / n
    denom = 1 + z * z / n
    centre = (p + z * z / (2 * n)) / denom
    half = z * np.sqrt(p * (1 - p) / n + z * z / (4 * n * n)) / denom
    return np.clip(centre - half, 0, 1), np.clip(centre + half, 0, 1)


@dataclass(frozen=True)
class ProbabilityProfile:
    """``P(field > threshold)`` along the section.

    Attributes
    ----------
    x_m : numpy.ndarray, shape (k,)
    thresholds : tuple of float
    p : numpy.ndarray, shape (len(thresholds), k)
    lower, upper : numpy.ndarray, shape (len(thresholds), k)
        Wilson interval, pointwise.
    n : int
        Runs with a profile.
    """

    x_m: np.ndarray
    thresholds: tuple[float, ...]
    p: np.ndarray
    lower: np.ndarray
    upper: np.ndarray
    n: int


def common_grid(profiles: Sequence[tuple[Sequence[float], Sequence[float]]]) -> np.ndarray:
    """The stations of the profiles: shared ones as they are, else a grid at the finest spacing."""
    xs = [np.asarray(x, dtype=float) for x, _ in profiles]
    if all(x.shape == xs[0].shape and np.allclose(x, xs[0]) for x in xs):
        return xs[0]
    lo = min(float(x.min()) for x in xs)
    hi = max(float(x.max()) for x in xs)
    step = min(float(np.min(np.diff(np.sort(x)))) for x in xs if x.size > 1) if any(x.size > 1 for x in xs) else hi - lo
    count = int(math.floor((hi - lo) / step + 1e-9)) + 1 if step > 0 else 1
    return lo + step * np.arange(count)


def probability_profile(profiles: Sequence[tuple[Sequence[float], Sequence[float]]],
                        thresholds: Sequence[float], alpha: float = 0.05,
                        x_m: np.ndarray | None = None) -> ProbabilityProfile:
    """Fraction of runs whose profile exceeds each threshold at each station (Wilson band).

    Parameters
    ----------
    profiles : sequence of (x_m, values)
        One per completed run; NaN values count as "not exceeded".
    thresholds : sequence of float
        Same unit as the profile field (m for heights, Pa for pressures).
    x_m : numpy.ndarray, optional
        Stations (default :func:`common_grid`).
    """
    thr = tuple(float(t) for t in thresholds)
    if not profiles:
        empty = np.empty((len(thr), 0))
        return ProbabilityProfile(np.empty(0), thr, empty, empty, empty, 0)
    x = common_grid(profiles) if x_m is None else np.asarray(x_m, dtype=float)
    stack = np.empty((len(profiles), x.size))
    for i, (px, pv) in enumerate(profiles):
        px, pv = np.asarray(px, dtype=float), np.asarray(pv, dtype=float)
        order = np.argsort(px)
        stack[i] = np.interp(x, px[order], np.nan_to_num(pv[order], nan=0.0), left=0.0, right=0.0)
    n = len(profiles)
    counts = np.stack([(stack > t).sum(axis=0) for t in thr])
    lower, upper = wilson_interval(counts, n, alpha)
    return ProbabilityProfile(x, thr, counts / n, lower, upper, n)


@dataclass(frozen=True)
class Sensitivity:
    """Spearman rank correlation of one parameter with one measure."""

    measure: str
    parameter: str
    rho: float
    p_value: float
    n: int


def sensitivity(parameters: Mapping[str, Sequence[object]], measures: Mapping[str, Sequence[float]]
                ) -> list[Sensitivity]:
    """Spearman's rho of every numeric parameter with every measure, strongest first per measure.

    Pairs where either side is constant or has fewer than 3 finite pairs get NaN (listed last).
    """
    from scipy.stats import spearmanr

    out: list[Sensitivity] = []
    for mkey, mvals in measures.items():
        m = np.asarray(mvals, dtype=float)
        rows = []
        for pkey, pvals in parameters.items():
            try:
                p = np.asarray(pvals, dtype=float)
            except (TypeError, ValueError):
                continue  # a text parameter (scheme names): no rank correlation
            ok = np.isfinite(m) & np.isfinite(p)
            rho = pv = math.nan
            if ok.sum() >= 3 and np.ptp(p[ok]) > 0 and np.ptp(m[ok]) > 0:
                res = spearmanr(p[ok], m[ok])
                rho, pv = float(res.statistic), float(res.pvalue)
            rows.append(Sensitivity(mkey, pkey, rho, pv, int(ok.sum())))
        rows.sort(key=lambda s: -abs(s.rho) if math.isfinite(s.rho) else 1.0)
        out.extend(rows)
    return out
