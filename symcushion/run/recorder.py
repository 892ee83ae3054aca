"""The recorder of a run: what happens to each block of rows the time loop hands over.

A :class:`Recorder` receives the times, states and outputs of a block of
steps and detects the legs' events (touchdown, lift-off, stick/slip), feeds
an optional run monitor (its findings are raised as :class:`RunWarning`),
tracks the peaks, streams the rows to a
:class:`~symcushion.run.results.ResultWriter`, keeps a thinned copy for the
figures, sums the energy terms and shows progress; at the end it assembles
the :class:`~symcushion.run.trajectory.Trajectory`.

This module owns that bookkeeping. It must not step the model (the time
loops of ``symcushion.run.time_loops`` do), choose a step, or format files.
"""
from __future__ import annotations

import sys
import warnings

import numpy as np

from symcushion.run.error_control import PeakTracker
from symcushion.layout.vectors import MODES, output_layout, state_layout
from symcushion.run.trajectory import Trajectory, assemble_trajectory, initial_output

__all__ = ["Recorder", "RunWarning", "MAX_EVENTS", "ENERGY_FIELDS"]


#: Events (touchdowns, lift-offs, stick/slip switches) recorded in full; a
#: chattering run beyond this counts the rest in ``info['events_dropped']``.
MAX_EVENTS = 10_000

#: The per-step work outputs summed into run.json's ``energy`` totals.
ENERGY_FIELDS = ("work_axial", "work_bending", "work_friction")


class RunWarning(UserWarning):
    """A finding of a run monitor, raised through :mod:`warnings` by the API."""


class Recorder:
    """Receives blocks of rows: events, monitor, streaming, thinning, progress."""

    def __init__(self, model, x0, sink, monitor, progress, keep_rows):
        self.model, self.sink, self.monitor = model, sink, monitor
        self.keep_rows = keep_rows
        self.events, self.warnings, self.dropped = [], [], 0
        self.energy = None
        self.kept, self.kept_idx, self.stride, self.count = [], [], 1, 0
        self.last_row = None
        self.peaks = PeakTracker(model.n_legs, model.scene.gravity)
        from tqdm.auto import tqdm

        self.bar = tqdm(total=model.scene.duration, unit="s", file=sys.stderr, leave=False,
                        disable=None if progress else True, desc=model.scene.name,
                        bar_format="{desc}: {percentage:3.0f}%|{bar}| t = {n:.3f}/{total:g} s "
                                   "[{elapsed}<{remaining}]")
        self.progress = progress
        y0 = initial_output(model, x0)
        self._rows(np.zeros(1), x0[:, None], y0[:, None])

    def _leg_flags(self, Y):
        yl = output_layout(self.model.n_legs)
        return yl.legs(Y, "in_contact") > 0.5, np.rint(yl.legs(Y, "mode")).astype(int)

    def _events(self, t, Y):
        contact, mode = self._leg_flags(Y)
        if self.count:
            contact = np.column_stack([self.prev[0], contact])
            mode = np.column_stack([self.prev[1], mode])
            t = np.concatenate([[np.nan], t])
        self.prev = (contact[:, -1], mode[:, -1])
        found = []
        for j in range(contact.shape[0]):
            c, m = contact[j], mode[j]
            for k in np.nonzero(c[1:] != c[:-1])[0] + 1:
                found.append((t[k], "touchdown" if c[k] else "lift-off", j))
            stays = c[1:] & c[:-1]
            for k in np.nonzero(stays & (m[1:] != m[:-1]) & (m[1:] > 0) & (m[:-1] > 0))[0] + 1:
                found.append((t[k], MODES.get(int(m[k]), "unknown"), j))
        for time_, kind, leg in sorted(found):
            if len(self.events) < MAX_EVENTS:
                self.events.append({"time": float(time_), "kind": kind, "leg": int(leg)})
            else:
                self.dropped += 1

    def _monitor(self, t, X, Y):
        for finding in self.monitor.check(t, X, Y) or []:
            when = getattr(finding, "time", None)      # the finding's own time, not the block's
            self.warn({"time": float(t[-1] if when is None else when), "kind": "warning",
                       "severity": str(getattr(finding, "severity", "warning")),
                       "message": str(finding.message), "details": finding.to_dict()})

    def warn(self, entry: dict, stacklevel: int = 5):
        """Record a warning of the run (a dict with ``time`` and ``message``) and show it."""
        self.warnings.append(entry)
        if len(self.events) < MAX_EVENTS:
            self.events.append(entry)
        text = f"t = {entry['time']:.4g} s: {entry['message']}"
        if self.progress:
            label = "error" if entry.get("severity") == "error" else "warning"
            self.bar.write(f"{label}: {text}", file=sys.stderr)
        else:
            warnings.warn(text, RunWarning, stacklevel=stacklevel)

    def _energy(self, Y):
        """Add the block's per-leg work (axial, bending, friction; J) to the run's totals."""
        yl = output_layout(self.model.n_legs)
        block = np.array([yl.legs(Y, f).sum(axis=-1) for f in ENERGY_FIELDS])
        self.energy = block if self.energy is None else self.energy + block

    def energy_totals(self) -> dict:
        """The run's energy per leg (J): on its axial element, on its hinge springs,
        dissipated by friction (``layout.LEG_OUT_FIELDS``); sums of the steps' work."""
        totals = np.zeros((len(ENERGY_FIELDS), self.model.n_legs)) if self.energy is None \
            else self.energy
        return {f"leg{j}": {f.replace("work_", "") + "_J": float(totals[i, j])
                            for i, f in enumerate(ENERGY_FIELDS)}
                for j in range(self.model.n_legs)}

    def _rows(self, t, X, Y):
        rows = np.column_stack([t, X.T, Y.T])
        self._energy(Y)
        if not np.all(np.isfinite(state_layout(self.model.n_legs).get(X, "position"))):
            raise FloatingPointError(
                f"the simulation produced non-finite body positions near t = {t[0]:.4g} s; "
                "reduce `dt` or check the scene.")
        self._events(t, Y)
        self.peaks.update(Y, t)
        if self.monitor is not None and self.count:
            self._monitor(t, X, Y)
        if self.sink is not None:
            self.sink.append(rows)
        idx = self.count + np.arange(len(rows))
        self.count += len(rows)
        self.last_row = rows[-1]
        if self.keep_rows is None:
            self.kept.append(rows)
            return
        mask = idx % self.stride == 0
        self.kept.append(rows[mask])
        self.kept_idx.append(idx[mask])
        if sum(len(k) for k in self.kept) > 2 * self.keep_rows:
            self.stride *= 2
            rows, idx = np.concatenate(self.kept), np.concatenate(self.kept_idx)
            mask = idx % self.stride == 0
            self.kept, self.kept_idx = [rows[mask]], [idx[mask]]

    def block(self, t, X, Y):
        """Record steps: t (B,) s, X (nx, B) states and Y (ny, B) outputs after each step."""
        self._rows(np.asarray(t, float), np.asarray(X, float), np.asarray(Y, float))
        self.bar.update(float(t[-1]) - self.bar.n)

    def finish(self, gravity) -> Trajectory:
        self.bar.close()
        rows = np.concatenate(self.kept)
        # a thinned run always ends on its last row, even where the last block kept none
        # (row 0 is always kept, so some block holds a kept index)
        if self.keep_rows is not None and np.concatenate(self.kept_idx)[-1] != self.count - 1:
            rows = np.vstack([rows, self.last_row])
        traj = assemble_trajectory(rows, self.model.n_legs, gravity)
        traj.info = {"events": self.events, "warnings": self.warnings,
                     "events_dropped": self.dropped, "rows": self.count,
                     "energy": self.energy_totals()}
        if self.keep_rows is not None:
            traj.info["stride"] = self.stride
        return traj
