"""MuJoCo peer: the scene as an MJCF model (optional dependency, ``symcushion[peers]``).

The body is a free body with the scene's mass and inertia about its centre
of mass. Each leg is a child body at the hinge point r_h with

* a hinge joint about e_β⁰ = e₀ × e_n/|e₀ × e_n| (fixed in the body): the
  swing in the plane of e₀ and e_n, i.e. the polar angle γ of (2.1), with the
  stiffness of M_γ;
* a hinge joint about e_γ⁰ = e₀ × (e_n × e₀)/|…| carried by the first
  rotation: the swing out of that plane, β of (2.1), with the stiffness of
  M_β;
* for a leg with an axial element S, a slide joint along the rod with the
  stiffness of S; a 'rigid' rod (no S) has no slide joint by default — MuJoCo
  makes it exactly rigid, while symcushion's axial spring of ratio
  ``RIGID_AXIAL_RATIO`` is a numerical device (``rigid_axial='spring'``
  gives the same stiff slide joint instead);
* a massless capsule for the rod (no collisions) and a small sphere of mass
  m_f at its end, the foot, the only geometry that touches the obstacles.

Every joint's spring reference is the rest pose (q = 0), so the unloaded leg
hangs along e₀. At rest the model has symcushion's stiffness
D_p = S′ e_S e_Sᵀ + (M_β′/L₀²) e_β e_βᵀ + (M_γ′/L₀²) e_γ e_γᵀ (docs/paper-notes.md §2); away
from rest the two hinges differ from (2.1) at second order in the swing.

Obstacles are static geoms: a sphere for a Sphere, a plane for a Plane, each
moved inwards by the foot radius so that the sphere's *centre* touches where
symcushion's point foot does. Contacts use elliptic cones with friction μ
(condim 3; condim 1 when μ = 0).

This module owns the MJCF text and the stepping loop. It imports mujoco only
when called, so symcushion works without it.
"""
from __future__ import annotations

import time
from xml.sax.saxutils import quoteattr

import numpy as np

from symcushion.legs.characteristics import Linear
from symcushion.model.obstacles import Plane, Sphere
from symcushion.model.scene_data import Scene
from symcushion.layout.vectors import state_layout
from symcushion.peers.run import (PeerRun, check_scene, leg_kinematics, output_times, positive,
    quat_to_rot_np, state_vector)

__all__ = ["mujoco_available", "mujoco_simulate", "build_mjcf", "FOOT_MASS_RATIO",
           "FOOT_RADIUS", "MODE_STEP", "TIMECONST_STEPS", "SOLIMP"]

INSTALL_HINT = "pip install symcushion[peers]"

#: Foot mass over body mass, as in the penalty peer (docs/peers.md).
FOOT_MASS_RATIO = 1e-4

#: Radius of the foot sphere (m). The obstacles are shifted by it, so its only
#: effect is that the contact point lies r_f from the foot centre along the
#: normal; 2 mm is a hundredth of the dome in Figs. 3–4.
FOOT_RADIUS = 2e-3

#: Radius of the (massless, collision-free) rod capsule, for viewing only (m).
ROD_RADIUS = 5e-3

#: Default step: ω_max·h = MODE_STEP for the fastest joint spring on its foot
#: (ω² = k/(m_f L₀²) for a hinge, k/m_f for a slide), capped by the scene's
#: dt. Joint springs are explicit in MuJoCo's Euler-type integrators, stable
#: for ω h < 2; 0.1 resolves the light foot's swing with 63 steps per period,
#: and puts the Fig. 3 rebound within 1e-3 m/s of its h → 0 limit
#: (docs/peers.md).
MODE_STEP = 0.1

#: Default contact time constant in steps: solref = [TIMECONST_STEPS·h, 1].
#: MuJoCo clamps timeconst to ≥ 2h (the ``refsafe`` flag) because a stiffer
#: reference spring is not resolved by the step; 2 is therefore the stiffest
#: value that runs as authored (docs/peers.md shows the trial).
TIMECONST_STEPS = 2.0

#: Default solimp (dmin, dmax, width, midpoint, power): MuJoCo's own default.
#: The harder (0.99, 0.99, 0.001) gives the same Fig. 3 rebound to 6e-5 m/s
#: but makes the light feet chatter on the dome under friction (Fig. 4: the
#: foot sinks 0.3 mm and pops out, 245 contact changes in 0.3 s against 31),
#: so it does not "run stably" in the sense that matters here (docs/peers.md).
SOLIMP = (0.9, 0.95, 1e-3, 0.5, 2.0)

#: Integrator: MuJoCo's recommended default (implicit in velocity, fast).
INTEGRATOR = "implicitfast"

#: Choices of ``rigid_axial``.
RIGID_AXIAL = ("rigid", "spring")

#: Largest allowed mismatch of output_dt/timestep from an integer.
_STEP_RATIO_SLACK = 1e-6


def mujoco_available() -> bool:
    """True when the optional ``mujoco`` package can be imported."""
    try:
        _import_mujoco()
    except ImportError:
        return False
    return True


def _import_mujoco():
    try:
        import mujoco
    except ImportError as exc:
        raise ImportError(f"the MuJoCo peer needs the optional `mujoco` package: "
                          f"{INSTALL_HINT} (or pip install mujoco).") from exc
    return mujoco


def _linear_slope(curve, where: str) -> float:
    """Stiffness of a linear, preload-free, single-branch curve; ValueError otherwise."""
    if curve is None:
        return 0.0
    if not isinstance(curve, Linear):
        raise ValueError(f"{where} is a {type(curve).__name__} characteristic; the MuJoCo peer "
                         "supports only linear joint springs (Linear, no preload, no unloading "
                         "branch). Use penalty_simulate for non-linear legs.")
    if curve.unloading is not None:
        raise ValueError(f"{where} has an unloading branch (hysteresis), which MuJoCo joint "
                         "springs cannot represent; use penalty_simulate or drop `unloading`.")
    k, preload = curve.param_values[:2]
    if preload != 0:
        raise ValueError(f"{where} has a preload {preload:g}; the MuJoCo peer supports only "
                         "preload-free linear springs (the rest pose is the spring's reference).")
    if k <= 0:
        raise ValueError(f"{where} has stiffness {k:g} <= 0; MuJoCo joint springs need k > 0.")
    return float(k)


def _leg_springs(scene: Scene, rigid_axial: str):
    """(k_γ, k_β, k_S or None) of every leg, checked for MuJoCo."""
    out = []
    for j, leg in enumerate(scene.legs):
        els = {el.name: el.curve for el in leg.elements}
        k_gamma = _linear_slope(els.get("M_gamma"), f"leg {j} `M_gamma`")
        k_beta = _linear_slope(els.get("M_beta"), f"leg {j} `M_beta`")
        if leg.rigid:
            k_S = float(els["S"].param_values[0]) if rigid_axial == "spring" else None
        else:
            k_S = _linear_slope(els["S"], f"leg {j} `S`")
        out.append((k_gamma, k_beta, k_S))
    return out


def _hinge_axes(leg):
    """Axes of the γ joint (e₀ × e_n) and of the β joint (e₀ × (e_n × e₀)), unit."""
    a_gamma = np.cross(leg.e0, leg.en)
    a_gamma /= np.linalg.norm(a_gamma)
    a_beta = np.cross(leg.e0, np.cross(leg.en, leg.e0))
    a_beta /= np.linalg.norm(a_beta)
    return a_gamma, a_beta


def _fmt(values) -> str:
    return " ".join(repr(float(v)) for v in np.ravel(values))


def _settings(scene: Scene, timestep, solref, solimp, foot_mass, output_dt, rigid_axial):
    """Resolve and check every setting; returns a dict."""
    if rigid_axial not in RIGID_AXIAL:
        raise ValueError(f"`rigid_axial` must be one of {RIGID_AXIAL}, got {rigid_axial!r}.")
    for i, ob in enumerate(scene.obstacles):
        if not isinstance(ob, (Plane, Sphere)):
            raise ValueError(f"obstacle {i} of scene {scene.name!r} is a {type(ob).__name__} "
                             f"({ob.kind}); the MuJoCo peer supports only Plane and Sphere "
                             "obstacles (use penalty_simulate for implicit surfaces).")
        if isinstance(ob, Sphere) and ob.radius <= 2 * FOOT_RADIUS:
            raise ValueError(f"obstacle {i} is a sphere of radius {ob.radius:g} m, too small for "
                             f"the foot sphere ({FOOT_RADIUS:g} m) the MuJoCo peer shifts it by.")
    padded = [j for j, leg in enumerate(scene.legs) if leg.footpad > 0]
    if padded:
        raise ValueError(f"legs {padded} of scene {scene.name!r} have footpads; the MuJoCo "
                         "peer's feet are its own small spheres: compare a scene with "
                         "`footpad` = 0, or use penalty_simulate, which offsets the obstacles "
                         "as symcushion does.")
    springs = _leg_springs(scene, rigid_axial)
    m_f = positive("foot_mass", foot_mass, FOOT_MASS_RATIO * scene.body.mass)
    t = output_times(scene, output_dt)
    out_dt = float(t[1] - t[0]) if len(t) > 1 else scene.dt
    omega2 = []
    for leg, (k_g, k_b, k_S) in zip(scene.legs, springs):
        omega2.append(max(k_g, k_b) / (m_f * leg.length ** 2))
        if k_S is not None:
            omega2.append(k_S / m_f)
    omega_max = float(np.sqrt(max(omega2)))
    if timestep is None:
        target = min(scene.dt, MODE_STEP / omega_max, out_dt)
        substeps = int(np.ceil(out_dt / target * (1 - _STEP_RATIO_SLACK)))
        h = out_dt / substeps
    else:
        h = positive("timestep", timestep)
        ratio = out_dt / h
        substeps = int(round(ratio))
        if substeps < 1 or abs(ratio - substeps) > _STEP_RATIO_SLACK * ratio:
            raise ValueError(f"`timestep` = {h!r} s must divide `output_dt` = {out_dt!r} s into "
                             "a whole number of steps; give e.g. "
                             f"timestep = {out_dt / max(1, int(np.ceil(ratio))):.6g}.")
    if solref is None:
        solref = (TIMECONST_STEPS * h, 1.0)
    solref = np.asarray(solref, dtype=float).ravel()
    if solref.size != 2 or not np.all(np.isfinite(solref)):
        raise ValueError(f"`solref` must be 2 finite numbers (timeconst s, dampratio), "
                         f"got {solref.tolist()}.")
    if solref[0] > 0 and solref[1] <= 0:
        raise ValueError(f"`solref` = {solref.tolist()}: a positive timeconst needs a positive "
                         "damping ratio (MuJoCo's mixed-sign form is not supported).")
    solimp = np.asarray(SOLIMP if solimp is None else solimp, dtype=float).ravel()
    if solimp.size not in (3, 5) or not np.all(np.isfinite(solimp)) \
            or not (0 < solimp[0] < 1 and 0 < solimp[1] < 1 and solimp[2] > 0):
        raise ValueError(f"`solimp` must be (dmin, dmax, width[, midpoint, power]) with "
                         f"0 < dmin, dmax < 1 and width > 0, got {solimp.tolist()}.")
    return dict(springs=springs, foot_mass=m_f, times=t, output_dt=out_dt, timestep=h,
                substeps=substeps, solref=solref, solimp=solimp, omega_max=omega_max,
                rigid_axial=rigid_axial, refsafe=bool(solref[0] <= 0
                                                      or solref[0] >= 2 * h * (1 - 1e-12)))


def build_mjcf(scene: Scene, *, timestep=None, solref=None, solimp=None, foot_mass=None,
               output_dt=None, rigid_axial: str = "rigid", integrator: str = INTEGRATOR):
    """The MJCF text of a scene and the resolved settings.

    Parameters are those of :func:`mujoco_simulate`. The ``refsafe`` flag is
    disabled when the given solref time constant is below 2·timestep, so that
    what is asked is what runs (MuJoCo would silently clamp it).

    Returns
    -------
    xml : str
    settings : dict
        timestep, substeps per output sample, solref, solimp, foot_mass,
        omega_max (fastest joint mode, rad/s), springs per leg.
    """
    scene = check_scene(scene)
    if integrator not in ("Euler", "implicit", "implicitfast", "RK4", "discrete"):
        raise ValueError(f"`integrator` must be a MuJoCo integrator name (Euler, implicit, "
                         f"implicitfast, RK4, discrete), got {integrator!r}.")
    s = _settings(scene, timestep, solref, solimp, foot_mass, output_dt, rigid_axial)
    s["integrator"] = integrator
    mu = scene.mu
    condim = 3 if mu > 0 else 1
    contact_attrs = (f'condim="{condim}" friction="{mu!r} 0 0" solref="{_fmt(s["solref"])}" '
                     f'solimp="{_fmt(s["solimp"])}"')
    b = scene.body
    I = b.inertia
    lines = [f"<mujoco model={quoteattr('symcushion_' + scene.name)}>",
             '  <compiler angle="radian" autolimits="true"/>',
             f'  <option timestep="{s["timestep"]!r}" gravity="{_fmt(scene.gravity)}" '
             f'cone="elliptic" integrator="{integrator}">',
             f'    <flag refsafe="{"enable" if s["refsafe"] else "disable"}"/>',
             "  </option>",
             "  <worldbody>"]
    for i, ob in enumerate(scene.obstacles):
        if isinstance(ob, Sphere):
            lines.append(f'    <geom name="obstacle{i}" type="sphere" pos="{_fmt(ob.center)}" '
                         f'size="{ob.radius - FOOT_RADIUS!r}" contype="0" conaffinity="1" '
                         f'{contact_attrs}/>')
        else:
            lines.append(f'    <geom name="obstacle{i}" type="plane" '
                         f'pos="{_fmt(ob.point - FOOT_RADIUS * ob.n)}" zaxis="{_fmt(ob.n)}" '
                         f'size="0 0 1" contype="0" conaffinity="1" {contact_attrs}/>')
    lines += [f'    <body name="body" pos="{_fmt(b.position)}" quat="{_fmt(b.attitude)}">',
              '      <freejoint name="root"/>',
              f'      <inertial pos="0 0 0" mass="{b.mass!r}" fullinertia="'
              f'{_fmt([I[0, 0], I[1, 1], I[2, 2], I[0, 1], I[0, 2], I[1, 2]])}"/>']
    for j, (leg, (k_g, k_b, k_S)) in enumerate(zip(scene.legs, s["springs"])):
        a_gamma, a_beta = _hinge_axes(leg)
        tip = leg.length * leg.e0
        lines += [f'      <body name="leg{j}" pos="{_fmt(leg.hinge)}">',
                  f'        <joint name="leg{j}_gamma" type="hinge" axis="{_fmt(a_gamma)}" '
                  f'stiffness="{k_g!r}" springref="0"/>',
                  f'        <joint name="leg{j}_beta" type="hinge" axis="{_fmt(a_beta)}" '
                  f'stiffness="{k_b!r}" springref="0"/>']
        if k_S is not None:
            lines.append(f'        <joint name="leg{j}_axial" type="slide" axis="{_fmt(leg.e0)}" '
                         f'stiffness="{k_S!r}" springref="0"/>')
        lines += [f'        <geom name="leg{j}_rod" type="capsule" fromto="0 0 0 {_fmt(tip)}" '
                  f'size="{ROD_RADIUS!r}" mass="0" contype="0" conaffinity="0"/>',
                  f'        <geom name="leg{j}_foot" type="sphere" pos="{_fmt(tip)}" '
                  f'size="{FOOT_RADIUS!r}" mass="{s["foot_mass"]!r}" contype="1" '
                  f'conaffinity="0" {contact_attrs}/>',
                  "      </body>"]
    lines += ["    </body>", "  </worldbody>", "</mujoco>"]
    return "\n".join(lines) + "\n", s


def _joint_state(scene: Scene, x0) -> tuple:
    """Free-joint qpos/qvel and leg joint angles from a symcushion state (13 + 7N)."""
    n_legs = len(scene.legs)
    size = state_layout(n_legs).size
    x0 = state_vector(scene, x0)
    if x0.size != size:
        raise ValueError(f"`x0` must be a finite symcushion state of {size} entries "
                         f"(initial_state(scene)), got {x0.size} entries.")
    xl = state_layout(n_legs)
    pos, vel, quat, omega = (xl.get(x0, k) for k in ("position", "velocity", "attitude",
                                                      "angular_velocity"))
    quat = quat / np.linalg.norm(quat)
    R = quat_to_rot_np(quat)
    legs = []
    for j, leg in enumerate(scene.legs):
        r = xl.get(x0, "foot", j)
        d = R.T @ (r - pos) - leg.hinge
        L = np.linalg.norm(d)
        e_S = d / L
        a_gamma, a_beta = _hinge_axes(leg)
        # rotation about a_beta (after the γ rotation) moves e_S out of the plane
        # (e₀, e_n) along w = a_beta × e₀ = ±a_gamma; the γ rotation keeps that part
        w = np.cross(a_beta, leg.e0)
        theta_beta = float(np.arcsin(np.clip(e_S @ w, -1.0, 1.0)))
        in_plane = e_S - (e_S @ w) * w
        in_plane /= np.linalg.norm(in_plane)
        theta_gamma = float(np.arctan2(np.cross(leg.e0, in_plane) @ a_gamma, leg.e0 @ in_plane))
        legs.append((theta_gamma, theta_beta, L - leg.length))
    return pos, vel, quat, omega, legs


def _foot_distance(scene: Scene, foot) -> np.ndarray:
    """Signed distance (T, N) of the foot centres to the nearest real obstacle (m).

    The foot sphere touches the obstacle moved in by its radius exactly when
    its centre is at distance 0 from the real one, so this is the distance
    symcushion's point foot would have; negative while in contact.
    """
    dist = np.full(foot.shape[:2], np.inf)
    for ob in scene.obstacles:
        if isinstance(ob, Sphere):
            d = np.linalg.norm(foot - ob.center, axis=-1) - ob.radius
        else:
            d = (foot - ob.point) @ ob.n
        dist = np.minimum(dist, d)
    return dist


def _start_model(mujoco, scene, xml, springs, x0):
    """The MuJoCo model of ``xml`` and its data at the initial state ``x0`` (joint
    angles solved from the feet; an axial joint only where ``springs`` has one),
    forwarded; and the qpos addresses of each leg's (γ, β) joints, shape (N, 2)."""
    pos0, vel0, quat0, omega0, legs0 = _joint_state(scene, x0)
    model = mujoco.MjModel.from_xml_string(xml)
    data = mujoco.MjData(model)
    data.qpos[0:3], data.qpos[3:7] = pos0, quat0
    data.qvel[0:3], data.qvel[3:6] = vel0, omega0
    for j, (th_g, th_b, stroke) in enumerate(legs0):
        data.qpos[model.jnt_qposadr[model.joint(f"leg{j}_gamma").id]] = th_g
        data.qpos[model.jnt_qposadr[model.joint(f"leg{j}_beta").id]] = th_b
        if springs[j][2] is not None:
            data.qpos[model.jnt_qposadr[model.joint(f"leg{j}_axial").id]] = stroke
    angle_adr = np.array([[model.jnt_qposadr[model.joint(f"leg{j}_{n}").id]
                           for n in ("gamma", "beta")] for j in range(len(scene.legs))])
    mujoco.mj_forward(model, data)
    return model, data, angle_adr


def _step_and_sample(mujoco, model, data, T, substeps, foot_ids):
    """``T`` samples, the first at the start, each after ``substeps`` MuJoCo steps:
    ``qpos``, ``qvel``, ``acc`` (the body's linear acceleration), ``foot`` and
    ``foot_vel`` (the feet's positions and linear velocities, world frame); and
    the wall and process CPU seconds of the stepping loop."""
    N = len(foot_ids)
    qpos = np.empty((T, model.nq))
    qvel = np.empty((T, model.nv))
    acc = np.empty((T, 3))
    foot = np.empty((T, N, 3))
    foot_vel = np.empty((T, N, 3))
    twist = np.empty(6)

    def record(k):
        qpos[k], qvel[k] = data.qpos, data.qvel
        acc[k] = data.qacc[0:3]         # free joint: linear acceleration of the CoM, world
        foot[k] = data.geom_xpos[foot_ids]
        for j, g in enumerate(foot_ids):
            mujoco.mj_objectVelocity(model, data, mujoco.mjtObj.mjOBJ_GEOM, g, twist, 0)
            foot_vel[k, j] = twist[3:6]     # (angular, linear), world frame

    started, cpu_started = time.perf_counter(), time.process_time()
    record(0)
    for k in range(1, T):
        for _ in range(substeps):
            mujoco.mj_step(model, data)
        # mj_step leaves qacc of the step's start; evaluate it at the sample
        mujoco.mj_forward(model, data)
        record(k)
    wall_seconds = time.perf_counter() - started
    cpu_seconds = time.process_time() - cpu_started
    samples = dict(qpos=qpos, qvel=qvel, acc=acc, foot=foot, foot_vel=foot_vel)
    return samples, wall_seconds, cpu_seconds


def _check_stable(mujoco, data, qpos, scene, s):
    """Refuse a run in which MuJoCo reset a bad state or that went non-finite."""
    bad = [w for w in ("mjWARN_BADQACC", "mjWARN_BADQPOS", "mjWARN_BADQVEL")
           if data.warning[getattr(mujoco.mjtWarning, w)].number > 0]
    if bad or not np.all(np.isfinite(qpos)):
        # MuJoCo resets the state after a bad acceleration and carries on; a run
        # with such a reset is not a simulation of the scene
        raise FloatingPointError(
            f"MuJoCo went unstable on scene {scene.name!r} ({', '.join(bad) or 'non-finite'}; "
            f"timestep {s['timestep']:g} s, solref {s['solref'].tolist()}): reduce `timestep` "
            "or raise the solref time constant to at least 2·timestep.")


def mujoco_simulate(scene: Scene, *, timestep=None, solref=None, solimp=None, foot_mass=None,
                    output_dt=None, x0=None, rigid_axial: str = "rigid",
                    integrator: str = INTEGRATOR) -> PeerRun:
    """Simulate a scene with MuJoCo (optional dependency).

    Parameters
    ----------
    scene : Scene
        Legs with linear, preload-free, single-branch elements only; Plane
        and Sphere obstacles only (anything else: ValueError).
    timestep : float, optional
        MuJoCo step h (s); must divide ``output_dt``. Default: the largest
        divisor of ``output_dt`` with ω_max·h ≤ :data:`MODE_STEP` and h ≤ dt.
    solref : (2,) array_like, optional
        Contact (timeconst, dampratio); default (:data:`TIMECONST_STEPS`·h, 1).
        A timeconst below 2h is honoured (``refsafe`` disabled).
    solimp : (3,) or (5,) array_like, optional
        Contact impedance; default :data:`SOLIMP`.
    foot_mass : float, optional
        Mass of each foot sphere (kg); default :data:`FOOT_MASS_RATIO`·m.
    output_dt : float, optional
        Sample interval (s); default ``scene.dt``.
    x0 : array_like, optional
        A symcushion state (13 + 7N, ``initial_state(scene)`` by default):
        body pose and velocity, and the foot positions, from which the joint
        angles are solved; the legs start at rest relative to the body.
    rigid_axial : {'rigid', 'spring'}
        A rod without S: no slide joint ('rigid', exactly rigid) or a slide
        joint with symcushion's axial spring ('spring'; needs a step
        ~√(m_f/k_S), which the default timestep takes care of).
    integrator : str
        MuJoCo integrator; default :data:`INTEGRATOR`.

    Returns
    -------
    PeerRun
        ``info``: settings, ``steps``, ``cpu_seconds`` (process CPU time of
        the stepping loop), ``joint_angles`` (T, N, 2: γ-joint,
        β-joint, rad), ``foot_velocity`` (T, N, 3, world), ``xml``.

    Raises
    ------
    ImportError
        When mujoco is not installed (``pip install symcushion[peers]``).
    """
    mujoco = _import_mujoco()
    scene = check_scene(scene)
    started = time.perf_counter()
    xml, s = build_mjcf(scene, timestep=timestep, solref=solref, solimp=solimp,
                        foot_mass=foot_mass, output_dt=output_dt, rigid_axial=rigid_axial,
                        integrator=integrator)
    model, data, angle_adr = _start_model(mujoco, scene, xml, s["springs"], x0)
    body_id = model.body("body").id
    foot_ids = np.array([model.geom(f"leg{j}_foot").id for j in range(len(scene.legs))])
    build_seconds = time.perf_counter() - started

    t = s["times"]
    T, N = len(t), len(scene.legs)
    samples, wall_seconds, cpu_seconds = _step_and_sample(mujoco, model, data, T, s["substeps"],
                                                          foot_ids)
    qpos, qvel, acc, foot, foot_vel = (samples[k] for k in ("qpos", "qvel", "acc", "foot",
                                                             "foot_vel"))
    _check_stable(mujoco, data, qpos, scene, s)
    quat = qpos[:, 3:7] / np.linalg.norm(qpos[:, 3:7], axis=1, keepdims=True)
    contact = _foot_distance(scene, foot) < 0
    stroke, deflection = leg_kinematics(scene, qpos[:, 0:3], quat, foot)
    if rigid_axial == "rigid":
        # exactly rigid in MuJoCo; the geometric value is round-off
        rigid = np.array([leg.rigid for leg in scene.legs])
        stroke[:, rigid] = 0.0
    info = {
        "peer": "mujoco", "mujoco_version": mujoco.__version__,
        "integrator": integrator, "timestep": s["timestep"], "substeps": s["substeps"],
        "output_dt": s["output_dt"], "solref": s["solref"].tolist(),
        "solimp": s["solimp"].tolist(), "refsafe": s["refsafe"], "foot_mass": s["foot_mass"],
        "foot_radius": FOOT_RADIUS, "rigid_axial": rigid_axial, "omega_max": s["omega_max"],
        "cpu_seconds": cpu_seconds, "steps": (T - 1) * s["substeps"], "forward_evaluations": (T - 1) * (s["substeps"] + 1),
        "joint_angles": qpos[:, angle_adr.ravel()].reshape(T, N, 2), "foot_velocity": foot_vel,
        "xml": xml,
        "body_id": body_id,
    }
    return PeerRun(t=t, position=qpos[:, 0:3], velocity=qvel[:, 0:3], acceleration=acc,
                   attitude=quat, foot=foot, stroke=stroke, deflection=deflection,
                   wall_seconds=wall_seconds, build_seconds=build_seconds, info=info,
                   contact=contact)
