"""Physical sanity *during* a run: the run monitor.

:class:`RunMonitor` inspects a rollout block by block (``check(t, X, Y)``)
and reports, once per leg and kind with its first time, what no step should
produce: penetration, a leg passing through the obstacle, the body centre
inside it, non-finite state, energy growing beyond what the elements can
supply, a foot in contact off a terrain grid. The checks before the run live
in ``symcushion.run.checks``, the :class:`~symcushion.run.findings.Finding` it
returns in ``symcushion.run.findings``.

It only inspects: it never changes a state and never drives the simulation
(``symcushion.run.driver`` does, and feeds it). docs/checks.md lists every
check with its tolerance and its test.
"""
from __future__ import annotations

import numpy as np

from symcushion.run.checks_obstacles import BODY_TOLERANCE
from symcushion.run.findings import Finding, obstacle_distances, rotations, world_points
from symcushion.model.obstacles import Terrain
from symcushion.model.scene_data import Scene
from symcushion.layout.vectors import output_layout, state_layout
from symcushion.scheme.touchdown import initial_state
from symcushion.validation import did_you_mean

__all__ = ["RunMonitor", "DEFAULT_TOLERANCES", "ENERGY_FLOOR", "no_touchdown"]

#: Tolerances of :class:`RunMonitor` (override by passing ``tolerances``).
DEFAULT_TOLERANCES = {
    # m: a foot in contact is projected onto the surface to round-off and a
    # free foot must be outside; 1 mm is deeper than any round-off yet well
    # inside a visible failure of the contact step.
    "penetration": 1e-3,
    # relative to the energy scale (kinetic energy at the start + m|g|L₀ +
    # what the elements can supply): velocity Verlet's energy fluctuates by
    # O((ωΔt)²) of a mode's energy — 3e-4 of the scale in the hard cases at a
    # stable step — while contact and friction only remove energy.
    "energy": 1e-2,
    # units of the shortest leg: see BODY_TOLERANCE.
    "body": BODY_TOLERANCE,
    # of the normal force N: a foot's end force whose tangential part exceeds
    # μN by more than this. The memory law's force at the end foot (A1)-(A5)
    # exceeds it by 3e-4 N in a measured slide, and by 1.7 N (|F_t| = 4.4 μN)
    # where the step took a wrong branch (docs/absorbers.md, "Open"); 1e-2
    # lies between.
    "friction_cone": 1e-2,
}

#: Smallest energy scale (J), so that a scene at rest in zero gravity still
#: has a finite relative tolerance.
ENERGY_FLOOR = 1e-6


class RunMonitor:
    """Checks of a rollout, fed block by block (state across blocks kept here).

    Each kind of finding is reported once per leg (or once for the body),
    with the first time it happens:

    ``non_finite`` (error)
        a NaN or inf in the state or output.
    ``penetration`` (warning)
        a foot deeper than ``tolerances['penetration']`` (m) below an obstacle.
    ``pass_through`` (error)
        a leg's hinge inside an obstacle: the strut has crossed the surface.
    ``body_inside`` (error)
        the body centre deeper inside an obstacle than ``tolerances['body']``
        × the shortest leg (:data:`BODY_TOLERANCE`).
    ``energy_growth`` (warning)
        kinetic + gravitational energy above its start value by more than the
        elements can supply (their elastic energy at the start plus preload ×
        stroke) plus ``tolerances['energy']`` of the energy scale.
    ``off_terrain`` (error)
        a foot in contact off a terrain's grid.
    ``friction_cone`` (warning)
        a foot in contact whose end force has a tangential part above μN by
        more than ``tolerances['friction_cone']`` of N: Coulomb's law does not
        hold there, and the run after it is not to be trusted.

    Parameters
    ----------
    scene : Scene
    model : StepModel, optional
        Unused beyond its scene; accepted so that the driver passes what it has.
    tolerances : dict, optional
        Overrides of :data:`DEFAULT_TOLERANCES`.
    x0 : array_like, shape (nx,), optional
        The initial state (default ``initial_state(scene)``): the energy reference.
    """

    def __init__(self, scene: Scene, model=None, tolerances=None, x0=None):
        if not isinstance(scene, Scene):
            raise TypeError(f"`scene` must be a Scene, got {type(scene).__name__}.")
        self.scene = scene
        self.tolerances = dict(DEFAULT_TOLERANCES)
        for key, value in (tolerances or {}).items():
            if key not in DEFAULT_TOLERANCES:
                raise ValueError(f"`tolerances` has unknown key {key!r}"
                                 f"{did_you_mean(key, DEFAULT_TOLERANCES)}; known: "
                                 f"{sorted(DEFAULT_TOLERANCES)}.")
            if not (isinstance(value, (int, float)) and value > 0 and np.isfinite(value)):
                raise ValueError(f"`tolerances['{key}']` must be a positive number, got "
                                 f"{value!r}.")
            self.tolerances[key] = float(value)
        self._xl = state_layout(len(scene.legs))
        self.nx = self._xl.size
        x0 = initial_state(scene) if x0 is None else np.asarray(x0, dtype=float).ravel()
        self._energy0 = float(self._energy(x0[:, None])[0])
        self._supply = _energy_supply(scene, x0)
        g = float(np.linalg.norm(scene.gravity))
        v0 = self._xl.get(x0, "velocity")
        scale = (0.5 * scene.body.mass * float(v0 @ v0)
                 + scene.body.mass * g * max(leg.length for leg in scene.legs) + self._supply)
        self._allowed = self._supply + self.tolerances["energy"] * max(scale, ENERGY_FLOOR)
        self._reported: set = set()

    def _energy(self, X):
        b = self.scene.body
        v, omega = self._xl.get(X, "velocity"), self._xl.get(X, "angular_velocity")
        return (0.5 * b.mass * np.sum(v * v, axis=0)
                + 0.5 * np.einsum("in,ij,jn->n", omega, b.inertia, omega)
                - b.mass * (self.scene.gravity @ self._xl.get(X, "position")))

    def _add(self, out, kind, severity, t, message, leg=None, value=None):
        if (kind, leg) in self._reported:
            return
        self._reported.add((kind, leg))
        out.append(Finding(kind, message, severity, time=float(t), leg=leg,
                           value=None if value is None else float(value)))

    def check(self, t, X, Y) -> list:
        """New findings of one block of the rollout.

        Parameters
        ----------
        t : ndarray, shape (steps,)
            Times of the columns (s).
        X : ndarray, shape (nx, steps)
            States after each step.
        Y : ndarray, shape (ny, steps)
            Per-step outputs.

        Returns
        -------
        list of Finding
            Only kinds (per leg) not reported in an earlier block.
        """
        t = np.asarray(t, dtype=float).ravel()
        X, Y = np.asarray(X, dtype=float), np.asarray(Y, dtype=float)
        if X.ndim != 2 or X.shape[0] != self.nx or X.shape[1] != t.size \
                or Y.ndim != 2 or Y.shape[1] != t.size:
            raise ValueError(f"`X` must have shape ({self.nx}, {t.size}) and `Y` (ny, {t.size}) "
                             f"to match `t`, got {X.shape} and {Y.shape}.")
        out = []
        finite = np.all(np.isfinite(X), axis=0) & np.all(np.isfinite(Y), axis=0)
        if not finite.all():
            i = int(np.argmin(finite))
            self._add(out, "non_finite", "error", t[i], f"the state became non-finite at "
                      f"t = {t[i]:.6g} s; reduce `dt` or check the scene (docs/checks.md).")
            t, X = t[:i], X[:, :i]
        if t.size == 0:
            return out
        self._check_geometry(out, t, X)
        self._check_end_stops(out, t, Y)
        self._check_friction_cone(out, t, Y)
        gain = self._energy(X) - self._energy0
        if np.max(gain) > self._allowed:
            i = int(np.argmax(gain > self._allowed))
            self._add(out, "energy_growth", "warning", t[i], f"the energy grew by "
                      f"{gain[i]:.3g} J by t = {t[i]:.6g} s, more than the elements can supply "
                      f"({self._allowed:.3g} J with tolerance); the step is unstable or the "
                      f"contact adds energy — reduce `dt` (command line: --dt "
                      f"{self.scene.dt / 4:.3g}) or cap each step at the stability limit "
                      "(command line: --stability; Python: simulate(..., adaptive=True, "
                      "stability=True)).", value=gain[i])
        return out

    def _check_end_stops(self, out, t, Y):
        """A leg whose axial element went past its ``stroke_limit``: it bottomed."""
        yl = output_layout(len(self.scene.legs))
        for j, leg in enumerate(self.scene.legs):
            limit = next((el.curve.stroke_limit for el in leg.elements
                          if el.name == leg.axial_element), None)
            if limit is None or Y.shape[0] != yl.size:
                continue
            stroke = yl.get(Y, "stroke", j)
            if np.min(stroke) < -limit:
                i = int(np.argmax(stroke < -limit))
                self._add(out, "bottomed", "warning", t[i], f"the absorber of leg {j} reached "
                          f"its end stop at t = {t[i]:.6g} s (stroke {stroke[i]:.4g} m, limit "
                          f"{-limit:g} m): the loads past it are the stop's, not the "
                          "absorber's; give it more stroke or a higher force.", leg=j,
                          value=-stroke[i])

    def _check_friction_cone(self, out, t, Y):
        """A foot in contact whose end force leaves the friction cone μN (1.4)."""
        yl = output_layout(len(self.scene.legs))
        if Y.shape[0] != yl.size:
            return
        tol, mu = self.tolerances["friction_cone"], self.scene.mu
        for j in range(len(self.scene.legs)):
            F, n = yl.get(Y, "force", j), yl.get(Y, "normal", j)
            N = np.sum(F * n, axis=0)
            tangential = np.linalg.norm(F - N * n, axis=0)
            bad = (yl.get(Y, "in_contact", j).ravel() > 0.5) & (N > 0) \
                & (tangential > (mu + tol) * N)
            if bad.any():
                i = int(np.argmax(bad))
                self._add(out, "friction_cone", "warning", t[i], f"the foot of leg {j} ended "
                          f"the step at t = {t[i]:.6g} s outside the friction cone: tangential "
                          f"force {tangential[i]:.4g} N against μN = {mu * N[i]:.4g} N "
                          f"(μ = {mu:g}); the step took a wrong branch there (docs/absorbers.md, "
                          "\"Open\") and the run after it is not to be trusted.", leg=j,
                          value=tangential[i] / N[i])

    def _check_geometry(self, out, t, X):
        scene, tol = self.scene, self.tolerances["penetration"]
        pos, hinges, feet = world_points(scene, X)
        d_body = obstacle_distances(scene, pos).min(axis=0)
        allowed = self.tolerances["body"] * min(leg.length for leg in scene.legs)
        if np.min(d_body) < -allowed:
            i = int(np.argmax(d_body < -allowed))
            self._add(out, "body_inside", "error", t[i], f"the body centre is inside an obstacle "
                      f"at t = {t[i]:.6g} s ({-d_body[i]:.3g} m deep): the legs did not hold it.",
                      value=-d_body[i])
        for j, leg in enumerate(scene.legs):
            d_foot = obstacle_distances(scene, feet[j], leg.footpad).min(axis=0)
            if np.min(d_foot) < -tol:
                i = int(np.argmax(d_foot < -tol))
                self._add(out, "penetration", "warning", t[i], f"foot of leg {j} is "
                          f"{-d_foot[i]:.3g} m inside an obstacle at t = {t[i]:.6g} s (tolerance "
                          f"{tol:g} m).", leg=j, value=-d_foot[i])
            d_hinge = obstacle_distances(scene, hinges[j]).min(axis=0)
            if np.min(d_hinge) < 0:
                i = int(np.argmax(d_hinge < 0))
                self._add(out, "pass_through", "error", t[i], f"leg {j} passed through the "
                          f"obstacle at t = {t[i]:.6g} s: its hinge is {-d_hinge[i]:.3g} m inside.",
                          leg=j, value=-d_hinge[i])
            contact = self._xl.get(X, "contact", j) > 0.5
            for k, ob in enumerate(scene.obstacles):
                if isinstance(ob, Terrain):
                    xs, ys = ob.grid
                    off = contact & ((feet[j, 0] < xs[0]) | (feet[j, 0] > xs[-1])
                                     | (feet[j, 1] < ys[0]) | (feet[j, 1] > ys[-1]))
                    if off.any():
                        i = int(np.argmax(off))
                        self._add(out, "off_terrain", "error", t[i], f"foot of leg {j} is in "
                                  f"contact off the grid of obstacle[{k}] at t = {t[i]:.6g} s.",
                                  leg=j)


def no_touchdown(traj) -> Finding | None:
    """A warning if no foot of a finished run ever touched an obstacle, else None.

    A run that never lands has nothing to say about the legs; most often the
    body starts too high for the simulated time. Read from the run's
    touchdown events (every one is recorded, or counted once the event list
    is full) and its kept rows (a foot in contact from the start has no
    touchdown event).

    Parameters
    ----------
    traj : Trajectory
        A finished run (``info['events']`` and ``contact``).
    """
    events = traj.info.get("events", [])
    touched = (any(e.get("kind") == "touchdown" for e in events)
               or traj.info.get("events_dropped", 0) > 0 or bool(np.any(traj.contact > 0.5)))
    if touched:
        return None
    t_end = float(traj.t[-1]) if len(traj.t) else 0.0
    return Finding("no_touchdown", f"no foot touched an obstacle in the {t_end:g} s simulated: "
                   "the body never landed, so the run says nothing about the legs; start it "
                   "closer to the ground (symcushion.model.placement.place_on_obstacle) or simulate "
                   "longer (`duration`, --duration).", "warning", time=t_end)


def _energy_supply(scene: Scene, x0) -> float:
    """Energy (J) the elements can give the body: elastic energy at x0 + |f(0)| × stroke."""
    supply = 0.0
    x = state_layout(len(scene.legs)).unpack(np.asarray(x0, dtype=float))
    R = rotations(x["attitude"][:, None])[0]
    for j, leg in enumerate(scene.legs):
        in_contact = x["contact"][j] > 0.5
        rho = R.T @ (x["foot"][j] - x["position"]) if in_contact else leg.rest_foot
        geo = leg.functions()["strut_geometry"](r=rho)
        deflection = {k: float(v) for k, v in leg.deflections(geo).items()}
        for el in leg.elements:
            stroke = (leg.length if el.name == leg.axial_element
                      else 2 * leg.element_extent(el.name))
            xs = np.linspace(0.0, deflection[el.name], 65)
            forces = np.array([abs(el.curve.force(float(x))) for x in xs])
            supply += float(np.sum(0.5 * (forces[1:] + forces[:-1]) * np.abs(np.diff(xs))))
            supply += abs(el.curve.force(0.0)) * stroke
    return supply
