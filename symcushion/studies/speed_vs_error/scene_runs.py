"""One scene of the speed-vs-error study: its reference and its grid of VM and compiled runs.

Owns building the models of a scene (compiled C per contact method, the
CasADi VM), the reference run and its self-check at twice its step, and
the loop over variants (contact step and slip rule), backends and Δt that yields the scene's
rows. It must not fit orders, plot or write files.
"""
from __future__ import annotations

import json
import time
from pathlib import Path

from symcushion.compiled.codegen import compiled_model
from symcushion.model.scene import load_scene
from symcushion.model.scene_data import Scene
from symcushion.scheme.touchdown import build_model

from .grid import BUILD, CHUNK, SCENES, STUDIES, VARIANTS, VM_MAX_STEPS, applies
from .metrics import errors, metrics, result_row, trajectory_error
from .peer_runs import peer_rows
from .runs import simulate_chunked


def _build_seconds(folder: Path) -> float:
    """Code generation plus the gcc commands of a build folder's manifest (s).

    The two objects compile in parallel, so this sum bounds the wall time of a
    fresh build from above; a cached build cost only its code generation.
    """
    info = json.loads((folder / "symcushion.json").read_text())
    return float(info.get("generate_seconds", 0.0)
                 + sum((info.get("build") or {}).get("seconds", {}).values()))



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
    folders = {m: BUILD / f"{name}-{m}" for m in VARIANTS}
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
    for method, settings in VARIANTS.items():
        if not applies(settings, base.mu):
            notes.append(f"{name}: no {method} rows: the stroke lock holds stuck feet, and "
                         f"the scene is frictionless (mu = {base.mu:g}), so it refuses "
                         f"events = 'lock'.")
            continue
        scene = base.with_(**settings)
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
                row = result_row(name, method, backend, dt, run, status, ref_m, ref, spec,
                                 scene, build=build)
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

