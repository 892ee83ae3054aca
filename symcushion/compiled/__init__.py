"""The step as C: which Functions are generated, the sources, the compiler and its
build cache, loading builds back, the standalone program and the FMU.

This folder owns turning named Functions into C and libraries. It must not change
what any Function computes.
"""
