"""The contact step of §1: one massless leg's foot against a rigid obstacle under
Coulomb friction, as pure expressions under named CasADi Functions.

This folder owns the step's three methods (the printed step (1.8)-(1.15), the
robust one, the exact implicit Coulomb step), their guards, the quartic and the
second-order slip rule. It must not know about struts, bodies, scenes or time
grids. This module only re-exports the public API of :mod:`.solve`, so that
``from symcushion.contact import solve_contact`` reads as before.
"""
from symcushion.contact.solve import *  # noqa: F401,F403
from symcushion.contact.solve import __all__  # noqa: F401
