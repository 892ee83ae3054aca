"""What is simulated: the scene as data (body, legs, obstacles, μ, g), read from
TOML with every field checked, the obstacles' geometry, the body's placement.

This folder owns the model a step is built from. It must not build Functions or
run anything.
"""
