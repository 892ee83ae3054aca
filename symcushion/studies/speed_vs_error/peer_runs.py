"""Rows of the peers (penalty contact integrated by CVODES, MuJoCo) of symcushion.peers.

Owns importing symcushion.peers if it can, converting a peer's result to a
:class:`~.runs.Run` and timing it the way symcushion's own runs are timed,
and the rows of the peer runs of one scene. It must not define contact
models (symcushion.peers does) nor run symcushion's own models.
"""
from __future__ import annotations

import time

import numpy as np

from symcushion.model.scene_data import Scene

from .grid import MUJOCO_TIMESTEPS, PEER_OUTPUT_DT, PENALTY_RTOLS
from .metrics import result_row
from .runs import Run


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
        row = result_row(name, name_m, "peer", dt, run, status, ref_m, ref, spec, scene,
                         tolerance=tol)
        row["method"] = name_m
        rows.append(row)
        progress(f"  {name_m:>28} {status[:40]:>10}  rebound err "
                 f"{row.get('rebound_error', float('nan')):.2e}  "
                 f"{row.get('wall_per_sim_second', float('nan')):.3g} s/sim-s")
    return rows

