"""The inverted-tripod (cantilever) landing leg: its geometry, foot force and stiffness.

The gear of Apollo LM, Surveyor and Chang'e-3: a primary strut on a
spherical joint at the hardpoint h₁ runs to the foot r, two secondary struts
from the hardpoints h₂, h₃ to a pin Q on its outer cylinder. Its geometry
(lengths, directions, the deflections q) is ``symcushion.legs.tripod_geometry``,
whose docstring derives the virtual-work law (T1) P = J(r)ᵀ f built here;
the NumPy evaluation of the leg is ``symcushion.legs.tripod_numeric``.

Leg-scheme interface. A leg scheme is a class with ``param_names``,
``param_values``, ``rest_foot``, ``length``, ``hinge``, ``footpad``, ``elements`` and
``functions()``, whose dict holds at least ``strut_geometry(r) -> (L,
delta_S, e_S, ...)``, ``strut_force(r, v, p) -> P`` and ``strut_stiffness(r,
v, p) -> Dp``. :class:`InvertedTripod` provides those three under the
``strut_*`` names (the second output of ``strut_geometry`` is δ_S, as for the
strut) besides its own ``tripod_*`` Functions built from the same
expressions, and, where its elements keep sets or have dampers, the memory
law's Functions (``symcushion.legs.leg_scheme``; the primary is the axial element).

This module owns the leg: its elements and curves, their forces, the memory
law's expressions, the singular-pose checks and the Functions built on the
geometry. It knows nothing of contact, of the body's motion or of scenes,
and it must not import them.
"""
from __future__ import annotations

from dataclasses import dataclass

import casadi as ca
import numpy as np

from symcushion.legs import absorber
from symcushion.legs.curve_base import Curve
from symcushion.layout.params import TRIPOD_GEOMETRY_FIELDS
from symcushion.legs.leg_scheme import (CurveParams, band_part, cached_memory_functions,
    elastic_line)
from symcushion.validation import real, vector
from symcushion.legs.tripod_geometry import (GEOMETRY_SIZE, ZERO_LENGTH, angle_from_parallel,
    numeric_geometry, tripod_deflections, tripod_geometry_expr, tripod_rest_lengths)
from symcushion.legs.tripod_numeric import TripodEvaluation

__all__ = ["InvertedTripod", "SINGULAR_ANGLE", "ELEMENTS", "tripod_geometry_expr",
           "tripod_rest_lengths"]

#: Smallest angle (rad) allowed at the rest pose between the lines whose
#: alignment makes the tripod a mechanism: u₂ ∥ u₃, u_k ∥ e_S, and the plane
#: of the two secondaries containing e_S (then their projections ⊥ e_S are
#: parallel and the foot has a direction with no stiffness but the curves'
#: preload). 5° keeps the smallest lateral stiffness above sin²5° ≈ 0.8 % of
#: the secondaries' scale; real gear is designed near 30°-90°.
SINGULAR_ANGLE = np.deg2rad(5.0)

#: Newton steps that put a free foot where its elements' free deflections meet: the
#: deflections of a free leg are its sets, millimetres from the rest foot, where
#: q(r) is nearly linear; three steps take the residual to round-off.
FREE_FOOT_NEWTON_STEPS = 3

#: Element names, in the order of q, f and ``p``.
ELEMENTS = ("primary", "secondary2", "secondary3")


@dataclass(frozen=True)
class _Element:
    name: str            # one of ELEMENTS
    curve: Curve
    offset: int          # start of its parameters in p (tunable only)


class InvertedTripod(CurveParams, TripodEvaluation):
    """Cantilever inverted-tripod leg: primary strut on h₁, two secondaries to its pin Q.

    Parameters
    ----------
    h1, h2, h3 : array_like, shape (3,)
        Hardpoints of the primary (spherical joint) and of the two
        secondaries, body frame (m).
    foot : array_like, shape (3,)
        Foot position at the unloaded rest pose, body frame (m); sets the
        rest lengths L₀ = |foot − h₁|, l_k0 = |Q₀ − h_k|.
    outer_length : float
        ℓ_o, distance from h₁ to the pin Q along the primary (m), 0 < ℓ_o < L₀.
    primary, secondary2, secondary3 : Curve
        Resistance curves of the primary stroke δ_S and of the secondary
        deflections δ₂, δ₃ (N vs m, extension positive); a
        :class:`~symcushion.legs.characteristics.TwoSided` curve crushes both ways.
    footpad : float
        Radius a ≥ 0 of the footpad (m): ``foot`` is the pad's centre, which
        touches the obstacle's surface offset by a (docs/footpads.md); 0, the
        default, is a point foot.

    Examples
    --------
    >>> from symcushion.legs.characteristics import Linear
    >>> leg = InvertedTripod(h1=(2.0, 0, 1.0), h2=(1.9, 1.0, -0.6), h3=(1.9, -1.0, -0.6),
    ...                      foot=(3.6, 0, -1.4), outer_length=1.9, primary=Linear(2e5),
    ...                      secondary2=Linear(1e6), secondary3=Linear(1e6))
    >>> sorted(leg.functions())[:3]
    ['strut_force', 'strut_geometry', 'strut_stiffness']
    """

    def __init__(self, h1, h2, h3, foot, outer_length, primary: Curve,
                 secondary2: Curve, secondary3: Curve, footpad: float = 0.0):
        self.h1, self.h2, self.h3 = (vector(n, v, (3,)) for n, v in
                                     (("h1", h1), ("h2", h2), ("h3", h3)))
        self.foot = vector("foot", foot, (3,))
        self.outer_length = real("outer_length", outer_length, positive=True, unit="m")
        self.footpad = real("footpad", footpad, nonnegative=True, unit="m")
        self.length = float(np.linalg.norm(self.foot - self.h1))
        if not self.length > 0:
            raise ValueError(f"`foot` = {self.foot.tolist()} is at the hardpoint `h1`: the "
                             "primary has zero rest length; put the foot away from `h1`.")
        if not self.outer_length < self.length:
            raise ValueError(f"`outer_length` = {self.outer_length:g} m must be shorter than "
                             f"the primary's rest length |foot − h1| = {self.length:g} m; "
                             "the pin Q lies between `h1` and the foot.")
        self._check_rest_pose()
        elements, offset = [], 0
        for name, curve in zip(ELEMENTS, (primary, secondary2, secondary3)):
            if not isinstance(curve, Curve):
                raise TypeError(f"`{name}` must be a characteristic curve such as "
                                f"Linear(1e5), got {curve!r}.")
            elements.append(_Element(name, curve, offset))
            offset += curve.n_params if curve.tunable else 0
        self.elements = tuple(elements)
        self.rest_lengths = np.asarray(ca.evalf(tripod_rest_lengths(*self._dm_geometry(
            ca.DM(self.foot))))).ravel()
        self._functions = {}            # by geometry mode
        self._memory_functions = {}

    # -- interface shared with HingedStrut ---------------------------------------
    hinge = property(lambda self: self.h1, doc="The primary's joint h₁ (m).")
    #: A free foot relaxes every element's deflection over a step (A4).
    relaxes_free = (1.0, 1.0, 1.0)

    @property
    def axial_state(self) -> bool:
        """True if the leg needs the memory law's state: an element that keeps a set
        or has a damper."""
        return any(el.curve.has_memory or el.curve.has_damper for el in self.elements)

    axial_memory = axial_state

    rigid = False                      # every element is a curve of the user's
    axial_element = "primary"

    @property
    def e0(self) -> np.ndarray:
        """Rest direction of the primary, (foot − h₁)/L₀."""
        return (self.foot - self.h1) / self.length

    def deflections(self, geo) -> dict:
        """Each element's deflection (m) from ``strut_geometry``'s outputs ``geo``."""
        return {"primary": geo["delta_S"], "secondary2": geo["stroke_secondary"][0],
                "secondary3": geo["stroke_secondary"][1]}

    def deflection_outputs(self, geo) -> dict:
        """The per-leg output fields of the deflections (``symcushion.layout.vectors``): the
        primary's stroke and the secondaries'; no hinge angles."""
        return dict(stroke=geo["delta_S"], beta=0.0, gamma_deflection=0.0,
                    secondary_stroke=geo["stroke_secondary"])

    def element_extent(self, name: str) -> float:
        """The range of an element's deflection worth sampling (m)."""
        return self.length

    @property
    def rest_foot(self) -> np.ndarray:
        """Foot position at the unloaded rest pose (m, body frame)."""
        return self.foot.copy()

    # -- singular poses ------------------------------------------------------------
    def pose_angles(self, r) -> dict[str, float]:
        """Angles (rad, 0 to π/2) from each singular alignment at foot position ``r``.

        Keys: ``secondaries`` (u₂ ∥ u₃), ``secondary2_primary`` and
        ``secondary3_primary`` (u_k ∥ e_S: the secondary pushes along the
        primary), ``plane`` (u₂, u₃ and e_S in one plane). A secondary of zero
        length gives 0 for every angle it enters.
        """
        r = vector("r", r, (3,))
        L, e_S, _, spans = numeric_geometry(r, self.h1, self.h2, self.h3, self.outer_length)
        short = [np.linalg.norm(s) <= ZERO_LENGTH * self.length for s in spans]
        u = [np.zeros(3) if z else s / np.linalg.norm(s) for s, z in zip(spans, short)]
        across = [uk - (uk @ e_S) * e_S for uk in u]                   # parts ⊥ e_S
        return dict(secondaries=angle_from_parallel(u[0], u[1]),
                    secondary2_primary=angle_from_parallel(u[0], e_S),
                    secondary3_primary=angle_from_parallel(u[1], e_S),
                    plane=angle_from_parallel(across[0], across[1]))

    def check_pose(self, r) -> float:
        """The smallest angle (rad) of :meth:`pose_angles` at foot position ``r``.

        A scene check compares it with :data:`SINGULAR_ANGLE` (or its own
        bound) to refuse poses a run meets; 0 means singular.
        """
        return min(self.pose_angles(r).values())

    def _check_rest_pose(self):
        _, _, Q, spans = numeric_geometry(self.foot, self.h1, self.h2, self.h3,
                                           self.outer_length)
        for k, span in zip((2, 3), spans):
            if np.linalg.norm(span) <= ZERO_LENGTH * self.length:
                raise ValueError(f"`h{k}` = {getattr(self, f'h{k}').tolist()} is at the pin Q = "
                                 f"{Q.tolist()}: secondary {k} has zero length; move `h{k}` "
                                 "off the primary or change `outer_length`.")
        angles, limit = self.pose_angles(self.foot), np.rad2deg(SINGULAR_ANGLE)
        fixes = dict(
            secondaries="the two secondaries are collinear; move `h2` or `h3` sideways so "
                        "that they meet Q from different directions",
            secondary2_primary="secondary 2 lies along the primary's axis; move `h2` off "
                               "the primary's line",
            secondary3_primary="secondary 3 lies along the primary's axis; move `h3` off "
                               "the primary's line",
            plane="the secondaries and the primary lie in one plane, so nothing resists "
                  "the foot across it; move `h2` or `h3` out of that plane")
        for key, angle in angles.items():
            if angle < SINGULAR_ANGLE:
                raise ValueError(f"singular rest pose: {fixes[key]} (angle "
                                 f"{np.rad2deg(angle):.3g}° < {limit:g}°).")

    # -- symbolic model ---------------------------------------------------------
    def _dm_geometry(self, r):
        return (r, ca.DM(self.h1), ca.DM(self.h2), ca.DM(self.h3), self.outer_length)

    # -- geometry as inputs (symcushion.layout.params.TRIPOD_GEOMETRY_FIELDS) -----------------
    geometry_fields = TRIPOD_GEOMETRY_FIELDS

    @property
    def geometry_values(self) -> np.ndarray:
        """The geometry block of ``p`` (13): h₁, h₂, h₃, the rest foot (m) and ℓ_o (m)."""
        return np.concatenate([self.h1, self.h2, self.h3, self.foot, [self.outer_length]])

    def _p_size(self, geometry: str) -> int:
        if geometry not in ("constant", "input"):
            raise ValueError(f"`geometry` must be 'constant' or 'input', got {geometry!r}.")
        return len(self.param_names) + (GEOMETRY_SIZE if geometry == "input" else 0)

    def _geometry_of(self, p=None) -> dict:
        """h1, h2, h3, foot, outer_length and the rest lengths: the leg's numbers, or
        expressions of the geometry block when ``p`` carries one after the curves'."""
        n = len(self.param_names)
        if p is None or p.shape[0] == n:
            return dict(h1=ca.DM(self.h1), h2=ca.DM(self.h2), h3=ca.DM(self.h3),
                        foot=ca.DM(self.foot), outer_length=self.outer_length,
                        rest_lengths=ca.DM(self.rest_lengths))
        if p.shape[0] != n + GEOMETRY_SIZE:
            raise ValueError(f"`p` must have {n} entries (curve parameters) or "
                             f"{n + GEOMETRY_SIZE} (and the geometry), got {p.shape[0]}.")
        G = dict(h1=p[n:n + 3], h2=p[n + 3:n + 6], h3=p[n + 6:n + 9], foot=p[n + 9:n + 12],
                 outer_length=p[n + 12])
        G["rest_lengths"] = tripod_rest_lengths(G["foot"], G["h1"], G["h2"], G["h3"],
                                                G["outer_length"])
        return G

    def rest_foot_expr(self, p):
        """The rest foot as a CasADi expression of ``p`` (a constant without a block)."""
        return self._geometry_of(p)["foot"]

    def check_geometry_block(self, block, where=""):
        """Refuse a geometry block of ``p`` the leg's Functions cannot take: the
        constructor's checks (finite points, 0 < ℓ_o < L₀, no singular rest pose)."""
        block = np.asarray(block, dtype=float).ravel()
        try:
            InvertedTripod(block[0:3], block[3:6], block[6:9], block[9:12], block[12],
                           *(el.curve for el in self.elements))
        except (ValueError, TypeError) as exc:
            raise ValueError(f"{where}{exc}") from None

    def geometry(self, r, p=None):
        """Geometry at foot position ``r`` (CasADi): :func:`tripod_geometry_expr`
        plus ``q`` (3), ``delta_S`` and ``stroke_secondary`` (2), in m; the leg's own
        geometry, or the one in ``p``'s geometry block."""
        G = self._geometry_of(p)
        g = tripod_geometry_expr(r, G["h1"], G["h2"], G["h3"], G["outer_length"])
        g["q"] = tripod_deflections(g, G["rest_lengths"])
        g["delta_S"], g["stroke_secondary"] = g["q"][0], g["q"][1:]
        return g

    def _theta(self, el: _Element, p):
        return p[el.offset:el.offset + el.curve.n_params] if el.curve.tunable else None

    def element_forces(self, r, v, p, r_branch=None):
        """f = (S, T₂, T₃) (N), each element's curve at its deflection q_i.

        ``r`` and ``r_branch`` (default ``r``) must be CasADi symbols: the rate
        q̇ = J(r_branch) v and the deflection at ``r_branch`` select the
        loading or unloading branch.
        """
        q = self.geometry(r, p)["q"]
        r_branch = r if r_branch is None else r_branch
        q_branch = self.geometry(r_branch, p)["q"]
        rate = ca.jacobian(q_branch, r_branch) @ v
        return ca.vertcat(*[el.curve.force(q[i], rate[i], self._theta(el, p),
                                           branch_x=q_branch[i])
                            for i, el in enumerate(self.elements)])

    def force_expr(self, r, v, p, r_branch=None):
        """P = J(r)ᵀ f (N), (T1): virtual work of the three elements.

        ``r`` must be a CasADi symbol (J = ∂q/∂r is taken by ``casadi.jacobian``).
        """
        J = ca.jacobian(self.geometry(r, p)["q"], r)
        return J.T @ self.element_forces(r, v, p, r_branch)            # (T1)

    # -- the memory law (symcushion.legs.absorber) ---------------------------------------
    def deflections_expr(self, r, p=None):
        """q = (δ_S, δ₂, δ₃) at foot ``r`` (m), with the geometry of ``p`` if it has one."""
        return self.geometry(r, p)["q"]

    def memory_force_expr(self, r, sets, p, r_regime=None, rate=None):
        """P = J(r)ᵀ f (T1) with the elements on the memory law (A1) at ``sets`` (3);
        ``r_regime`` picks each element's regime, ``rate`` = (a, b) the dampers'
        rates a·q + b (A3)."""
        q = self.geometry(r, p)["q"]
        q_regime = None if r_regime is None else self.geometry(r_regime, p)["q"]
        f = ca.vertcat(*[absorber.element_force(
            el.curve, q[i], sets[i], self._theta(el, p),
            None if q_regime is None else q_regime[i],
            None if rate is None else (rate[0], rate[1][i]))
            for i, el in enumerate(self.elements)])
        return ca.jacobian(q, r).T @ f                                  # (T1)

    def next_sets_expr(self, r, sets, p, rate=None):
        """The elements' sets after the foot reached ``r`` (A2), (A5)."""
        q = self.geometry(r, p)["q"]
        return ca.vertcat(*[absorber.element_next_set(
            el.curve, q[i], sets[i], self._theta(el, p),
            None if rate is None else (rate[0], rate[1][i]))
            for i, el in enumerate(self.elements)])

    def axial_lower_bound_expr(self, x, p):
        """lo(x) of (A1) for the primary, the loading curve it crushes along (N), or None
        where it keeps no set or its band has no lower bound."""
        el = self.elements[0]
        if not el.curve.has_memory:
            return None
        lo, _ = absorber.band(el.curve, x, self._theta(el, p))
        return lo

    def axial_elastic_line_expr(self, x, s, rate, p):
        """The primary's elastic line through its set ``s`` (N): k_e (x − s) + c·ė (A1),
        (A5), ė = ``rate`` its elastic deflection's rate (m/s)."""
        el = self.elements[0]
        return elastic_line(el.curve, x, s, rate, self._theta(el, p))

    def axial_band_force_expr(self, r, P, rate, p):
        """The primary's force (A1), (A5) that the foot force ``P`` (N, body axes) carries
        at foot ``r``, f of P = Jᵀ f (T1), less its end stop and its orifice damper at
        the elastic deflection's rate ``rate`` (N)."""
        q = self.geometry(r, p)["q"]
        el = self.elements[0]
        return band_part(el.curve, q[0], ca.solve(ca.jacobian(q, r).T, P)[0], rate,
                         self._theta(el, p))

    def free_foot_expr(self, sets, p, x_start, mean_rate, dt):
        """A free foot at the end of a step (body frame): each element at its free
        deflection, or relaxing towards it behind a damper (A4); the foot where the
        three deflections meet, by Newton's method from the rest foot."""
        target = ca.vertcat(*[absorber.relaxed_deflection(
            el.curve, x_start[i], sets[i], mean_rate[i], dt, self._theta(el, p))
            for i, el in enumerate(self.elements)])
        r = ca.SX.sym("r", 3)
        q = self.geometry(r, p)["q"]
        newton = r - ca.solve(ca.jacobian(q, r), q - target)
        foot = self._geometry_of(p)["foot"]
        for _ in range(FREE_FOOT_NEWTON_STEPS):
            foot = ca.substitute(newton, r, foot)
        return foot

    def memory_functions(self, geometry: str = "constant") -> dict[str, ca.Function]:
        """The memory law's named Functions, as ``HingedStrut.memory_functions``."""
        return cached_memory_functions(self, geometry)

    # -- Functions --------------------------------------------------------------
    def functions(self, geometry: str = "constant") -> dict[str, ca.Function]:
        """The named CasADi Functions of this leg (built once per ``geometry``, cached).

        ``geometry="input"``: ``p`` ends with the geometry block
        (:attr:`geometry_values`) and the geometry Functions take ``p`` too.

        Returns
        -------
        dict
            ``tripod_geometry(r) -> L, delta_S, e_S, Q, stroke_secondary``,
            ``tripod_element_forces(r, v, p) -> S, T``,
            ``tripod_force(r, v, p) -> P`` (T1) and
            ``tripod_stiffness(r, v, p) -> Dp`` (``casadi.jacobian`` of P with
            the branches held), and the leg-scheme interface
            ``strut_geometry``, ``strut_force``, ``strut_stiffness``: the same
            expressions under the strut's names. ``r``: foot position (3, m,
            body frame); ``v``: foot velocity relative to the body (3, m/s;
            selects the branches); ``p``: tunable parameters
            (``param_names``), empty when all curves are numeric.

        Notes
        -----
        At r = h₁ or with a secondary of zero length these raw Functions
        return NaN; :meth:`force` and :meth:`stiffness` check their inputs.
        """
        if geometry not in self._functions:
            self._functions[geometry] = self._build_functions(geometry)
        return self._functions[geometry]

    def _build_functions(self, geometry):
        r, v = ca.SX.sym("r", 3), ca.SX.sym("v", 3)
        p = ca.SX.sym("p", self._p_size(geometry))
        r_branch = ca.SX.sym("r_branch", 3)
        g = self.geometry(r, p)
        f = self.element_forces(r, v, p)
        P = self.force_expr(r, v, p)
        # ∂P/∂r with the branch test frozen at r_branch, as HingedStrut does:
        # the smooth blend weight's derivative is not a stiffness.
        Dp = ca.substitute(ca.jacobian(self.force_expr(r, v, p, r_branch), r), r_branch, r)
        geo_out = [g["L"], g["delta_S"], g["e_S"], g["Q"], g["stroke_secondary"]]
        geo_names = ["L", "delta_S", "e_S", "Q", "stroke_secondary"]
        names_in = ["r", "v", "p"]
        geo_in, geo_in_names = ([r], ["r"]) if geometry == "constant" else ([r, p], ["r", "p"])
        out = {}
        for prefix in ("tripod", "strut"):
            out[f"{prefix}_geometry"] = ca.Function(f"{prefix}_geometry", geo_in, geo_out,
                                                    geo_in_names, geo_names)
            out[f"{prefix}_force"] = ca.Function(f"{prefix}_force", [r, v, p], [P],
                                                 names_in, ["P"])
            out[f"{prefix}_stiffness"] = ca.Function(f"{prefix}_stiffness", [r, v, p], [Dp],
                                                     names_in, ["Dp"])
        out["tripod_element_forces"] = ca.Function("tripod_element_forces", [r, v, p],
                                                   [f[0], f[1:]], names_in, ["S", "T"])
        return out
