"""How much accuracy does a second of computing buy? The speed-vs-error study.

Question: for the Fig. 3 scene (μ = 0), the Fig. 4 scene (μ = 0.05) and a
four-legged lander on a 10° slope (``studies/lander_slope.toml``), how does
the error of each contact step (paper, robust, implicit) fall with the time
step Δt, at what orders, and what does each error level cost per simulated
second, in CasADi's virtual machine (``METHOD/vm``) and as compiled C
(``METHOD/c``)? The peers of ``symcushion.peers``, a penalty contact model
integrated by CVODES (``penalty-cvodes/rtol=...``) and MuJoCo (``mujoco``),
are measured the same way when that module is importable.

Reference: the implicit step, compiled, at Δt = DT_REF (1e-6 s), far below
the grid; its own error is estimated by running it again at 2·DT_REF and
taking the difference of every metric (a Richardson estimate of order 1, an
upper bound for any order ≥ 1). Errors below FLOOR_FACTOR times that
estimate are not used to fit orders.

Metrics of a run (docs/speed-vs-error.md defines them with formulas):

* rebound speed: Fig. 3, the vertical speed with which the ball passes the
  height of first contact on the way up, from the first sample above it by
  ballistic extrapolation (as ``symcushion.reproduce`` measures Δy′);
  Fig. 4 and the lander, which need not leave the ground, the largest upward
  vertical velocity of the centre of mass over the run;
* peak deceleration: max over the run of |a − g|, the contact force per
  unit mass (m/s²);
* peak deflection: max over the run and the legs of the hinge deflection
  (angle between the strut and its rest direction, rad) and of the axial
  stroke |δ_S| (m); the error column uses the hinge angle for Figs. 3–4
  (rigid rods) and the stroke for the lander;
* trajectory: RMS over the run's samples of the distance between its centre
  of mass and the reference's (interpolated to the same times), over the
  largest distance the reference's centre of mass travels from its start.

Errors: rebound speed absolute (m/s); peaks and trajectory relative.
Timing: the step loop only (the compiled or VM rollout calls), best of up to
BEST_OF passes when a pass is short. The machine is shared, so the cost
column ``wall_per_sim_second`` is process CPU time per simulated second (for
this single-threaded loop the wall time of an idle core); the wall clock is
kept in ``eval_wall_seconds``. Peers: see :func:`run_from_peer`. Build and
compile times have their own column.
The VM runs a rollout of at most CHUNK steps (``mapaccum``) again and again,
from the last state of the previous call, so that no rollout longer than
CHUNK is ever built; the compiled model runs its compiled CHUNK-step rollout
the same way (the last call runs past the end; wall per simulated second
divides by the steps actually run).

Output: ``figures/speed_vs_error.csv`` (one row per scene, method, backend
and Δt or tolerance), ``figures/speed_vs_error.png``, and the section
"Results" of ``docs/speed-vs-error.md``. Run from the repository root:
``python studies/speed_vs_error.py`` (10–20 min on 2 shared cores, most of
it the VM at small Δt and the references, plus about 5 min of gcc the first
time), or ``--quick`` for a smoke run (a few
Δt, reference at 1e-5, outputs to /tmp/symcushion-sve/quick, docs untouched).
"""
from __future__ import annotations

import argparse
import csv
import json
import math
import platform
import sys
import time
from dataclasses import dataclass, field
from pathlib import Path

import casadi as ca
import numpy as np

from symcushion import report
from symcushion.codegen import CompiledModel, compiled_model
from symcushion.contact import METHODS
from symcushion.scene import Scene, load_scene
from symcushion.layout import default_p, quat_to_rot_np, state_layout
from symcushion.simulate import build_model, initial_state

ROOT = Path(__file__).resolve().parents[2]
STUDIES = ROOT / "studies"
FIGURES = ROOT / "figures"
DOC = ROOT / "docs" / "speed-vs-error.md"
#: One build folder per scene and method (git-ignored ``build/``): a process
#: cannot load two different libraries from one path (symcushion.codegen).
BUILD = ROOT / "build" / "speed_vs_error"
QUICK_OUT = Path("/tmp/symcushion-sve/quick")

#: Δt of the grid (s): 1e-2 down to 1e-5, about three per decade.
DT_GRID = (1e-2, 3e-3, 1e-3, 3e-4, 1e-4, 3e-5, 1e-5)
QUICK_DT_GRID = (3e-3, 1e-3, 3e-4)
#: Δt of the reference (implicit step, compiled): 10× below the finest grid
#: point, and a divisor of every grid Δt, so its samples fall on theirs.
DT_REF = 1e-6
QUICK_DT_REF = 1e-5
#: Steps per rollout call. Building a VM rollout costs about 0.5–2 ms per step
#: (CasADi's analysis of the repeated step), so longer runs reuse this one.
CHUNK = 2000
#: Longest VM run (steps); longer points are skipped on the VM (not on C).
#: 250 000 covers the whole grid (Fig. 4 at 1e-5: 200 000 steps, ~30 s).
VM_MAX_STEPS = 250_000
#: Timing passes: a run whose first pass took less than REPEAT_BELOW seconds of
#: CPU is run again, up to BEST_OF passes, and the fastest pass is kept (the
#: machine is shared: the minimum is the least disturbed measurement).
BEST_OF = 3
REPEAT_BELOW = 1.0
#: Orders are fitted for Δt ≤ ORDER_DT_MAX (the asymptotic range: coarser steps
#: do not resolve the stiff axial mode of the rigid rods, 2/ω ≈ 3.8 ms) and to
#: errors above FLOOR_FACTOR × the reference's own error estimate.
ORDER_DT_MAX = 1e-3
FLOOR_FACTOR = 10.0
#: Peers (symcushion.peers): CVODES relative tolerances, MuJoCo time steps and
#: their output spacing, about PEER_OUTPUT_DT or one step if longer (MuJoCo: a
#: whole number of steps): fine enough for the peaks, coarse enough that
#: recording (a Python loop for MuJoCo) costs little.
PENALTY_RTOLS = (1e-4, 1e-6, 1e-8, 1e-10)
MUJOCO_TIMESTEPS = (1e-3, 3e-4, 1e-4, 3e-5, 1e-5)
PEER_OUTPUT_DT = 1e-4
#: The paper's bound on the Fig. 3 rebound, |Δy′| < 1e-2 m/s, and the aim of the study.
REBOUND_BOUND = 1e-2
REBOUND_AIM = 1e-4

#: Per scene: its file, how its rebound speed is measured and which deflection
#: the peak_deflection_error column compares.
SCENES = {
    "fig3": {"file": "fig3.toml", "rebound": "ballistic", "deflection": "hinge"},
    "fig4": {"file": "fig4.toml", "rebound": "max_up", "deflection": "hinge"},
    "lander_slope": {"file": "lander_slope.toml", "rebound": "max_up", "deflection": "stroke"},
}

#: Columns of the CSV; the first five are the ones the study is built around.
REQUIRED_COLUMNS = ("scene", "method", "dt", "rebound_error", "wall_per_sim_second")
COLUMNS = REQUIRED_COLUMNS + (
    "peak_decel_error", "peak_deflection_error", "trajectory_error", "contact_step",
    "backend", "tolerance", "status", "steps_run", "sim_seconds", "eval_wall_seconds",
    "eval_cpu_seconds", "cpu_per_sim_second", "passes", "build_seconds", "rebound_speed",
    "rebound_dv", "rebound_kind", "peak_decel", "peak_hinge", "peak_stroke")


# ---------------------------------------------------------------------------
# runs reduced to what the metrics read
# ---------------------------------------------------------------------------
@dataclass
class Run:
    """A touchdown reduced to the quantities the metrics read (SI, world frame).

    Attributes
    ----------
    t : ndarray, shape (T,)
        Sample times (s), t[0] = 0 the initial state.
    position, velocity : ndarray, shape (T, 3)
        Centre of mass (m, m/s).
    decel : ndarray, shape (T,)
        |a − g| (m/s²): the legs' total force over the mass.
    hinge : ndarray, shape (T,)
        Largest hinge deflection over the legs: angle between the strut and
        its rest direction e₀, body frame (rad).
    stroke : ndarray, shape (T,)
        Largest axial stroke |δ_S| = |L − L₀| over the legs (m).
    info : dict
        Timing (``wall``, ``cpu``, ``passes``, ``steps_run``, ``build``) and
        the backend's notes.
    """

    t: np.ndarray
    position: np.ndarray
    velocity: np.ndarray
    decel: np.ndarray
    hinge: np.ndarray
    stroke: np.ndarray
    info: dict = field(default_factory=dict)

    def __post_init__(self):
        T = len(self.t)
        for name in ("position", "velocity"):
            if np.shape(getattr(self, name)) != (T, 3):
                raise ValueError(f"`{name}` must have shape ({T}, 3), got "
                                 f"{np.shape(getattr(self, name))}.")
        for name in ("decel", "hinge", "stroke"):
            if np.shape(getattr(self, name)) != (T,):
                raise ValueError(f"`{name}` must have shape ({T},), got "
                                 f"{np.shape(getattr(self, name))}.")

    def finite(self) -> bool:
        """True when every sampled quantity is finite."""
        return bool(all(np.all(np.isfinite(getattr(self, k)))
                        for k in ("position", "velocity", "decel", "hinge", "stroke")))


def reduce_states(scene: Scene, X) -> dict:
    """The Run quantities of state columns X (nx × K), symcushion.simulate's layout.

    The state holds each leg's foot (world), contact flag and force on the
    foot (body axes), so |a − g| = |Σ_j P_j| / m and the strut vector is
    ρ_j − r_h with ρ_j = Rᵀ(foot_j − x); a free foot is stored at its rest
    pose, deflection zero.
    """
    X = np.asarray(X, dtype=float)
    xl = state_layout(len(scene.legs))
    pos, vel = xl.get(X, "position").T, xl.get(X, "velocity").T
    R = quat_to_rot_np(xl.get(X, "attitude").T, normalise=False)
    force = np.zeros((X.shape[1], 3))
    hinge = np.zeros(X.shape[1])
    stroke = np.zeros(X.shape[1])
    for j, leg in enumerate(scene.legs):
        force += xl.get(X, "force_body", j).T
        rho = np.einsum("tki,tk->ti", R, xl.get(X, "foot", j).T - pos)
        strut = rho - leg.hinge
        length = np.linalg.norm(strut, axis=1)
        e_S = strut / length[:, None]
        angle = np.arctan2(np.linalg.norm(np.cross(e_S, leg.e0), axis=1), e_S @ leg.e0)
        hinge = np.maximum(hinge, angle)
        stroke = np.maximum(stroke, np.abs(length - leg.length))
    return {"position": pos, "velocity": vel,
            "decel": np.linalg.norm(force, axis=1) / scene.body.mass,
            "hinge": hinge, "stroke": stroke}


def simulate_chunked(model, scene: Scene, dt: float, *, chunk: int = CHUNK,
                     passes: int = BEST_OF, repeat_below: float = REPEAT_BELOW) -> Run:
    """Simulate ``scene`` at step ``dt`` by repeated rollout calls; time the calls.

    Parameters
    ----------
    model : StepModel or CompiledModel
        A VM model (``build_model``) or a compiled one (``compiled_model``).
        A compiled model runs its compiled rollout (``compiled_steps`` steps
        per call); a VM model a rollout of min(chunk, steps) steps, built here
        and cached by the model.
    scene : Scene
        Its duration sets the steps, round(duration/dt).
    dt : float
        Time step (s).
    chunk : int
        Steps per VM rollout call.
    passes : int
        Most timing passes; a pass is repeated only while the first took less
        than ``repeat_below`` s of CPU.

    Returns
    -------
    Run
        Samples 0..steps; ``info`` has ``wall`` and ``cpu`` (fastest pass, s),
        ``passes``, ``steps_run`` (steps evaluated, ≥ steps), ``build`` (s,
        rollout construction) and ``sim_seconds`` (steps_run·dt).
    """
    if not (isinstance(dt, (float, int)) and np.isfinite(dt) and dt > 0):
        raise ValueError(f"`dt` must be a positive number of seconds, got {dt!r}.")
    if isinstance(chunk, bool) or not isinstance(chunk, int) or chunk < 1:
        raise ValueError(f"`chunk` must be a positive integer, got {chunk!r}.")
    steps = max(1, int(round(scene.duration / dt)))
    started = time.perf_counter()
    if isinstance(model, CompiledModel):
        length = model.compiled_steps
    else:
        length = min(chunk, steps)
    rollout = model.rollout(length)
    build = time.perf_counter() - started
    calls = -(-steps // length)
    x0 = initial_state(scene)
    p = default_p(scene)

    def one_pass(keep):
        # only the rollout calls are timed; each chunk is reduced as it comes
        # (a reference run has millions of steps: the states would not fit)
        x, wall, cpu = x0, 0.0, 0.0
        parts = [reduce_states(scene, x0[:, None])] if keep else None
        for _ in range(calls):
            w0, c0 = time.perf_counter(), time.process_time()
            X, _ = rollout(x, p, dt)
            wall += time.perf_counter() - w0
            cpu += time.process_time() - c0
            X = np.asarray(X, dtype=float)
            x = X[:, -1]
            if keep:
                parts.append(reduce_states(scene, X))
        return wall, cpu, parts

    wall, cpu, reduced = one_pass(keep=True)
    n_pass = 1
    while n_pass < passes and cpu < repeat_below:
        w, c, _ = one_pass(keep=False)
        wall, cpu = min(wall, w), min(cpu, c)
        n_pass += 1
    arrays = {k: np.concatenate([r[k] for r in reduced])[:steps + 1] for k in reduced[0]}
    return Run(t=dt * np.arange(steps + 1), **arrays,
               info={"wall": wall, "cpu": cpu, "cost": cpu, "passes": n_pass,
                     "steps_run": calls * length,
                     "sim_seconds": calls * length * dt, "build": build, "steps": steps})


def run_from_peer(peer, scene: Scene, call_cpu: float | None = None) -> Run:
    """A :class:`Run` from a ``symcushion.peers`` result (``PeerRun``).

    Reads its t, position, velocity, acceleration (world, with gravity),
    stroke and deflection (T × legs), wall_seconds and build_seconds.

    Cost (``info['cost']``, s): the peer's own integration CPU time
    ``info['cpu_seconds']`` when it reports one; else ``call_cpu``, the
    process CPU time of the whole peer call measured by the caller, minus the
    peer's build time; else its integration wall time. On a shared machine
    wall time counts the time other jobs hold the core, CPU time does not, and
    symcushion's own runs are timed in CPU time.
    """
    t = np.asarray(peer.t, dtype=float)
    acc = np.asarray(peer.acceleration, dtype=float)
    stroke = np.asarray(peer.stroke, dtype=float).reshape(len(t), -1)
    hinge = np.asarray(peer.deflection, dtype=float).reshape(len(t), -1)
    sim = float(t[-1] - t[0]) if len(t) > 1 else float("nan")
    wall = float(peer.wall_seconds)
    build = float(getattr(peer, "build_seconds", 0.0))
    peer_info = dict(getattr(peer, "info", None) or {})
    reported = peer_info.get("cpu_seconds")
    if isinstance(reported, (int, float)) and np.isfinite(reported):
        cpu, how = float(reported), "peer's integration CPU time"
    elif call_cpu is not None:
        cpu, how = max(call_cpu - build, 0.0), "CPU time of the call minus the peer's build time"
    else:
        cpu, how = float("nan"), "peer's integration wall time"
    return Run(t=t, position=np.asarray(peer.position, dtype=float),
               velocity=np.asarray(peer.velocity, dtype=float),
               decel=np.linalg.norm(acc - scene.gravity, axis=1),
               hinge=np.nanmax(np.abs(hinge), axis=1), stroke=np.nanmax(np.abs(stroke), axis=1),
               info={"wall": wall, "cpu": cpu, "cost": cpu if np.isfinite(cpu) else wall,
                     "cost_how": how, "passes": 1, "steps_run": len(t) - 1,
                     "sim_seconds": sim, "build": build})


# ---------------------------------------------------------------------------
# metrics and errors
# ---------------------------------------------------------------------------
def rebound_speed(run: Run, kind: str, gravity: float = 9.81) -> tuple[float, str]:
    """Rebound speed of a run (m/s) and how it was measured.

    ``kind='ballistic'`` (Fig. 3): after the lowest point (first sample with
    upward velocity), the first sample k at or above the height of first
    contact z₀ = z(0) gives v = sqrt(v_z,k² + 2|g|(z_k − z₀)), the speed at z₀
    of the free flight through sample k (the rods are back at rest, β = 0,
    exactly at z₀). If the ball never gets back to z₀ the largest upward
    velocity is returned instead, kind ``'max_up'``.
    ``kind='max_up'``: the largest upward vertical velocity over the run.
    """
    if kind not in ("ballistic", "max_up"):
        raise ValueError(f"`kind` must be 'ballistic' or 'max_up', got {kind!r}.")
    vz, z = run.velocity[:, 2], run.position[:, 2]
    if kind == "ballistic":
        up = np.flatnonzero(vz > 0)
        if up.size:
            above = np.flatnonzero(z[up[0]:] >= z[0])
            if above.size:
                k = up[0] + above[0]
                return float(np.sqrt(max(vz[k] ** 2 + 2 * gravity * (z[k] - z[0]), 0.0))), kind
    return float(np.max(vz)), "max_up"


def metrics(run: Run, scene: Scene, kind: str) -> dict:
    """The metrics of a run: rebound speed (m/s) and how it was measured, Δy′ =
    v_reb − |ż(0)| (m/s; NaN unless measured ballistically at z₀), peak
    |a − g| (m/s²), peak hinge angle (rad) and peak stroke (m)."""
    g = float(np.linalg.norm(scene.gravity))
    v, used = rebound_speed(run, kind, g)
    return {"rebound_speed": v, "rebound_kind": used,
            # Δy′ of the paper's claim: only where the rebound is measured at z₀
            "rebound_dv": v - abs(float(run.velocity[0, 2])) if used == "ballistic"
            else float("nan"),
            "peak_decel": float(np.max(run.decel)), "peak_hinge": float(np.max(run.hinge)),
            "peak_stroke": float(np.max(run.stroke))}


def trajectory_error(run: Run, ref: Run) -> float:
    """RMS over the run's samples of |x(t_k) − x_ref(t_k)|, over the reference's travel.

    x_ref is linearly interpolated to the run's times (exact when they fall on
    the reference's samples, as every grid Δt does); the scale is
    max_t |x_ref(t) − x_ref(0)|. Samples past the reference's end are ignored.
    """
    t = run.t[run.t <= ref.t[-1] * (1 + 1e-12)]
    if t.size == 0:
        raise ValueError("`run` has no samples inside the reference's time span.")
    ref_x = np.column_stack([np.interp(t, ref.t, ref.position[:, i]) for i in range(3)])
    diff = run.position[:t.size] - ref_x
    scale = float(np.max(np.linalg.norm(ref.position - ref.position[0], axis=1)))
    if not scale > 0:
        raise ValueError("the reference's centre of mass never moves: no trajectory scale.")
    return float(np.sqrt(np.mean(np.sum(diff ** 2, axis=1))) / scale)


def errors(run_metrics: dict, ref_metrics: dict, deflection: str) -> dict:
    """Errors of a run's metrics against the reference's.

    rebound_error absolute (m/s); peak_decel_error and peak_deflection_error
    relative to the reference's value; ``deflection`` picks the hinge angle
    (``'hinge'``) or the stroke (``'stroke'``).
    """
    if deflection not in ("hinge", "stroke"):
        raise ValueError(f"`deflection` must be 'hinge' or 'stroke', got {deflection!r}.")
    key = "peak_" + deflection
    return {"rebound_error": abs(run_metrics["rebound_speed"] - ref_metrics["rebound_speed"]),
            "peak_decel_error": abs(run_metrics["peak_decel"] / ref_metrics["peak_decel"] - 1),
            "peak_deflection_error": abs(run_metrics[key] / ref_metrics[key] - 1)}


def convergence_order(dts, errs, floor: float = 0.0, dt_max: float = ORDER_DT_MAX):
    """Least-squares slope of log(error) against log(Δt).

    Uses the points with Δt ≤ ``dt_max`` and error > FLOOR_FACTOR·``floor``
    (finite, positive). Returns (order, (Δt_min, Δt_max), n) with order NaN
    and an empty range when fewer than two points qualify.
    """
    dts, errs = np.asarray(dts, dtype=float), np.asarray(errs, dtype=float)
    keep = (np.isfinite(errs) & (errs > 0) & (dts <= dt_max * (1 + 1e-9))
            & (errs > FLOOR_FACTOR * floor))
    if keep.sum() < 2:
        return float("nan"), (), int(keep.sum())
    slope = np.polyfit(np.log(dts[keep]), np.log(errs[keep]), 1)[0]
    return float(slope), (float(dts[keep].min()), float(dts[keep].max())), int(keep.sum())


# ---------------------------------------------------------------------------
# CSV
# ---------------------------------------------------------------------------
def _cell(value):
    if value is None:
        return ""
    if isinstance(value, (float, np.floating)):
        return "" if not np.isfinite(value) else f"{float(value):.12g}"
    return str(value)


def write_csv(rows, path) -> None:
    """Write the study's rows (dicts) with :data:`COLUMNS` as header.

    Missing or non-finite numbers are written as empty cells; ``status``
    says why (e.g. ``non-finite``).
    """
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    with open(path, "w", newline="") as fh:
        writer = csv.writer(fh)
        writer.writerow(COLUMNS)
        for row in rows:
            unknown = set(row) - set(COLUMNS)
            if unknown:
                raise ValueError(f"row has unknown column(s) {sorted(unknown)}; add them to "
                                 "COLUMNS.")
            writer.writerow([_cell(row.get(c)) for c in COLUMNS])


def read_csv(path) -> list:
    """Rows of a CSV written by :func:`write_csv`, numbers as floats."""
    rows = []
    with open(path, newline="") as fh:
        for row in csv.DictReader(fh):
            out = {}
            for k, v in row.items():
                try:
                    out[k] = float(v) if v != "" else float("nan")
                except ValueError:
                    out[k] = v
            rows.append(out)
    return rows


# ---------------------------------------------------------------------------
# the study
# ---------------------------------------------------------------------------
def _build_seconds(folder: Path) -> float:
    """Code generation plus the gcc commands of a build folder's manifest (s).

    The two objects compile in parallel, so this sum bounds the wall time of a
    fresh build from above; a cached build cost only its code generation.
    """
    info = json.loads((folder / "symcushion.json").read_text())
    return float(info.get("generate_seconds", 0.0)
                 + sum((info.get("build") or {}).get("seconds", {}).values()))


def _row(scene_name, contact_step, backend, dt, run: Run | None, status, ref_metrics, ref,
         spec, scene, tolerance=None, build=None):
    method = f"{contact_step}/{backend}" if backend in ("vm", "c") else contact_step
    row = {"scene": scene_name, "method": method, "contact_step": contact_step,
           "backend": backend, "dt": dt, "tolerance": tolerance, "status": status}
    if run is None:
        return row
    info = run.info
    row.update(steps_run=info["steps_run"], sim_seconds=info["sim_seconds"],
               eval_wall_seconds=info["wall"], eval_cpu_seconds=info["cpu"],
               wall_per_sim_second=info["cost"] / info["sim_seconds"],
               cpu_per_sim_second=info["cpu"] / info["sim_seconds"], passes=info["passes"],
               build_seconds=info["build"] if build is None else build)
    if status != "ok":
        return row
    m = metrics(run, scene, spec["rebound"])
    row.update(m)
    row.update(errors(m, ref_metrics, spec["deflection"]))
    row["trajectory_error"] = trajectory_error(run, ref)
    return row


def _peers():
    """(module, reason): symcushion.peers if importable, else None and why not."""
    try:
        from symcushion import peers
    except Exception as exc:  # noqa: BLE001 - any import failure means "skip the peers"
        return None, f"symcushion.peers is not importable ({type(exc).__name__}: {exc})"
    missing = [f for f in ("penalty_simulate", "mujoco_simulate") if not hasattr(peers, f)]
    if missing:
        return None, f"symcushion.peers lacks {missing}"
    return peers, ""


def reference(scene: Scene, folder: Path, dt_ref: float, progress=print):
    """The reference run (implicit, compiled, Δt = dt_ref) and its check at 2·dt_ref."""
    model = compiled_model(scene.with_(method="implicit"), folder, steps=CHUNK)
    progress(f"  reference: implicit/c at dt = {dt_ref:g} ...")
    ref = simulate_chunked(model, scene.with_(method="implicit"), dt_ref, passes=1)
    progress(f"  reference done ({ref.info['wall']:.1f} s); check at dt = {2 * dt_ref:g} ...")
    check = simulate_chunked(model, scene.with_(method="implicit"), 2 * dt_ref, passes=1)
    return ref, check


def run_scene(name: str, dt_grid, dt_ref, *, vm=True, peers=True, progress=print):
    """All rows of one scene, its reference check and notes."""
    spec = SCENES[name]
    base = load_scene(STUDIES / spec["file"])
    notes = []
    folders = {m: BUILD / f"{name}-{m}" for m in METHODS}
    ref, check = reference(base, folders["implicit"], dt_ref, progress)
    if not (ref.finite() and check.finite()):
        raise FloatingPointError(f"{name}: the reference run is not finite; lower DT_REF.")
    ref_m = metrics(ref, base, spec["rebound"])
    check_m = metrics(check, base, spec["rebound"])
    ref_check = {"scene": name, "dt_ref": dt_ref, "ref": ref_m, "check": check_m,
                 "self_error": errors(check_m, ref_m, spec["deflection"]),
                 "trajectory": trajectory_error(check, ref), "wall": ref.info["wall"]}
    del check
    floor = dict(ref_check["self_error"], trajectory_error=ref_check["trajectory"])
    rows = []
    for method in METHODS:
        scene = base.with_(method=method)
        started = time.perf_counter()
        cmodel = compiled_model(scene, folders[method], steps=CHUNK)
        c_build = _build_seconds(folders[method])
        progress(f"  {method}/c: compiled ({time.perf_counter() - started:.1f} s here, "
                 f"{c_build:.1f} s generate + gcc when built)")
        vmodel, vm_build = None, float("nan")
        if vm:
            started = time.perf_counter()
            vmodel = build_model(scene)
            vm_build = time.perf_counter() - started
        for dt in dt_grid:
            steps = max(1, int(round(scene.duration / dt)))
            by_backend = {}
            for backend, model in (("c", cmodel), ("vm", vmodel)):
                if model is None:
                    continue
                if backend == "vm" and steps > VM_MAX_STEPS:
                    notes.append(f"{name} {method}/vm at dt = {dt:g} skipped: {steps} steps > "
                                 f"VM_MAX_STEPS = {VM_MAX_STEPS}.")
                    continue
                run = simulate_chunked(model, scene, dt)
                status = "ok" if run.finite() else "non-finite"
                build = c_build if backend == "c" else vm_build + run.info["build"]
                row = _row(name, method, backend, dt, run, status, ref_m, ref, spec, scene,
                           build=build)
                rows.append(row)
                by_backend[backend] = row
                progress(f"  {row['method']:>14} dt={dt:<7g} {status:>10}  "
                         f"rebound err {row.get('rebound_error', float('nan')):.2e}  "
                         f"traj err {row.get('trajectory_error', float('nan')):.2e}  "
                         f"{row['wall_per_sim_second']:.3g} s/sim-s ({run.info['passes']} pass)")
            c_row, vm_row = by_backend.get("c"), by_backend.get("vm")
            if c_row and vm_row and c_row["status"] == vm_row["status"] == "ok":
                # VM and compiled code are the same arithmetic: their results must agree
                diff = max(abs(c_row[k] - vm_row[k]) for k in
                           ("rebound_speed", "peak_decel", "peak_hinge", "peak_stroke",
                            "trajectory_error"))
                ref_check["vm_c_max_diff"] = max(ref_check.get("vm_c_max_diff", 0.0), diff)
    if peers:
        rows += peer_rows(name, base, spec, ref, ref_m, notes, progress)
    return rows, ref_check, floor, notes


def peer_rows(name, scene, spec, ref, ref_m, notes, progress=print):
    """Rows of the penalty/CVODES and MuJoCo peers (skipped with a note if unavailable)."""
    module, reason = _peers()
    if module is None:
        notes.append(f"{name}: peers skipped: {reason}.")
        progress(f"  peers skipped: {reason}")
        return []
    rows = []
    runs = [("penalty-cvodes", f"rtol={r:g}", dict(rtol=r, output_dt=PEER_OUTPUT_DT), None, r)
            for r in PENALTY_RTOLS]
    available = getattr(module, "mujoco_available", lambda: True)()
    if available:
        # MuJoCo samples every whole number of steps: the multiple of h nearest 0.1 ms
        runs += [("mujoco", "mujoco", dict(timestep=h, output_dt=h * max(1, round(
            PEER_OUTPUT_DT / h))), h, None) for h in MUJOCO_TIMESTEPS]
    else:
        notes.append(f"{name}: MuJoCo rows skipped: mujoco_available() is False.")
    for label, method, kwargs, dt, tol in runs:
        fn = module.penalty_simulate if label == "penalty-cvodes" else module.mujoco_simulate
        name_m = f"{label}/{method}" if label == "penalty-cvodes" else "mujoco"
        try:
            c0 = time.process_time()
            peer = fn(scene, **kwargs)
            run = run_from_peer(peer, scene, call_cpu=time.process_time() - c0)
            status = "ok" if run.finite() else "non-finite"
        except Exception as exc:  # noqa: BLE001 - a failing peer run is a result, not a crash
            run, status = None, f"failed: {type(exc).__name__}: {exc}".replace("\n", " ")[:200]
        row = _row(name, name_m, "peer", dt, run, status, ref_m, ref, spec, scene,
                   tolerance=tol)
        row["method"] = name_m
        rows.append(row)
        progress(f"  {name_m:>28} {status[:40]:>10}  rebound err "
                 f"{row.get('rebound_error', float('nan')):.2e}  "
                 f"{row.get('wall_per_sim_second', float('nan')):.3g} s/sim-s")
    return rows


# ---------------------------------------------------------------------------
# analysis
# ---------------------------------------------------------------------------
ERROR_KEYS = ("rebound_error", "peak_decel_error", "peak_deflection_error", "trajectory_error")


def orders_table(rows, floors) -> list:
    """Fitted orders per scene, contact step and metric (compiled rows; VM rows are equal)."""
    out = []
    for scene in SCENES:
        for method in METHODS:
            sel = [r for r in rows if r["scene"] == scene and r["method"] == f"{method}/c"
                   and r["status"] == "ok"]
            if not sel or scene not in floors:
                continue
            entry = {"scene": scene, "method": method}
            for key in ERROR_KEYS:
                entry[key] = convergence_order([r["dt"] for r in sel],
                                               [r.get(key, np.nan) for r in sel],
                                               floors[scene][key])
            out.append(entry)
    return out


def pareto(points):
    """Points (wall, error) on the lower-left front: each cheaper one is less accurate."""
    pts = sorted((w, e) for w, e in points if np.isfinite(w) and np.isfinite(e) and e > 0)
    front, best = [], math.inf
    for w, e in pts:
        if e < best:
            front.append((w, e))
            best = e
    return front


def cost_at_error(front, error):
    """Wall per simulated second to reach ``error`` along a front, log-log interpolated.

    Returns (cost, how): how is ``'interpolated'``, ``'at most'`` (the error
    is above the front's largest: its cheapest point already reaches it) or
    ``'not reached'`` (below its smallest error; cost NaN).
    """
    if not front:
        return float("nan"), "not reached"
    walls = np.array([w for w, _ in front])
    errs = np.array([e for _, e in front])
    if error >= errs[0]:
        return float(walls[0]), "at most"
    if error < errs[-1]:
        return float("nan"), "not reached"
    # errs decreases along the front; interpolate log wall against log error
    return float(np.exp(np.interp(-np.log(error), -np.log(errs), np.log(walls)))), "interpolated"


def equal_error_comparison(rows, scene="fig3", key="rebound_error"):
    """For every peer point of a scene: the compiled methods' cost at the same error."""
    out = []
    fronts = {m: pareto([(r["wall_per_sim_second"], r.get(key, np.nan)) for r in rows
                         if r["scene"] == scene and r["method"] == f"{m}/c"
                         and r["status"] == "ok"]) for m in METHODS}
    for r in rows:
        if r["scene"] != scene or r["backend"] != "peer" or r["status"] != "ok":
            continue
        entry = {"peer": r["method"], "dt": r["dt"], "tolerance": r["tolerance"],
                 "error": r[key], "peer_cost": r["wall_per_sim_second"], "ours": {}}
        for m in METHODS:
            cost, how = cost_at_error(fronts[m], r[key])
            entry["ours"][m] = (cost, how)
        out.append(entry)
    return out


# ---------------------------------------------------------------------------
# figure
# ---------------------------------------------------------------------------
COLOURS = {"paper": "tab:blue", "robust": "tab:orange", "implicit": "tab:green"}
PEER_STYLE = {"penalty-cvodes": ("tab:red", "s"), "mujoco": ("tab:purple", "D")}
TITLES = {"fig3": "Fig. 3 (μ = 0)", "fig4": "Fig. 4 (μ = 0.05)",
          "lander_slope": "lander, 10° slope (μ = 0.4)"}
#: Errors are drawn at no less than this (a log axis has no 0).
PLOT_FLOOR = 1e-14


def plot(rows, orders, path, floors=None) -> None:
    """Two rows of panels: rebound error vs wall per simulated second; errors vs Δt."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    import matplotlib.ticker

    scenes = [s for s in SCENES if any(r["scene"] == s for r in rows)]
    fig, axes = plt.subplots(2, len(scenes), figsize=(5.2 * len(scenes), 9.0), squeeze=False)
    for col, scene in enumerate(scenes):
        ax = axes[0, col]
        for method in METHODS:
            for backend, style in (("c", "-o"), ("vm", "--^")):
                sel = [r for r in rows if r["scene"] == scene and r["method"] ==
                       f"{method}/{backend}" and r["status"] == "ok"]
                if sel:
                    ax.plot([r["wall_per_sim_second"] for r in sel],
                            [max(r["rebound_error"], PLOT_FLOOR) for r in sel], style,
                            color=COLOURS[method], ms=4, lw=1.2,
                            mfc="none" if backend == "vm" else COLOURS[method],
                            label=f"{method}/{backend}")
        for peer, (colour, marker) in PEER_STYLE.items():
            sel = [r for r in rows if r["scene"] == scene and r["backend"] == "peer"
                   and r["method"].startswith(peer) and r["status"] == "ok"]
            if sel:
                ax.plot([r["wall_per_sim_second"] for r in sel],
                        [max(r["rebound_error"], PLOT_FLOOR) for r in sel], ":" + marker,
                        color=colour, ms=6, lw=1, label=peer)
        ax.set_xscale("log")
        ax.set_yscale("log")
        ax.set_xlabel("time per simulated second (s/s)")
        ax.set_ylabel("rebound-speed error (m/s)")
        ax.set_title(TITLES[scene])
        ax.grid(True, which="major", alpha=0.3)
        if col == 0:
            ax.legend(fontsize=7, ncol=2, loc="lower left")
        ax = axes[1, col]
        for method in METHODS:
            sel = [r for r in rows if r["scene"] == scene and r["method"] == f"{method}/c"
                   and r["status"] == "ok"]
            if not sel:
                continue
            entry = next((o for o in orders if o["scene"] == scene and o["method"] == method),
                         None)
            for key, style in (("rebound_error", "-o"), ("trajectory_error", "--s")):
                p = entry[key][0] if entry else float("nan")
                label = f"{method}, {'rebound' if key == 'rebound_error' else 'trajectory'}"
                label += f" (order {p:.1f})" if np.isfinite(p) else " (no order)"
                ax.plot([r["dt"] for r in sel], [max(r[key], PLOT_FLOOR) for r in sel], style,
                        color=COLOURS[method], ms=4, lw=1.2,
                        mfc="none" if key == "trajectory_error" else COLOURS[method],
                        label=label)
        if floors and scene in floors:
            ax.axhline(max(floors[scene]["rebound_error"], PLOT_FLOOR), color="grey", lw=0.8,
                       ls=":", label="reference's own rebound error")
        ax.set_xscale("log")
        ax.set_yscale("log")
        ax.set_xlabel("Δt (s)")
        ax.xaxis.set_minor_formatter(matplotlib.ticker.NullFormatter())
        ax.set_ylabel("rebound error (m/s) / trajectory error (rel.)")
        ax.grid(True, which="major", alpha=0.3)
        ax.legend(fontsize=6.5)
    fig.suptitle("Speed vs error: compiled C (filled, solid) and CasADi VM (open, dashed); "
                 "peers dotted", fontsize=10)
    fig.tight_layout()
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=110)
    plt.close(fig)


# ---------------------------------------------------------------------------
# report
# ---------------------------------------------------------------------------
def _fmt(x, spec=".2e"):
    return "—" if x is None or not np.isfinite(x) else format(x, spec)


def _machine() -> str:
    import subprocess

    cpu = platform.processor() or platform.machine()
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name"):
                cpu = line.split(":", 1)[1].strip()
                break
    except OSError:
        pass
    cc = subprocess.run(["gcc", "--version"], capture_output=True, text=True).stdout
    return (f"{cpu}, {platform.system()} {platform.machine()}, "
            f"{cc.splitlines()[0] if cc else 'gcc ?'}, CasADi {ca.__version__}, "
            f"CPython {platform.python_version()}")


def report_text(rows, checks, orders, notes, dt_grid, total_seconds,
                out: str = "figures") -> str:
    """The Markdown of the results section."""
    lines = [f"Produced by `python studies/speed_vs_error.py` in {total_seconds / 60:.1f} min "
             f"on {_machine()}; the machine has 2 cores and was shared with other jobs. "
             f"Δt grid {', '.join(f'{d:g}' for d in dt_grid)} s; the data are in "
             f"`{out}/speed_vs_error.csv`, the plot in `{out}/speed_vs_error.png`. Times "
             "are process CPU time per simulated second of the step loop (best of up to "
             f"{BEST_OF} passes; peers as described under \"Timing\").", ""]
    lines += ["![speed vs error](../figures/speed_vs_error.png)", ""]

    lines += ["### Reference and its check", "",
              "| scene | Δt_ref (s) | rebound speed (m/s) | peak \\|a − g\\| (m/s²) | "
              "peak hinge (rad) | peak stroke (m) | self-error: rebound (m/s) | peak decel "
              "(rel.) | peak deflection (rel.) | trajectory (rel.) | run time (s) |",
              "|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|"]
    for c in checks:
        m, s = c["ref"], c["self_error"]
        lines.append(f"| {c['scene']} | {c['dt_ref']:g} | {m['rebound_speed']:.8f} | "
                     f"{m['peak_decel']:.5f} | {m['peak_hinge']:.6f} | {m['peak_stroke']:.3e} | "
                     f"{_fmt(s['rebound_error'])} | {_fmt(s['peak_decel_error'])} | "
                     f"{_fmt(s['peak_deflection_error'])} | {_fmt(c['trajectory'])} | "
                     f"{c['wall']:.1f} |")
    vm_c = max((c.get("vm_c_max_diff", 0.0) for c in checks), default=0.0)
    lines += ["", "Self-error = |metric(2·Δt_ref) − metric(Δt_ref)|, the Richardson estimate "
              "of the reference's own error for order 1 (for order p it is that over 2^p − 1, "
              "smaller). Errors below 10× this are not used in the order fits. VM and "
              f"compiled runs agree: largest difference of any metric {vm_c:.1e}.", ""]

    lines += ["### Convergence orders", "",
              f"Slope of log(error) against log(Δt), least squares over the grid points with "
              f"Δt ≤ {ORDER_DT_MAX:g} s (the range used and the number of points in brackets) "
              f"whose error is above {FLOOR_FACTOR:g}× the reference's self-error; — where "
              "fewer than two points qualify.", "",
              "| scene | method | rebound speed | peak deceleration | peak deflection | "
              "trajectory |", "|---|---|---|---|---|---|"]
    for o in orders:
        cells = []
        for key in ERROR_KEYS:
            p, rng, n = o[key]
            cells.append("—" if not np.isfinite(p) else
                         f"{p:.2f} ({rng[0]:g}–{rng[1]:g}, {n})")
        lines.append(f"| {o['scene']} | {o['method']} | " + " | ".join(cells) + " |")

    lines += ["", "### Acceptance", ""]
    lines += _acceptance_text(rows)

    for scene in SCENES:
        sel = [r for r in rows if r["scene"] == scene]
        if not sel:
            continue
        lines += ["", f"### {TITLES[scene]}", "",
                  "Errors against the reference (rebound absolute, the others relative); "
                  "time per simulated second of the compiled rollout (C) and the VM rollout "
                  "(VM), step loop only. VM and C results are identical, so their errors are "
                  "listed once.", "",
                  "| method | Δt (s) | rebound err (m/s) | peak decel err | peak defl. err | "
                  "trajectory err | C (s/sim-s) | VM (s/sim-s) | status |",
                  "|---|---:|---:|---:|---:|---:|---:|---:|---|"]
        for method in METHODS:
            for r in [r for r in sel if r["method"] == f"{method}/c"]:
                vm = next((v for v in sel if v["method"] == f"{method}/vm"
                           and v["dt"] == r["dt"]), None)
                lines.append(
                    f"| {method} | {r['dt']:g} | {_fmt(r.get('rebound_error'))} | "
                    f"{_fmt(r.get('peak_decel_error'))} | {_fmt(r.get('peak_deflection_error'))} "
                    f"| {_fmt(r.get('trajectory_error'))} | {_fmt(r['wall_per_sim_second'], '.3g')}"
                    f" | {_fmt(vm['wall_per_sim_second'], '.3g') if vm else 'skipped'} | "
                    f"{r['status']} |")
        peers = [r for r in sel if r["backend"] == "peer"]
        if peers:
            lines += ["", "| peer | Δt or rtol | rebound err (m/s) | peak decel err | "
                      "peak defl. err | trajectory err | wall (s/sim-s) | status |",
                      "|---|---:|---:|---:|---:|---:|---:|---|"]
            for r in peers:
                knob = f"rtol {r['tolerance']:g}" if r.get("tolerance") is not None \
                    and np.isfinite(r["tolerance"]) else f"{r['dt']:g}"
                lines.append(
                    f"| {r['method']} | {knob} | {_fmt(r.get('rebound_error'))} | "
                    f"{_fmt(r.get('peak_decel_error'))} | {_fmt(r.get('peak_deflection_error'))} "
                    f"| {_fmt(r.get('trajectory_error'))} | "
                    f"{_fmt(r.get('wall_per_sim_second', np.nan), '.3g')} | {r['status']} |")
    if notes:
        lines += ["", "Notes of this run:", ""] + [f"* {n}" for n in notes]
    return "\n".join(lines)


def _acceptance_text(rows) -> list:
    lines = []
    comp = equal_error_comparison(rows)
    if not comp:
        lines.append("* **Compiled vs peers at equal rebound error (Fig. 3):** not measured: "
                     "no peer rows (see the notes below).")
    else:
        lines += ["* **Compiled vs peers at equal rebound error (Fig. 3).** For each peer run, "
                  "the cost of each compiled method at the same rebound-speed error, "
                  "log-log interpolated along its Pareto front (cheapest first, each point "
                  "more accurate than the last); ratio = peer cost / compiled cost, > 1 means "
                  "the compiled simulator is faster. \"≥\": the peer's error is above the "
                  "compiled method's coarsest point, whose cost is an upper bound.", "",
                  "| peer run | rebound err (m/s) | peer (s/sim-s) | " +
                  " | ".join(f"{m}/c ratio" for m in METHODS) + " |",
                  "|---|---:|---:|" + "---:|" * len(METHODS)]
        for e in comp:
            # the penalty runs are named by their tolerance already
            knob = "" if e["peer"].startswith("penalty") else f" (Δt {e['dt']:g})"
            cells = []
            for m in METHODS:
                cost, how = e["ours"][m]
                if how == "not reached":
                    cells.append("not reached")
                else:
                    bound = "≥ " if how == "at most" else ""
                    cells.append(f"{bound}{e['peer_cost'] / cost:.3g}")
            lines.append(f"| {e['peer']}{knob} | {e['error']:.2e} | {e['peer_cost']:.3g} | "
                         + " | ".join(cells) + " |")
        lines.append("")
    fig3 = [r for r in rows if r["scene"] == "fig3" and r["backend"] == "c"
            and r["status"] == "ok"]
    if fig3:
        lines.append("* **The paper's |Δy′| < 1e-2 m/s on Fig. 3** (Δy′ = rebound speed at the "
                     "height of first contact − impact speed, as `symcushion reproduce` "
                     "measures it; the exact value is 0, the frictionless rods being "
                     "conservative):")
        lines.append("")
        lines.append(f"| method | Δy′ at Δt = 1e-3 (m/s) | \\|Δy′\\| < {REBOUND_BOUND:g} | "
                     f"\\|Δy′\\| < {REBOUND_AIM:g} (the aim) | largest grid Δt with "
                     f"\\|Δy′\\| < {REBOUND_AIM:g} |")
        lines.append("|---|---:|---|---|---:|")
        for m in METHODS:
            sel = [r for r in fig3 if r["contact_step"] == m and r["rebound_kind"] == "ballistic"]
            at = next((r for r in sel if abs(r["dt"] - 1e-3) < 1e-12), None)
            aim = [r["dt"] for r in sel if abs(r["rebound_dv"]) < REBOUND_AIM]
            dv = at["rebound_dv"] if at else float("nan")
            largest = f"{max(aim):g}" if aim else "none"
            lines.append(f"| {m} | {_fmt(dv)} | {'yes' if abs(dv) < REBOUND_BOUND else 'NO'} | "
                         f"{'yes' if abs(dv) < REBOUND_AIM else 'NO'} | {largest} |")
    return lines


# ---------------------------------------------------------------------------
def main(argv=None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true",
                        help="smoke run: Δt grid 3e-3..3e-4, reference at 1e-5, outputs to "
                             f"{QUICK_OUT} (docs untouched)")
    parser.add_argument("--scenes", nargs="+", choices=list(SCENES), default=list(SCENES))
    parser.add_argument("--no-vm", action="store_true", help="compiled runs only")
    parser.add_argument("--no-peers", action="store_true", help="skip symcushion.peers")
    parser.add_argument("--out", type=Path, default=None,
                        help="folder of the CSV and PNG (default figures/, or the quick folder)")
    args = parser.parse_args(argv)
    dt_grid = QUICK_DT_GRID if args.quick else DT_GRID
    dt_ref = QUICK_DT_REF if args.quick else DT_REF
    out = args.out or (QUICK_OUT if args.quick else FIGURES)
    started = time.perf_counter()
    rows, checks, floors, notes = [], [], {}, []
    for name in args.scenes:
        print(f"{name}:", flush=True)
        r, check, floor, n = run_scene(name, dt_grid, dt_ref, vm=not args.no_vm,
                                       peers=not args.no_peers,
                                       progress=lambda s: print(s, flush=True))
        rows += r
        checks.append(check)
        floors[name] = floor
        notes += n
    orders = orders_table(rows, floors)
    write_csv(rows, out / "speed_vs_error.csv")
    plot(rows, orders, out / "speed_vs_error.png", floors)
    total = time.perf_counter() - started
    shown = "figures" if out == FIGURES else str(out)
    text = report_text(rows, checks, orders, notes, dt_grid, total, shown)
    print(text)
    if not args.quick and args.out is None:
        report.write_section(DOC, "Results", text, title="# Speed versus error")
    print(f"wrote {out / 'speed_vs_error.csv'}, {out / 'speed_vs_error.png'}"
          + ("" if args.quick or args.out else f", {DOC}") + f" in {total:.0f} s", flush=True)


if __name__ == "__main__":
    main(sys.argv[1:])
