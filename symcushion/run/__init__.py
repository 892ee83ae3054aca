"""Running a scene: the checks before and during a run, the driver and its time
loops, error control, the recorded rows, trajectories and the result folder.

This folder owns what happens between a built step and the files a run leaves.
It must not derive physics (the step comes from :mod:`symcushion.scheme`).
"""
