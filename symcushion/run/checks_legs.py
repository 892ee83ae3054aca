"""The checks before a run of the legs' elements and of the time step.

A resistance curve with a negative slope, a strut whose hinge springs cannot
hold its axial force straight, damping times too unlike for a sliding foot,
a step above the explicit stability limit: each family of findings of
:func:`~symcushion.run.checks.check_scene` that looks at the legs' characteristics
or at Δt is here, with its tolerance.

This module owns those checks and their named tolerances (re-exported by
``symcushion.run.checks``; docs/checks.md lists each). It must not run them in
order or raise (``symcushion.run.checks`` does), and it never changes a scene, a
state or a step.
"""
from __future__ import annotations

import numpy as np

from symcushion.run.findings import Finding
from symcushion.scheme.stability import stable_dt
from symcushion.scheme.touchdown import build_model

__all__ = ["check_curves", "check_buckling", "check_damping_times", "check_time_step",
           "DAMPING_TIME_SPREAD", "DT_ERROR_RATIO"]


#: Ratio dt/stable_dt above which the step is an error rather than a warning.
#: ``stable_dt`` holds every foot fixed; a sliding foot (above all a
#: frictionless one) resists along the normal only, which can soften the
#: stiffest mode: Fig. 3 (μ = 0) runs stably at 1.4× the estimate. Past 10×
#: (ω Δt = 20) the effective stiffness would have to be 100 times below the
#: held one for the step to be stable.
DT_ERROR_RATIO = 10.0


#: Deflection range sampled for the slope check: ± the leg length for the
#: axial element (m), ± a quarter turn for the hinge elements (rad).
_SLOPE_SAMPLES = 81


#: Largest spread of a leg's damping times c/k (the largest over the smallest) that
#: keeps its damped foot's step stiffness close to the shape of its elastic one.
DAMPING_TIME_SPREAD = 3.0


def check_damping_times(scene):
    """With friction, a leg whose elements are damped with very different time constants
    c/k (say the axial element alone) gives its massless foot a step stiffness of
    another shape than its elastic one; near the friction cone's edge the slip Coulomb's
    law asks for may then push the force out of the cone, and the foot hops
    (docs/absorbers.md, "Dampers on every element")."""
    if scene.mu == 0 or scene.hysteresis != "memory":
        return []
    out = []
    for j, leg in enumerate(scene.legs):
        times = {}
        for el in leg.elements:
            k = abs(float(el.curve.slope(0.0)))
            if k > 0:
                times[el.name] = el.curve.damping / k
        damped = [t for t in times.values() if t > 0]
        if not damped:
            continue
        low, high = min(times.values()), max(times.values())
        if low == 0 or high / low > DAMPING_TIME_SPREAD:
            shown = ", ".join(f"{name} {1e3 * t:.3g} ms" for name, t in times.items())
            out.append(Finding(
                "damping_times", f"leg {j}: its elements' damping times c/k differ ({shown}); "
                "a sliding foot behind dampers of unlike time constants can hop; give every "
                "element of the leg the same c/k (docs/absorbers.md, \"Dampers on every "
                "element\").", "warning", leg=j, value=high / max(low, 1e-300),
                field=f"legs[{j}]"))
    return out


def _axial_load(scene, leg) -> tuple[float, str]:
    """The axial force (N) a leg's strut is sure to carry, and what it is: the crush
    force of a crushable element S (it carries it whenever it crushes), else the
    leg's share of the weight m|g|/legs (it carries that at rest)."""
    weight = scene.body.mass * float(np.linalg.norm(scene.gravity)) / len(scene.legs)
    axial = next((el for el in leg.elements if el.name == "S"), None)
    names = getattr(axial.curve, "param_names", ()) if axial is not None else ()
    if "crush_force" in names:
        crush = float(axial.curve.param_values[names.index("crush_force")])
        if crush > weight:
            return crush, "its crush force"
    return weight, "its share of the weight"


def check_buckling(scene):
    """The stiffness D_p of a strut (2.1) on hinge springs has, across the strut, the
    springs' k/L² less the axial force over the length, f_S/L (the turning of e_S under
    a compressive f_S; (2.3)). Where f_S/L exceeds k/L² D_p is indefinite: the straight
    leg would fold (an Euler column with a rotational spring, P·L > k), and the contact
    step, which solves P₀ + D_p δ on the plane (1.3), finds no compressive state and
    releases the foot: it lifts off with the foot inside the ground. With the memory
    law D_p keeps the loading branch's crush force after the leg unloads, so the
    refusal goes by the crush force (docs/checks.md)."""
    out = []
    for j, leg in enumerate(scene.legs):
        names = {el.name: el for el in leg.elements}
        if not {"M_beta", "M_gamma"} <= set(names):
            continue                         # a tripod: no hinge springs to fold about
        k = min(abs(float(names[n].curve.slope(0.0, 0.0))) for n in ("M_beta", "M_gamma"))
        load, what = _axial_load(scene, leg)
        if k < load * leg.length:
            out.append(Finding(
                "leg_buckles", f"leg {j}: its weaker hinge spring (k = {k:.4g} N·m/rad at "
                f"rest) gives k/L² = {k / leg.length ** 2:.4g} N/m across the strut, below "
                f"the axial force over the length, S/L = {load / leg.length:.4g} N/m ({what}, "
                f"{load:.4g} N): loaded off its axis the leg would fold, and the contact "
                "step, which cannot fold a massless leg, lifts its foot off inside the "
                f"ground instead; stiffen `M_beta` and `M_gamma` to at least "
                f"{load * leg.length:.4g} N·m/rad or lower the axial force.", "warning",
                leg=j, value=k / leg.length ** 2,
                field=f"legs[{j}].M_beta"))
    return out


def check_curves(scene):
    """Restoring curves: slope ≥ 0 at rest (error) and over the sampled range (warning)."""
    out = []
    for j, leg in enumerate(scene.legs):
        for el in leg.elements:
            extent = leg.element_extent(el.name)
            xs = np.linspace(-extent, extent, _SLOPE_SAMPLES)
            branches = [("loading", el.curve)]
            if el.curve.unloading is not None:
                branches.append(("unloading", el.curve.unloading))
            for branch, curve in branches:
                slopes = np.array([curve.slope(float(x)) if branch == "unloading" else
                                   curve.slope(float(x), 0.0) for x in xs])
                rest = slopes[_SLOPE_SAMPLES // 2]
                where = f"legs[{j}].{el.name}"
                hinge = "hinge stiffness" if el.name != "S" else "axial stiffness"
                if rest < 0:
                    out.append(Finding("negative_stiffness", f"`{where}`: the {branch} branch "
                                       f"has negative {hinge} {rest:.4g} at rest; the element "
                                       "pushes away from rest instead of restoring — give a "
                                       "curve with a non-negative slope at 0.", "error", leg=j,
                                       value=float(rest), field=where))
                elif np.min(slopes) < 0:
                    i = int(np.argmin(slopes))
                    out.append(Finding("negative_slope", f"`{where}`: the {branch} branch has "
                                       f"slope {slopes[i]:.4g} < 0 at deflection {xs[i]:.4g}; "
                                       "the element snaps through there (D_p indefinite) — "
                                       "check the knots.", "warning", leg=j,
                                       value=float(slopes[i]), field=where))
    return out


def check_time_step(scene, model, x0):
    """The step against the run's duration and the explicit stability limit."""
    out = []
    if scene.dt > scene.duration:
        out.append(Finding("dt_above_duration", f"`scene.dt` = {scene.dt:g} s is longer than "
                           f"`scene.duration` = {scene.duration:g} s: the run would be one "
                           "step of dt; reduce `dt` or raise `duration`.", "error",
                           value=scene.dt / scene.duration, field="scene.dt"))
    model = build_model(scene) if model is None else model
    try:
        limit = stable_dt(model, x0)
    except FloatingPointError as exc:
        return out + [Finding("stiffness_not_finite", f"the legs' stiffness at the start is "
                              f"not finite ({exc}); check the leg geometry.", "error")]
    if scene.dt > limit:
        ratio = scene.dt / limit
        severity = "error" if ratio > DT_ERROR_RATIO else "warning"
        out.append(Finding("dt_unstable", f"`scene.dt` = {scene.dt:g} s is {ratio:.3g} times "
                           f"the stable step 2/ω_max = {limit:.3g} s of the stiffest leg mode "
                           "(feet held): the explicit body update may diverge — use dt ≤ "
                           f"{limit / 2:.3g} s (command line: --dt {limit / 2:.3g}), or cap "
                           "each step at the limit (command line: --stability; Python: "
                           "simulate(..., adaptive=True, stability=True)).",
                           severity, value=ratio, field="scene.dt"))
    return out
