"""What every benchmark checks before it times: finite outputs equal to a reference.

A benchmark that times a computation on the wrong inputs measures nothing
about the simulator: a touchdown rollout called with a parameter vector of
zeros (no gravity, no mass, no inertia, μ = 0) runs the same instructions but
ends in NaN after the first step, and its timing is not that of a touchdown.
So every ``studies/bench_*.py`` runs what it is about to time once, with the
scene's own parameters, and hands the outputs to this module before the
clock starts:

* :func:`check_finite`: every entry finite;
* :func:`check_equal`: equal to the reference computation of the same scene
  (the uncompiled CasADi model, ``symcushion.simulate``, the Function on the
  VM), bit for bit or to round-off;
* :func:`check_rollout`: both, for a touchdown rollout against the
  uncompiled ``build_model(scene)`` rolled out with the same x0, p and Δt.

A failed check raises :class:`BenchmarkCheckError` naming the benchmark, what
was non-finite or different, and by how much. This module owns the checks
only; it times nothing and builds no physics.
"""
from __future__ import annotations

import numpy as np

from symcushion.scheme.touchdown import build_model

#: Relative tolerance of "equal to round-off": a few hundred ulps of the
#: largest entry, far below any modelling difference (the contact steps'
#: exact and printed forms differ by 1e-6 and more) and above the 1e-14 by
#: which two evaluation orders of the same graph (VM and gcc -O3 with
#: contraction) can differ.
ROUNDOFF_RTOL = 1e-12
#: Relative tolerance 0 asks for the same bits (NaN nowhere): where the docs
#: say the compiled code equals the CasADi VM bit for bit.
BITWISE = 0.0
#: Entries listed in an error message, at most.
SHOWN = 3


class BenchmarkCheckError(ValueError):
    """A benchmark's outputs are non-finite or differ from its reference."""


def _where(mask: np.ndarray) -> str:
    """The first SHOWN indices where ``mask`` holds, as text."""
    hits = np.argwhere(mask)[:SHOWN]
    return ", ".join(str(tuple(int(i) for i in hit)) for hit in hits)


def check_finite(bench: str, what: str, values) -> np.ndarray:
    """Raise unless every entry of ``values`` is finite; return them as an array.

    Parameters
    ----------
    bench : str
        The benchmark's name (``"bench_touchdown"``), for the message.
    what : str
        What the values are (``"Fig. 3 compiled rollout X"``).
    values : array_like

    Returns
    -------
    ndarray of float

    Raises
    ------
    BenchmarkCheckError
        When an entry is NaN or infinite, or ``values`` is empty.
    """
    array = np.asarray(values, dtype=float)
    if array.size == 0:
        raise BenchmarkCheckError(f"{bench}: {what} is empty; nothing to time.")
    bad = ~np.isfinite(array)
    if bad.any():
        raise BenchmarkCheckError(
            f"{bench}: {what} has {int(bad.sum())} non-finite of {array.size} entries "
            f"(first at index {_where(bad)}); the timed computation does not simulate the "
            "scene (are its parameters the scene's own, e.g. `model.default_p`?).")
    return array


def check_equal(bench: str, what: str, values, reference, *, rtol: float = ROUNDOFF_RTOL,
                reference_name: str = "the reference") -> float:
    """Raise unless ``values`` equal ``reference`` to ``rtol``; return the largest difference.

    Both must be finite (:func:`check_finite`) and of one shape. With
    ``rtol = 0`` (:data:`BITWISE`) the bits must agree; otherwise
    ``max |values - reference| <= rtol · max |reference|``.

    Parameters
    ----------
    bench, what : str
        As in :func:`check_finite`.
    values, reference : array_like
    rtol : float
        Relative tolerance, ≥ 0.
    reference_name : str
        What the reference is, for the message.

    Returns
    -------
    float
        max |values - reference| (0.0 when bit for bit).

    Raises
    ------
    BenchmarkCheckError
        When the shapes differ, an entry is not finite or the difference is
        larger than allowed.
    ValueError
        When ``rtol`` is negative or not finite.
    """
    if not (np.isfinite(rtol) and rtol >= 0):
        raise ValueError(f"`rtol` must be a finite number >= 0, got {rtol!r}.")
    got = check_finite(bench, what, values)
    ref = check_finite(bench, f"{reference_name} of {what}", reference)
    if got.shape != ref.shape:
        raise BenchmarkCheckError(f"{bench}: {what} has shape {got.shape}, {reference_name} "
                                  f"{ref.shape}.")
    diff = np.abs(got - ref)
    worst = float(diff.max())
    scale = float(np.abs(ref).max())
    if rtol == BITWISE:
        bad = got != ref
        allowed = "the same bits"
    else:
        bad = diff > rtol * scale
        allowed = f"rtol {rtol:g} of max |reference| = {scale:.3g}"
    if bad.any():
        raise BenchmarkCheckError(
            f"{bench}: {what} differs from {reference_name} in {int(bad.sum())} of "
            f"{got.size} entries by up to {worst:.3g} (relative {worst / max(scale, 1e-300):.3g}; "
            f"allowed: {allowed}), first at index {_where(bad)}.")
    return worst


def reference_rollout(scene, x0, p, dt: float, steps: int) -> tuple[np.ndarray, np.ndarray]:
    """(X, Y) of the uncompiled ``build_model(scene)`` rolled out ``steps`` steps."""
    X, Y = build_model(scene).rollout(steps)(x0, p, dt)
    return np.asarray(X, dtype=float), np.asarray(Y, dtype=float)


def check_rollout(bench: str, what: str, rollout, scene, x0, p, dt: float, steps: int, *,
                  rtol: float = BITWISE) -> tuple[np.ndarray, np.ndarray]:
    """Run ``rollout(x0, p, dt)`` once; raise unless it equals the uncompiled model's.

    Parameters
    ----------
    bench, what : str
        As in :func:`check_finite`.
    rollout : casadi.Function
        ``touchdown_rollout(x0, p, dt) -> (X, Y)`` of ``steps`` steps: what the
        benchmark times (compiled or not).
    scene : Scene
        The scene the rollout was built from; the reference is
        ``build_model(scene).rollout(steps)`` on the CasADi VM.
    x0 : array_like, shape (nx,)
    p : array_like, shape (np,)
        The parameters the benchmark times with.
    dt : float
    steps : int
    rtol : float
        :data:`BITWISE` by default (compiled code equals the VM bit for bit).

    Returns
    -------
    X, Y : ndarray
        The checked outputs.
    """
    X, Y = (np.asarray(out, dtype=float) for out in rollout(x0, p, dt))
    X_ref, Y_ref = reference_rollout(scene, x0, p, dt, steps)
    name = f"the uncompiled model of {scene.name!r} (same x0, p, Δt)"
    check_equal(bench, f"{what}: states X", X, X_ref, rtol=rtol, reference_name=name)
    check_equal(bench, f"{what}: outputs Y", Y, Y_ref, rtol=rtol, reference_name=name)
    return X, Y


def buffered(rollout, x0, p, dt: float):
    """``rollout`` bound to preallocated NumPy arrays (``casadi.Function.buffer``): returns
    (evaluate, outputs); each ``evaluate()`` writes the rollout of (x0, p, dt) into
    ``outputs`` without allocating, as a timing loop needs."""
    buffer, evaluate = rollout.buffer()
    inputs = [np.array(x0, dtype=float), np.array(p, dtype=float), np.array([dt])]
    outputs = [np.zeros(rollout.nnz_out(i)) for i in range(rollout.n_out())]
    for i, a in enumerate(inputs):
        buffer.set_arg(i, memoryview(a))
    for i, a in enumerate(outputs):
        buffer.set_res(i, memoryview(a))
    def run(_keep=(buffer, inputs)):          # the buffers outlive the closure
        evaluate()

    return run, outputs
