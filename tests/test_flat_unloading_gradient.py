"""The derivative of a slide on a flat spring-back (docs/design-geometry.md, "A wrong
derivative at the start").

On a flat stretch of its spring-back an axial element carries a constant force:
the leg's D_p has no axial stiffness there. The midpoint slip rule of the memory
law (``FeetStep.memory_midpoint``) once moved its trial path to the foot's start
force through D_p⁻¹, and the design's check found AD 5.5e6 where central
differences gave −0.03. Checked here: the rule's path given by its forces is the
moved path where D_p is regular, and a rebound of the example's lander on its
flat spring-back (−420 N from 0.30 to 0.01 m) has the derivative of central
differences with respect to the spring-back's knots.
"""
from __future__ import annotations

from pathlib import Path

import casadi as ca
import numpy as np

from symcushion.contact.dispatch import contact_step
from symcushion.contact.midpoint import midpoint_slip_call
from symcushion.design.robust.study import robust_study_from_dict
from symcushion.envelope.cases import case_params, initial_states
from symcushion.model.scene import read_toml
from symcushion.scheme.touchdown import build_model

ROOT = Path(__file__).resolve().parent.parent

#: A touchdown of the example's ranges whose leg 2 slides on its flat spring-back
#: while leg 3 touches down (step 126, 0.126 s): the step where the derivative was
#: 2e13 N/N.
CASE = dict(vertical_speed=1.8412262739581198, horizontal_speed=0.9703819488632701,
            heading_deg=353.06539192844593, slope_deg=14.424857904956802,
            yaw_deg=65.23109466961803, tilt_deg=-0.3495441841103239,
            tilt_azimuth_deg=99.68083345633349)
#: Steps run before the checked window, and the window (s of 1 ms).
BEFORE, WINDOW = 115, 25
#: Central differences' step on the knot values (N, of 420 N): their error here is the
#: round-off of the differences, 7e-7 relative (6e-6 at 1e-3 N, 8e-8 at 0.1 N).
H = 1e-2
#: The relative error the design's gradient checks allow (tests/test_robust.py).
TOLERANCE = 1e-5


def _slipping_leg():
    """(P0, Dp, n, l, F0): a leg slipping across the plane, its stored force F0 off P0."""
    n = np.array([0.0, 0.0, 1.0])
    Dp = np.array([[3e4, 2e3, 5e3], [1e3, 2.5e4, -4e3], [6e3, -2e3, 1e5]])
    P0 = np.array([60.0, 20.0, 400.0])
    F0 = np.array([55.0, 26.0, 380.0])
    return P0, Dp, n, np.array([4e-3, 1e-3, -2e-4]), F0


def test_the_path_given_by_its_forces_is_the_moved_path_where_Dp_is_regular():
    P0, Dp, n, l, F0 = _slipping_leg()
    be = contact_step("implicit")(P0=P0, Dp=Dp, n=n, l=l, mu=0.1, u0=np.zeros(3))
    assert float(be["contact"]) == 1.0 and np.linalg.norm(np.asarray(be["k"])) > 1e-4
    path = (F0, P0 + Dp @ l - F0)                          # (1.3): P_t − F₀
    given = midpoint_slip_call(P0, Dp, n, l, 0.1, be, None, tuple(map(ca.DM, path)))
    moved = midpoint_slip_call(F0, Dp, n, l + np.linalg.solve(Dp, P0 - F0), 0.1, be)
    for key in ("P", "k"):
        a, b = (np.asarray(ca.evalf(out[key]), dtype=float).ravel() for out in (given, moved))
        np.testing.assert_allclose(a, b, rtol=1e-10, atol=1e-12 * np.abs(b).max())
    # and it moved the slip off the backward-Euler one
    assert np.abs(np.asarray(ca.evalf(given["k"])) - np.asarray(be["k"])).max() > 1e-6


#: The example's crush curve at the knots of the design study (0.30, 0.20, 0.10,
#: 0.05, 0.02, 0.002, 0 m): 2.0 kN at 2 mm rising straight to 2.4 kN at 0.30 m.
STRAIGHT_CRUSH = [-2400.0, -2265.771812080537, -2131.5436241610737, -2064.4295302013425,
                  -2024.1610738255033, -2000.0, 0.0]


def _rebound():
    """(model, state at BEFORE steps, p, dt) of CASE on the example's scene."""
    data = read_toml(ROOT / "studies" / "design_geometry_memory.toml", "study")
    data["legs"]["S"]["f"] = STRAIGHT_CRUSH       # the example's curve, whatever the study starts at
    study = robust_study_from_dict(data, "design_geometry_memory.toml").envelope
    scene = study.scene
    conditions = {k: np.array([v]) for k, v in CASE.items()}
    x0, gravity = initial_states(study, conditions)
    model = build_model(scene)
    p = case_params(scene, np.array([scene.mu]), gravity)[:, 0]
    X, _ = model.rollout(BEFORE)(x0[:, 0], p, scene.dt)
    return model, np.asarray(X[:, -1], dtype=float).ravel(), p, scene.dt


def test_a_slide_on_the_flat_spring_back_has_the_derivative_of_central_differences():
    model, x, p, dt = _rebound()
    names = ("leg2.S.unload.f0", "leg2.S.unload.f1")
    assert np.all(p[[model.param_names.index(nm) for nm in names]] == -420.0)    # flat
    E = np.zeros((model.np, len(names)))
    for k, name in enumerate(names):
        E[model.param_names.index(name), k] = 1.0
    w = ca.MX.sym("w", len(names))
    X, _ = model.rollout(WINDOW)(x, p + ca.DM(E) @ w, dt)
    end = ca.Function("end", [w], [X[:, -1], ca.jacobian(X[:, -1], w)])
    _, ad = end(np.zeros(len(names)))
    ad = np.asarray(ad, dtype=float)
    for k in range(len(names)):
        e = np.zeros(len(names))
        e[k] = H
        fd = np.asarray(end(e)[0] - end(-e)[0], dtype=float).ravel() / (2 * H)
        error = np.abs(ad[:, k] - fd).max() / np.abs(fd).max()
        assert error < TOLERANCE, (names[k], error, np.abs(ad[:, k]).max(), np.abs(fd).max())
