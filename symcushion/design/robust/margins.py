"""Smooth margins of one touchdown: the named Function ``touchdown_margins``.

A design that must be stable over many touchdowns needs, per touchdown, a
few numbers that say how close it came to each limit and that are smooth in
the design. This module owns them: the scene's ``touchdown_step`` folded over
a horizon, with each limit's running maximum replaced by a Kreisselmeier–
Steinhauser (log-sum-exp) aggregate of value/limit over every step and leg,

    KS_ρ(v) = m + ln Σ_k exp(ρ (v_k − m)) / ρ,     m = max_k v_k,

carried through the fold as the pair (m, Σ) and updated stably each step.
KS is smooth in the samples (the shift by m cancels exactly), never below
the true maximum and at most ln(K)/ρ above it for K samples; near a single
sharp peak it is within a few 1/ρ of it.

Ratios, in :data:`CHECKS` order, are value/limit of: the tilt of the body
axis from the true vertical as (1 − cos)/(1 − cos tilt_max); the tip-over
energy of the support polygon's edges as 1 + surplus/unit (``tip_surplus``
of :mod:`symcushion.scheme.measures`, ≥ 0 once the body has the energy to pass
over an edge; see :func:`tip_energy`), which keeps a gradient where the
tilt has none (a lander that tips over reaches the same tilt whatever the
design, while its surplus falls as the stance widens); the axial
stroke ±δ_S; the hinge angles ±β and ±(γ − γ₀); the norm of the specific
force low-pass filtered as in the envelope (``DECEL_FILTER_TIME``); the
upward speed; and the motion at the end: the mean of (|v| + |ω|·reach) over
the last :data:`REST_WINDOW` of the horizon over rest_speed (the envelope's
at-rest check, averaged over a window so that a body chattering between an
absorber's branches, still at one step and moving at the next, is seen,
while a single-step spike of the chatter does not decide it as a maximum
would). With the energy check on, every sample fades out once the lander is
past the tilt limit (:func:`upright`): a lander lying on its side moves and
deflects its legs in ways that saturate every check whatever the design,
and its failure is the energy check's. A ratio above 1 fails that limit.
Signed pairs (±δ) keep the aggregate smooth where a deflection passes
through zero.

It must not choose scenarios, designs or weights, and it must not classify:
the envelope's running extrema (``symcushion.envelope``) stay the judge of a
case; these are their smooth stand-ins for the optimiser.
"""
from __future__ import annotations

import casadi as ca
import numpy as np

from symcushion.envelope.cases import DECEL_FILTER_TIME
from symcushion.layout.vectors import state_layout
from symcushion.scheme.measures import measures_function
from symcushion.scheme.touchdown import StepModel

__all__ = ["CHECKS", "REST_WINDOW", "DEFAULT_SHARPNESS", "margins_function"]

#: The aggregated ratios, in output order.
CHECKS = ("tip_over", "tip_energy", "stroke", "beta", "gamma", "deceleration", "rebound",
          "moving")

#: The at-rest ratio is aggregated over this last part of the horizon (s):
#: long enough to hold several periods of a chatter between branches (one or
#: two steps each) and of the legs' hinge vibration (tens of ms), short
#: enough that the touchdown itself is over.
REST_WINDOW = 0.2

#: ρ of the KS aggregate, in units of 1/ratio. 200: the aggregate of a peak
#: spread over ten samples is about ln(10)/200 ≈ 0.012 above the true
#: maximum ratio (1.2 % of the limit, on the safe side), while the weights of
#: samples more than 0.05 below the peak are below e^-10.
DEFAULT_SHARPNESS = 200.0

#: Width of the fade of the tip-over energy samples past the tilt limit, in
#: units of the tilt ratio (1 − cos)/(1 − cos tilt_max): they are half faded
#: at the limit and gone 10 % beyond it.
TIP_GATE_WIDTH = 0.05
#: What a faded sample is worth (the energy check's, and with it on every
#: check's, once the lander has tipped): far below any ratio of an upright
#: lander (a surplus of −10 units), so it never sets the aggregate.
TIP_FADED = -9.0
#: Start of the running maximum: far below any ratio, so the first sample
#: takes over (exp(ρ·(−1e3)) underflows to 0 exactly).
_FLOOR = -1e3


def _ks_update(m, s, samples, rho):
    """One step of the stable log-sum-exp fold: (m, Σ) after adding ``samples``."""
    m1 = ca.fmax(m, ca.mmax(samples))
    total = s * ca.exp(rho * (m - m1))
    for i in range(samples.numel()):
        total = total + ca.exp(rho * (samples[i] - m1))
    return m1, total


def tip_energy(surplus, one_minus_cos_tilt, limits):
    """Samples of the ``tip_energy`` check: 1 + surplus/limit, while the body is upright.

    ``surplus`` is the tip-over energy surplus of every support edge in m of
    lift (``tip_surplus`` of :mod:`symcushion.scheme.measures`), ``limits["tip_energy"]``
    the lift that counts as one unit of margin. Beyond the tilt limit a lander
    has tipped and lies on another face, where the support polygon means
    nothing: the samples fade out there (:data:`TIP_GATE_WIDTH`), so that the
    aggregate is the largest surplus of the touchdown itself.
    """
    unit, tilt = limits.get("tip_energy"), limits.get("tip_over")
    if unit is None or surplus.numel() == 0:
        return ca.SX.zeros(1)
    ratio = 1 + surplus / unit
    if tilt is None:
        return ratio
    gate = upright(one_minus_cos_tilt, tilt)
    return gate * ratio + (1 - gate) * TIP_FADED


def upright(one_minus_cos_tilt, tilt: float):
    """Smooth indicator of a lander within the tilt limit: 1 upright, 0 tipped over.

    Half at the limit, gone :data:`TIP_GATE_WIDTH` × 2 beyond it in units of
    the tilt ratio (1 − cos)/(1 − cos tilt_max).
    """
    over = (one_minus_cos_tilt - (1 - np.cos(tilt))) / (1 - np.cos(tilt))
    return 0.5 * (1 - ca.tanh(over / TIP_GATE_WIDTH))


def margins_function(model: StepModel, steps: int, limits: dict, *,
                     sharpness: float = DEFAULT_SHARPNESS, design=None,
                     reach: float = 0.0) -> ca.Function:
    """``touchdown_margins(x0, p0, w, dt) -> ratio``: smooth value/limit of every check.

    Parameters
    ----------
    model : StepModel
        ``build_model(scene)``; its step is called, not inlined.
    steps : int
        Steps of the horizon (≥ 1).
    limits : dict
        ``{check: limit}`` for the names of :data:`CHECKS` (tilt in rad, the
        unit of the tip-over energy surplus in m, stroke in m,
        β and γ in rad, deceleration in m/s², rebound and moving in
        m/s). A check whose limit is None or missing gets ratio 0.
    sharpness : float
        ρ of the KS aggregate (:data:`DEFAULT_SHARPNESS`).
    design : ndarray, shape (np, nw), optional
        The map M from the design vector w into the step's parameters:
        p = p0 + M w. Default: w is empty and p = p0.
    reach : float
        Lever arm of the at-rest check (m): the largest distance of a foot at
        rest from the centre of mass.

    Returns
    -------
    casadi.Function
        Inputs ``x0`` (nx), ``p0`` (np), ``w`` (nw), ``dt`` (s); output
        ``ratio`` (len(CHECKS)): the KS aggregate of value/limit over the
        horizon's steps (and legs), unsaturated.
    """
    if isinstance(steps, bool) or not isinstance(steps, (int, np.integer)) or steps < 1:
        raise ValueError(f"`steps` must be a positive integer, got {steps!r}.")
    if not (isinstance(sharpness, (int, float)) and np.isfinite(sharpness) and sharpness > 0):
        raise ValueError(f"`sharpness` must be a positive number, got {sharpness!r}; "
                         f"use {DEFAULT_SHARPNESS:g}.")
    unknown = sorted(set(limits) - set(CHECKS))
    if unknown:
        raise ValueError(f"`limits` has unknown check(s) {unknown}; allowed: {list(CHECKS)}.")
    scene = model.scene
    M = np.zeros((model.np, 0)) if design is None else np.asarray(design, dtype=float)
    if M.ndim != 2 or M.shape[0] != model.np:
        raise ValueError(f"`design` must be an array of shape ({model.np}, nw), got "
                         f"{M.shape}.")
    n_checks = len(CHECKS)
    rho = float(sharpness)
    axial = [j for j, leg in enumerate(scene.legs) if not leg.rigid]
    xl = state_layout(model.n_legs)

    x = ca.SX.sym("x", model.nx)
    a_f = ca.SX.sym("a_filtered", 3)
    t = ca.SX.sym("t")                                  # time at the start of the step
    n_ks = n_checks - 1                                 # every check but 'moving'
    m = ca.SX.sym("m", n_ks)
    s = ca.SX.sym("s", n_ks)
    p = ca.SX.sym("p", model.np)
    h = ca.SX.sym("dt")
    x1, y = model.step(x, p, h)
    meas = measures_function(scene).call(dict(x=x1, y=y, p=p))
    # first-order low-pass of the specific force, as the envelope's peak deceleration
    a_f1 = a_f + (1 - ca.exp(-h / DECEL_FILTER_TIME)) * (meas["specific_force"] - a_f)

    def ratio(name, values):
        limit = limits.get(name)
        if limit is None:
            return ca.SX.zeros(1)
        if name == "tip_over":
            return values / (1 - np.cos(limit))
        return values / limit

    samples = [ratio("tip_over", meas["one_minus_cos_tilt"]),
               tip_energy(meas["tip_surplus"], meas["one_minus_cos_tilt"], limits),
               ratio("stroke", ca.vertcat(meas["stroke"][axial], -meas["stroke"][axial]))
               if axial else ca.SX.zeros(1),
               ratio("beta", ca.vertcat(meas["beta"], -meas["beta"])),
               ratio("gamma", ca.vertcat(meas["gamma_deflection"], -meas["gamma_deflection"])),
               ratio("deceleration", ca.norm_2(a_f1)),
               ratio("rebound", meas["upward_speed"])]
    # the at-rest mean: the window depends on time only, never on the design
    weight = ca.if_else(t + h >= (steps * h) - REST_WINDOW * (1 - 1e-9), h, 0.0)
    motion = ratio("moving", ca.norm_2(xl.get(x1, "velocity"))
                   + ca.norm_2(xl.get(x1, "angular_velocity")) * float(reach))
    if limits.get("tip_energy") is not None and limits.get("tip_over") is not None:
        # a lander that has tipped over lies on another face: its legs' and body's
        # motion then says nothing a design can use (every check would saturate,
        # flat), and its failure is the energy check's; fade every sample out
        gate = upright(meas["one_minus_cos_tilt"], limits["tip_over"])
        samples[2:] = [gate * v + (1 - gate) * TIP_FADED for v in samples[2:]]
        motion = gate * motion
    m1, s1 = [], []
    for i, v in enumerate(samples):
        mi, si = _ks_update(m[i], s[i], v, rho)
        m1.append(mi)
        s1.append(si)
    mean = ca.SX.sym("mean", 2)                         # ∫ motion dt, ∫ dt over the window
    state = ca.vertcat(x, a_f, t, mean, m, s)
    state1 = ca.vertcat(x1, a_f1, t + h, mean + ca.vertcat(weight * motion, weight), *m1, *s1)
    step = ca.Function("margins_step", [state, p, h], [state1], ["state", "p", "dt"],
                       ["state_next"])

    x0 = ca.MX.sym("x0", model.nx)
    p0 = ca.MX.sym("p0", model.np)
    w = ca.MX.sym("w", M.shape[1])
    dt = ca.MX.sym("dt")
    start = ca.vertcat(x0, ca.MX.zeros(6), ca.MX(n_ks, 1) + _FLOOR, ca.MX.zeros(n_ks))
    end = step.fold(int(steps))(start, p0 + ca.DM(M) @ w, dt)
    tail = model.nx + 4
    at_rest = end[tail] / end[tail + 1]
    peak, total = end[tail + 2:tail + 2 + n_ks], end[tail + 2 + n_ks:]
    out = ca.vertcat(peak + ca.log(total) / rho, at_rest)
    # checks without a limit contribute exactly 0 (their samples are all 0 ⇒ KS = ln K/ρ)
    keep = ca.DM([1.0 if limits.get(c) is not None else 0.0 for c in CHECKS])
    return ca.Function("touchdown_margins", [x0, p0, w, dt], [out * keep],
                       ["x0", "p0", "w", "dt"], ["ratio"])
