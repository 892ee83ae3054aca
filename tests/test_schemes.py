"""What, how, when: the model, the scheme and the time grid apart, and every valid
scheme built and stepped once (symcushion.model.parts, symcushion.scheme.registry)."""
import numpy as np
import pytest

from symcushion import Body, Crushable, Linear, Plane, Scene, build_model, initial_state
from symcushion.model.parts import SCHEME_OPTIONS, Model, Scheme, TimeGrid, check_scheme
from symcushion.model.scene_data import symmetric_legs
from symcushion.scheme.registry import SCHEME_PARTS, valid_schemes


def _model(mu):
    """Two struts whose axial crushable unloads along a steeper line (a branch to
    locate and lock), dropped at 2 m/s onto a plane."""
    S = Crushable(4e4, 600.0, unloading=Linear(4e5))
    legs = symmetric_legs(2, radius=0.4, height=0.0, length=0.6, e0_local=(0.3, 0, -1),
                          en_local=(0, 0, 1), S=S, M_beta=Linear(500.0))
    body = Body(mass=60.0, inertia=(4.0, 4.0, 6.0), position=(0, 0, 0.58),
                velocity=(0.3, 0, -2.0))
    return Model(body, legs, [Plane()], mu=mu)


def test_the_registry_names_every_choice_of_every_option():
    assert SCHEME_PARTS.keys() == SCHEME_OPTIONS.keys()
    for option, choices in SCHEME_OPTIONS.items():
        assert tuple(SCHEME_PARTS[option]) == choices
        for part in SCHEME_PARTS[option].values():
            assert part.summary and all(callable(f) for f in part.functions)


def test_the_valid_schemes_are_those_the_checks_allow():
    # implicit: 2 tangent planes × 2 slip rules × {none, branch, lock} on the printed law
    # and none on the memory law; paper and robust: the backward slip rule only
    assert len(valid_schemes(_model(0.4))) == 2 * 2 * 4 + 2 * (2 * 1 * 4)
    # without friction no foot sticks: no stroke lock
    frictionless = valid_schemes(_model(0.0))
    assert len(frictionless) == 2 * 2 * 3 + 2 * (2 * 1 * 3)
    assert all(s.events != "lock" for s in frictionless)


@pytest.mark.parametrize("changes, message", [
    (dict(method="paper", slip="midpoint"), "implicit contact step's slip"),
    (dict(events="branch", hysteresis="memory"), "continuous force"),
    (dict(method="exact"), "method"),
])
def test_a_scheme_refuses_choices_that_do_not_go_together(changes, message):
    with pytest.raises(ValueError, match=message):
        Scheme(**changes)


def test_a_scheme_the_model_cannot_take_is_refused_with_the_fix():
    with pytest.raises(ValueError, match="Set mu > 0"):
        check_scheme(_model(0.0), Scheme(events="lock"))


def test_a_time_grid_checks_its_values_and_counts_its_steps():
    assert TimeGrid(1e-3, 0.25).steps == 250
    with pytest.raises(ValueError, match="dt"):
        TimeGrid(-1e-3, 1.0)


def test_a_scene_is_its_three_parts_and_back():
    model = _model(0.4)
    scheme, grid = Scheme(slip="midpoint", events="lock"), TimeGrid(5e-4, 0.3)
    scene = Scene.from_parts(model, scheme, grid)
    assert scene.scheme == scheme and scene.grid == grid
    assert scene.model.legs == model.legs and scene.model.mu == model.mu
    assert Scene.from_parts(scene.model, scene.scheme, scene.grid) == scene


def test_every_valid_scheme_builds_and_steps():
    """One build and forty steps per valid scheme (32 here), through a touchdown with
    sliding feet: finite. Every choice but the method changes the step's graph (the
    method is the named contact Function the step calls): 16 graphs for 16 schemes
    that differ in something else."""
    model = _model(0.4)
    sizes = {}
    for scheme in valid_schemes(model):
        scene = Scene.from_parts(model, scheme, TimeGrid(1e-3, 0.04))
        step = build_model(scene)
        x, y = step.rollout(scene.steps)(initial_state(scene), step.default_p, scene.dt)
        assert np.all(np.isfinite(np.asarray(x))) and np.all(np.isfinite(np.asarray(y))), scheme
        assert np.asarray(x)[2, -1] < 0.55, scheme        # the body came down on its legs
        rest = tuple(getattr(scheme, name) for name in SCHEME_OPTIONS if name != "method")
        sizes.setdefault(rest, set()).add(tuple(step.graph_size().values()))
    assert all(len(v) == 1 for v in sizes.values())       # the method adds no graph
    assert len({v.pop() for v in sizes.values()}) == len(sizes) == 16


def test_a_step_is_built_from_a_model_and_a_scheme_alone():
    model, scheme = _model(0.4), Scheme(slip="midpoint")
    from_parts = build_model(model, scheme=scheme)
    from_scene = build_model(Scene.from_parts(model, scheme, TimeGrid(2e-4, 0.01)))
    x0 = initial_state(from_scene.scene)
    a = from_parts.step(x0, from_parts.default_p, 1e-3)
    b = from_scene.step(x0, from_scene.default_p, 1e-3)
    assert all(np.array_equal(np.asarray(u), np.asarray(v)) for u, v in zip(a, b))
    with pytest.raises(ValueError, match="has its own"):
        build_model(from_scene.scene, scheme=scheme)
    with pytest.raises(TypeError, match="must be a Scheme"):
        build_model(model, scheme="implicit")
