"""One leg's force law: the force curves of its elements, the absorbers' memory law,
the hinged strut of (2.1) and the inverted tripod, with D_p by AD.

This folder owns what a leg pushes back with for a given foot position and
element state. It must not know about contact, the body, scenes or time steps.
"""
