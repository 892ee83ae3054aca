"""The design NLP on compiled C: the scenario rollouts and their Jacobian built once.

A :class:`~symcushion.design.optimise.DesignProblem` states its NLP as one MX graph
in which each scenario calls ``touchdown_rollout`` on the CasADi VM. Almost
all of Ipopt's time goes into those rollouts and their Jacobian. This module
replaces them, and nothing else, by compiled code:

1. one Function ``design_scenarios(k, w) -> (X, Y)`` returns the rollout of
   scenario k (0-based) at the scaled design w: a ``Function.conditional``
   over the scenarios' rollouts, with each scenario's initial state, fixed
   parameters and time step built in;
2. its Jacobian is generated into the same C file under the name
   ``jac_design_scenarios``: ``casadi.external`` finds that symbol and uses it
   for every derivative of the loaded Function, so Ipopt's Jacobian runs in C;
3. the library is compiled with :func:`symcushion.compiled.codegen.compile_cached`
   (the package's one build cache, keyed by a hash of the source, the flags
   and the compiler) in a folder named after that hash, so a second run of
   the same problem skips gcc, and two problems never share a library path;
4. the loaded Function is mapped over the scenarios with
   ``map(n, "thread", threads)``, and substituted for the VM rollouts in the
   problem's f, g and output graphs (``casadi.graph_substitute``); or, given
   a Dask client, evaluated one task per scenario by a ``casadi.Callback``
   whose Jacobian is again tasks calling the library's Jacobian.

The rest of the NLP (measures, epigraph rows, shape constraints) stays on the
VM: it is cheap. The result is the same NLP, evaluated by other code, so the
optimum is the same to the solver's tolerance.

This module owns the compiled NLP and its timings. It must not state the
problem (``symcushion.design.optimise`` does), integrate (``symcushion.simulate``
does) or keep a build cache of its own (``symcushion.compiled.codegen`` does).
"""
from __future__ import annotations

import os
import time
from dataclasses import dataclass, field
from pathlib import Path

import casadi as ca
import numpy as np

from symcushion.compiled import codegen

__all__ = ["COMPILE_FLAGS", "DEFAULT_CACHE", "DIRECTIONS", "SCENARIOS", "CompiledDesign",
           "compile_design", "scenario_function"]

#: Name of the compiled Function; its Jacobian is ``"jac_" + SCENARIOS``, the
#: symbol ``casadi.external`` looks for.
SCENARIOS = "design_scenarios"

#: Folder of compiled design libraries when no ``cache_dir`` is given.
DEFAULT_CACHE = Path("build") / "design"

#: gcc flags of the design library. -O1: on the 1-D absorber its Jacobian
#: runs 3× faster than at -O0 for 3× the compile time, and -O2/-O3 gain
#: nothing more (``python studies/bench_design.py --opt-levels
#: studies/absorber_1d.toml``, table in docs/optimise.md).
COMPILE_FLAGS = ("-O1", "-std=c99", "-fPIC", "-fno-semantic-interposition", "-fno-math-errno",
                 "-ffp-contract=off")

#: Forward directions per derivative pass of the rollout (CasADi's
#: ``max_num_dir``). One direction keeps the generated Jacobian small (the
#: step's tangent once, ~2× the step) and therefore quick to compile; the
#: rollout is then swept once per design variable. Batching directions
#: makes the C grow about linearly with their number.
DIRECTIONS = 1


@dataclass
class CompiledDesign:
    """The compiled NLP of a design problem.

    Attributes
    ----------
    nlp : dict
        ``{"x", "f", "g"}`` as MX, for ``casadi.nlpsol``: the problem's NLP
        with the rollouts evaluated by the compiled library.
    fg : casadi.Function
        ``design_fg(x) -> (f, g)`` on the compiled library.
    outputs : casadi.Function
        ``design_outputs(w) -> y`` on the compiled library.
    library : Path
        The shared library loaded.
    seconds : dict
        ``generate`` (the Functions and their Jacobian), ``compile`` (C and
        gcc through the cache; 0 when cached), ``load``.
    cached : bool
        True when gcc was skipped because the cache held the same build.
    threads : int
        Threads evaluating the scenarios.
    """

    nlp: dict
    fg: ca.Function
    outputs: ca.Function
    library: Path
    seconds: dict = field(default_factory=dict)
    cached: bool = False
    threads: int = 1


def _check_problem(problem):
    calls = getattr(problem, "_rollout_calls", None)
    if not calls or len(calls) != len(problem.scenarios):
        raise TypeError("`problem` must be a DesignProblem (symcushion.design.optimise) built with "
                        f"its rollouts recorded, got {type(problem).__name__}.")
    shapes = {(X.shape, Y.shape) for X, Y in calls}
    if len(shapes) != 1:
        raise ValueError("compiled design needs scenarios with the same rollout shapes (same "
                         f"number of legs and of steps), got {sorted(shapes)}; give every "
                         "scenario the same `dt` and `duration`, or solve with compiled=False.")
    return calls


def scenario_function(problem, directions: int = DIRECTIONS) -> tuple:
    """``design_scenarios(k, w) -> (X, Y)`` and its Jacobian ``jac_design_scenarios``.

    Parameters
    ----------
    problem : DesignProblem
    directions : int
        Forward directions per derivative pass (:data:`DIRECTIONS`).

    Returns
    -------
    f, jac : casadi.Function
        ``f`` takes k (scalar, the scenario's index, 0-based) and w (n_w, the
        scaled design) and returns the scenario's X (nx × steps) and Y
        (ny × steps); ``jac`` is ``f.jacobian()`` renamed so that
        ``casadi.external`` uses it.
    """
    if isinstance(directions, bool) or not isinstance(directions, int) or directions < 1:
        raise ValueError(f"`directions` must be a positive integer, got {directions!r}; "
                         f"use {DIRECTIONS}.")
    calls = _check_problem(problem)
    opts = {"max_num_dir": directions}
    w = problem._w
    each = [ca.Function(f"design_scenario{k}", [w], [X, Y], ["w"], ["X", "Y"], opts)
            for k, (X, Y) in enumerate(calls)]
    switch = ca.Function.conditional(SCENARIOS + "_switch", each, each[0], opts)
    k, wm = ca.MX.sym("k"), ca.MX.sym("w", w.numel())
    f = ca.Function(SCENARIOS, [k, wm], switch(k, wm), ["k", "w"], ["X", "Y"], opts)
    jac = f.jacobian()
    args = [ca.MX.sym(n, jac.sparsity_in(i)) for i, n in enumerate(jac.name_in())]
    jac = ca.Function("jac_" + SCENARIOS, args, jac(*args), jac.name_in(), jac.name_out())
    return f, jac


def _substituted(problem, ext, threads, client=None, library=None):
    """The problem's f, g and outputs with the rollouts replaced by ``ext``
    mapped on threads, or by a Dask evaluation when ``client`` is given."""
    calls = problem._rollout_calls
    n = len(calls)
    w = problem._w
    if client is not None:
        problem._dask_scenarios = _DaskScenarios(str(library), calls, w.numel(), client)
        X_all, Y_all = problem._dask_scenarios(w)   # kept alive by the problem
    else:
        mapped = ext.map(n, "thread", threads) if threads > 1 else ext.map(n)
        X_all, Y_all = mapped(ca.DM(list(range(n))).T, ca.repmat(w, 1, n))
    steps = calls[0][0].shape[1]
    old, new = [], []
    for k, (X, Y) in enumerate(calls):
        old += [X, Y]
        new += [X_all[:, k * steps:(k + 1) * steps], Y_all[:, k * steps:(k + 1) * steps]]
    f, g, y = ca.graph_substitute([problem.nlp["f"], problem.nlp["g"], problem._outputs_expr],
                                  old, new)
    return f, g, y


def compile_design(problem, cache_dir=None, *, threads: int | None = None,
                   cflags=COMPILE_FLAGS, directions: int = DIRECTIONS, client=None,
                   progress: bool = False) -> CompiledDesign:
    """Generate, build (or reuse) and load the compiled NLP of a design problem.

    Parameters
    ----------
    problem : DesignProblem
    cache_dir : str or Path, optional
        Parent folder of the builds (default :data:`DEFAULT_CACHE`, relative
        to the working directory); each build lives in a subfolder named by
        a hash of its source and flags.
    threads : int, optional
        Threads evaluating the scenarios (default: the number of cores, at
        most the number of scenarios).
    cflags : sequence of str
        gcc flags (:data:`COMPILE_FLAGS`).
    directions : int
        Forward directions per derivative pass (:data:`DIRECTIONS`).
    client : distributed.Client, optional
        Evaluate the scenarios (and their Jacobians) as Dask tasks, one per
        scenario and call, instead of on local threads. Every worker must see
        the library's path (a shared filesystem, or a local cluster).
    progress : bool
        Print one line per stage.

    Returns
    -------
    CompiledDesign
    """
    n = len(problem.scenarios) if hasattr(problem, "scenarios") else 0
    if threads is None:
        threads = max(1, min(n, os.cpu_count() or 1))
    if isinstance(threads, bool) or not isinstance(threads, int) or threads < 1:
        raise ValueError(f"`threads` must be a positive integer, got {threads!r}; use 2 on "
                         "a two-core machine.")
    if codegen.find_compiler() is None:
        raise FileNotFoundError("no C compiler: set $CC or install gcc, or solve with "
                                "`compiled=False`.")
    seconds = {}
    started = time.perf_counter()
    f, jac = scenario_function(problem, directions)
    seconds["generate"] = time.perf_counter() - started
    started = time.perf_counter()
    record = codegen.compile_cached(
        [f, jac], SCENARIOS + ".c", f"lib{SCENARIOS}.so",
        Path(DEFAULT_CACHE if cache_dir is None else cache_dir), SCENARIOS,
        note="the design's rollouts and their Jacobian" if progress else None,
        cflags=tuple(cflags))
    # C generation (inside compile_cached) and gcc; 0 when the cache held the build
    seconds["compile"] = time.perf_counter() - started if record.fresh else 0.0
    started = time.perf_counter()
    library = record.library.resolve()
    ext = ca.external(SCENARIOS, str(library))
    f, g, y = _substituted(problem, ext, threads, client, library)
    x = problem.nlp["x"]
    fg = ca.Function("design_fg", [x], [f, g], ["x"], ["f", "g"])
    outputs = ca.Function("design_outputs", [problem._w], [y], ["w"], ["y"])
    seconds["load"] = time.perf_counter() - started
    if progress:
        state = "cached" if not record.fresh else f"compiled in {seconds['compile']:.1f} s"
        print(f"compiled design: {library} {state}, {threads} thread(s)", flush=True)
    return CompiledDesign(nlp={"x": x, "f": f, "g": g}, fg=fg, outputs=outputs,
                          library=library, seconds=seconds, cached=not record.fresh,
                          threads=threads)


# ---------------------------------------------------------------------------
# the scenarios on a Dask cluster
# ---------------------------------------------------------------------------
_LOADED = {}   # library path -> (design_scenarios, its Jacobian), per worker process


def scenario_on_worker(library: str, k: int, w, jacobian: bool):
    """A Dask task: scenario k's rollout (X, Y), or its Jacobians in w, at w.

    Loads the library once per worker process. Returns two arrays:
    X (nx × steps) and Y (ny × steps), or ∂vec(X)/∂w and ∂vec(Y)/∂w.
    """
    if library not in _LOADED:
        f = ca.external(SCENARIOS, library)
        _LOADED[library] = (f, f.jacobian())
    f, jac = _LOADED[library]
    X, Y = f(k, w)
    if not jacobian:
        return np.asarray(X), np.asarray(Y)
    out = jac(k=k, w=w, out_X=X, out_Y=Y)
    return np.asarray(out["jac_X_w"]), np.asarray(out["jac_Y_w"])


class _DaskScenarios(ca.Callback):
    """(X_all, Y_all)(w): every scenario's rollout side by side, one task each."""

    def __init__(self, library, calls, nw, client, jacobian=False):
        ca.Callback.__init__(self)
        self.library, self.client, self.nw, self.jacobian = library, client, nw, jacobian
        self.n, self.steps = len(calls), calls[0][0].shape[1]
        self.rows = (calls[0][0].shape[0], calls[0][1].shape[0])
        self.calls = calls
        self.construct(("jac_" if jacobian else "") + SCENARIOS + "_dask", {})

    def get_n_in(self):
        return 3 if self.jacobian else 1

    def get_n_out(self):
        return 2

    def get_name_in(self, i):
        return ("w", "out_X", "out_Y")[i]

    def get_name_out(self, i):
        return (("jac_X_w", "jac_Y_w") if self.jacobian else ("X", "Y"))[i]

    def _value_shape(self, i):
        return self.rows[i], self.steps * self.n

    def get_sparsity_in(self, i):
        return ca.Sparsity.dense(self.nw, 1) if i == 0 else ca.Sparsity.dense(
            *self._value_shape(i - 1))

    def get_sparsity_out(self, i):
        rows, cols = self._value_shape(i)
        return ca.Sparsity.dense(rows * cols, self.nw) if self.jacobian else \
            ca.Sparsity.dense(rows, cols)

    def eval(self, arg):
        w = np.asarray(arg[0], dtype=float).ravel()
        futures = [self.client.submit(scenario_on_worker, self.library, k, w, self.jacobian,
                                      pure=False) for k in range(self.n)]
        parts = self.client.gather(futures)
        # vec of the side-by-side blocks is the scenarios' vecs stacked: stack Jacobians
        stack = np.vstack if self.jacobian else np.hstack
        return [ca.DM(stack([p[i] for p in parts])) for i in range(2)]

    def has_jacobian(self):
        return not self.jacobian

    def get_jacobian(self, name, inames, onames, opts):
        self._jac = _DaskScenarios(self.library, self.calls, self.nw, self.client, True)
        return self._jac
