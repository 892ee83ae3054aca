"""Rigid obstacles: signed distance, unit normal and projection onto the surface.

§3 of the paper replaces the obstacle near each foot by its tangent plane at
every step. An obstacle here therefore supplies, as CasADi expressions of a
world point x:

* ``distance(x)`` — signed distance (m), positive outside; for curved
  implicit surfaces and terrain the first-order estimate φ/|∇φ|;
* ``normal(x)`` — unit normal out of the obstacle at the surface point
  nearest x;
* ``project(x)`` — a point on the surface near x (the foot's contact point
  after a step along the tangent plane).

Each takes an optional ``pad`` a ≥ 0 (m, a float or a CasADi scalar): the
same three for the obstacle's *offset surface* at distance a, on which the
centre of a footpad of radius a slides (docs/footpads.md). The offset is
exact for a plane (the plane moved by a along its normal) and a sphere
(radius R + a); for an implicit surface and a terrain it is the zero set of

    ψ(x) = φ(x) − a |∇φ(x)|,

exact where φ is a signed distance (|∇φ| = 1) or a plane's height field,
and within O(a²κ) of the true offset where the surface bends (κ its
curvature). ``pad = 0`` (a Python number) builds the expressions of a point
foot, node for node.

This module owns obstacle geometry only; it knows nothing of legs or contact.
"""
from __future__ import annotations

from typing import Callable, Sequence

import casadi as ca
import numpy as np

from symcushion.validation import direction, real, vector

__all__ = ["Obstacle", "Plane", "Sphere", "ImplicitSurface", "Terrain", "PROJECTION_ITERS",
           "closest_obstacle"]

#: Newton steps x ← x − φ ∇φ/|∇φ|² used to project onto an implicit surface or
#: terrain. A foot leaves the surface by O(|δ|²κ) in one time step (κ the
#: curvature), so two steps bring it back to round-off for any smooth surface
#: at the step sizes used here (quadratic convergence from 1e-6 m).
PROJECTION_ITERS = 2

#: Guard of |∇φ|² in projections and normals (a critical point of φ has no
#: normal; the guard only keeps the branch not taken finite).
_GRAD_GUARD = 1e-300


def _padded(pad) -> bool:
    """False for a point foot given as a Python or NumPy zero: its expressions are
    built without a pad term, so a scene without pads keeps its graph node for node.
    A CasADi symbol is a pad whatever its value."""
    if isinstance(pad, (int, float, np.integer, np.floating)) and not isinstance(pad, bool):
        return pad != 0
    return True


def _vec3(name, value):
    return vector(name, value, (3,))


class Obstacle:
    """Base class: a rigid, fixed obstacle."""

    kind = "obstacle"

    def distance(self, x, pad=0.0):  # pragma: no cover - abstract
        raise NotImplementedError

    def normal(self, x, pad=0.0):  # pragma: no cover - abstract
        raise NotImplementedError

    def project(self, x, pad=0.0):  # pragma: no cover - abstract
        raise NotImplementedError


class Plane(Obstacle):
    """The half-space below a plane through ``point`` with outward ``normal``."""

    kind = "plane"

    def __init__(self, point=(0.0, 0.0, 0.0), normal=(0.0, 0.0, 1.0)):
        self.point = _vec3("point", point)
        self.n = direction("normal", normal)

    @classmethod
    def inclined(cls, angle, point=(0.0, 0.0, 0.0)):
        """A plane tilted by ``angle`` (rad) about the y axis: it descends along +x."""
        angle = real("angle", angle, unit="rad")
        return cls(point, (np.sin(angle), 0.0, np.cos(angle)))

    def distance(self, x, pad=0.0):
        d = ca.dot(ca.DM(self.n), x - ca.DM(self.point))
        return d - pad if _padded(pad) else d                   # the plane moved by a

    def normal(self, x, pad=0.0):
        return ca.DM(self.n) + 0 * x

    def project(self, x, pad=0.0):
        return x - self.distance(x, pad) * ca.DM(self.n)


class Sphere(Obstacle):
    """A solid ball (a dome, the hemisphere of Figs. 3–4) of given centre and radius."""

    kind = "sphere"

    def __init__(self, center=(0.0, 0.0, 0.0), radius=1.0):
        self.center = _vec3("center", center)
        self.radius = real("radius", radius, positive=True, unit="m")

    def _offset(self, x):
        d = x - ca.DM(self.center)
        dist = ca.norm_2(d)
        # at the centre the direction is undefined: use +z (never reached by a foot)
        safe = ca.if_else(dist > 0, dist, 1.0)
        direction = ca.if_else(dist > 0, d / safe, ca.DM([0, 0, 1]))
        return dist, direction

    def _radius(self, pad):
        """R, or R + a with a pad: the offset of a ball is the concentric ball."""
        return self.radius + pad if _padded(pad) else self.radius

    def distance(self, x, pad=0.0):
        return ca.norm_2(x - ca.DM(self.center)) - self._radius(pad)

    def normal(self, x, pad=0.0):
        return self._offset(x)[1]

    def project(self, x, pad=0.0):
        return ca.DM(self.center) + self._radius(pad) * self._offset(x)[1]


class ImplicitSurface(Obstacle):
    """The region φ(x) ≤ 0 of a smooth function φ given as CasADi code.

    Parameters
    ----------
    phi : callable
        ``phi(x)`` with x a CasADi 3-vector, returning a scalar expression;
        negative inside the obstacle. The normal is ∇φ/|∇φ| (``casadi.gradient``);
        the projection is :data:`PROJECTION_ITERS` Newton steps
        x ← x − φ ∇φ/|∇φ|², which for a foot displaced by a tangent-plane step
        lands on the surface to round-off.
    """

    kind = "implicit"

    def __init__(self, phi: Callable):
        if not callable(phi):
            raise TypeError(f"`phi` must be a callable φ(x) of a CasADi 3-vector, got {phi!r}.")
        x = ca.SX.sym("x", 3)
        try:
            expr = phi(x)
        except Exception as exc:  # report what the user's function did
            raise TypeError(f"`phi` failed on a CasADi SX 3-vector: {exc}") from exc
        if not isinstance(expr, ca.SX) or expr.numel() != 1:
            raise TypeError("`phi` must return a scalar CasADi expression of its argument.")
        grad = ca.gradient(expr, x)
        self._phi = ca.Function("phi", [x], [expr])
        self._grad = ca.Function("grad_phi", [x], [grad])
        self._offset_functions = None   # ψ and ∇ψ of a pad, built at its first use

    @property
    def functions(self) -> dict:
        """``phi(x) -> φ`` and ``grad_phi(x) -> ∇φ``: CasADi Functions of a 3-vector (m)."""
        return {"phi": self._phi, "grad_phi": self._grad}

    def _offset(self):
        """``phi_offset(x, a) -> ψ`` and ``grad_phi_offset(x, a) -> ∇ψ`` of the offset
        surface ψ = φ − a|∇φ| = 0 (its gradient carries φ's Hessian, by AD)."""
        if self._offset_functions is None:
            x, a = ca.SX.sym("x", 3), ca.SX.sym("a")
            grad = self._grad(x)
            psi = self._phi(x) - a * ca.sqrt(ca.dot(grad, grad))
            self._offset_functions = (
                ca.Function("phi_offset", [x, a], [psi], ["x", "a"], ["psi"]),
                ca.Function("grad_phi_offset", [x, a], [ca.gradient(psi, x)], ["x", "a"],
                            ["grad_psi"]))
        return self._offset_functions

    def _value(self, x, pad):
        """φ(x), or ψ(x) of the offset surface at distance ``pad``."""
        return self._offset()[0](x, pad) if _padded(pad) else self._phi(x)

    def _grad_safe(self, x, pad=0.0):
        g = self._offset()[1](x, pad) if _padded(pad) else self._grad(x)
        g2 = ca.dot(g, g)
        return g, ca.if_else(g2 > _GRAD_GUARD, g2, 1.0)

    def distance(self, x, pad=0.0):
        g, g2 = self._grad_safe(x, pad)
        return self._value(x, pad) / ca.sqrt(g2)

    def normal(self, x, pad=0.0):
        g, g2 = self._grad_safe(self.project(x, pad), pad)
        return g / ca.sqrt(g2)

    def project(self, x, pad=0.0):
        for _ in range(PROJECTION_ITERS):
            g, g2 = self._grad_safe(x, pad)
            x = x - self._value(x, pad) * g / g2
        return x


class Terrain(ImplicitSurface):
    """A height field z = h(x, y) from a grid, interpolated by a cubic B-spline.

    Parameters
    ----------
    x, y : sequence of float
        Strictly increasing grid lines (m), at least 4 each (cubic spline).
    heights : array_like, shape (len(x), len(y))
        h at the grid points (m).
    """

    kind = "terrain"

    def __init__(self, x: Sequence[float], y: Sequence[float], heights):
        xs = vector("x", x, (None,), what="grid lines")
        ys = vector("y", y, (None,), what="grid lines")
        H = vector("heights", heights, (xs.size, ys.size), what="heights")
        for name, g in (("x", xs), ("y", ys)):
            if g.size < 4 or np.any(np.diff(g) <= 0) or not np.all(np.isfinite(g)):
                raise ValueError(f"`{name}` must hold at least 4 strictly increasing finite "
                                 f"grid lines, got {g.tolist()}.")
        if H.shape != (xs.size, ys.size) or not np.all(np.isfinite(H)):
            raise ValueError(f"`heights` must be a finite array of shape ({xs.size}, {ys.size}), "
                             f"got shape {H.shape}.")
        self.grid = (xs, ys)
        self.heights = H
        self._h = ca.interpolant("terrain_height", "bspline", [xs, ys], H.ravel(order="F"))
        super().__init__(lambda p: p[2] - self._h(p[:2]))

    def height(self, x, y):
        """h(x, y) as a float (m)."""
        return float(self._h([x, y]))

    @classmethod
    def crater(cls, radius=2.0, depth=0.3, rim=0.1, extent=6.0, cells=49):
        """A smooth crater: a bowl of given radius and depth with a raised rim."""
        radius = real("radius", radius, positive=True, unit="m")
        depth, rim = real("depth", depth, unit="m"), real("rim", rim, unit="m")
        g = np.linspace(-extent / 2, extent / 2, cells)
        X, Y = np.meshgrid(g, g, indexing="ij")
        rho = np.hypot(X, Y) / radius
        H = -depth * np.exp(-2 * rho ** 2) + rim * np.exp(-8 * (rho - 1) ** 2)
        return cls(g, g, H)

    @classmethod
    def slope_with_rocks(cls, angle=0.1, rocks=((0.5, 0.3, 0.08, 0.15),), extent=6.0,
                         cells=61):
        """A plane descending along +x by ``angle`` (rad) with Gaussian rocks.

        ``rocks`` holds (x, y, height, radius) tuples in metres.
        """
        angle = real("angle", angle, unit="rad")
        if not abs(angle) < np.pi / 2:
            raise ValueError(f"`angle` must be within (-pi/2, pi/2) rad, got {angle!r}.")
        g = np.linspace(-extent / 2, extent / 2, cells)
        X, Y = np.meshgrid(g, g, indexing="ij")
        H = -np.tan(angle) * X
        for x0, y0, h0, r0 in rocks:
            H += h0 * np.exp(-((X - x0) ** 2 + (Y - y0) ** 2) / (2 * r0 ** 2))
        return cls(g, g, H)


def closest_obstacle(obstacles: Sequence[Obstacle], x, pad=0.0):
    """Distance, normal and projection of x for the nearest of several obstacles.

    Branch-free: every obstacle is evaluated and the one with the smallest
    signed distance is selected with ``casadi.if_else``. With ``pad`` a (m),
    the obstacles' offset surfaces at distance a: x is the centre of a
    footpad of radius a, ``dist`` its clearance and ``proj`` where its centre
    sits on the offset surface (the contact point is ``proj − a·normal``).
    """
    if not obstacles:
        raise ValueError("`obstacles` is empty; a scene needs at least one obstacle.")
    best = obstacles[0]
    dist, normal, proj = best.distance(x, pad), best.normal(x, pad), best.project(x, pad)
    for ob in obstacles[1:]:
        d = ob.distance(x, pad)
        nearer = d < dist
        normal = ca.if_else(nearer, ob.normal(x, pad), normal)
        proj = ca.if_else(nearer, ob.project(x, pad), proj)
        dist = ca.if_else(nearer, d, dist)
    return dist, normal, proj
