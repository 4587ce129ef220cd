"""What the wall's contact nodes do in one incline case (docs/validation.md, contact: issue 11's
remaining failures).

One block of :class:`studies.contact_scenes.WallIncline` on the bottom wall, settled and released as
in the matrix, then stepped stage by stage so that the contact law's input and output at the wall
line's nodes can be read at the main grid update (the law acts there on ``v_old + dt f / m``,
apic-affine on its fused momentum; mpm and apic apply it also to the interpolated velocity, which
is not counted here). Printed:

- per wall node under the block, the fraction of steps in stick (tangential velocity cancelled),
  slip down the slope, slip up the slope, separation (trial normal velocity not into the wall);
- the time-mean friction impulse over ``mu`` times the time-mean normal impulse, for the whole
  contact (the recorded contact impulse) and for the wall line's nodes, and how much of the
  friction that ``mu N`` allows is not given in stick steps and in slip steps, with the normal
  and tangential speeds of those steps;
- the wall node's mass at stick and slip steps, against its value at the release;
- the block's kinetic energy of translation and the rest (elastic waves and rotation), over time.

- with ``--light-share`` (on by default from the command line: 0.01): the light nodes (mass below that
  fraction of a full node's ``rho dx^2``), their speed after the grid update and their share of the
  particles' G2P velocity, affine matrix ``C`` and (mpm, apic) the velocity gradient of the stress
  update (the norm of their terms over the norm of the whole, all particles, per step).

Experiments (not the engine's law; docs/validation.md, contact), at the main grid update unless said:
``--transfer`` (a stuck wall node's unused friction to the node inside it); ``--light F
--light-mode old|zero`` (nodes below F of a full node take their interpolated velocity, no force,
as MUSL's re-mapping gives it (six-stage schemes), or are treated as empty); ``--gap F`` (wall nodes
below F of a full node take no contact); ``--lag K [--lag-all]`` (the wall line's friction bound
follows each node's normal impulse with a lag of K steps; with ``--lag-all`` also while
separating); ``--patch R [--patch-iter P] [--patch-first]`` (patch friction: each approaching wall
node's allowance ``mu m |vn|`` shared among the approaching wall nodes within R cells along the wall
by binomial weight x mass, capped at each node's tangential momentum, what a capped node cannot take
going round again, P passes; with ``--patch-first`` also at the first application, on the
interpolated velocity; ``--patch-rows 3``: over the wall line and its two ghost rows, a square
patch); ``--transfer-first``, ``--transfer-depth D``, ``--transfer-spread`` (the
transfer also at the first application, down D rows of nodes inside, over the three columns about
the node by mass). ``--dx`` changes the cell size (refinement of the same block with ``--aspect``).

Also printed: a momentum audit of the block (the recorded normal impulse over the weight's normal
impulse; the recorded friction, and the friction the block's final momentum says it felt, over
``mu`` times the weight's normal impulse: with an experiment, which the recorded impulse does not
see, the felt one is the measure); the signed friction at the wall line; and where the friction
lost in stick steps sits (is a wall node within two cells slipping, could the node inside take it).

With Cundall's damping (``--damping``) the six-stage schemes' trial velocity read here leaves the
damping out (the counts are then approximate; the slip is the engine's).

Usage::

    PYTHONPATH=$PWD python -m benchmarks.contact_diagnose apic-affine f64 20 1e6 40 45 [--aspect 4]
        [--time 1] [--damping 0] [--cfl 0.5] [--ppc 2] [--dx 2] [--samples 12] [--light-share 0.01]
        [--transfer [--transfer-first --transfer-depth 3 --transfer-spread] | --patch 2 --patch-iter 3
         [--patch-first] | --light 0.01 --light-mode old | --gap 0.02 | --lag 30 --lag-all]
"""

from __future__ import annotations

import argparse
import math
import sys

import numpy as np

PAD_ROW = 2  # solver.engine.PAD (the wall line's node index), checked in diagnose()


def node_law_engine():
    """The engine with friction decided node by node at the wall line and at each ghost node (the
    law of sessions 8-10, which this diagnosis reads and its experiments change), not by wall
    column (``Engine.COLUMN_FRICTION``, docs/solver.md, contact)."""
    from solver.engine import Engine

    class NodeLawEngine(Engine):
        COLUMN_FRICTION = False

    return NodeLawEngine


def diagnose(scheme: str, precision: str, thickness: int, youngs: float, theta: float, delta: float,
             aspect: float = 4.0, time_factor: float = 1.0, damping: float = 0.0, samples: int = 12,
             transfer: bool = False, light: float = 0.0, light_mode: str = "", light_share: float = 0.0,
             gap: float = 0.0, lag: float = 0.0, lag_all: bool = False, patch: int = 0, patch_iter: int = 1,
             patch_rows: int = 1, patch_first: bool = False, transfer_first: bool = False, transfer_depth: int = 1,
             transfer_spread: bool = False) -> dict:
    """One case (bottom wall); ``transfer``: the experiment of docs/validation.md (contact; not the
    engine's law): after the grid update, the friction a stuck wall node left unused is applied to
    the node one cell inside it, never reversing that node's velocity along the wall."""
    from solver import runtime
    from solver.engine import PAD
    from studies import contact_scenes as cs

    assert PAD == PAD_ROW
    runtime.acquire("cpu", precision)
    try:
        sc = cs.WallIncline(scheme, precision, thickness, youngs, "bottom", aspect=aspect, engine_class=node_law_engine())
        e = sc.engine

        g = sc.gravity(theta)
        dt = sc.release(theta, delta)
        t_end = cs.run_time(theta, delta, sc.dx) * time_factor
        steps = int(math.ceil(t_end / dt))
        dt = t_end / steps
        x0 = e.x.to_numpy().astype(np.float64)
        m = e.m.to_numpy()[: e.n].astype(np.float64)
        mu = math.tan(math.radians(delta))
        e.read_contacts()
        recipe = e.recipe
        cut = recipe.index("grid update")
        counts = None
        lost = {"stick": 0.0, "slip": 0.0}
        signed = [0.0, 0.0]
        transfer_lost = [0.0, 0.0]  # friction left unused at stuck wall nodes; what the nodes inside could not take
        where_lost = {"slip": 0.0, "stick": 0.0, "none": 0.0, "inside_room": 0.0}
        speeds = {"stick_vn": [], "stick_vt": [], "slip_vn": [], "stick_m": [], "slip_m": [], "stick_lost": []}
        full = None
        normal = friction = 0.0
        energy = []
        every = max(1, steps // samples)

        nbar = None
        full_node = cs.DENSITY * sc.dx * sc.dx  # mass of a node inside uniform material
        origin = np.asarray(sc.grid.origin_m, float)
        lightstat = {"sep_speed": [], "sep_count": 0, "C_share": [], "C_rms": [], "v_share": [], "L_share": [],
                     "wall_sep_speed": [], "wall_sep_vn": []}

        def kernel(stage):
            e._stage_kernel(stage, dt, g[0], g[1], damping, damping > 0.0)

        for k in range(steps):
            if patch_first and e.six_stage:
                # experiment: the patch at the first application of the law too (interpolated velocity)
                first = recipe.index("grid velocity")
                for stage in recipe[:first]:
                    kernel(stage)
                M0 = e.g_mass.to_numpy()[:, PAD]
                trial0 = e.g_mom.to_numpy()[:, PAD] / np.maximum(M0, 1e-300)[:, None]
                kernel("grid velocity")
                V = e.g_v_old.to_numpy()
                _patch(V, M0, trial0, mu, patch, patch_iter)
                e.g_v_old.from_numpy(V)
                for stage in recipe[first + 1:cut]:
                    kernel(stage)
            elif transfer_first and e.six_stage:
                # experiment: the same transfer at the first application of the law (interpolated velocity)
                first = recipe.index("grid velocity")
                for stage in recipe[:first]:
                    kernel(stage)
                M0 = e.g_mass.to_numpy()
                trial0 = e.g_mom.to_numpy()[:, PAD] / np.maximum(M0[:, PAD], 1e-300)[:, None]
                kernel("grid velocity")
                V = e.g_v_old.to_numpy()
                left = _unused(M0[:, PAD], trial0, V[:, PAD, 0], mu)
                transfer_lost[1] += _pass_inside(V, M0, left, transfer_depth, transfer_spread)
                transfer_lost[0] += left.sum()
                e.g_v_old.from_numpy(V)
                for stage in recipe[first + 1:cut]:
                    kernel(stage)
            else:
                for stage in recipe[:cut]:
                    kernel(stage)
            M = e.g_mass.to_numpy()[:, PAD]
            if e.six_stage:
                trial = e.g_v_old.to_numpy()[:, PAD] + dt * e.g_f.to_numpy()[:, PAD] / np.maximum(M, 1e-300)[:, None]
            else:
                trial = e.g_mom.to_numpy()[:, PAD] / np.maximum(M, 1e-300)[:, None]
                if damping > 0.0:
                    trial = trial + dt * e.g_f.to_numpy()[:, PAD] / np.maximum(M, 1e-300)[:, None]
            if patch > 0 and patch_rows > 1:  # the ghost rows' trial velocities too
                Mg = e.g_mass.to_numpy()[:, PAD - patch_rows + 1: PAD + 1]
                if e.six_stage:
                    trial_g = (e.g_v_old.to_numpy()[:, PAD - patch_rows + 1: PAD + 1]
                               + dt * e.g_f.to_numpy()[:, PAD - patch_rows + 1: PAD + 1] / np.maximum(Mg, 1e-300)[..., None])
                else:
                    trial_g = e.g_mom.to_numpy()[:, PAD - patch_rows + 1: PAD + 1] / np.maximum(Mg, 1e-300)[..., None]
            kernel("grid update")
            if light > 0.0 and light_mode:
                # experiment (not the engine's law): nodes below ``light`` of a full node's mass
                Mall = e.g_mass.to_numpy()
                G = e.g_mom.to_numpy()
                sel = (Mall > 0.0) & (Mall < light * full_node)
                if light_mode == "old":  # velocity from the momentum alone (no force), then the contact
                    if not e.six_stage:
                        raise ValueError("--light-mode old needs a six-stage scheme (mpm, apic)")
                    V = e.g_v_old.to_numpy()
                    G[sel] = V[sel]
                elif light_mode == "zero":
                    G[sel] = 0.0
                e.g_mom.from_numpy(G)
            if lag > 0.0:
                # experiment: the friction bound of each wall-line node follows its normal impulse with a
                # relaxation of ``lag`` steps (Prakash-Clifton type); ``lag_all``: also while separating
                G = e.g_mom.to_numpy()
                if nbar is None:
                    nbar = np.zeros(len(M))
                N = np.where((M > 0.0) & (trial[:, 1] < 0.0), M * np.maximum(-trial[:, 1], 0.0), 0.0)
                nbar += (N - nbar) / lag
                act = (M > 0.0) & ((trial[:, 1] < 0.0) | lag_all)
                vt = trial[:, 0]
                new_t = np.sign(vt) * np.maximum(np.abs(vt) - mu * nbar / np.maximum(M, 1e-300), 0.0)
                G[act, PAD, 0] = new_t[act]
                G[act & (trial[:, 1] < 0.0), PAD, 1] = 0.0
                e.g_mom.from_numpy(G)
            if gap > 0.0:
                # experiment: a wall node whose mass says the material has left the wall (below ``gap``
                # of a full node's mass) takes no contact: its trial velocity, unconstrained
                G = e.g_mom.to_numpy()
                open_ = (M > 0.0) & (M < gap * full_node)
                G[open_, PAD] = trial[open_]
                e.g_mom.from_numpy(G)
            if light_share > 0.0:
                # the share of the particles' G2P velocity and affine matrix that comes from light nodes
                Mall = e.g_mass.to_numpy()
                G = e.g_mom.to_numpy()
                xp = e.x.to_numpy()[: e.n].astype(np.float64)
                X = (xp - origin) / sc.dx + PAD
                base = np.floor(X - 0.5).astype(int)
                fx = X - base
                W = [0.5 * (1.5 - fx) ** 2, 0.75 - (fx - 1.0) ** 2, 0.5 * (fx - 0.5) ** 2]
                DW = [fx - 1.5, -2.0 * (fx - 1.0), fx - 0.5]
                Vold = e.g_v_old.to_numpy() if e.six_stage else None
                Ll = np.zeros((e.n, 2, 2))
                Lt = np.zeros((e.n, 2, 2))
                Cl = np.zeros((e.n, 2, 2))
                Ct = np.zeros((e.n, 2, 2))
                vl = np.zeros((e.n, 2))
                vt_ = np.zeros((e.n, 2))
                for i in range(3):
                    for j in range(3):
                        w = W[i][:, 0] * W[j][:, 1]
                        I0 = base[:, 0] + i
                        I1 = base[:, 1] + j
                        gv = G[I0, I1]
                        dpos = (np.array([i, j]) - fx) * sc.dx
                        c = 4.0 / sc.dx ** 2 * w[:, None, None] * gv[:, :, None] * dpos[:, None, :]
                        lt = (Mall[I0, I1] < light_share * full_node)
                        Ct += c
                        if Vold is not None:  # the six-stage schemes' velocity gradient (stress update)
                            grad = np.c_[DW[i][:, 0] * W[j][:, 1], W[i][:, 0] * DW[j][:, 1]] / sc.dx
                            lc = Vold[I0, I1][:, :, None] * grad[:, None, :]
                            Lt += lc
                            Ll += lc * lt[:, None, None]
                        Cl += c * lt[:, None, None]
                        vt_ += w[:, None] * gv
                        vl += (w * lt)[:, None] * gv
                if Vold is not None:
                    lightstat["L_share"].append(np.linalg.norm(Ll) / max(np.linalg.norm(Lt), 1e-300))
                lightstat["C_share"].append(np.linalg.norm(Cl) / max(np.linalg.norm(Ct), 1e-300))
                lightstat["v_share"].append(np.linalg.norm(vl) / max(np.linalg.norm(vt_), 1e-300))
                lightstat["C_rms"].append(np.sqrt((Ct ** 2).sum((1, 2)).mean()))
                sepl = (Mall > 0) & (Mall < light_share * full_node) & (np.linalg.norm(G, axis=-1) > 0)
                lightstat["sep_speed"] += np.linalg.norm(G[sepl], axis=-1).tolist()
            if patch > 0:
                # experiment: patch friction at the wall line (grid update only); each approaching node's
                # allowance mu m |vn| shared among the approaching nodes within ``patch`` cells along the
                # wall in proportion to binomial weight x mass, capped at each node's tangential momentum;
                # what a capped node cannot take goes round again (``patch_iter`` passes)
                G = e.g_mom.to_numpy()
                if patch_rows > 1:
                    _patch_rows(G, Mg, trial_g, mu, patch, patch_iter)
                else:
                    _patch(G, M, trial, mu, patch, patch_iter)
                e.g_mom.from_numpy(G)
            if transfer:
                G = e.g_mom.to_numpy()
                left = _unused(M, trial, G[:, PAD, 0], mu)
                transfer_lost[1] += _pass_inside(G, e.g_mass.to_numpy(), left, transfer_depth, transfer_spread)
                transfer_lost[0] += left.sum()
                e.g_mom.from_numpy(G)
            new = e.g_mom.to_numpy()[:, PAD]
            for stage in recipe[cut + 1:]:
                kernel(stage)
            live = M > 0.0
            vn, vt, vt_new = trial[:, 1], trial[:, 0], new[:, 0]
            if counts is None:
                counts = np.zeros((len(M), 4))
            sep = live & (vn >= 0.0)
            held = live & ~sep
            stick = held & (vt_new == 0.0)
            down = held & (vt_new > 0.0)
            up = held & (vt_new < 0.0)
            for c, sel in enumerate((stick, down, up, sep)):
                counts[:, c] += sel
            allowed = M * np.maximum(-vn, 0.0) * mu
            given = M * np.abs(vt - vt_new)
            normal += float(allowed[held].sum())
            friction += float(given[held].sum())
            # signed: the impulse up the slope (against the slide, +x down the slope); a stuck node whose
            # trial velocity points up the slope is pushed down it
            signed[0] += float((M * (vt - vt_new))[held].sum())
            signed[1] += float((M * (vt - vt_new))[stick & (vt < 0.0)].sum())
            lost["stick"] += float((allowed - given)[stick].sum())
            lost["slip"] += float((allowed - given)[down | up].sum())
            if light_share > 0.0:  # light wall nodes that separate: their (free) velocity
                lightsep = sep & (M < light_share * full_node)
                lightstat["wall_sep_speed"] += np.linalg.norm(trial[lightsep], axis=-1).tolist()
                lightstat["wall_sep_vn"] += vn[lightsep].tolist()
            speeds["stick_vn"] += (-vn[stick]).tolist()
            speeds["stick_vt"] += np.abs(vt[stick]).tolist()
            speeds["slip_vn"] += (-vn[down | up]).tolist()
            if full is None:
                full = float(np.median(M[M > 0]))
            speeds["stick_m"] += (M[stick] / full).tolist()
            speeds["slip_m"] += (M[down | up] / full).tolist()
            speeds["stick_lost"] += (allowed - given)[stick].tolist()
            # where the friction lost in stick steps sits: the state of the wall nodes within two
            # cells along the wall (could a neighbour take it?): all separating or empty / some stuck,
            # none slipping / some slipping
            lossv = np.where(stick, allowed - given, 0.0)
            slipping = down | up
            near_slip = np.zeros(len(M), bool)
            near_stick = np.zeros(len(M), bool)
            for d in (-2, -1, 1, 2):
                near_slip |= np.roll(slipping, d)
                near_stick |= np.roll(stick, d)
            where_lost["slip"] += float(lossv[near_slip].sum())
            where_lost["stick"] += float(lossv[~near_slip & near_stick].sum())
            where_lost["none"] += float(lossv[~near_slip & ~near_stick].sum())
            # the node inside (one cell up): its tangential momentum after the update, against the loss
            inside = e.g_mom.to_numpy()[:, PAD + 1, 0] * e.g_mass.to_numpy()[:, PAD + 1]
            where_lost["inside_room"] += float(np.minimum(lossv, np.abs(inside)).sum())
            if k % every == 0 or k == steps - 1:
                v = e.v.to_numpy()[: e.n].astype(np.float64)
                vbar = (m[:, None] * v).sum(0) / m.sum()
                x = e.x.to_numpy().astype(np.float64)
                energy.append(((k + 1) * dt, 0.5 * (m * ((v - vbar) ** 2).sum(1)).sum(), 0.5 * m.sum() * vbar @ vbar,
                               float(((x - x0)[sc.base_row] @ sc.slope).mean())))
        impulse, _, _ = e.read_contacts()
        vend = e.v.to_numpy()[: e.n].astype(np.float64)
        x = e.x.to_numpy().astype(np.float64)
    finally:
        runtime.release()
    slip = float(((x - x0)[sc.base_row] @ sc.slope).mean())
    centroid = float((m @ ((x - x0)[: len(m)] @ sc.slope)) / m.sum())
    total = counts.sum(1)
    under = total > 0.5 * total.max()
    bottom = impulse[2]
    return dict(
        steps=steps, t_end=t_end, slip_m=slip, centroid_m=centroid, analytic_m=cs.analytic_distance(theta, delta, t_end),
        frictionless_m=cs.analytic_distance(theta, 0.0, t_end), fractions=counts[under] / total[under, None],
        contact_ratio=abs(bottom[0]) / (mu * abs(bottom[1])) if mu > 0 else float("nan"),
        wall_ratio=friction / normal if normal > 0 else float("nan"),
        lost_stick=lost["stick"] / normal if normal > 0 else 0.0, lost_slip=lost["slip"] / normal if normal > 0 else 0.0,
        speeds={k: np.asarray(v) for k, v in speeds.items()}, energy=energy,
        demand=math.tan(math.radians(theta)) / mu if mu > 0 else float("inf"), light=lightstat,
        audit=_audit(bottom, m, vend, g, t_end, mu),
        signed=(signed[0] / normal, signed[1] / normal) if normal > 0 else (0.0, 0.0),
        transfer=(transfer_lost[0] / normal, transfer_lost[1] / normal) if normal > 0 else (0.0, 0.0),
        where_lost={k: v / normal if normal > 0 else 0.0 for k, v in where_lost.items()})


def _audit(J, m, v, g, t, mu):
    """Momentum audit of the block over the run (bottom wall, slope along +x): the recorded normal impulse
    over the weight's normal impulse; the recorded friction and the friction the block's final momentum
    says it felt (weight's impulse along the slope less the momentum gained), over mu times the weight's
    normal impulse."""
    M = m.sum()
    P = (m[:, None] * v).sum(0)
    weight_n = -M * g[1] * t
    felt = M * g[0] * t - P[0]
    return dict(normal=abs(J[1]) / weight_n, friction=abs(J[0]) / (mu * weight_n), felt=felt / (mu * weight_n),
                normal_momentum=P[1] / weight_n)


def _patch(V, M, trial, mu, patch, passes):
    """Experiment: patch friction at the wall line, on the velocities ``V`` (changed in place) after the
    law: each approaching node's allowance ``mu m |vn|`` shared among the approaching nodes with room (a
    tangential speed) within ``patch`` cells along the wall, in proportion to binomial weight x mass, capped
    at each node's tangential momentum (never reversed); what a capped node cannot take goes round again
    (``passes``). Reduces to the law for a uniform contact and for an isolated node."""
    K = np.array([math.comb(2 * patch, k) for k in range(2 * patch + 1)], float) / 4.0 ** patch
    vn, vt = trial[:, 1], trial[:, 0]
    act = (M > 0.0) & (vn < 0.0)
    A = np.where(act, mu * M * np.maximum(-vn, 0.0), 0.0)
    room = np.where(act, M * np.abs(vt), 0.0)
    give = np.zeros(len(M))
    for _ in range(passes):
        take = act & (room > 0.0)
        mact = np.where(take, M, 0.0)
        Mj = np.convolve(mact, K, "same")
        F = mact * np.convolve(np.where(Mj > 0.0, A / np.maximum(Mj, 1e-300), 0.0), K, "same")
        got = np.minimum(F, room)
        give += got
        room -= got
        A = F - got  # the allowance of a node with no taker in reach is lost
        if A.sum() <= 1e-12 * max(give.sum(), 1e-300):
            break
    new_t = vt - np.sign(vt) * give / np.maximum(M, 1e-300)
    V[act, PAD_ROW, 0] = new_t[act]
    V[act, PAD_ROW, 1] = 0.0


def _patch_rows(V, M, trial, mu, patch, passes):
    """Experiment: :func:`_patch` over the wall line and the ghost rows beyond it (``M``, ``trial``: the
    last ``rows`` rows up to the wall line), the patch a square of binomial weights over the contact's
    nodes."""
    K = np.array([math.comb(2 * patch, k) for k in range(2 * patch + 1)], float) / 4.0 ** patch
    rows = M.shape[1]

    def conv(a):
        out = np.zeros_like(a)
        for r in range(rows):
            line = np.convolve(a[:, r], K, "same")
            for d in range(-patch, patch + 1):
                if 0 <= r + d < rows:
                    out[:, r + d] += K[d + patch] * line
        return out

    vn, vt = trial[..., 1], trial[..., 0]
    act = (M > 0.0) & (vn < 0.0)
    A = np.where(act, mu * M * np.maximum(-vn, 0.0), 0.0)
    room = np.where(act, M * np.abs(vt), 0.0)
    give = np.zeros_like(M)
    for _ in range(passes):
        take = act & (room > 0.0)
        mact = np.where(take, M, 0.0)
        Mj = conv(mact)
        F = mact * conv(np.where(Mj > 0.0, A / np.maximum(Mj, 1e-300), 0.0))
        got = np.minimum(F, room)
        give += got
        room -= got
        A = F - got
        if A.sum() <= 1e-12 * max(give.sum(), 1e-300):
            break
    new_t = vt - np.sign(vt) * give / np.maximum(M, 1e-300)
    block = V[:, PAD_ROW - rows + 1: PAD_ROW + 1]
    block[..., 0] = np.where(act, new_t, block[..., 0])
    block[..., 1] = np.where(act, 0.0, block[..., 1])


def _unused(M, trial, vt_new, mu):
    """Friction that the wall nodes' normal impulse allows and the law did not give (stuck nodes)."""
    vn, vt = trial[:, 1], trial[:, 0]
    left = np.where((M > 0) & (vn < 0), mu * M * np.maximum(-vn, 0) - M * np.abs(vt - vt_new), 0.0)
    return np.maximum(left, 0.0)


def _pass_inside(V, Mall, left, depth, spread):
    """Experiment: apply the friction ``left`` (per wall node, momentum) to the nodes inside, down the column
    (``depth`` rows), or spread over the three columns about it (1/4 1/2 1/4 by mass, ``spread``), never
    reversing a node's velocity along the wall; ``V`` holds velocities, changed in place. Returns what is
    left over."""
    K = np.array([0.25, 0.5, 0.25])
    for r in range(1, depth + 1):
        row = PAD_ROW + r
        Mr = Mall[:, row]
        vr = V[:, row, 0]
        if spread:
            Mj = np.convolve(Mr, K, "same")
            F = Mr * np.convolve(np.where(Mj > 0, left / np.maximum(Mj, 1e-300), 0.0), K, "same")
            lost_here = np.where(Mj > 0, 0.0, left)
        else:
            F = np.where(Mr > 0, left, 0.0)
            lost_here = np.where(Mr > 0, 0.0, left)
        got = np.minimum(F, Mr * np.abs(vr))
        V[:, row, 0] = vr - np.sign(vr) * got / np.maximum(Mr, 1e-300)
        left = F - got + lost_here
    return float(left.sum())


def report(r: dict, label: str) -> None:
    print(label + f": {r['steps']} steps, {r['t_end']:.3f} s")
    if r["analytic_m"] > 0:
        print(f"  slip {r['slip_m']:.5g} m, analytic {r['analytic_m']:.5g} m: {r['slip_m'] / r['analytic_m'] - 1:+.2%}; "
              f"the block's centre of mass {r['centroid_m'] / r['analytic_m'] - 1:+.2%}")
    else:
        print(f"  slip {r['slip_m']:.5g} m = {r['slip_m'] / r['frictionless_m']:.3%} of the frictionless {r['frictionless_m']:.4g} m")
    print(f"  friction / (mu N): whole contact {r['contact_ratio']:.5f}, wall line {r['wall_ratio']:.5f} "
          f"(tan th / mu = {r['demand']:.5f}); not given of mu N: in stick steps {r['lost_stick']:.4%}, "
          f"in slip steps {r['lost_slip']:.4%}")
    a = r["audit"]
    print(f"  audit: recorded normal impulse / weight's {a['normal']:.5f}; recorded friction / (mu weight's) "
          f"{a['friction']:.5f}; felt by the block (momentum) / (mu weight's) {a['felt']:.5f}; block's normal "
          f"momentum / weight's impulse {a['normal_momentum']:+.5f}")
    print(f"  signed friction (up the slope) / (mu N), wall line: {r['signed'][0]:.5f}; of it, stick steps whose trial "
          f"velocity points up the slope (pushed down it): {r['signed'][1]:.5f}")
    if r["transfer"][0] > 0:
        print(f"  transfer: unused at stuck wall nodes {r['transfer'][0]:.4%} of mu N, not taken inside {r['transfer'][1]:.4%}")
    w = r["where_lost"]
    print(f"  lost in stick steps (of mu N) at nodes with a wall node within 2 cells slipping {w['slip']:.4%}, "
          f"only stuck ones {w['stick']:.4%}, none in contact {w['none']:.4%}; could the node inside take it "
          f"(its tangential momentum): {w['inside_room']:.4%}")
    s = r["speeds"]
    if len(s["stick_vn"]) and len(s["slip_vn"]):
        print(f"  stick steps: |vn| median {np.median(s['stick_vn']):.3g} m/s (p90 {np.percentile(s['stick_vn'], 90):.3g}), "
              f"|vt| median {np.median(s['stick_vt']):.3g}; slip steps: |vn| median {np.median(s['slip_vn']):.3g} "
              f"(p90 {np.percentile(s['slip_vn'], 90):.3g})")
    if len(s["stick_m"]) and len(s["slip_m"]):
        lost = np.asarray(s["stick_lost"])
        order = np.argsort(-lost)
        heavy = order[: max(1, int(0.1 * len(order)))]
        print(f"  wall-node mass / its value at the release (median): stick steps {np.median(s['stick_m']):.3g}, "
              f"slip steps {np.median(s['slip_m']):.3g}; the 10 % of stick steps that lose most friction "
              f"({lost[heavy].sum() / max(lost.sum(), 1e-300):.0%} of the loss): mass {np.median(np.asarray(s['stick_m'])[heavy]):.3g}")
    ls = r.get("light")
    if ls and ls["C_share"]:
        sp = np.asarray(ls["sep_speed"])
        cs_ = np.asarray(ls["C_share"])
        med, p90, top = (np.median(sp), np.percentile(sp, 90), sp.max()) if len(sp) else (0.0, 0.0, 0.0)
        print(f"  light nodes: node-steps with a nonzero velocity {len(sp)}, speed median {med:.3g} m/s, "
              f"p90 {p90:.3g}, max {top:.3g}; their share of the particles' affine matrix (norm over all particles): "
              f"median {np.median(cs_):.3g}, p90 {np.percentile(cs_, 90):.3g}, max {cs_.max():.3g}; "
              f"of the velocity: median {np.median(ls['v_share']):.3g}; "
              f"rms |C| of particles: first {ls['C_rms'][0]:.3g}, median {np.median(ls['C_rms']):.3g} 1/s")
        ws = np.asarray(ls["wall_sep_speed"])
        if len(ws):
            print(f"  light wall nodes in separation steps: {len(ws)} node-steps, speed median {np.median(ws):.3g} m/s, "
                  f"p90 {np.percentile(ws, 90):.3g}, max {ws.max():.3g}; normal (away from the wall) median "
                  f"{np.median(ls['wall_sep_vn']):.3g}")
        if ls["L_share"]:
            print(f"  light nodes' share of the velocity gradient of the stress update (norm over all particles): "
                  f"median {np.median(ls['L_share']):.3g}, p90 {np.percentile(ls['L_share'], 90):.3g}")
    f = r["fractions"]
    print(f"  wall nodes under the block: {len(f)}; fraction of steps stick / slip down / slip up / separate:")
    print("    all nodes   " + " ".join(f"{v:.3f}" for v in f.mean(0)))
    n = len(f)
    for q, name in ((0, "upslope end"), (n // 4, "quarter"), (n // 2, "middle"), (3 * n // 4, "3 quarters"),
                    (n - 1, "downslope end")):
        print(f"    {name:12s}" + " ".join(f"{v:.3f}" for v in f[q]))
    print("  t s, kinetic energy J/m: elastic (not translation), translation; slip m")
    for t, el, tr, sl in r["energy"]:
        print(f"    {t:8.3f} {el:10.4g} {tr:10.4g} {sl:10.4g}")


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("scheme")
    ap.add_argument("precision")
    ap.add_argument("thickness", type=int)
    ap.add_argument("youngs", type=float)
    ap.add_argument("incline", type=float)
    ap.add_argument("friction", type=float)
    ap.add_argument("--aspect", type=float, default=4.0)
    ap.add_argument("--time", type=float, default=1.0, help="run time as a multiple of the matrix's")
    ap.add_argument("--damping", type=float, default=0.0, help="Cundall's local damping after the release")
    ap.add_argument("--cfl", type=float, default=None, help="time step as a fraction of dx / c_p (the scenes': 0.5)")
    ap.add_argument("--ppc", type=int, default=None, help="particles per cell along each axis (the scenes': 2)")
    ap.add_argument("--transfer", action="store_true",
                    help="experiment: a stuck wall node's unused friction to the node inside it (not the engine's law)")
    ap.add_argument("--light", type=float, default=0.0,
                    help="experiment: nodes below this fraction of a full node's mass")
    ap.add_argument("--light-mode", default="", choices=("", "old", "zero"),
                    help="experiment: such nodes take their interpolated velocity (old) or zero after the grid update")
    ap.add_argument("--samples", type=int, default=12, help="kinetic-energy samples over the run")
    ap.add_argument("--light-share", type=float, default=0.01,
                    help="measure light nodes (below this fraction of a full node's mass): their speed and share of "
                         "the particles' G2P velocity and affine matrix (0: off)")
    ap.add_argument("--dx", type=float, default=None, help="cell size (m; the scenes': 2 for E >= 1e7 Pa, 0.1 below)")
    ap.add_argument("--lag", type=float, default=0.0,
                    help="experiment: wall-line friction bound relaxed over this many steps")
    ap.add_argument("--lag-all", action="store_true", help="experiment: the lagged friction also while separating")
    ap.add_argument("--transfer-first", action="store_true",
                    help="experiment: the transfer also at the first application (interpolated velocity; mpm, apic)")
    ap.add_argument("--patch-rows", type=int, default=1,
                    help="experiment: the patch over this many rows of the contact (the wall line and ghost rows)")
    ap.add_argument("--patch-first", action="store_true",
                    help="experiment: the patch also at the first application (interpolated velocity; mpm, apic)")
    ap.add_argument("--transfer-depth", type=int, default=1, help="experiment: rows of nodes inside that take it")
    ap.add_argument("--transfer-spread", action="store_true",
                    help="experiment: the transfer spread over the three columns about the node, by mass")
    ap.add_argument("--patch", type=int, default=0,
                    help="experiment: patch friction along the wall line over this many cells each way")
    ap.add_argument("--patch-iter", type=int, default=1, help="experiment: passes of the patch's redistribution")
    ap.add_argument("--gap", type=float, default=0.0,
                    help="experiment: wall nodes below this fraction of a full node's mass take no contact")
    a = ap.parse_args(argv)
    from studies import contact_scenes as cs

    if a.dx is not None:
        cs.cell_size_for = lambda youngs_pa: a.dx
    if a.cfl is not None:
        cs.CFL = a.cfl
    if a.ppc is not None:
        cs.PPC = a.ppc
    r = diagnose(a.scheme, a.precision, a.thickness, a.youngs, a.incline, a.friction, a.aspect, a.time, a.damping,
                 transfer=a.transfer, light=a.light, light_mode=a.light_mode, samples=a.samples, gap=a.gap,
                 lag=a.lag, lag_all=a.lag_all, light_share=a.light_share, patch=a.patch, patch_iter=a.patch_iter,
                 patch_rows=a.patch_rows, patch_first=a.patch_first, transfer_first=a.transfer_first, transfer_depth=a.transfer_depth, transfer_spread=a.transfer_spread)
    report(r, f"{a.scheme} {a.precision} {a.thickness} cells E={a.youngs:g} aspect {a.aspect:g} "
              f"{a.incline:g}/{a.friction:g} deg, damping {a.damping:g}, cfl {a.cfl or 0.5:g}, ppc {a.ppc or 2}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
