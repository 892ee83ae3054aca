"""Progress of the Ipopt solve: a CasADi callback called once per iteration.

Owns :class:`IterationCallback`, which hands Ipopt's iterate to the
problem's progress handler. It must not change the iterate.
"""
from __future__ import annotations

import casadi as ca
import numpy as np

__all__: list = []


class IterationCallback(ca.Callback):
    """Ipopt's intermediate callback: hands (x, f, g) to a Python function."""

    def __init__(self, nx, ng, handler):
        ca.Callback.__init__(self)
        self.nx, self.ng, self.handler = nx, ng, handler
        self.construct("design_iteration", {})

    def get_n_in(self):
        return ca.nlpsol_n_out()

    def get_n_out(self):
        return 1

    def get_name_in(self, i):
        return ca.nlpsol_out(i)

    def get_name_out(self, i):
        return "ret"

    def get_sparsity_in(self, i):
        name = ca.nlpsol_out(i)
        if name == "f":
            return ca.Sparsity.scalar()
        if name in ("x", "lam_x"):
            return ca.Sparsity.dense(self.nx)
        if name in ("g", "lam_g"):
            return ca.Sparsity.dense(self.ng)
        return ca.Sparsity(0, 0)

    def eval(self, arg):
        names = [ca.nlpsol_out(i) for i in range(ca.nlpsol_n_out())]
        values = dict(zip(names, arg))
        self.handler(np.asarray(values["x"], dtype=float).ravel(), float(values["f"]),
                     np.asarray(values["g"], dtype=float).ravel())
        return [0]
