"""Leg geometry as design variables, and the practical limits on it.

Owns :class:`GeometryVariable` (hinge radius and height, leg length L₀,
splay of the rest direction e₀, footpad radius; per leg or shared by
symmetric legs), :class:`PracticalLimits` (footprint radius, leg mass proxy,
ground clearance at full stroke) and the mixin :class:`GeometryDesign` of
both design problems: it resolves the variables against the legs, maps the
design θ into the geometry entries of the step's ``p`` (the legs' blocks of
``build_model(scene, geometry="input")``, docs/strut.md) as a CasADi
expression, places the body of a scenario so that its lowest foot keeps its
clearance whatever the geometry, and states the practical-limit rows. It
must not simulate, choose curves' variables or call a solver.

Geometry of leg j, in the body frame with ẑ its vertical axis: u_j is the
horizontal unit vector from the axis towards the leg's hinge at the start
and t_j = ẑ × u_j. The hinge is ρ_j u_j + h_t t_j + z_j ẑ (ρ_j the hinge
radius, z_j its height; the tangential offset h_t stays). The splay s_j is
the angle of e₀ from −ẑ in the plane (u_j, ẑ), positive outwards:
e₀ = sin s u_j − cos s ẑ. A change of splay rotates e₀ *and* e_n about t_j
by the same angle, so the angle between them (γ₀ of the hinge's polar
deflection, docs/paper-notes.md §2) and the orientation sign σ = sign(e₀·e_n)
never change; e₀ must lie in its radial plane at the start.
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Sequence

import casadi as ca
import numpy as np

from symcushion.design.optimise.shape_points import branch_rate, shape_points
from symcushion.layout.vectors import state_layout
from symcushion.scheme.quaternion import quat_to_rot, quat_to_rot_np
from symcushion.model.obstacles import closest_obstacle
from symcushion.legs.strut import HingedStrut
from symcushion.design.optimise.spec import real_number

__all__ = ["GEOMETRY_QUANTITIES", "PRACTICAL_KINDS", "GeometryVariable", "PracticalLimits",
           "PLACEMENT_ITERS"]

#: Geometry quantities a design may vary, with their units (splay in rad).
GEOMETRY_QUANTITIES = {"hinge_radius": "m", "hinge_height": "m", "length": "m",
                       "splay": "rad", "footpad": "m"}
#: Kinds of the practical-limit rows (``Block.kind``), as named in reports.
PRACTICAL_KINDS = ("footprint", "leg_mass", "ground_clearance")
#: Symbolic placement steps of a scenario's body above a curved obstacle (one is
#: exact on a plane; each further step halves the error of the last many times
#: over on the gentle surfaces of the studies, docs/optimise.md "Geometry").
PLACEMENT_ITERS = 3
#: |e₀·t_j| above which a leg's rest direction is not in its radial plane, so
#: that its splay is not defined (round-off of the scene's unit vectors is ~1e-16).
_PLANE_TOL = 1e-9
#: Relative spread of the start values of legs that share one variable.
_SHARED_TOL = 1e-9
#: A splay this close to ±90° would turn e₀ horizontal: the leg would stand on
#: its side and the clearance placement has no lowest foot below the body.
_SPLAY_MAX = math.radians(80.0)


@dataclass
class GeometryVariable:
    """A geometry quantity of some legs as a design variable.

    Attributes
    ----------
    quantity : {'hinge_radius', 'hinge_height', 'length', 'splay', 'footpad'}
        Hinge distance from the body's vertical axis (m), hinge height along
        it (m), rest length L₀ (m), angle of e₀ from the body's downward
        vertical in the leg's radial plane (rad), footpad radius (m).
    lower, upper : float
        Bounds (m or rad); both required.
    legs : sequence of int, optional
        The legs it applies to (default: every leg).
    shared : bool
        True: one variable for all those legs (their start values must be
        equal); False: one per leg, named ``leg{j}.{quantity}``.
    scale : float, optional
        Typical magnitude (default: the largest |start value|, or the
        bounds' width when that is 0).
    """

    quantity: str
    lower: float
    upper: float
    legs: Sequence[int] | None = None
    shared: bool = True
    scale: float | None = None


@dataclass
class PracticalLimits:
    """Practical limits on the geometry (None: not imposed).

    Attributes
    ----------
    footprint_radius : float
        Every foot at rest within this distance of the body's vertical axis (m).
    leg_mass : float
        Mass proxy of each leg ≤ this (N·m): L₀ times the largest force of its
        axial loading curve at its check points (a column sized for a given
        stress has a mass ∝ force × length).
    ground_clearance : float
        Each hinge at least this high above level ground when the body sits
        upright on its feet with every leg at the full stroke ``limits.stroke``
        along e₀: a + (L₀ − stroke)·cos(splay) ≥ ground_clearance (m).
    """

    footprint_radius: float | None = None
    leg_mass: float | None = None
    ground_clearance: float | None = None

    def __post_init__(self):
        for name in ("footprint_radius", "leg_mass", "ground_clearance"):
            value = getattr(self, name)
            if value is not None:
                setattr(self, name, real_number(f"design.limits.{name}", value, positive=True))

    @property
    def any(self) -> bool:
        return any(v is not None for v in self.__dict__.values())


def _leg_frame(leg, j: int, need_radial: bool, need_splay: bool) -> dict:
    """Radial frame and start values of one hinged strut (see the module docstring)."""
    z = np.array([0.0, 0.0, 1.0])
    radial = np.array([leg.hinge[0], leg.hinge[1], 0.0])
    rho = float(np.linalg.norm(radial))
    if rho == 0.0 and need_radial:
        raise ValueError(f"leg {j}: its hinge is on the body's vertical axis, so it has no "
                         "radial direction; move the hinge off the axis to design its hinge "
                         "radius or splay.")
    # a hinge on the axis has no radial plane; any one serves its height and length
    u = radial / rho if rho > 0 else np.array([1.0, 0.0, 0.0])
    t = np.cross(z, u)
    e0 = np.asarray(leg.e0, dtype=float)
    if need_splay and abs(float(e0 @ t)) > _PLANE_TOL:
        raise ValueError(f"leg {j}: e0 = {e0.tolist()} is not in the leg's radial plane "
                         f"(component {float(e0 @ t):.3g} along the tangent), so its splay is "
                         "not defined; give the leg a radial rest direction or do not design "
                         "`splay`.")
    return dict(u=u, t=t, z=z, hinge_radius=rho, hinge_height=float(leg.hinge[2]),
                tangential=float(leg.hinge @ t), length=float(leg.length),
                splay=float(math.atan2(float(e0 @ u), -float(e0[2]))),
                footpad=float(leg.footpad), e0=e0, en=np.asarray(leg.en, dtype=float))


def _rotate(v, axis, angle):
    """Rodrigues: v rotated about the unit ``axis`` by ``angle`` (CasADi)."""
    axis = ca.DM(axis)
    return (v * ca.cos(angle) + ca.cross(axis, v) * ca.sin(angle)
            + axis * ca.dot(axis, v) * (1 - ca.cos(angle)))


class GeometryDesign:
    """Geometry variables, the geometry entries of ``p`` and practical rows (a mixin).

    Reads ``legs``, ``var_names``, ``lower``, ``upper``, ``scale``, ``initial``
    and ``_map`` of its host (after the curves' variables are resolved) and
    appends the geometry variables to them.
    """

    def _resolve_geometry(self, specs, practical, layout):
        """Append geometry variables; check their bounds against the legs' own checks."""
        self.practical = practical if practical is not None else PracticalLimits()
        if not isinstance(self.practical, PracticalLimits):
            raise TypeError(f"`practical` must be a PracticalLimits, got {practical!r}.")
        self._layout = layout
        self.geometry_vars = []                  # (variable index, quantity, legs)
        self._geo = {}                           # (leg, quantity) -> variable index
        specs = list(specs)
        if not specs and not self.practical.any:
            self._frames = None
            self._is_curve = np.ones(len(self.var_names), dtype=bool)
            return
        legs = self.legs
        if not all(isinstance(leg, HingedStrut) for leg in legs):
            raise ValueError("geometry variables and practical limits need hinged struts "
                             "(scheme = \"strut\"); the scene has other legs.")
        quantities = {getattr(s, "quantity", None) for s in specs}
        need_radial = bool(quantities & {"hinge_radius", "splay"})
        self._frames = [_leg_frame(leg, j, need_radial, "splay" in quantities)
                        for j, leg in enumerate(legs)]
        names, lower, upper, scale, start = [], [], [], [], []
        for i, spec in enumerate(specs):
            if not isinstance(spec, GeometryVariable):
                raise TypeError(f"`geometry[{i}]` must be a GeometryVariable, got {spec!r}.")
            q = spec.quantity
            if q not in GEOMETRY_QUANTITIES:
                raise ValueError(f"`geometry[{i}].quantity` must be one of "
                                 f"{list(GEOMETRY_QUANTITIES)}, got {q!r}.")
            lo = real_number(f"geometry[{i}].lower", spec.lower)
            hi = real_number(f"geometry[{i}].upper", spec.upper)
            if not (math.isfinite(lo) and math.isfinite(hi)) or lo > hi:
                raise ValueError(f"geometry variable `{q}`: bounds [{lo:g}, {hi:g}] must be "
                                 "finite with lower ≤ upper; give both bounds.")
            _check_bounds(q, lo, hi, self.limits)
            if q == "footpad" and not layout.footpads:
                raise ValueError("geometry variable `footpad`: the scene's legs have no "
                                 "footpad entries in p; give some leg a `footpad` > 0 "
                                 "(docs/footpads.md).")
            which = list(range(len(legs))) if spec.legs is None else list(spec.legs)
            bad = [j for j in which if isinstance(j, bool) or not isinstance(j, int)
                   or not 0 <= j < len(legs)]
            if bad or not which:
                raise ValueError(f"geometry variable `{q}`: `legs` = {list(which)} must be "
                                 f"leg indices in 0…{len(legs) - 1}.")
            groups = [which] if spec.shared else [[j] for j in which]
            for group in groups:
                values = np.array([self._frames[j][q] for j in group])
                if np.ptp(values) > _SHARED_TOL * max(1.0, float(np.max(np.abs(values)))):
                    raise ValueError(f"geometry variable `{q}` is shared by legs {group} whose "
                                     f"start values differ ({values.tolist()}); give the legs "
                                     "equal values or set `shared = false`.")
                if not lo <= values[0] <= hi:
                    raise ValueError(f"geometry variable `{q}` starts at {values[0]:g}, "
                                     f"outside its bounds [{lo:g}, {hi:g}]; widen the bounds.")
                for j in group:
                    if (j, q) in self._geo:
                        raise ValueError(f"`{q}` of leg {j} is designed by two geometry "
                                         "variables; give each leg's quantity once.")
                    self._geo[(j, q)] = len(self.var_names) + len(names)
                label = q if (spec.shared and spec.legs is None) else \
                    (f"leg{group[0]}.{q}" if len(group) == 1 else
                     f"legs{','.join(map(str, group))}.{q}")
                names.append(label)
                lower.append(lo)
                upper.append(hi)
                start.append(float(values[0]))
                sc = spec.scale if spec.scale is not None else \
                    (max(abs(lo), abs(hi)) if values[0] == 0 else abs(float(values[0])))
                scale.append(real_number(f"geometry[{i}].scale", sc, positive=True))
                self.geometry_vars.append((len(self.var_names) + len(names) - 1, q, group))
        n_curve = len(self.var_names)
        self._is_curve = np.r_[np.ones(n_curve, dtype=bool), np.zeros(len(names), dtype=bool)]
        self.var_names = list(self.var_names) + names
        self.lower = np.r_[self.lower, lower]
        self.upper = np.r_[self.upper, upper]
        self.scale = np.r_[self.scale, scale]
        self.initial = np.r_[self.initial, start]
        self._map = np.hstack([self._map, np.zeros((self._map.shape[0], len(names)))])
        self._check_geometry_box()

    @property
    def designs_geometry(self) -> bool:
        """True when some design variable is a geometry quantity."""
        return bool(self.geometry_vars)

    def _check_geometry_box(self):
        """The legs' own checks at the start and at every geometry bound (one at a time)."""
        for k, q, group in self.geometry_vars:
            for bound in (self.lower[k], self.upper[k]):
                theta = self.initial.copy()
                theta[k] = bound
                for j in group:
                    G = self.leg_geometry(theta, j)
                    try:
                        self.legs[j].check_geometry(G["hinge"], G["e0"], G["en"], G["length"],
                                                    where=f"leg {j}: ")
                    except ValueError as exc:
                        raise ValueError(f"geometry variable `{self.var_names[k]}` at its bound "
                                         f"{bound:g} gives a geometry the leg refuses ({exc}); "
                                         "narrow the bounds.") from None

    # -- the geometry as expressions of θ --------------------------------------------
    def _leg_geometry_expr(self, theta, j: int) -> dict:
        """hinge, e0, en, length, footpad of leg j (CasADi; constants where not designed)."""
        F, leg = self._frames[j], self.legs[j]

        def value(q):
            k = self._geo.get((j, q))
            return None if k is None else theta[k]

        rho, height = value("hinge_radius"), value("hinge_height")
        if rho is None and height is None:
            hinge = ca.DM(leg.hinge)
        else:
            rho = F["hinge_radius"] if rho is None else rho
            height = F["hinge_height"] if height is None else height
            hinge = rho * ca.DM(F["u"]) + F["tangential"] * ca.DM(F["t"]) + height * ca.DM(F["z"])
        splay = value("splay")
        if splay is None:
            e0, en = ca.DM(F["e0"]), ca.DM(F["en"])
        else:
            # e₀ and e_n turn together about t_j (module docstring): a rotation by φ about
            # t = ẑ × u takes sin s·u − cos s·ẑ to sin(s − φ)·u − cos(s − φ)·ẑ
            angle = F["splay"] - splay
            e0 = _rotate(ca.DM(F["e0"]), F["t"], angle)
            en = _rotate(ca.DM(F["en"]), F["t"], angle)
        length = value("length")
        pad = value("footpad")
        return dict(hinge=hinge, e0=e0, en=en,
                    length=F["length"] if length is None else length,
                    footpad=F["footpad"] if pad is None else pad)

    def leg_geometry(self, theta, j: int) -> dict:
        """Leg j's hinge, e0, en (NumPy), length and footpad (floats) at design θ (SI)."""
        G = self._leg_geometry_expr(ca.DM(np.asarray(theta, dtype=float)), j)
        out = {k: np.asarray(ca.evalf(v), dtype=float).ravel() for k, v in G.items()}
        return {k: (float(v[0]) if v.size == 1 else v) for k, v in out.items()}

    def _rest_feet(self, theta) -> list:
        """Each leg's foot at rest, r_h + L₀ e₀, in the body frame (CasADi)."""
        out = []
        for j in range(len(self.legs)):
            G = self._leg_geometry_expr(theta, j)
            out.append(G["hinge"] + G["length"] * G["e0"])
        return out

    def _full_p_tail(self, theta, model, tail=None):
        """The entries of the step's ``p`` after the curve parameters at design θ.

        ``tail``: those entries as they are without the design (default the
        scene's own values; the envelope's cases give their own μ and gravity).
        Without geometry variables ``tail`` itself (the graph of a curve-only
        design is unchanged); with them, the designed legs' geometry blocks (and
        footpads) as expressions of θ in its place.
        """
        lay = model.params
        if tail is None:
            tail = ca.DM(np.asarray(model.default_p[lay.n_leg_params:], dtype=float))
        if not self.designs_geometry:
            return tail
        entries = [ca.MX(tail[i]) for i in range(tail.shape[0])]
        start = lay.n_leg_params
        for j in range(len(self.legs)):
            if not any((j, q) in self._geo for q in GEOMETRY_QUANTITIES):
                continue
            G = self._leg_geometry_expr(theta, j)
            for field, expr in (("hinge", G["hinge"]), ("e0", G["e0"]), ("en", G["en"]),
                                ("length", G["length"])):
                sl = lay.slice(f"leg{j}.{field}")
                expr = ca.vec(ca.MX(expr)) if not isinstance(expr, ca.MX) else expr
                for i, k in enumerate(range(sl.start, sl.stop)):
                    entries[k - start] = expr[i]
            if lay.footpads:
                k = lay.slice(f"leg{j}.footpad").start
                entries[k - start] = G["footpad"]
        return ca.vertcat(*entries)

    # -- initial states that follow the geometry -----------------------------------------
    def _placed_state(self, x0, theta, scene, clearance, up):
        """x0 with the feet at the rest poses of design θ and, when the scenario was placed
        by ``clearance``, the body moved along ``up`` so that the lowest foot keeps it.

        The numeric placement (``optimise.study._place``) repeated on the graph: one
        step is exact on a plane, :data:`PLACEMENT_ITERS` steps on curved obstacles.
        The lowest foot is a ``fmin`` over the legs: smooth except where two feet swap.
        """
        if not self.designs_geometry:
            return ca.DM(x0)
        xl = state_layout(len(self.legs))
        R = ca.DM(_rotation(xl.get(x0, "attitude")))
        feet = [R @ r for r in self._rest_feet(theta)]
        pads = [self._leg_geometry_expr(theta, j)["footpad"] for j in range(len(self.legs))]
        pos = ca.DM(xl.get(x0, "position"))
        if clearance is not None:
            up = ca.DM(up)
            for _ in range(PLACEMENT_ITERS):
                d = [closest_obstacle(scene.obstacles, pos + f, a) for f, a in zip(feet, pads)]
                low = d[0][0]
                rate = ca.dot(d[0][1], up)
                for dj, nj, _ in d[1:]:
                    lower = dj < low
                    rate = ca.if_else(lower, ca.dot(nj, up), rate)
                    low = ca.fmin(low, dj)
                pos = pos - (low - clearance) / rate * up
        return _with_pose(x0, xl, pos, feet)

    def _placed_state_on_ground(self, x0, theta):
        """x0 (symbolic, an envelope case) re-placed for design θ: the body moved along the
        ground normal z of the slope frame so that the lowest unloaded foot keeps its
        height, as the envelope's case builder places it (``envelope.cases.initial_states``)."""
        xl = state_layout(len(self.legs))
        R = quat_to_rot(xl.get(x0, "attitude"))
        feet = [R @ r for r in self._rest_feet(theta)]
        feet0 = [R @ ca.DM(leg.rest_foot) for leg in self.legs]
        low = ca.mmin(ca.horzcat(*[f[2] for f in feet]))
        low0 = ca.mmin(ca.horzcat(*[f[2] for f in feet0]))
        pos = xl.get(x0, "position") + ca.vertcat(0, 0, low0 - low)
        return _with_pose(x0, xl, pos, feet)

    # -- practical limits ------------------------------------------------------------------
    def _add_practical_rows(self, theta, add, stroke):
        """Footprint, leg-mass and ground-clearance rows (:class:`PracticalLimits`)."""
        lim = self.practical
        if not lim.any:
            return
        if lim.ground_clearance is not None and stroke is None:
            raise ValueError("`design.limits.ground_clearance` is taken at full stroke; give "
                             "`limits.stroke` too.")
        p = ca.DM(self.p_fixed) + ca.DM(self._map) @ theta
        for j, leg in enumerate(self.legs):
            G = self._leg_geometry_expr(theta, j)
            foot = G["hinge"] + G["length"] * G["e0"]
            if lim.footprint_radius is not None:
                add(ca.sqrt(foot[0] ** 2 + foot[1] ** 2), "footprint", lim.footprint_radius,
                    -math.inf, 1.0, "m", leg=j, label="foot at rest from the body axis")
            if lim.leg_mass is not None:
                self._add_mass_rows(j, leg, G["length"], p, add)
            if lim.ground_clearance is not None:
                cos_splay = -G["e0"][2]
                add(G["footpad"] + (G["length"] - stroke) * cos_splay, "ground_clearance",
                    lim.ground_clearance, 1.0, math.inf, "m", leg=j,
                    label="hinge height above level ground at full stroke")

    def _add_mass_rows(self, j, leg, length, p, add):
        """L₀ · sign(x)·f_L(x) ≤ leg_mass at every check point of leg j's axial curve."""
        element = next((el for el in leg.elements if el.name == "S"), None)
        if element is None or leg.rigid:
            return
        curve = element.curve
        th = None
        if curve.tunable:
            th = ca.vertcat(*[p[self.param_names.index(f"leg{j}.S.{n}")]
                              for n in curve.param_names])
        extent = self.limits.stroke
        for x in shape_points(curve, extent):
            if x == 0:
                continue
            force = float(np.sign(x)) * curve.force(float(x), branch_rate(curve, float(x), True), th)
            add(length * force, "leg_mass", self.practical.leg_mass, -math.inf, 1.0, "N·m",
                leg=j, label=f"L₀ × axial loading force at x = {x:.4g}")

    def geometry_report(self, theta) -> dict:
        """Per leg: hinge radius, height, length, splay (deg), footpad, foot radius (m)."""
        if self._frames is None:
            return {}
        out = {}
        for j in range(len(self.legs)):
            G = self.leg_geometry(theta, j)
            F = self._frames[j]
            foot = G["hinge"] + G["length"] * G["e0"]
            out[f"leg{j}"] = dict(
                hinge_radius=float(G["hinge"] @ F["u"]), hinge_height=float(G["hinge"][2]),
                length=G["length"], splay_deg=math.degrees(math.atan2(float(G["e0"] @ F["u"]),
                                                                      -float(G["e0"][2]))),
                footpad=G["footpad"], foot_radius=float(np.hypot(foot[0], foot[1])))
        return out

    def curve_design(self, theta) -> dict:
        """The curve variables of design θ by name (the geometry's left out)."""
        return {name: float(value) for name, value, curve in
                zip(self.var_names, np.asarray(theta, dtype=float), self._is_curve) if curve}

    def scene_at(self, theta, scene):
        """``scene`` with its legs rebuilt at the geometry of design θ (curves unchanged)."""
        if not self.designs_geometry:
            return scene
        legs = []
        for j, leg in enumerate(scene.legs):
            G = self.leg_geometry(theta, j)
            curves = {el.name: el.curve for el in leg.elements}
            legs.append(HingedStrut(hinge=G["hinge"], e0=G["e0"], en=G["en"], length=G["length"],
                                    S=None if leg.rigid else curves.get("S"),
                                    M_beta=curves.get("M_beta"), M_gamma=curves.get("M_gamma"),
                                    axial_ratio=leg.axial_ratio, law=leg.law,
                                    footpad=G["footpad"]))
        return scene.with_(legs=legs)


def _check_bounds(q, lo, hi, limits):
    """Bounds a leg can take whatever the other variables are (refused with the fix)."""
    if q == "length" and lo <= 0:
        raise ValueError(f"geometry variable `length`: lower bound {lo:g} m must be > 0 (a "
                         "leg of no length is singular); raise it.")
    if q == "length" and limits is not None and limits.stroke is not None \
            and lo <= limits.stroke:
        raise ValueError(f"geometry variable `length`: lower bound {lo:g} m is not above the "
                         f"stroke limit {limits.stroke:g} m (the leg would pass through its "
                         "hinge); raise it.")
    if q in ("hinge_radius", "footpad") and lo < 0:
        raise ValueError(f"geometry variable `{q}`: lower bound {lo:g} m must be ≥ 0; raise "
                         "it.")
    if q == "splay" and not (-_SPLAY_MAX <= lo and hi <= _SPLAY_MAX):
        raise ValueError(f"geometry variable `splay`: bounds [{math.degrees(lo):.4g}°, "
                         f"{math.degrees(hi):.4g}°] must lie within ±"
                         f"{math.degrees(_SPLAY_MAX):.0f}° (a leg splayed to the horizontal "
                         "has no foot below the body); narrow them.")


def _rotation(q) -> np.ndarray:
    return quat_to_rot_np(np.asarray(q, dtype=float))


def _with_pose(x0, xl, pos, feet):
    """x0 with the body position ``pos`` and the feet at ``pos + feet[j]`` (CasADi)."""
    x = ca.vertcat(*[x0[i] for i in range(x0.shape[0])]) if isinstance(x0, (ca.MX, ca.SX)) \
        else ca.DM(x0)
    parts = [x[i] for i in range(x.shape[0])]
    sl = xl.slice("position")
    for i, k in enumerate(range(sl.start, sl.stop)):
        parts[k] = pos[i]
    for j, f in enumerate(feet):
        sl = xl.slice("foot", j)
        for i, k in enumerate(range(sl.start, sl.stop)):
            parts[k] = pos[i] + f[i]
    return ca.vertcat(*parts)

