"""How fast is a compiled touchdown step against MuJoCo, and how long does it compile?

Question (the cost items of the exact contact step): for the Fig. 4 scene
(4 rods on a dome, μ = 0.05) with the implicit contact step, and the Fig. 3
scene (μ = 0, its own method), how many µs does one compiled symcushion step
take against one MuJoCo step on the project's MuJoCo model of the same scene,
both run natively in this process (the two timed alternately, call by call,
in the thread's CPU time, so that the load of the shared machine does not
favour the shorter calls); and how long does gcc take at -O3 on the
touchdown source? The same for the tutorial lander (studies/tutorial/lander.toml)
and lander_slope (studies/lander_slope.toml), each with its own method, against
MuJoCo on the same lander with linear legs (:func:`mujoco_scene`: the MuJoCo
peer cannot express their crushable absorbers).

Method.
symcushion: ``symcushion.compiled.codegen.compiled_model`` builds the scene's C code;
its compiled ``touchdown_rollout`` (N steps in one C call, no Python per
step) is called on the scene's initial state with the scene's own
parameters (``model.default_p``: gravity, mass, inertia, μ) through
``Function.buffer()``, which evaluates into NumPy arrays allocated once (as
``mj_step`` writes into its ``MjData``; a plain call also allocates the
N-column outputs, 0.1-0.4 µs per step, printed for comparison), best of
BEST_OF calls; µs per step = thread CPU time / N. Before timing, one call's states and
outputs must be finite and equal, bit for bit, to the uncompiled
``build_model(scene)`` rolled out with the same x0, p and Δt
(``studies/bench_check.py``). Also timed: the rollout asked for its states
alone (Y a null pointer: the compiled loop then runs the step without its
per-step outputs, ``touchdown_step_states``), its X checked equal, bit for
bit, to the full rollout's; the ratio on it is printed beside the full step's
("states only"). Compile time: gcc's CPU time on the generated touchdown
source alone with ``codegen.CFLAGS`` (-O3).
MuJoCo: ``symcushion.peers.build_mjcf`` on the same scene (its default
timestep, solver settings of docs/peers.md), the state set by one short
``mujoco_simulate``-equivalent start (free joint at the scene's initial pose
and velocity), then ``mujoco.mj_step(model, data, nstep=M)`` once, best of
BEST_OF calls; µs per MuJoCo step = thread CPU time / M. Before timing, the state after
the M steps must be finite and equal, bit for bit, to the end of
``symcushion.peers.mujoco_simulate`` on the same scene. The ratio printed is MuJoCo's
µs per step over symcushion's µs per step, as in the cost target.

Also, so that one run prints every cost target of the exact step: the
implicit contact step against the robust one per evaluation, both as the
simulator calls them, compiled into one C harness and timed on the same
2 000 random 3-D cases (``bench_contact.native_ratio``, docs/contact.md).

Output: the numbers and ratios on stdout. Run:
``python studies/bench_touchdown.py``.
"""
from __future__ import annotations

import resource
import subprocess
import tempfile
import time
from pathlib import Path

import numpy as np

from bench_check import (BITWISE, buffered, check_equal, check_finite,  # studies/
                         check_rollout)
from bench_contact import NATIVE_CASES, native_ratio, spatial_cases  # studies/bench_contact.py
from symcushion.compiled import codegen
from symcushion.compiled.codegen import CFLAGS, compiled_model
from symcushion.peers.mujoco_model import build_mjcf, mujoco_available, mujoco_simulate
from symcushion.legs.characteristics import Linear
from symcushion.model.scene import load_scene
from symcushion.legs.strut import HingedStrut
from symcushion.scheme.touchdown import build_model, initial_state

ROOT = Path(__file__).resolve().parent.parent
#: Name of this benchmark in the messages of its checks.
BENCH = "bench_touchdown"
FIG3 = ROOT / "studies" / "fig3.toml"
FIG4 = ROOT / "studies" / "fig4.toml"
TUTORIAL = ROOT / "studies" / "tutorial" / "lander.toml"
SLOPE = ROOT / "studies" / "lander_slope.toml"
#: (label, scene file, method or None for the scene's own, target ratio): the scenes
#: of the speed target, each timed against the project's MuJoCo model of it.
SCENES = (("Fig. 4", FIG4, "implicit", 5.0),
          ("Fig. 3", FIG3, None, 5.0),
          ("tutorial lander", TUTORIAL, None, 5.0),
          ("lander_slope", SLOPE, None, 5.0))
#: Timed calls per measurement, the same for both programs, alternated; the best is kept
#: (the least disturbed). The first few calls of the compiled rollout run
#: up to 1.7 times slower than the rest (caches, the output arrays' first
#: pages), and a loaded 2-core machine preempts some calls: with 5 calls the
#: Fig. 3 step measured 4.7 µs, with 30 calls 2.8 µs, the same as the
#: standalone C program's step loop.
#: Each call is timed in the thread's CPU time (``time.thread_time``), not wall
#: time: a MuJoCo call (0.3 s at its step of 0.11 ms: 2 700 steps, 20-40 ms) is
#: longer than a time slice of a loaded machine and is preempted in every one of
#: 30 calls, where a 0.7 ms symcushion call often runs whole, so under load the
#: best wall times favoured symcushion: Fig. 3 measured 7.3, 12.1 and 16.3 µs per
#: MuJoCo step in three runs (load average 0.5 to 5.6) against 2.3 µs for the
#: rollout in each, ratios 3.1 to 7.2. The wall-clock ratio is still printed.
BEST_OF = 30
#: Simulated time per timed call (s): the touchdown and the first rebound.
SECONDS = 0.3


def compile_cpu(source: Path, out_dir: Path) -> float:
    """CPU seconds of gcc on one generated source with codegen.CFLAGS (-O3)."""
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    subprocess.run([codegen.find_compiler(), *CFLAGS, "-c", str(source), "-o",
                    str(out_dir / "timed.o")], check=True, capture_output=True)
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    return (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)


def check_symcushion(scene, rollout, steps: int) -> np.ndarray:
    """Check the rollout this benchmark times; return its parameters ``p``.

    One call of ``rollout`` (``steps`` steps) on the scene's initial state and
    own parameters (``default_p``) must be finite and equal, bit for bit, to
    the uncompiled ``build_model(scene)`` rolled out the same way.
    """
    p = build_model(scene).default_p
    check_rollout(BENCH, f"{scene.name} ({scene.method}) compiled rollout", rollout, scene,
                  initial_state(scene), p, scene.dt, steps, rtol=BITWISE)
    return p


def states_buffered(rollout, x0, p, dt: float):
    """(evaluate, X): ``rollout`` bound to preallocated inputs and X, its output Y left a
    null pointer, so that the compiled rollout runs the step without its per-step
    outputs (``touchdown_step_states``, docs/codegen.md)."""
    buffer, evaluate = rollout.buffer()
    inputs = [np.array(x0, dtype=float), np.array(p, dtype=float), np.array([dt])]
    X = np.zeros(rollout.nnz_out(0))
    for i, a in enumerate(inputs):
        buffer.set_arg(i, memoryview(a))
    buffer.set_res(0, memoryview(X))

    def run(_keep=(buffer, inputs)):          # the buffers outlive the closure
        evaluate()

    return run, X


def symcushion_timer(scene, folder: Path):
    """(timer, steps, gcc CPU s of the touchdown source, SX instructions): ``timer()``
    runs the checked compiled rollout once into preallocated arrays and returns its
    (wall, thread CPU) seconds; ``timer(call=True)`` times a plain call (outputs
    allocated by CasADi), ``timer(states=True)`` the rollout asked for X alone
    (checked equal to the full rollout's X, bit for bit)."""
    steps = int(round(SECONDS / scene.dt))
    model = compiled_model(scene, folder, steps=steps)
    x0 = initial_state(scene)
    rollout = model.rollout(steps)
    p = check_symcushion(scene, rollout, steps)
    evaluate, outputs = buffered(rollout, x0, p, scene.dt)
    evaluate()
    X_ref = np.asarray(rollout(x0, p, scene.dt)[0], dtype=float).ravel(order="F")
    check_equal(BENCH, f"{scene.name} rollout evaluated into buffers: X", outputs[0], X_ref,
                rtol=BITWISE, reference_name="the checked rollout")

    states_only, X_only = states_buffered(rollout, x0, p, scene.dt)
    states_only()
    check_equal(BENCH, f"{scene.name} rollout without Y (touchdown_step_states): X", X_only,
                X_ref, rtol=BITWISE, reference_name="the checked rollout")

    def timer(call: bool = False, states: bool = False, _keep=(outputs, X_only)) -> float:
        # the buffers hold raw pointers: their arrays must live as long as the timer
        start, cpu = time.perf_counter(), time.thread_time()
        if call:
            rollout(x0, p, scene.dt)
        elif states:
            states_only()
        else:
            evaluate()
        return time.perf_counter() - start, time.thread_time() - cpu

    seconds = compile_cpu(folder / f"{codegen.TOUCHDOWN}.c", folder)
    return timer, steps, seconds, build_model(scene).step.n_instructions()


def mujoco_scene(scene):
    """The scene MuJoCo is built from: the scene itself when its legs are linear springs
    (Figs. 3-4); otherwise (the tutorial lander's crushable, damped absorbers on the
    memory law, lander_slope's crushable absorbers with an unloading branch) the same
    body, obstacles, μ and leg geometry with every element replaced by the linear
    spring of its slope at rest, which ``build_mjcf`` can express (it refuses
    non-linear, hysteretic and damped-law scenes). The MuJoCo model has the same
    bodies, joints, contacts and friction cone, so its cost per step is that of the
    scene's; MuJoCo's own dampers or a non-linear spring (a passive-force callback)
    would only add to it."""
    linear = all(isinstance(el.curve, Linear) and el.curve.unloading is None
                 and not el.curve.has_damper for leg in scene.legs for el in leg.elements)
    if linear:
        return scene
    legs = []
    for leg in scene.legs:
        curves = {el.name: Linear(float(el.curve.slope(0.0))) for el in leg.elements}
        if leg.rigid:
            curves.pop("S")
        legs.append(HingedStrut(leg.hinge, leg.e0, leg.en, leg.length, law=leg.law,
                                axial_ratio=leg.axial_ratio, **curves))
    return scene.with_(legs=legs, hysteresis="sign", events="none",
                       name=f"{scene.name} (linear legs)")


def mujoco_start(scene):
    """(mujoco, model, data, start): the project's MuJoCo model of the scene, and
    ``start()``, which puts ``data`` at the scene's initial state as
    ``mujoco_simulate`` does (free joint at the initial pose and velocity, the
    legs' joint angles solved from the feet)."""
    import mujoco
    from symcushion.peers import mujoco_model as mm

    xml, settings = build_mjcf(scene)
    model = mujoco.MjModel.from_xml_string(xml)
    data = mujoco.MjData(model)
    pos0, vel0, quat0, omega0, legs0 = mm._joint_state(scene, initial_state(scene))
    axial = [s[2] is not None for s in settings["springs"]]

    def start():
        mujoco.mj_resetData(model, data)
        data.qpos[0:3], data.qpos[3:7] = pos0, quat0
        data.qvel[0:3], data.qvel[3:6] = vel0, omega0
        for j, (th_g, th_b, stroke) in enumerate(legs0):
            data.qpos[model.jnt_qposadr[model.joint(f"leg{j}_gamma").id]] = th_g
            data.qpos[model.jnt_qposadr[model.joint(f"leg{j}_beta").id]] = th_b
            if axial[j]:
                data.qpos[model.jnt_qposadr[model.joint(f"leg{j}_axial").id]] = stroke
        mujoco.mj_forward(model, data)

    return mujoco, model, data, start


def check_mujoco(scene, steps: int) -> None:
    """Check the native MuJoCo stepping this benchmark times.

    ``mj_step(nstep=steps)`` from the scene's start must leave a finite state
    equal, bit for bit, to the end of ``mujoco_simulate`` on the scene run for
    ``steps`` MuJoCo steps (its duration rounded to whole steps).
    """
    mujoco, model, data, start = mujoco_start(scene)
    start()
    mujoco.mj_step(model, data, nstep=steps)
    what = f"{scene.name} MuJoCo state after {steps} mj_step"
    check_finite(BENCH, f"{what}: qpos", data.qpos)
    check_finite(BENCH, f"{what}: qvel", data.qvel)
    run = mujoco_simulate(scene.with_(duration=steps * model.opt.timestep),
                          timestep=model.opt.timestep, output_dt=steps * model.opt.timestep)
    name = "the end of mujoco_simulate on the same scene"
    check_equal(BENCH, f"{what}: body position", data.qpos[0:3], run.position[-1],
                rtol=BITWISE, reference_name=name)
    check_equal(BENCH, f"{what}: body velocity", data.qvel[0:3], run.velocity[-1],
                rtol=BITWISE, reference_name=name)


def mujoco_timer(scene):
    """(timer, steps, MuJoCo timestep in s): ``timer()`` runs the checked native
    ``mj_step`` over SECONDS from the scene's start and returns its (wall, thread CPU)
    seconds; ``scene``
    is that of :func:`mujoco_scene`."""
    mujoco, model, data, start = mujoco_start(scene)
    steps = int(round(SECONDS / model.opt.timestep))
    check_mujoco(scene, steps)

    def timer() -> float:
        start()
        began, cpu = time.perf_counter(), time.thread_time()
        mujoco.mj_step(model, data, nstep=steps)
        return time.perf_counter() - began, time.thread_time() - cpu

    return timer, steps, float(model.opt.timestep)


def measure(scene, folder: Path) -> dict:
    """Best of BEST_OF interleaved calls of symcushion's rollout and MuJoCo's steps, in
    thread CPU time (and the ratio of the best wall times, for comparison)."""
    sym, n_sym, gcc, instr = symcushion_timer(scene, folder)
    mj, n_mj, h = mujoco_timer(mujoco_scene(scene))
    wall = dict(sym=np.inf, call=np.inf, states=np.inf, mj=np.inf)
    best = dict(wall)                    # thread CPU time
    for _ in range(BEST_OF):
        for key, run in (("sym", sym), ("mj", mj), ("call", lambda: sym(call=True)),
                         ("states", lambda: sym(states=True))):
            w, c = run()
            wall[key], best[key] = min(wall[key], w), min(best[key], c)
    return dict(us=1e6 * best["sym"] / n_sym, us_call=1e6 * best["call"] / n_sym,
                us_states=1e6 * best["states"] / n_sym,
                mj=1e6 * best["mj"] / n_mj, h=h, gcc=gcc, instr=instr,
                wall_ratio=(wall["mj"] / n_mj) / (wall["sym"] / n_sym))


def main() -> None:
    if not mujoco_available():
        raise SystemExit("MuJoCo is not installed: pip install symcushion[peers]")
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        for label, path, method, target in SCENES:
            scene = load_scene(path)
            if method:
                scene = scene.with_(method=method)
            scene = scene.with_(duration=SECONDS)
            rows.append((label, scene, target, measure(scene, Path(tmp) / label.replace(". ", "").replace(" ", "_"))))
    print("| scene | method | μ | SX instr. (step) | gcc -O3 CPU s | symcushion µs/step "
          "(plain call) | states only µs/step | MuJoCo µs/step (h) | MuJoCo/symcushion "
          "per step | states only | target | (wall-clock ratio) |")
    print("|---|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|")
    for label, scene, target, m in rows:
        print(f"| {label} | {scene.method} | {scene.mu:g} | {m['instr']:,} | {m['gcc']:.1f} | "
              f"{m['us']:.2f} ({m['us_call']:.2f}) | {m['us_states']:.2f} | "
              f"{m['mj']:.2f} ({m['h']:g} s) | {m['mj'] / m['us']:.2f} | "
              f"{m['mj'] / m['us_states']:.2f} | ≥ {target:g} | ({m['wall_ratio']:.2f}) |")
    cases = spatial_cases(np.random.default_rng(2024), NATIVE_CASES)
    called = native_ratio(cases, called=True)
    implicit, robust = called["contact_step_implicit"], called["contact_step_robust"]
    print(f"\nContact step, as the simulator calls it ({NATIVE_CASES} random 3-D cases, "
          f"C, -O3): implicit {implicit:.0f} ns, robust {robust:.0f} ns per evaluation; "
          f"implicit/robust {implicit / robust:.2f} (target ≤ 1.5).")


if __name__ == "__main__":
    main()
