"""Peer simulators of symcushion's scenes, for comparisons.

Two usual alternatives to symcushion's contact step, built from the same
:class:`~symcushion.model.scene.Scene` and returning the same :class:`PeerRun`:

* :func:`penalty_simulate` — light feet on stiff penalty springs with
  regularised Coulomb friction, the strut's own force law, CVODES (BDF);
* :func:`mujoco_simulate` — a MuJoCo model (optional ``peers`` extra:
  ``pip install symcushion[peers]``).

This module only re-exports; see docs/peers.md.
"""
from symcushion.peers.mujoco_model import build_mjcf, mujoco_available, mujoco_simulate
from symcushion.peers.penalty import penalty_simulate
from symcushion.peers.run import PeerRun, leg_kinematics, rebound_speed, trajectory_deflection

__all__ = ["PeerRun", "penalty_simulate", "mujoco_simulate", "mujoco_available", "build_mjcf",
           "rebound_speed", "trajectory_deflection", "leg_kinematics"]
