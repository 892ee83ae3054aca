"""How a touchdown is stepped: the state and output layouts, the body's velocity
Verlet, the feet's contact pass, the event rules, and ``build_model``, which
composes them into the step Function ``touchdown_step(x, p, dt)``.

This folder owns the step's composition. It must not run time loops, write files
or derive a contact step or a force law of its own.
"""
