"""Fuzz test: mutated scene files either run cleanly or fail with a clear message.

Hypothesis mutates the valid scenes of ``studies/`` (the scene tables of
every study file): wrong types, flipped signs, magnitudes scaled by up to
1e±12, zero, NaN and ±inf, missing and extra (misspelt) keys, vectors of the
wrong size and degenerate geometry. Each mutant must either

* load, pass :func:`check_scene` without errors, and run a short simulation
  (at most :data:`FUZZ_STEPS` steps) with finite output, or
* fail with ``SceneError``/``ValueError``/``TypeError`` whose message names a
  field or argument in backticks —

never another exception, never NaN in the output, never more than
:data:`BUDGET_SECONDS` per example.

CI runs ``FUZZ_EXAMPLES`` examples (default 60, derandomised, about 15 s); a longer run:
``SYMCUSHION_FUZZ_EXAMPLES=2000 python -m pytest tests/test_fuzz_scenes.py``
(docs/checks.md gives the count of the last long run).
"""
import copy
import math
import os
import sys
import time
import warnings
from pathlib import Path

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from symcushion.run.checks import check_scene
from symcushion.model.scene import scene_from_dict
from symcushion.scheme.touchdown import build_model
from symcushion.run.driver import simulate

if sys.version_info >= (3, 11):
    import tomllib
else:  # pragma: no cover
    import tomli as tomllib

ROOT = Path(__file__).resolve().parents[1]
SCENE_KEYS = ("scene", "body", "legs", "leg", "obstacle")
#: Files whose scene tables are a complete scene (envelope_lander.toml and
#: optimise_lander.toml place the body per case or scenario, so their scene
#: tables alone start with the feet in the slope).
STUDY_FILES = ("fig3.toml", "fig4.toml", "lander_slope.toml", "absorber_1d.toml")
#: Examples per CI run; override with the environment variable for a long run.
FUZZ_EXAMPLES = int(os.environ.get("SYMCUSHION_FUZZ_EXAMPLES", "60"))
#: Steps of the short simulation of a mutant that passes the checks.
FUZZ_STEPS = 40
#: Wall-time budget of one example (s): loading, checking, building and 40
#: steps take under 2 s on the shared CI machine; 20 s flags a hang, not noise.
BUDGET_SECONDS = 20.0


def base_scenes():
    out = {}
    for name in STUDY_FILES:
        data = tomllib.loads((ROOT / "studies" / name).read_text())
        out[name] = {k: v for k, v in data.items() if k in SCENE_KEYS}
    return out


BASES = base_scenes()


def leaf_paths(node, prefix=()):
    """Paths to every value (tables and lists included) of a nested dict/list."""
    paths = []
    items = node.items() if isinstance(node, dict) else enumerate(node) \
        if isinstance(node, list) else ()
    for key, value in items:
        paths.append(prefix + (key,))
        paths += leaf_paths(value, prefix + (key,))
    return paths


WEIRD = st.sampled_from([math.nan, math.inf, -math.inf, 0, 0.0, -1.0, 1e300, -1e-300, True,
                         "x", "", [], {}, [1.0], [0.0, 0.0, 0.0], [math.nan] * 3,
                         [[1.0, 2.0], [3.0, 4.0]], {"type": "linear"}])


@st.composite
def mutation(draw, data):
    """Apply one mutation in place to ``data``; return a description."""
    paths = leaf_paths(data)
    path = draw(st.sampled_from(paths))
    parent = data
    for key in path[:-1]:
        parent = parent[key]
    key, value = path[-1], parent[path[-1]]
    kind = draw(st.sampled_from(["weird", "sign", "scale", "delete", "extra", "resize",
                                 "degenerate"]))
    if kind == "delete" and isinstance(parent, dict):
        del parent[key]
    elif kind == "extra" and isinstance(parent, dict):
        parent[draw(st.sampled_from([f"{key}x", f"_{key}", "colour"]))] = 1.0
    elif kind == "sign" and _is_number(value):
        parent[key] = -value
    elif kind == "scale" and _is_number(value):
        parent[key] = value * 10.0 ** draw(st.integers(-12, 12))
    elif kind == "resize" and isinstance(value, list):
        parent[key] = value[:-1] if value and draw(st.booleans()) else value + [0.5]
    elif kind == "degenerate" and isinstance(value, list) and len(value) == 3 \
            and all(_is_number(v) for v in value):
        parent[key] = draw(st.sampled_from([[0.0, 0.0, 0.0], [0.0, 0.0, -1.0], [1e-9, 0, 0]]))
    else:
        parent[key] = copy.deepcopy(draw(WEIRD))      # never share WEIRD's lists
    return f"{kind} {'.'.join(map(str, path))}"


def _is_number(v):
    return isinstance(v, (int, float)) and not isinstance(v, bool)


@st.composite
def mutants(draw):
    name = draw(st.sampled_from(sorted(BASES)))
    data = copy.deepcopy(BASES[name])
    done = [draw(mutation(data)) for _ in range(draw(st.integers(1, 3)))]
    return name, done, data


def assert_clear(exc):
    message = str(exc)
    assert "`" in message, f"message names no field: {message!r}"
    assert "Traceback" not in message and len(message) < 5000, message


@settings(max_examples=FUZZ_EXAMPLES, deadline=None, derandomize=FUZZ_EXAMPLES <= 60,
          suppress_health_check=[HealthCheck.too_slow, HealthCheck.data_too_large])
@given(mutants())
def test_mutated_scene_runs_cleanly_or_fails_clearly(case):
    name, done, data = case
    started = time.perf_counter()
    try:
        scene = scene_from_dict(data, f"fuzz/{name}")
        model = build_model(scene)
        errors = [f for f in check_scene(scene, model) if f.severity == "error"]
        if errors:
            return
        scene = scene.with_(duration=scene.dt * min(scene.steps, FUZZ_STEPS))
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")            # physics warnings are allowed
            traj = simulate(scene, model=model)
    except (ValueError, TypeError) as exc:
        assert_clear(exc)
        return
    finally:
        elapsed = time.perf_counter() - started
        assert elapsed < BUDGET_SECONDS, f"{name} {done}: {elapsed:.1f} s"
    for field in ("position", "velocity", "attitude", "angular_velocity", "foot", "force"):
        assert np.all(np.isfinite(getattr(traj, field))), (name, done, field)


@pytest.mark.parametrize("name", sorted(BASES))
def test_unmutated_scenes_are_valid(name):
    scene = scene_from_dict(BASES[name], name)
    assert [f for f in check_scene(scene) if f.severity == "error"] == []
