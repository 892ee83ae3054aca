"""A second importer: does DNV's libcosim run the touchdown FMU as FMPy does?

Question (docs/toolchain.md, "How it is checked"): the tests import the FMU
with FMPy only; libcosim (the Open Simulation Platform's co-simulation
library, through FMI Library) is an independent importer. This script builds
the FMU of a scene (default ``studies/fig3.toml``), runs it through libcosim
at the scene's Δt for the scene's duration, and prints the largest
difference of the body's pose, velocities and acceleration and of every
leg's stroke and foot force from ``symcushion.simulate``.

Needs ``pip install libcosimpy`` (not an extra of symcushion: one study).
Run: ``python studies/fmu_libcosim.py [SCENE.toml]``.
"""
from __future__ import annotations

import sys
import tempfile
from pathlib import Path

import numpy as np

from symcushion import build_model, load_scene, simulate
from symcushion.compiled.fmu import build_fmu
from symcushion.compiled.fmu_variables import fmu_variables

#: libcosim counts time in integer nanoseconds.
NANOSECONDS = 1e9


def run_libcosim(path: Path, names, dt: float, steps: int) -> np.ndarray:
    """The Real variables ``names`` of the FMU at ``path`` after each of ``steps``
    co-simulation steps of ``dt`` s, shape (steps, len(names))."""
    from libcosimpy.CosimExecution import CosimExecution
    from libcosimpy.CosimObserver import CosimObserver
    from libcosimpy.CosimSlave import CosimLocalSlave

    execution = CosimExecution.from_step_size(int(round(dt * NANOSECONDS)))
    index = execution.add_local_slave(CosimLocalSlave(fmu_path=str(path), instance_name="fmu"))
    observer = CosimObserver.create_last_value()
    execution.add_observer(observer)
    rows = []
    for _ in range(steps):
        execution.step(1)
        rows.append(observer.last_real_values(index, list(names.values())))
    return np.array(rows)


def main(argv=None) -> int:
    argv = sys.argv[1:] if argv is None else argv
    scene_file = Path(argv[0]) if argv else Path(__file__).parent / "fig3.toml"
    try:
        import libcosimpy  # noqa: F401
    except ImportError:
        print("libcosimpy is not installed: pip install libcosimpy", file=sys.stderr)
        return 2
    scene = load_scene(scene_file)
    model = build_model(scene)
    outputs = {v.name: v.vr for v in fmu_variables(model)
               if v.causality == "output" and v.type == "Real"}
    with tempfile.TemporaryDirectory() as tmp:
        path = build_fmu(scene, Path(tmp) / f"{scene.name}.fmu", model=model)
        fmu = run_libcosim(path, outputs, scene.dt, scene.steps)
    traj = simulate(scene, model=model, monitor=False)
    reference = np.column_stack([traj.position, traj.velocity, traj.attitude,
                                 traj.angular_velocity, traj.acceleration]
                                + [np.column_stack([traj.stroke[:, j], traj.force[:, j]])
                                   for j in range(model.n_legs)])[1:]
    gap = np.max(np.abs(fmu - reference))
    print(f"{scene.name}: {scene.steps} steps of {scene.dt} s through libcosim; largest "
          f"|FMU - simulate| over {len(outputs)} outputs: {gap:.3g}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
