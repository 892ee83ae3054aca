"""The Apollo-class example (studies/apollo_lander.toml, docs/tripod.md): its generated C
equals the Python rollout to round-off, and the lander lands, strokes within its end
stops and comes to rest at the LM's design limit (3.05 m/s down, 1.22 m/s downhill, 12°).
"""
from __future__ import annotations

import subprocess

import numpy as np
import pytest

from symcushion.compiled import codegen
from symcushion.layout.vectors import output_layout
from symcushion.model.scene import load_scene
from symcushion.scheme.touchdown import build_model, initial_state
from symcushion.run.driver import simulate

from conftest import STUDIES

APOLLO = STUDIES / "apollo_lander.toml"
#: The first contact (the uphill foot, at 1 ms), its stroke and the foot's lift-off as
#: the body pitches about it (about 0.07 s): 150 steps keep the build the test's cost.
SHORT_DURATION = 0.15
#: Compiled against SX (VM): the same operations in the same order without fused
#: multiply-add, so they differ at most by libm (tests/test_codegen.py).
REL_TOL = 1e-12
#: The standalone program prints its states with 17 significant digits.
TRAJ_TOL = 1e-10
#: The scene's criterion for "at rest" (docs/envelope.md, "Stable means at rest"), m/s.
REST_SPEED = 0.05


def _rel_err(a, b):
    a, b = np.asarray(a, float), np.asarray(b, float)
    return float(np.max(np.abs(a - b))) / max(float(np.max(np.abs(b))), np.finfo(float).tiny)


@pytest.mark.skipif(codegen.find_compiler() is None,
                    reason="no C compiler found (set $CC or install gcc)")
def test_generated_c_of_the_apollo_scene_equals_the_python_rollout(tmp_path):
    scene = load_scene(APOLLO).with_(duration=SHORT_DURATION)
    gen = codegen.generate(tmp_path, scene, build=True)
    fns = codegen.load_compiled(tmp_path)
    model = build_model(scene)
    x0 = initial_state(scene)
    X, Y = model.rollout(scene.steps)(x0, model.default_p, scene.dt)
    got = fns["touchdown_rollout"](x0, model.default_p, scene.dt)
    assert np.all(np.isfinite(np.asarray(X))) and np.all(np.isfinite(np.asarray(Y)))
    assert _rel_err(got[0], X) <= REL_TOL and _rel_err(got[1], Y) <= REL_TOL
    contact = output_layout(len(scene.legs)).legs(np.asarray(Y), "in_contact")
    assert contact.max() == 1.0, "the run must include the first contact"

    csv = tmp_path / "traj.csv"
    run = subprocess.run([str(gen.program), "-o", str(csv)], capture_output=True, text=True,
                         timeout=60)
    assert run.returncode == 0, run.stderr
    table = np.loadtxt(csv, delimiter=",", skiprows=1)
    expected = np.column_stack([x0, np.asarray(X)]).T
    assert table.shape == (scene.steps + 1, 1 + model.nx)
    assert np.max(np.abs(table[:, 1:] - expected)) <= TRAJ_TOL


def test_the_apollo_example_lands_strokes_within_its_stops_and_comes_to_rest():
    """At the design limit the uphill foot touches first and leaves the ground as the
    body pitches about it (the pitch, not a weak leg: docs/tripod.md); the downhill legs
    take the stroke, the slide stops and every foot but the uphill one is stuck."""
    scene = load_scene(APOLLO)
    traj = simulate(scene, estimate=False)
    first = [e for e in traj.events if e["kind"] == "touchdown"][0]
    assert first["leg"] == 2 and first["time"] <= 2 * scene.dt
    assert not traj.info["warnings"], traj.info["warnings"]          # no end stop reached
    limit = scene.legs[0].elements[0].curve.stroke_limit
    assert 0.2 < -traj.stroke.min() < 0.6 * limit
    speed = np.linalg.norm(traj.velocity, axis=1)
    assert np.all(speed[traj.t >= 3.2] < REST_SPEED)
    assert np.linalg.norm(traj.angular_velocity[-1]) < 1e-3
    np.testing.assert_array_equal(traj.mode[-1, [0, 1, 3]], 1.0)    # stuck
