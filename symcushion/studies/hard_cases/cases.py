"""The twelve hard cases: their scenes, initial states and what each run must check.

Owns the scenes of the battery (legs, bodies, obstacles, steps), the
:class:`Setup` that says how each case is run and checked, the registry
:data:`CASES`, and the case-specific closed forms (the explicit limit of
the sticking stiff rods, the flights of the re-contact case). It must not
run the battery, check results or format them.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from symcushion.legs.characteristics import Linear
from symcushion.layout.vectors import state_layout
from symcushion.scheme.quaternion import quat_to_rot_np
from symcushion.model.obstacles import Plane, Sphere
from symcushion.model.scene_data import Body, Scene, symmetric_legs
from symcushion.scheme.touchdown import build_model, equilibrium_state, initial_state
from symcushion.scheme.stability import stable_dt
from symcushion.legs.strut import HingedStrut

#: Standard gravity (m/s²) of the re-contact case's closed form, as in its scene.
G = 9.81


def _rod_legs(ratio):
    """The four rods of Figs. 3–4 (studies/fig4.toml) with a chosen axial ratio."""
    return symmetric_legs(4, 0.3, -0.18, 0.6, (0.0, 0.0, -1.0),
                          (-np.sqrt(0.5), 0.0, -np.sqrt(0.5)), M_beta=Linear(1200.0),
                          M_gamma=Linear(1200.0), axial_ratio=ratio)


def _lander_legs(count=4, k_axial=2e4, k_hinge=1200.0, splay=np.deg2rad(20), azimuth0=0.0):
    """Compliant legs splayed outward; e_n 45° from the rest direction, in the swing plane."""
    e0 = (np.sin(splay), 0.0, -np.cos(splay))
    tilt = splay - np.pi / 4          # e_n rotated 45° towards the axis, radial plane
    en = (np.sin(tilt), 0.0, -np.cos(tilt))
    return symmetric_legs(count, 0.3, -0.18, 0.6, e0, en, S=Linear(k_axial),
                          M_beta=Linear(k_hinge), M_gamma=Linear(k_hinge), azimuth0=azimuth0)


def _height_on(obstacle_top, legs, gap=0.0):
    """Body height at which the lowest unloaded foot is ``gap`` above ``obstacle_top``."""
    return obstacle_top - min(leg.rest_foot[2] for leg in legs) + gap


@dataclass
class Setup:
    """One runnable case: the scene, its initial state and how to run and check it."""

    scene: Scene
    x0: np.ndarray | None = None
    symmetry: str | None = None          # None, "axial", "c4" or "mirror"
    creep: str = ""                      # "", "feet" or "feet+body": check they do not move
    adaptive: bool = False               # also run the adaptive driver (step criterion)
    stability: float = 0.0               # ... with its stability cap (fraction of 2/ω_max)
    energy: str = "mechanical"           # energy check: "mechanical" or "work" (see Result)
    note: str = ""


def _stiff_scene(method, mu, duration, name):
    legs = _rod_legs(STIFF_RATIO)
    body = Body(50.0, [1.25, 1.25, 1.25], position=[0, 0, 1.18], velocity=[0, 0, -0.5])
    return Scene(body, legs, [Sphere((0, 0, 0), 0.5)], mu=mu, method=method, dt=1e-3,
                 duration=duration, name=name)


#: Axial stiffness of the stiff rods relative to their bending stiffness scale.
STIFF_RATIO = 1e8
#: Step of the sticking stiff case as a fraction of the stability limit
#: 2/ω_max: the energy error of the impact is O((ω_max Δt)²) of the impact
#: energy (measured: 1.0 J of 6.25 J at 0.5, 0.22 J at 0.25, 0.035 J at 0.1,
#: 0.0087 J at 0.05 — second order), 0.1 keeps it at 1e-4 of the energy scale.
STIFF_FRACTION = 0.1


def case_stiff_axial(method, full=True):
    """Rods of axial ratio 1e8 sliding on the Fig. 4 dome (μ = 0.05), Δt = 1 ms.

    The feet slide, so the stiff axial direction is not held and the explicit
    body update stays stable at the paper's step; the contact step sees
    cond(D_p) ≈ 1e8 (docs/paper-notes.md §3.7).
    """
    return Setup(_stiff_scene(method, 0.05, 0.3, "stiff_axial"), symmetry="axial")


def case_stiff_axial_stick(method, full=True):
    """The same rods with μ = 1: the feet stick and hold the stiff direction.

    Velocity Verlet is then stable only for ω_max Δt < 2 (ω_max of the axial
    and rocking modes, 2/ω_max = 9.1 µs), and the impact's whole kinetic
    energy passes through the stiff mode in ~20 µs, so the step must also
    resolve it: Δt = STIFF_FRACTION·stable_dt (ω_max Δt = 0.2). At Δt = 1 ms
    the first step throws the body off at kilometres per second
    (:func:`explicit_limit`).
    """
    scene = _stiff_scene(method, 1.0, 0.05 if full else 0.01, "stiff_axial_stick")
    dt = STIFF_FRACTION * stable_dt(build_model(scene), initial_state(scene))
    return Setup(scene.with_(dt=dt), symmetry="axial", adaptive=full,
                 stability=STIFF_FRACTION)


def explicit_limit(method, dt=1e-3, steps=20):
    """Body speed (m/s) after each of ``steps`` steps of the sticking stiff case at ``dt``."""
    scene = case_stiff_axial_stick(method, full=False).scene.with_(dt=dt)
    model = build_model(scene)
    X, _ = model.rollout(steps)(initial_state(scene), model.default_p, dt)
    return np.linalg.norm(state_layout(model.n_legs).get(np.asarray(X, dtype=float), "velocity"),
                          axis=0)


#: Interference of the grazing foot's path with the sphere (m): the line of
#: its unloaded position passes this far below the top, so the foot touches
#: for about 2√(2Rd)/v ≈ 1.5 ms, one or two steps, with a force of ~k·d.
GRAZE_DEPTH = 1e-6


def case_grazing(method, full=True):
    """A foot moving along a line tangent to a sphere's top (no gravity), μ = 0.3."""
    leg = HingedStrut(hinge=(0, 0, -0.1), e0=(0, 0, -1), en=(0.6, 0, -0.8), length=0.5,
                      S=Linear(2e4), M_beta=Linear(500.0), M_gamma=Linear(500.0))
    radius = 0.3
    z = _height_on(radius, [leg], gap=-GRAZE_DEPTH)
    body = Body(10.0, [0.5, 0.5, 0.5], position=[0.2, 0, z], velocity=[-1.0, 0, 0])
    scene = Scene(body, [leg], [Sphere((0, 0, 0), radius)], mu=0.3, method=method,
                  dt=1e-3, duration=0.4, gravity=[0, 0, 0], name="grazing")
    return Setup(scene, symmetry="mirror", adaptive=True)


def case_simultaneous(method, full=True):
    """Four feet crossing a plane in the same step, inside it (vertical drop at 2 m/s)."""
    legs = _lander_legs(k_axial=5e4)
    # feet 0.37 mm above the plane: they cross at t = 0.185 ms, inside the first step
    body = Body(50.0, [2.0, 2.0, 2.0], position=[0, 0, _height_on(0.0, legs, 3.7e-4)],
                velocity=[0, 0, -2.0])
    scene = Scene(body, legs, [Plane()], mu=0.5, method=method, dt=1e-3, duration=0.5,
                  name="simultaneous")
    return Setup(scene, symmetry="axial")


#: Drop height of the re-contact case (m): flights last 2√(2h/g) = 6.4 ms,
#: less than one step of 10 ms.
RECONTACT_DROP = 5e-5


def case_recontact(method, full=True):
    """A body bouncing on one leg with flights shorter than a step (Δt = 10 ms)."""
    leg = HingedStrut(hinge=(0, 0, -0.1), e0=(0, 0, -1), en=(0.6, 0, -0.8), length=0.5,
                      S=Linear(2e4), M_beta=Linear(500.0), M_gamma=Linear(500.0))
    body = Body(10.0, [0.5, 0.5, 0.5], position=[0, 0, _height_on(0.0, [leg], RECONTACT_DROP)])
    scene = Scene(body, [leg], [Plane()], mu=0.5, method=method, dt=1e-2, duration=2.0,
                  name="recontact")
    return Setup(scene, symmetry="mirror")


#: Slope of the sticking case and the margin of μ over tan θ.
SLOPE = np.deg2rad(35.0)
SLOPE_MARGIN = 1e-3


def case_slope_stick(method, full=True):
    """A sled at rest on a 35° slope with μ = tan θ + 1e-3 for 100 s (Δt = 10 ms)."""
    # four vertical legs whose feet are level with the centre of mass: each foot
    # carries −mg/4, T/N = tan θ, 1e-3 inside the cone (as in tests/test_simulate.py)
    legs = symmetric_legs(4, 0.4, 0.5, 0.5, (0, 0, -1), (-0.6, 0, -0.8), S=Linear(2e4),
                          M_beta=Linear(3e3), M_gamma=Linear(3e3), azimuth0=np.pi / 4)
    attitude = [np.cos(SLOPE / 2), 0, np.sin(SLOPE / 2), 0]
    body = Body(40.0, [2.0, 2.0, 2.0], position=[0, 0, 0.01], attitude=attitude)
    scene = Scene(body, legs, [Plane.inclined(SLOPE)], mu=float(np.tan(SLOPE)),
                  method=method, dt=1e-2, duration=100.0, name="slope_stick")
    # held where they land (cone=False): μ is set from their forces below
    x0 = equilibrium_state(scene, placement="nearest", cone=False)
    # the legs' 5 mm compression lowers the feet below the centre of mass, so the
    # friction forces tilt the load and the feet's T/N differ from tan θ by ~0.5 %:
    # μ is set just above the largest one at the equilibrium
    n = scene.obstacles[0].n
    xl = state_layout(len(scene.legs))
    forces = xl.legs(x0, "force_body") @ quat_to_rot_np(xl.get(x0, "attitude"), normalise=False).T
    normal = forces @ n
    ratio = np.linalg.norm(forces - np.outer(normal, n), axis=1) / normal
    return Setup(scene.with_(mu=float(ratio.max()) + SLOPE_MARGIN), x0=x0, creep="feet+body",
                 note=f"μ − tan θ = {ratio.max() + SLOPE_MARGIN - np.tan(SLOPE):.2g}")


def case_high_friction(method, full=True):
    """An oblique landing (1.5 m/s across, 2 m/s down) with μ = 2."""
    legs = _lander_legs(k_axial=5e4)
    body = Body(50.0, [2.0, 2.0, 2.0], position=[0, 0, _height_on(0.0, legs, 1e-3)],
                velocity=[1.5, 0, -2.0])
    scene = Scene(body, legs, [Plane()], mu=2.0, method=method, dt=1e-3, duration=0.6,
                  name="high_friction")
    return Setup(scene, symmetry="mirror")


#: Angle between each strut's rest direction and its hinge's polar axis e_n
#: (rad), and the out-of-plane tilt of e_n: the strut swings outward in its
#: radial plane through the projection of e_n and passes the e_n line at
#: about NEAR_SINGULAR_MISS.
NEAR_SINGULAR_GAMMA0 = np.deg2rad(1.5)
NEAR_SINGULAR_MISS = 1e-3
#: Impact speed of the near-singular case (m/s): enough for the struts to
#: swing past e_n (a swing of more than NEAR_SINGULAR_GAMMA0).
NEAR_SINGULAR_SPEED = 2.0


def case_near_singular(method, full=True):
    """Struts that swing past their hinge's polar axis within ~1e-3 rad (docs/paper-notes.md §2)."""
    splay = np.deg2rad(30)
    e0 = np.array([np.sin(splay), 0.0, -np.cos(splay)])
    outward = splay + NEAR_SINGULAR_GAMMA0
    en = np.array([np.sin(outward) * np.cos(NEAR_SINGULAR_MISS), np.sin(NEAR_SINGULAR_MISS),
                   -np.cos(outward) * np.cos(NEAR_SINGULAR_MISS)])
    legs = symmetric_legs(4, 0.3, -0.18, 0.6, e0, en, S=Linear(5e4), M_beta=Linear(300.0),
                          M_gamma=Linear(300.0))
    body = Body(50.0, [2.0, 2.0, 2.0], position=[0, 0, _height_on(0.0, legs, 1e-3)],
                velocity=[0, 0, -NEAR_SINGULAR_SPEED])
    scene = Scene(body, legs, [Plane()], mu=1.0, method=method, dt=1e-3, duration=0.5,
                  name="near_singular")
    # (2.1) is not conservative near e_n (the β element works off e_β), so the
    # energy check is the obstacle's work on the feet (docs/hard-cases.md)
    return Setup(scene, symmetry="c4", adaptive=True, energy="work")


def _dome_lander(method, dt, duration, name, radius=1.0, speed=1.0, k_axial=2e4,
                 k_hinge=1200.0, mu=0.3, count=4):
    legs = _lander_legs(count=count, k_axial=k_axial, k_hinge=k_hinge)
    foot_r = np.hypot(*legs[0].rest_foot[:2])
    top = np.sqrt(radius ** 2 - foot_r ** 2)        # height of the dome under the feet
    body = Body(50.0, [2.0, 2.0, 2.0], position=[0, 0, _height_on(top, legs, 1e-4)],
                velocity=[0, 0, -speed])
    return Scene(body, legs, [Sphere((0, 0, 0), radius)], mu=mu, method=method, dt=dt,
                 duration=duration, name=name)


def case_tiny_step(method, full=True):
    """The compliant lander landing on a dome at 1 m/s with Δt = 1e-6 (impact only)."""
    scene = _dome_lander(method, 1e-6, 0.02 if full else 0.01, "tiny_step")
    return Setup(scene, symmetry="axial")


def case_large_step(method, full=True):
    """The compliant lander landing on a dome at 1 m/s with Δt = 1e-2."""
    scene = _dome_lander(method, 1e-2, 2.0, "large_step")
    # the feet slide on the dome fast enough for 1 − n·n′ to exceed ε at 10 ms
    return Setup(scene, symmetry="axial", adaptive=True)


def case_fast_impact(method, full=True):
    """A stiff lander hitting a dome of radius 3 m at 10 m/s."""
    scene = _dome_lander(method, 1e-3, 0.3, "fast_impact", radius=3.0, speed=10.0,
                         k_axial=2e5, k_hinge=2e4)
    return Setup(scene, symmetry="axial", adaptive=True)


#: Vertical velocity given to the resting lander (m/s): it sets an undamped
#: oscillation of the legs that must neither grow nor make a foot creep.
REST_KICK = 1e-3


def case_long_rest(method, full=True):
    """A three-legged lander resting on a dome (radius 2 m) for 1000 s (Δt = 10 ms)."""
    # three legs, the fewest that stand, to keep 1e5 steps × 3 methods in the test budget;
    # μ = 1 holds the splayed feet (their force is 35° off the dome normal)
    scene = _dome_lander(method, 1e-2, 1000.0 if full else 100.0, "long_rest", radius=2.0,
                         mu=1.0, count=3)
    x0 = equilibrium_state(scene)
    x0[state_layout(len(scene.legs)).slice("velocity")] = (0.0, 0.0, -REST_KICK)
    # the kick makes the body oscillate by ~25 µm for ever: only the feet must not move
    return Setup(scene, x0=x0, symmetry="axial", creep="feet")


CASES = {
    "stiff_axial": case_stiff_axial,
    "stiff_axial_stick": case_stiff_axial_stick,
    "grazing": case_grazing,
    "simultaneous": case_simultaneous,
    "recontact": case_recontact,
    "slope_stick": case_slope_stick,
    "high_friction": case_high_friction,
    "near_singular": case_near_singular,
    "tiny_step": case_tiny_step,
    "large_step": case_large_step,
    "fast_impact": case_fast_impact,
    "long_rest": case_long_rest,
}



def recontact_flights(duration) -> int:
    """Flights of the re-contact case in ``duration`` s, closed form of a mass on a spring.

    The body lands at v = √(2gh), rides the leg's spring k for
    (2π − 2 atan(v/(ω δ)))/ω (δ = mg/k the static deflection, ω = √(k/m)),
    and flies for 2v/g.
    """
    setup = case_recontact("implicit")
    scene = setup.scene
    leg = scene.legs[0]
    k = leg.elements[0].curve.param_values[0]
    m = scene.body.mass
    v = np.sqrt(2 * G * RECONTACT_DROP)
    omega = np.sqrt(k / m)
    contact = (2 * np.pi - 2 * np.arctan(v / (omega * m * G / k))) / omega
    flight = 2 * v / G
    first = np.sqrt(2 * RECONTACT_DROP / G)              # the drop before the first landing
    return int(np.floor((duration - first - contact) / (contact + flight))) + 1
