"""The in-memory result of a run: :class:`Trajectory`, assembled from rows [t, x, y].

This module owns the arrays a user reads (positions, forces, angles, modes,
per time point) and how they are derived from the state x and output y of
``touchdown_step`` (named fields of ``symcushion.layout.vectors``). It must not run the
time loop (``symcushion.run.driver``) nor format files (``symcushion.run.results``);
it calls them for ``load``, ``save_csv`` and ``save_npz``.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import casadi as ca
import numpy as np

from symcushion.model.obstacles import closest_obstacle
from symcushion.layout.vectors import MODES, output_layout, state_layout
from symcushion.scheme.quaternion import quat_to_rot_np
from symcushion.scheme.touchdown import StepModel
from symcushion.run.results import (check_output_file, column_unit, read_result, to_json,
    trajectory_columns, write_csv)

__all__ = ["Trajectory", "trajectory_from", "initial_output", "contact_points",
           "UP_WITHOUT_GRAVITY"]

#: "Up" when gravity is zero (angles from the vertical need a direction).
UP_WITHOUT_GRAVITY = np.array([0.0, 0.0, 1.0])


@dataclass
class Trajectory:
    """A simulated touchdown, one row per time point (SI units, world frame).

    Attributes
    ----------
    t : (T,) s
    position, velocity, acceleration : (T, 3) m, m/s, m/s²
    attitude : (T, 4) unit quaternion (w, x, y, z)
    angular_velocity : (T, 3) rad/s, body axes
    foot : (T, N, 3) foot positions (m)
    contact : (T, N) 1 in contact
    mode : (T, N) 0 free, 1 stick, 2 slip, 3 lift-off (:data:`MODES`)
    force : (T, N, 3) force on each foot from the obstacle (N)
    normal : (T, N, 3) unit surface normal at the contact point (0 when free)
    axis : (T, N, 3) unit strut direction e_S, hinge to foot (world)
    alpha : (T, N) angle of the surface normal from the vertical (rad, NaN when free)
    rod_angle : (T, N) angle of the strut from the downward vertical (rad)
    force_angle : (T, N) angle of the contact force from the vertical (rad, NaN when free)
    stroke, beta, gamma_deflection : (T, N) δ_S (m), hinge β and γ − γ₀ (rad)
    criterion : (T,) max over feet of 1 − n_k·n_{k+1} (§3 step criterion)
    info : dict
        dt, steps, halvings, wall_seconds, criterion_max, method, name,
        gravity (m/s², world), ``events``
        (dicts with ``time``, ``kind``, ``leg``), ``warnings`` (monitor findings),
        ``final_state`` (the state vector after the last step, to continue a
        run) and, for a streamed run, ``stride`` (every stride-th row kept).

    The vertical is −gravity (+z when gravity is zero).
    """

    t: np.ndarray
    position: np.ndarray
    velocity: np.ndarray
    acceleration: np.ndarray
    attitude: np.ndarray
    angular_velocity: np.ndarray
    foot: np.ndarray
    contact: np.ndarray
    mode: np.ndarray
    force: np.ndarray
    normal: np.ndarray
    axis: np.ndarray
    alpha: np.ndarray
    rod_angle: np.ndarray
    force_angle: np.ndarray
    stroke: np.ndarray
    beta: np.ndarray
    gamma_deflection: np.ndarray
    criterion: np.ndarray
    rows: np.ndarray = field(default=None, repr=False)
    info: dict = field(default_factory=dict)

    def states(self) -> np.ndarray:
        """The state vector of every row, as columns (nx, T) (``symcushion.layout.vectors``)."""
        if self.rows is None:
            raise ValueError("this Trajectory keeps no rows; load it with Trajectory.load or "
                             "take it from simulate to read its states.")
        return self.rows[:, 1:1 + state_layout(self.n_legs).size].T

    @property
    def n_legs(self) -> int:
        return self.foot.shape[1]

    @property
    def events(self) -> list:
        """The run's events (dicts with ``time`` in s, ``kind``, ``leg`` or ``message``)."""
        return list(self.info.get("events", []))

    @classmethod
    def load(cls, result_dir) -> "Trajectory":
        """Read a result directory written by :func:`save` or ``symcushion simulate``."""
        columns, data, meta = read_result(result_dir)
        n_legs = sum(1 for c in columns if c.endswith("_mode_1"))
        if n_legs < 1 or columns != trajectory_columns(n_legs):
            raise ValueError(f"{result_dir} does not hold a symcushion trajectory of this "
                             "version (unexpected columns); rerun the scene.")
        gravity = meta.get("gravity", (meta.get("scene_summary") or {}).get("gravity"))
        if gravity is None:
            raise ValueError(f"{result_dir}: run.json does not give the gravity of the run; "
                             "rerun the scene.")
        gravity = np.asarray(gravity, dtype=float)
        traj = assemble_trajectory(data, n_legs, gravity)
        traj.info = {k: v for k, v in meta.items() if k not in ("columns", "scene")}
        traj.info["scene"] = meta.get("scene")
        return traj

    def to_dataframe(self):
        """A pandas DataFrame of the rows, columns as in ``trajectory.csv``."""
        try:
            import pandas as pd
        except ImportError:
            raise ImportError("Trajectory.to_dataframe needs pandas, which is not installed; "
                              "`pip install pandas`, or use the arrays of the Trajectory "
                              "(traj.t, traj.position, ...) directly.") from None
        frame = pd.DataFrame(self.rows, columns=trajectory_columns(self.n_legs))
        for j in range(self.n_legs):
            frame[f"leg{j}_mode_1"] = frame[f"leg{j}_mode_1"].round().astype(int).map(MODES)
        return frame

    def plot(self, path=None):
        """Summary figure (``symcushion.viz.plots.summary_figure``); saved if ``path`` is given."""
        from symcushion.viz.plots import summary_figure

        return summary_figure(self, path)

    def save_csv(self, path):
        """Write the rows as ``trajectory.csv`` does (atomically) to ``path``."""
        path = check_output_file(path, "path")
        return write_csv(path, trajectory_columns(self.n_legs), self.rows)

    def save_npz(self, path):
        """Write ``data`` (the rows), ``columns``, ``units``, ``metadata`` (JSON) to ``path``."""
        path = check_output_file(path, "path")
        cols = trajectory_columns(self.n_legs)
        np.savez(path, data=self.rows, columns=np.array(cols),
                 units=np.array([column_unit(c) for c in cols]), metadata=np.array(to_json(
                     {k: v for k, v in self.info.items() if k != "final_state"})))
        return path


def _up(gravity):
    g = np.asarray(gravity, dtype=float)
    norm = np.linalg.norm(g)
    return -g / norm if norm > 0 else UP_WITHOUT_GRAVITY


def _angle_from(vectors, axis):
    norm = np.linalg.norm(vectors, axis=-1)
    with np.errstate(invalid="ignore", divide="ignore"):
        cos = np.einsum("...i,i->...", vectors, axis) / norm
    return np.arccos(np.clip(cos, -1.0, 1.0))


def assemble_trajectory(rows, n_legs, gravity) -> Trajectory:
    """A :class:`Trajectory` from rows [t, x, y] (shape (T, 1 + nx + ny))."""
    rows = np.asarray(rows, dtype=float)
    T = len(rows)
    xl, yl = state_layout(n_legs), output_layout(n_legs)
    X, Y = rows[:, 1:1 + xl.size].T, rows[:, 1 + xl.size:].T     # columns are time points
    x, y = xl.unpack(X), yl.unpack(Y)
    def per_leg(v):
        """(legs, [3,] T) -> (T, legs[, 3])."""
        return np.moveaxis(v, -1, 0)

    up = _up(gravity)
    contact, force, normal, e_S = (per_leg(y["in_contact"]), per_leg(y["force"]),
                                   per_leg(y["normal"]), per_leg(y["axis"]))
    alpha = _angle_from(normal, up)
    alpha[contact < 0.5] = np.nan
    force_angle = _angle_from(force, up)
    force_angle[contact < 0.5] = np.nan
    crit = np.zeros(T)
    if T > 2:
        dots = np.einsum("tni,tni->tn", normal[1:-1], normal[2:])
        both = (contact[1:-1] > 0.5) & (contact[2:] > 0.5)
        crit[2:] = np.where(both, 1 - dots, 0.0).max(axis=1)
    return Trajectory(
        t=rows[:, 0], position=x["position"].T, velocity=x["velocity"].T,
        acceleration=y["acceleration"].T, attitude=x["attitude"].T,
        angular_velocity=x["angular_velocity"].T, foot=per_leg(x["foot"]),
        contact=contact, mode=per_leg(y["mode"]), force=force, normal=normal, axis=e_S,
        alpha=alpha, rod_angle=_angle_from(e_S, -up), force_angle=force_angle,
        stroke=per_leg(y["stroke"]), beta=per_leg(y["beta"]),
        gamma_deflection=per_leg(y["gamma_deflection"]), criterion=crit, rows=rows)


def _numeric(value):
    """A float, or a 1-D array, from a CasADi or NumPy value."""
    value = np.asarray(ca.evalf(value) if isinstance(value, (ca.DM, ca.SX)) else value,
                       dtype=float).ravel()
    return float(value[0]) if value.size == 1 else value


def initial_output(model: StepModel, x0) -> np.ndarray:
    """The output row y of the initial state (no step taken yet), shape (ny,).

    Forces come from the stored state, geometry from the feet's positions
    (a free foot at its unloaded pose), normals from the obstacle at feet in
    contact; modes are stick (in contact) or free. All finite.
    """
    scene = model.scene
    x = state_layout(model.n_legs).unpack(np.asarray(x0, dtype=float))
    R = quat_to_rot_np(x["attitude"])
    legs = {f: [] for f in ("in_contact", "mode", "force", "normal", "axis", "stroke", "beta",
                            "gamma_deflection", "secondary_stroke")}
    for j, leg in enumerate(scene.legs):
        touching = bool(x["contact"][j] > 0.5)
        rho = R.T @ (x["foot"][j] - x["position"]) if touching else np.asarray(leg.rest_foot)
        geo = leg.functions()["strut_geometry"](r=rho)
        normal = np.zeros(3)
        if touching:
            _, n, _ = closest_obstacle(scene.obstacles, ca.DM(x["foot"][j]), leg.footpad)
            normal = np.asarray(ca.evalf(n), dtype=float).ravel()
        for name, value in (("in_contact", float(touching)), ("mode", 1.0 if touching else 0.0),
                            ("force", R @ x["force_body"][j]), ("normal", normal),
                            ("axis", R @ np.asarray(geo["e_S"]).ravel()),
                            *((k, _numeric(v)) for k, v in leg.deflection_outputs(geo).items())):
            legs[name].append(value)
    acc0 = scene.gravity + R @ x["force_body"].sum(axis=0) / scene.body.mass
    return np.asarray(output_layout(model.n_legs).pack(acceleration=acc0, **legs),
                      dtype=float).ravel()


def contact_points(traj: Trajectory, footpads) -> np.ndarray:
    """Where each foot's pad touches the obstacle: r − a·n, shape (T, N, 3) (m, world).

    ``traj.foot`` is the pad's centre r and ``traj.normal`` the unit normal of
    the contact (0 for a free foot, whose point is then its centre);
    ``footpads`` the legs' radii a (m, shape (N,): ``[leg.footpad for leg in
    scene.legs]``). Exact on planes and spheres; on implicit surfaces and
    terrain within the offset's first-order error of the surface
    (docs/footpads.md).
    """
    a = np.asarray(footpads, dtype=float)
    if a.shape != (traj.n_legs,) or not np.all(np.isfinite(a)) or np.any(a < 0):
        raise ValueError(f"`footpads` must be {traj.n_legs} finite radii >= 0 (m), one per leg, "
                         f"got {a.tolist()}.")
    return traj.foot - a[None, :, None] * traj.normal


def trajectory_from(model: StepModel, x0, X, Y, t) -> Trajectory:
    """Assemble a :class:`Trajectory` from a state history X (nx, K) and outputs Y (ny, K)."""
    x0 = np.asarray(x0, float).ravel()
    X = np.column_stack([x0, np.asarray(X, float)])
    Y = np.column_stack([initial_output(model, x0), np.asarray(Y, float)])
    rows = np.column_stack([np.asarray(t, float), X.T, Y.T])
    return assemble_trajectory(rows, model.n_legs, model.scene.gravity)
