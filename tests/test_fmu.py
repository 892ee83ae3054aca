"""The touchdown FMU (symcushion.compiled.fmu), checked by a real importer: FMPy.

Three FMUs are built once, concurrently, through the command line
(``symcushion fmu``): Figs. 3-4 and the tutorial lander. FMPy's validator
must find no problem; FMPy's co-simulation at the scene's Δt must give the
trajectory of ``symcushion.simulate`` (to 1e-12; it is the same bits); a
held thrust must move the body as the Python reference
:func:`symcushion.compiled.fmu.held_input_step` on the uncompiled step does; a saved
FMU state (in memory or serialised) must continue bit for bit. Skipped, with
the reason, when FMPy or a C compiler is missing.
"""
import os
import shutil
import subprocess
import sys
import zipfile
from pathlib import Path

import numpy as np
import pytest

from symcushion import build_model, initial_state, load_scene, simulate
from symcushion.compiled.cbuild import find_compiler
from symcushion.legs.characteristics import Crushable, Linear
from symcushion.compiled.fmu import build_fmu, held_input_step
from symcushion.compiled.fmu_variables import fmu_variables, model_description, variables_markdown
from symcushion.layout.vectors import output_layout, state_layout
from symcushion.model.scene import Body, Scene, symmetric_legs
from symcushion.model.obstacles import Plane

fmpy = pytest.importorskip("fmpy", reason="FMPy is not installed: pip install "
                           "'symcushion[fmu]' to build and import FMUs")
from fmpy import simulate_fmu  # noqa: E402
from fmpy.fmi1 import FMICallException  # noqa: E402
from fmpy.fmi2 import FMU2Slave  # noqa: E402
from fmpy.validation import validate_fmu  # noqa: E402

pytestmark = pytest.mark.skipif(find_compiler() is None,
                                reason="no C compiler found (set $CC or install gcc)")

ROOT = Path(__file__).resolve().parents[1]
SCENES = {"fig3": ROOT / "studies" / "fig3.toml", "fig4": ROOT / "studies" / "fig4.toml",
          "lander": ROOT / "studies" / "tutorial" / "lander.toml"}

#: The FMU runs the compiled step, which equals the CasADi VM bit for bit
#: (docs/codegen.md); the brief's bound is 1e-12 in the state's units.
AGREEMENT = 1e-12

BODY = ("position", "velocity", "attitude", "angular_velocity")


@pytest.fixture(scope="module")
def fmus(tmp_path_factory):
    """{name: (scene, model, path)}: the three FMUs, built by ``symcushion fmu`` in
    parallel processes (CasADi is not thread-safe; gcc dominates the time)."""
    folder = tmp_path_factory.mktemp("fmu")
    env = dict(os.environ, PYTHONPATH=str(ROOT))
    procs = {name: subprocess.Popen([sys.executable, "-m", "symcushion.cli", "fmu", str(path),
                                     "--out", str(folder / f"{name}.fmu")], env=env,
                                    stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
             for name, path in SCENES.items()}
    out = {}
    for name, proc in procs.items():
        stdout, stderr = proc.communicate()
        assert proc.returncode == 0, stderr
        assert f"wrote {folder / f'{name}.fmu'}" in stdout
        scene = load_scene(SCENES[name])
        out[name] = (scene, build_model(scene), folder / f"{name}.fmu")
    return out


def _vrs(path, names):
    md = fmpy.read_model_description(str(path))
    by_name = {v.name: v.valueReference for v in md.modelVariables}
    return [by_name[n] for n in names]


def _columns(result, names):
    return np.column_stack([result[n] for n in names])


def test_fmpy_validator_finds_no_problem(fmus):
    for name, (_, _, path) in fmus.items():
        assert validate_fmu(str(path)) == [], name


def test_the_fmu_holds_binary_sources_and_the_layout_names(fmus):
    scene, model, path = fmus["lander"]
    with zipfile.ZipFile(path) as zf:
        names = set(zf.namelist())
    assert {"modelDescription.xml", "binaries/linux64/lander.so", "sources/fmu.c",
            "sources/touchdown_step.c", "sources/touchdown_step.h",
            "sources/fmu_model.h"} <= names
    assert not any("fmi2" in n for n in names)          # the importer brings the headers
    md = fmpy.read_model_description(str(path))
    assert md.coSimulation.canGetAndSetFMUstate and md.coSimulation.canSerializeFMUstate
    assert float(md.defaultExperiment.stepSize) == scene.dt
    variables = {v.name: v for v in md.modelVariables}
    params = [v for v in md.modelVariables if v.causality == "parameter"]
    assert [v.name for v in params] == list(model.param_names)
    assert [float(v.start) for v in params] == list(model.default_p)
    assert variables["mass"].unit == "kg" and variables["inertia.xy"].unit == "kg.m2"
    assert variables["body_external_torque_z_N_m"].unit == "N.m"
    assert variables["leg0_mode_1"].type == "Integer"
    outputs = {v.name for v in md.modelVariables if v.causality == "output"}
    xl, yl = state_layout(model.n_legs), output_layout(model.n_legs)
    assert set(xl.columns()[:13]) | set(yl.columns()[:3]) <= outputs
    assert {f"leg{j}_{c}" for j in range(model.n_legs)
            for c in ("stroke_m", "force_x_N", "force_z_N", "mode_1")} <= outputs
    energy = {f"leg{j}_energy_{what}_J" for j in range(model.n_legs)
              for what in ("axial", "bending", "friction")}
    assert energy <= outputs and variables["leg0_energy_axial_J"].unit == "J"
    assert outputs <= set(xl.columns()) | set(yl.columns()) | energy


@pytest.mark.parametrize("name", list(SCENES))
def test_fmpy_cosimulation_equals_simulate(fmus, name):
    scene, model, path = fmus[name]
    result = simulate_fmu(str(path), step_size=scene.dt, output_interval=scene.dt,
                          stop_time=scene.duration)
    traj = simulate(scene, model=model, monitor=False)
    assert len(result) == len(traj.t) == scene.steps + 1
    np.testing.assert_allclose(result["time"], traj.t, rtol=0, atol=1e-12)
    xl, yl = state_layout(model.n_legs), output_layout(model.n_legs)
    worst = 0.0
    for field in BODY:
        names = [c for c in xl.columns() if c.startswith(f"body_{field}_")]
        worst = max(worst, np.max(np.abs(_columns(result, names) - getattr(traj, field))))
    worst = max(worst, np.max(np.abs(_columns(result, yl.columns()[:3]) - traj.acceleration)))
    for j in range(model.n_legs):
        worst = max(worst, np.max(np.abs(result[f"leg{j}_stroke_m"] - traj.stroke[:, j])),
                    np.max(np.abs(_columns(result, [f"leg{j}_force_{a}_N" for a in "xyz"])
                                  - traj.force[:, j])))
        assert np.array_equal(result[f"leg{j}_mode_1"], traj.mode[:, j])
    assert worst <= AGREEMENT, f"{name}: FMU against simulate {worst:.3g}"
    assert traj.mode.max() >= 1                          # the feet did touch down
    # the energy totals: the sums of the steps' work outputs of the same rollout
    _, Y = model.rollout(scene.steps)(initial_state(scene), model.default_p, scene.dt)
    for j in range(model.n_legs):
        for what in ("axial", "bending", "friction"):
            steps = np.cumsum(yl.get(np.asarray(Y), f"work_{what}", j))
            column = result[f"leg{j}_energy_{what}_J"]
            assert column[0] == 0.0
            np.testing.assert_allclose(column[1:], steps, rtol=1e-12,
                                       atol=1e-12 * max(1.0, np.max(np.abs(steps))))


#: The thrust: a force (N) and a torque (N·m) at t = 0 that tail off linearly
#: to zero over THRUST_TIME s (a retro-rocket burning out at touchdown).
THRUST_FORCE = np.array([30.0, -20.0, 350.0])
THRUST_TORQUE = np.array([4.0, -6.0, 2.5])
THRUST_TIME = 0.2


def test_held_thrust_moves_the_body_as_the_python_reference(fmus):
    scene, model, path = fmus["lander"]
    inputs = [f"body_external_{q}_{a}_{u}" for q, u in (("force", "N"), ("torque", "N_m"))
              for a in "xyz"]
    signal = np.zeros(3, dtype=[("time", float)] + [(n, float) for n in inputs])
    signal["time"] = [0.0, THRUST_TIME, scene.duration]
    for k, n in enumerate(inputs):
        signal[n][0] = np.concatenate([THRUST_FORCE, THRUST_TORQUE])[k]
    xl = state_layout(model.n_legs)
    body = [c for f in BODY for c in xl.columns() if c.startswith(f"body_{f}_")]
    result = simulate_fmu(str(path), step_size=scene.dt, output_interval=scene.dt,
                          stop_time=scene.duration, input=signal, output=body + inputs)
    held = _columns(result, inputs)
    # the value held over step k is the one read after it (FMPy sets the next one later)
    t = result["time"][:-1]
    law = np.clip(1 - t / THRUST_TIME, 0, None)[:, None] * np.concatenate(
        [THRUST_FORCE, THRUST_TORQUE])
    np.testing.assert_allclose(held[1:], law, rtol=0, atol=1e-9)

    x, p = initial_state(scene), model.default_p
    states = [x]
    for u in held[1:]:
        x, _ = held_input_step(model, x, p, scene.dt, u[:3], u[3:])
        states.append(x)
    reference = np.array(states)[:, :xl.body_size]
    gap = np.max(np.abs(_columns(result, body) - reference))
    assert gap <= AGREEMENT, f"FMU against the reference loop: {gap:.3g}"
    free = simulate(scene, model=model, monitor=False)
    moved = np.max(np.abs(result["body_position_z_m"] - free.position[:, 2]))
    assert moved > 1e-3                                 # the thrust is felt


def _slave(path, name):
    md = fmpy.read_model_description(str(path))
    fmu = FMU2Slave(guid=md.guid, unzipDirectory=fmpy.extract(str(path)),
                    modelIdentifier=md.coSimulation.modelIdentifier, instanceName=name)
    fmu.instantiate()
    fmu.setupExperiment(startTime=0.0)
    fmu.enterInitializationMode()
    fmu.exitInitializationMode()
    return fmu


def _run(fmu, t, steps, dt, vrs):
    rows = []
    for _ in range(steps):
        fmu.doStep(t, dt)
        t += dt
        rows.append(fmu.getReal(vrs))
    return np.array(rows)


def test_saved_states_continue_bit_for_bit_and_branch(fmus):
    scene, model, path = fmus["lander"]
    xl = state_layout(model.n_legs)
    vrs = _vrs(path, xl.columns()[:13] + ["leg0_force_z_N", "leg2_stroke_m"])
    mass, thrust = _vrs(path, ["mass", "body_external_force_z_N"])
    dt = scene.dt
    fmu = _slave(path, "a")
    fmu.setReal([thrust], [200.0])
    _run(fmu, 0.0, 150, dt, vrs)                        # in contact by now
    t = 150 * dt
    state = fmu.getFMUstate()
    blob = fmu.serializeFMUstate(state)
    first = _run(fmu, t, 100, dt, vrs)
    fmu.setFMUstate(state)
    again = _run(fmu, t, 100, dt, vrs)
    assert np.array_equal(first, again)
    # a Monte Carlo branch: heavier body from the same state, then back
    fmu.setFMUstate(state)
    fmu.setReal([mass], [1.1 * model.default_p[model.param_names.index("mass")]])
    heavier = _run(fmu, t, 100, dt, vrs)
    assert np.max(np.abs(heavier - first)) > 1e-6
    fmu.setFMUstate(state)                              # the parameters are in the state
    assert np.array_equal(_run(fmu, t, 100, dt, vrs), first)
    fmu.freeFMUstate(state)
    # serialised: into another instance of the same FMU
    other = _slave(path, "b")
    restored = other.deSerializeFMUstate(blob)
    other.setFMUstate(restored)
    assert np.array_equal(_run(other, t, 100, dt, vrs), first)
    other.freeFMUstate(restored)
    # a state of another FMU is refused
    fig3 = _slave(fmus["fig3"][2], "c")
    foreign = fig3.serializeFMUstate(fig3.getFMUstate())
    with pytest.raises(FMICallException):
        other.deSerializeFMUstate(foreign)
    for one in (fmu, other, fig3):
        one.terminate()
        one.freeInstance()


def test_a_step_that_is_not_a_whole_number_of_dt_is_an_error(fmus):
    scene, model, path = fmus["fig3"]
    vrs = _vrs(path, state_layout(model.n_legs).columns()[:13])
    dt = scene.dt
    one, three = _slave(path, "one"), _slave(path, "three")
    by_one = _run(one, 0.0, 3, dt, vrs)[-1]
    three.doStep(0.0, 3 * dt)
    assert np.array_equal(np.array(three.getReal(vrs)), by_one)
    # FMPy's own intervals carry round-off: (k + 1)·H − k·H
    three.doStep(3 * dt, 0.007 - 0.004)
    for off in (1.5 * dt, (1 + 1e-6) * dt):             # a fraction of a step, or a ppm
        with pytest.raises(FMICallException):
            three.doStep(6 * dt, off)
    with pytest.raises(FMICallException):               # an output cannot be set
        one.setReal(vrs[:1], [1.0])
    for fmu in (one, three):
        fmu.terminate()
        fmu.freeInstance()


@pytest.mark.skipif(shutil.which("cmake") is None, reason="no cmake (FMPy's rebuild uses it)")
def test_the_sources_rebuild_the_same_fmu(fmus, tmp_path):
    from fmpy.build import build_platform_binary

    scene, _, path = fmus["fig3"]
    unzipped = tmp_path / "fig3"
    with zipfile.ZipFile(path) as zf:
        zf.extractall(unzipped)
    shutil.rmtree(unzipped / "binaries")
    build_platform_binary(unzipped.resolve(), build_dir=tmp_path)
    runs = [simulate_fmu(str(p), step_size=scene.dt, output_interval=scene.dt,
                         stop_time=scene.duration) for p in (path, unzipped.resolve())]
    for name in runs[0].dtype.names:
        assert np.array_equal(runs[0][name], runs[1][name]), name


def test_bad_output_path_or_failed_build_leaves_no_fmu(tmp_path, monkeypatch, fmus):
    scene, model, _ = fmus["fig3"]
    with pytest.raises(ValueError, match=r"must end in \.fmu"):
        build_fmu(scene, tmp_path / "lander.zip", model=model)
    monkeypatch.setenv("CC", "false")                   # a compiler that always fails
    with pytest.raises(RuntimeError, match="compiling"):
        build_fmu(scene, tmp_path / "lander.fmu", model=model)
    assert list(tmp_path.iterdir()) == []


def test_tunable_curve_parameters_carry_their_units(tmp_path):
    legs = symmetric_legs(4, 0.4, 0.5, 0.5, (0, 0, -1), (-0.6, 0, -0.8),
                          S=Crushable(2e5, 3e3, tunable=True),
                          M_beta=Linear(3e3, tunable=True), M_gamma=Linear(3e3),
                          azimuth0=np.pi / 4)
    body = Body(mass=40.0, inertia=[2.0, 2.0, 3.0], position=[0, 0, 1.0])
    model = build_model(Scene(body, legs, [Plane.inclined(0.0)], mu=0.3, dt=1e-3,
                              duration=0.1))
    units = {v.name: v.fmi_unit for v in fmu_variables(model)}
    assert units["leg0.S.k"] == "N/m" and units["leg0.S.crush_force"] == "N"
    assert units["leg3.M_beta.k"] == "N.m/rad" and units["leg3.M_beta.preload"] == "N.m"
    assert units["mu"] is None
    (tmp_path / "modelDescription.xml").write_text(model_description(model, "sled", "{0}"))
    assert validate_fmu(str(tmp_path)) == []


def test_the_docs_show_the_generated_table_of_the_tutorial_lander(fmus):
    _, model, _ = fmus["lander"]
    assert variables_markdown(model) in (ROOT / "docs" / "toolchain.md").read_text()
