"""What is simulated, and the three parts a scene groups: the model (body, legs,
obstacles, μ, g), the scheme that steps it and its time grid (:mod:`.parts`); the
scene as data, read from TOML with every field checked; the obstacles' geometry;
the body and its placement.

This folder owns the model a step is built from and the choices it is built
with. It must not build Functions or run anything.
"""
