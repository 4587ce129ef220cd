"""Constitutive models behind one interface: per-material parameter tables and ``stress_update``.

Each model lives in its own module (``linear_elastic``, ``drucker_prager``); the three step
schemes all call :func:`MaterialTable.stress_update`, so they are compared on the same physics.
Material parameters live in per-material tables (one row per material); state lives per particle.
"""


import math
from collections.abc import Sequence

import numpy as np
from solver.runtime import mat_mat, ti, transpose

from solver.config import Material, flows_inertially, has_rigid, softens
from solver.contact import contact_codes
from solver.fieldio import FieldIO
from solver.materials import drucker_prager, linear_elastic, softening

MODEL_CODES = {"linear-elastic": 0, "drucker-prager": 1, "rigid": 2}
#: The model code of a rigid body (solver/rigid.py: no stress update, no weight)
RIGID = MODEL_CODES["rigid"]
#: Columns of the per-material table (one Taichi field each).
MATERIAL_COLUMNS = ("model", "K", "G", "alpha", "kc", "alpha_psi", "t_cut", "rho0", "beta", "relax")
#: The softening's columns (solver/materials/softening.py): the law's code (0: none), its
#: strains, the factor from plastic strain to softening strain, the match's code, peak and
#: residual (c Pa, phi rad, psi rad) and the tensile strength (Pa, 1e30 for none)
SOFTENING_COLUMNS = ("soft_law", "soft_e_peak", "soft_e_res", "soft_scale", "soft_match", "soft_peak",
                     "soft_res", "soft_tension")
#: The mu(I) law's columns (solver.config.InertialFriction): the friction increase over the
#: material's own ``tan(phi)`` (0: none), the reference inertial number ``I0`` and
#: ``d sqrt(rho_s)``, so that ``I = gamma_dot d sqrt(rho_s) / sqrt(p)``
INERTIAL_COLUMNS = ("mui_ratio", "mui_i0", "mui_scale")
#: A rigid body's columns (solver/rigid.py): its velocity in dynamic stages (m/s), its contact's
#: kind code and friction coefficient, and its index among the rigid materials (-1: not rigid)
RIGID_COLUMNS = ("rigid_v", "rigid_kind", "rigid_mu", "rigid_index")
_INT_COLUMNS = ("model", "soft_law", "soft_match", "rigid_kind", "rigid_index")
softening.check_match_codes(drucker_prager.MATCHES)


def material_rows(materials: Sequence[Material], cell_size_m: float | None = None) -> dict[str, np.ndarray]:
    """The per-material parameter table as numpy columns (SI units); ``cell_size_m`` sets the
    softening's regularisation scale (None: one, as in a single-point test)."""
    rows: dict[str, list] = {k: [] for k in MATERIAL_COLUMNS + SOFTENING_COLUMNS + INERTIAL_COLUMNS + RIGID_COLUMNS}
    rigid_count = 0
    for m in materials:
        kind, mu = contact_codes((m.contact,))
        rows["rigid_v"].append(m.velocity_m_s if m.rigid else (0.0, 0.0))
        rows["rigid_kind"].append(int(kind[0]))
        rows["rigid_mu"].append(float(mu[0]))
        rows["rigid_index"].append(rigid_count if m.rigid else -1)
        rigid_count += int(m.rigid)
        mui = m.inertial if m.model == "drucker-prager" and m.friction_angle_rad > 0.0 else None
        rows["mui_ratio"].append(0.0 if mui is None else mui.friction_increase / math.tan(m.friction_angle_rad))
        rows["mui_i0"].append(1.0 if mui is None else mui.reference_inertial_number)
        rows["mui_scale"].append(0.0 if mui is None else mui.grain_diameter_m * math.sqrt(mui.grain_density_kg_m3))
        soft = m.softening if m.model == "drucker-prager" else None
        peak = (m.cohesion_pa, m.friction_angle_rad, m.dilatancy_angle_rad)
        rows["soft_law"].append(0 if soft is None else softening.LAW_CODES[soft.law])
        rows["soft_e_peak"].append(0.0 if soft is None else soft.peak_strain)
        rows["soft_e_res"].append(1.0 if soft is None else soft.residual_strain)
        rows["soft_scale"].append(1.0 if soft is None else softening.regularisation_scale(soft.length_m, cell_size_m))
        rows["soft_match"].append(softening.MATCH_CODES[m.mohr_coulomb_match])
        rows["soft_peak"].append(peak)
        rows["soft_res"].append(peak if soft is None else (soft.residual_cohesion_pa, soft.residual_friction_angle_rad,
                                                           soft.residual_dilatancy_angle_rad))
        rows["soft_tension"].append(1e30 if m.tensile_strength_pa is None else min(m.tensile_strength_pa, 1e30))
        alpha, kc, alpha_psi = drucker_prager.dp_constants(
            m.friction_angle_rad, m.dilatancy_angle_rad, m.cohesion_pa, m.mohr_coulomb_match
        )
        if m.model == "drucker-prager":
            apex = kc / (3.0 * alpha) if alpha > 0.0 else math.inf
            t_cut = apex if m.tensile_strength_pa is None else min(apex, m.tensile_strength_pa)
        else:
            t_cut = math.inf
        rows["model"].append(MODEL_CODES[m.model])
        rows["K"].append(m.bulk_modulus_pa)
        rows["G"].append(m.shear_modulus_pa)
        rows["alpha"].append(alpha)
        rows["kc"].append(kc)
        rows["alpha_psi"].append(alpha_psi)
        rows["t_cut"].append(min(t_cut, 1e30))
        rows["rho0"].append(m.density_kg_m3)
        rows["beta"].append(m.damping_beta_s)
        rows["relax"].append(m.damping_relaxation_s)
    return {k: np.asarray(v, dtype=np.int32 if k in _INT_COLUMNS else np.float64) for k, v in rows.items()}


@ti.data_oriented
class MaterialTable:
    """Taichi fields holding one row of constitutive constants per material.

    With ``shared_io`` the table has no field I/O of its own until :meth:`use_io` hands it one
    that also moves other fields (the engine's: one copy kernel compiled per process instead of
    two, see solver.fieldio); its rows are loaded then.
    """

    def __init__(self, materials: Sequence[Material], np_float=np.float32, shared_io: bool = False,
                 cell_size_m: float | None = None, softening: bool | None = None, inertial: bool | None = None):
        n = max(1, len(materials))
        self.np_float = np_float
        self.count = len(materials)
        self.cell_size_m = cell_size_m
        #: some material may soften (compiled in; default: one of ``materials`` does; a run whose
        #: stages change materials decides it for all of them)
        self.softening = softens(materials) if softening is None else bool(softening)
        #: some material's friction depends on the rate (mu(I), compiled in only then; default: one of
        #: ``materials``'s does)
        self.inertial = flows_inertially(materials) if inertial is None else bool(inertial)
        self.model = ti.field(ti.i32, n)
        self.K = ti.field(float, n)
        self.G = ti.field(float, n)
        self.alpha = ti.field(float, n)
        self.kc = ti.field(float, n)
        self.alpha_psi = ti.field(float, n)
        self.t_cut = ti.field(float, n)
        self.rho0 = ti.field(float, n)
        self.beta = ti.field(float, n)  # the damping's viscosity per unit stiffness, s
        self.relax = ti.field(float, n)  # the Maxwell arm's relaxation time, s (0: Rayleigh)
        names = MATERIAL_COLUMNS
        if self.softening:
            for name in ("soft_law", "soft_match"):
                setattr(self, name, ti.field(ti.i32, n))
            for name in ("soft_e_peak", "soft_e_res", "soft_scale", "soft_tension"):
                setattr(self, name, ti.field(float, n))
            self.soft_peak = ti.Vector.field(3, float, n)
            self.soft_res = ti.Vector.field(3, float, n)
            names = names + SOFTENING_COLUMNS
        if self.inertial:
            for name in INERTIAL_COLUMNS:
                setattr(self, name, ti.field(float, n))
            names = names + INERTIAL_COLUMNS
        #: some material is a rigid body (solver/rigid.py, compiled in only then); fixed at
        #: construction, as the stages' changes keep every material's model
        self.rigid = has_rigid(materials)
        #: the rigid materials' names, in their index order (their contacts follow the structures')
        self.rigid_names = tuple(m.name for m in materials if m.rigid)
        if self.rigid:
            self.rigid_v = ti.Vector.field(2, float, n)
            self.rigid_kind = ti.field(ti.i32, n)
            self.rigid_mu = ti.field(float, n)
            self.rigid_index = ti.field(ti.i32, n)
            names = names + RIGID_COLUMNS
        #: the table's fields by column name
        self.columns = {name: getattr(self, name) for name in names}
        #: the table as loaded, numpy columns in the fields' dtypes
        self.host: dict[str, np.ndarray] = {}
        self._materials = tuple(materials)
        self._io: FieldIO | None = None
        if not shared_io:
            self.use_io(FieldIO(self.columns))

    def use_io(self, io: FieldIO) -> None:
        """Move the table's fields with ``io`` (it must hold :attr:`columns` under their names) and
        load the rows."""
        self._io = io
        self.load(self._materials)

    def load(self, materials: Sequence[Material]) -> None:
        """Replace every row (a stage's material changes): one kernel launch for the whole table."""
        if softens(materials) and not self.softening:
            raise ValueError("a material softens, but the table was built without softening")
        if flows_inertially(materials) and not self.inertial:
            raise ValueError("a material's friction depends on the rate (mu(I)), but the table was built without it")
        if tuple(m.name for m in materials if m.rigid) != self.rigid_names:
            raise ValueError("a stage's materials must keep which of them are rigid bodies")
        rows = material_rows(materials, self.cell_size_m)
        self.host = {name: column.astype(np.int32 if name in _INT_COLUMNS else self.np_float)
                     for name, column in rows.items() if name in self.columns}
        self._materials = tuple(materials)
        if len(materials) and self._io is not None:
            self._io.write(self.host)

    @ti.func
    def stress_update(self, mat, s, D, W, dt, eps):
        """Jaumann elastic trial, then the material's plastic correction; ``eps``: the particle's
        equivalent plastic strain before the step (a softening material's strength follows it).

        Returns (stress vec4, equivalent plastic strain increment, yielded 0/1).
        """
        K = self.K[mat]
        G = self.G[mat]
        trial = linear_elastic.trial_stress(s, D, W, dt, K, G)
        out = trial
        deq = 0.0 * K
        yielded = 0
        if self.model[mat] == 1:
            if ti.static(self.softening):
                if self.soft_law[mat] > 0:
                    out, deq, yielded = drucker_prager.return_map_softening(
                        trial, K, G, eps, self.soft_scale[mat], self.soft_law[mat], self.soft_e_peak[mat],
                        self.soft_e_res[mat], self.soft_match[mat], self.soft_peak[mat], self.soft_res[mat],
                        self.soft_tension[mat], ti.Vector([self.alpha[mat], self.kc[mat], self.alpha_psi[mat]]))
                else:
                    out, deq, yielded = drucker_prager.return_map(
                        trial, K, G, self.alpha[mat], self.kc[mat], self.alpha_psi[mat], self.t_cut[mat])
            else:
                alpha = self.alpha[mat]
                if ti.static(self.inertial):
                    alpha *= 1.0 + self.mui_ratio[mat] * self._inertial_fraction(mat, trial, D)
                out, deq, yielded = drucker_prager.return_map(
                    trial, K, G, alpha, self.kc[mat], self.alpha_psi[mat], self.t_cut[mat]
                )
        return out, deq, yielded

    @ti.func
    def _inertial_fraction(self, mat, s, D):
        """``I / (I0 + I)`` of the mu(I) law (solver.config.InertialFriction) at the rate of
        deformation ``D`` (in-plane; no out-of-plane rate) and the pressure of the stress ``s``
        (the step's elastic trial): the inertial number ``I = gamma_dot d / sqrt(p / rho_s)`` with
        ``gamma_dot = sqrt(2 D':D')``; 1 where the material carries no pressure (``I`` without
        bound), 0 at rest."""
        tr = D[0, 0] + D[1, 1]
        d0 = D[0, 0] - tr / 3.0
        d1 = D[1, 1] - tr / 3.0
        dz = -tr / 3.0
        gamma_dot = ti.sqrt(2.0 * (d0 * d0 + d1 * d1 + dz * dz + 2.0 * D[0, 1] * D[0, 1]))
        pressure = ti.max(-(s[0] + s[1] + s[3]) / 3.0, 0.0)
        x = gamma_dot * self.mui_scale[mat]
        return x / (self.mui_i0[mat] * ti.sqrt(pressure) + x + 1e-30)

    @ti.func
    def viscous_stress(self, mat, sv, D, W, dt, before, after, yielded):
        """The damping stress after a step of ``dt`` at strain rate ``D`` and spin ``W``, from
        ``sv`` before it (plane xx, yy, xy; Pa): ``beta C^e : D_e``, a dashpot beside the
        material's own response on the elastic part of the rate of deformation (``C^e : D_e`` is
        ``C^e : D`` less the step's plastic correction, from the stress ``before`` and ``after``
        the update where it ``yielded``), zero for rigid motion and for steady plastic flow
        (Rayleigh); the Maxwell arm's stress, turned with the material (Jaumann, as the
        material's own), relaxes towards it in its time ``t``: ``sv e + (1 - e) beta C^e : D_e``
        with ``e = exp(-dt / t)``, exact for a constant rate."""
        K = self.K[mat]
        G = self.G[mat]
        beta = self.beta[mat]
        lam = K - 2.0 * G / 3.0
        tr = D[0, 0] + D[1, 1]
        rate = ti.Vector([lam * tr + 2.0 * G * D[0, 0], lam * tr + 2.0 * G * D[1, 1], 2.0 * G * D[0, 1]])
        if yielded:
            correction = linear_elastic.trial_stress(before, D, W, dt, K, G) - after
            rate -= ti.Vector([correction[0], correction[1], correction[2]]) / dt
        target = beta * rate
        tau = self.relax[mat]
        out = target
        if tau > 0.0:
            S = ti.Matrix([[sv[0], sv[2]], [sv[2], sv[1]]])
            rot = mat_mat(W, S) - mat_mat(S, W)
            turned = sv + dt * ti.Vector([rot[0, 0], rot[1, 1], rot[0, 1]])
            e = ti.exp(-dt / tau)
            out = e * turned + (1.0 - e) * target
        return out


@ti.data_oriented
class MaterialPointDriver:
    """Single-point driver for closed-form material tests: applies ``stress_update`` to a batch.

    Needs an acquired runtime (:func:`solver.runtime.acquire`).
    """

    def __init__(self, materials: Sequence[Material], n: int, np_float=np.float64, cell_size_m: float | None = None):
        self.table = MaterialTable(materials, np_float, cell_size_m=cell_size_m)
        self.np_float = np_float
        self.n = n
        self.s = ti.Vector.field(4, float, n)
        self.L = ti.Matrix.field(2, 2, float, n)
        self.mat = ti.field(ti.i32, n)
        self.deq = ti.field(float, n)
        self.eps = ti.field(float, n)  # the accumulated equivalent plastic strain
        self.yielded = ti.field(ti.i32, n)

    @ti.kernel
    def _update(self, dt: float):
        for i in range(self.n):
            L = self.L[i]
            Lt = transpose(L)
            D = 0.5 * (L + Lt)
            W = 0.5 * (L - Lt)
            s, deq, y = self.table.stress_update(self.mat[i], self.s[i], D, W, dt, self.eps[i])
            self.s[i] = s
            self.deq[i] += deq
            self.eps[i] += deq
            self.yielded[i] = y

    def run(self, stress: np.ndarray, velocity_gradient: np.ndarray, dt_s: float, steps: int = 1,
            material_ids: np.ndarray | None = None, plastic_strain: np.ndarray | None = None,
            history: bool = False) -> dict[str, np.ndarray]:
        """Apply ``steps`` updates with a constant velocity gradient, from the accumulated
        equivalent plastic strain ``plastic_strain`` (default zero). With ``history`` the result
        also holds ``stress_history`` and ``strain_history``, (steps, n, 4) and (steps, n), after
        each step.

        Parameters
        ----------
        stress : (n, 4) float, Pa (xx, yy, xy, zz)
        velocity_gradient : (n, 2, 2) float, 1/s
        """
        self.s.from_numpy(np.asarray(stress, dtype=self.np_float))
        self.L.from_numpy(np.asarray(velocity_gradient, dtype=self.np_float))
        self.mat.from_numpy(np.zeros(self.n, np.int32) if material_ids is None else material_ids.astype(np.int32))
        self.deq.fill(0.0)
        self.eps.from_numpy(np.zeros(self.n, self.np_float) if plastic_strain is None
                            else np.asarray(plastic_strain, dtype=self.np_float))
        stresses, strains = [], []
        for _ in range(steps):
            self._update(dt_s)
            if history:
                stresses.append(self.s.to_numpy())
                strains.append(self.eps.to_numpy())
        out = {"stress": self.s.to_numpy(), "plastic_strain": self.deq.to_numpy(), "yielded": self.yielded.to_numpy()}
        if history:
            out["stress_history"] = np.asarray(stresses)
            out["strain_history"] = np.asarray(strains)
        return out
