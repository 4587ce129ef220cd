"""Limit-equilibrium slope stability (numpy only): Bishop's simplified method of slices.

:mod:`stability.bishop` finds the critical circular slip surface of a 2D section made of
polygons of Mohr-Coulomb soils, dry or with water (a phreatic line, free water, ``ru``). It
knows nothing of the solver, the projects or the app; the strength-reduction driver (:mod:`projects.strength`) reports its factor beside the MPM one.
"""

from stability.bishop import (
    Circle,
    NoAdmissibleCircle,
    Section,
    SlipResult,
    Soil,
    Water,
    bishop_factor,
    critical_circle,
    fellenius_factor,
    slices_factor,
)

__all__ = [
    "Circle",
    "NoAdmissibleCircle",
    "Section",
    "SlipResult",
    "Soil",
    "Water",
    "bishop_factor",
    "critical_circle",
    "fellenius_factor",
    "slices_factor",
]
