"""The scenarios' margins in compiled C, on threads or a Dask cluster, with their Jacobian.

Owns the compiled library of ``touchdown_margins`` and of
``touchdown_margins_jac`` (the ratios and their Jacobian in the design vector
w only: forward sweeps in w, not in the initial state or the scene's
parameters), built once per scene, horizon and limits through the package's
one build cache (:func:`symcushion.compiled.codegen.compile_cached`); and
:class:`ScenarioRatios`, a CasADi Callback R(w) whose columns are the
scenarios' ratios and whose Jacobian is the library's, so Ipopt's derivatives
run in C. Scenarios are inputs, not constants: one library serves every
selection of scenarios. It must not state the design problem or choose
scenarios.
"""
from __future__ import annotations

import time
from pathlib import Path

import casadi as ca
import numpy as np

from symcushion.compiled.codegen import compile_cached
from symcushion.design.compiled_nlp import COMPILE_FLAGS  # -O1: the design library's flags
from symcushion.design.robust.margins import margins_function

__all__ = ["DEFAULT_CACHE", "MARGINS", "build_margins", "design_margins", "ScenarioRatios"]

#: Folder of the compiled margins libraries (git-ignored ``build/``).
DEFAULT_CACHE = Path("build") / "robust"
#: Name of the compiled ratios Function; its Jacobian in w is ``MARGINS + "_jac"``.
MARGINS = "touchdown_margins"


def design_margins(model, steps: int, limits: dict, design: np.ndarray, *, sharpness: float,
                   reach: float = 0.0, design_map: ca.Function | None = None) -> ca.Function:
    """``touchdown_margins(x0, p0, w, dt)`` of a design.

    Without ``design_map`` the linear map p = p0 + design·w of
    :func:`~symcushion.design.robust.margins.margins_function`. With it (a Function
    ``(x0, p0, w) -> (x0_design, p_design)``: geometry variables, docs/optimise.md)
    the margins of the state and parameters it returns; the same inputs and output.
    """
    if design_map is None:
        return margins_function(model, steps, limits, sharpness=sharpness, design=design,
                                reach=reach)
    inner = margins_function(model, steps, limits, sharpness=sharpness, reach=reach)
    x0, p0 = ca.MX.sym("x0", model.nx), ca.MX.sym("p0", model.np)
    w, dt = ca.MX.sym("w", design.shape[1]), ca.MX.sym("dt")
    x_design, p_design = design_map(x0, p0, w)
    ratio = inner(x_design, p_design, ca.MX(0, 1), dt)
    return ca.Function(MARGINS, [x0, p0, w, dt], [ratio], ["x0", "p0", "w", "dt"], ["ratio"])


def build_margins(model, steps: int, limits: dict, design: np.ndarray, *, sharpness: float,
                  reach: float = 0.0, cache_dir=None, name: str = "scene",
                  progress: bool = False, design_map: ca.Function | None = None) -> tuple:
    """Generate and compile ``touchdown_margins`` and its Jacobian in w; return the library.

    Parameters
    ----------
    model : StepModel
    steps : int
        Steps of the horizon.
    limits : dict
        Limits by check (:func:`~symcushion.design.robust.margins.margins_function`).
    design : ndarray, shape (np, nw)
        p = p0 + design·w.
    sharpness : float
        ρ of the KS aggregate.
    reach : float
        Lever arm of the at-rest check (m).
    cache_dir : str or Path, optional
        Default :data:`DEFAULT_CACHE`.
    design_map : casadi.Function, optional
        ``(x0, p0, w) -> (x0_design, p_design)`` when the design is not linear
        in w (:func:`design_margins`).

    Returns
    -------
    library : Path
    seconds : float
        C generation and gcc (0.0 when the cache held the build).
    """
    started = time.perf_counter()
    f = design_margins(model, steps, limits, design, sharpness=sharpness, reach=reach,
                       design_map=design_map)
    args = [ca.MX.sym(n, f.sparsity_in(i)) for i, n in enumerate(f.name_in())]
    ratio = f(*args)
    jac = ca.Function(MARGINS + "_jac", args, [ratio, ca.jacobian(ratio, args[2])],
                      f.name_in(), ["ratio", "jac_ratio_w"])
    built = compile_cached([f, jac], MARGINS + ".c", f"lib{MARGINS}.so",
                           Path(DEFAULT_CACHE if cache_dir is None else cache_dir),
                           "".join(c if c.isalnum() or c in "-_" else "_" for c in name),
                           note="the scenarios' margins and their Jacobian" if progress
                           else None, cflags=COMPILE_FLAGS)
    return built.library.resolve(), (time.perf_counter() - started) if built.fresh else 0.0


_LOADED: dict = {}


def _functions(library: str) -> tuple:
    """(ratios, ratios-and-Jacobian) from a library, loaded once per process."""
    if library not in _LOADED:
        if not Path(library).is_file():
            raise FileNotFoundError(f"compiled margins library {library!r} does not exist; "
                                    "build it with `build_margins`.")
        _LOADED[library] = (ca.external(MARGINS, library),
                            ca.external(MARGINS + "_jac", library))
    return _LOADED[library]


def scenario_task(library: str, x0, p0, w, dt: float, jacobian: bool):
    """One scenario's ratios (C,) or (ratios, Jacobian (C, nw)): a Dask task."""
    f, jac = _functions(library)
    if jacobian:
        r, J = jac(x0, p0, w, dt)
        return np.asarray(r, dtype=float).ravel(), np.asarray(J, dtype=float)
    return np.asarray(f(x0, p0, w, dt), dtype=float).ravel()


class ScenarioRatios(ca.Callback):
    """R(w): the ratios of every scenario side by side (C × S), Jacobian in C.

    Parameters
    ----------
    library : str or Path
        From :func:`build_margins`.
    x0 : ndarray, shape (nx, S)
    p0 : ndarray, shape (np, S)
        The scenarios' step parameters with the designed entries zero.
    dt : float
    threads : int
        Threads of the local ``map``; ignored with ``client``.
    client : distributed.Client, optional
        Evaluate one Dask task per scenario instead (every worker must see
        ``library``: a shared filesystem or a local cluster).
    """

    def __init__(self, library, x0, p0, dt: float, threads: int = 1, client=None,
                 jacobian: bool = False):
        ca.Callback.__init__(self)
        self.library = str(library)
        self.x0, self.p0, self.dt = np.asarray(x0, float), np.asarray(p0, float), float(dt)
        self.threads, self.client, self.jacobian = int(threads), client, jacobian
        f, jac = _functions(self.library)
        self.S = self.x0.shape[1]
        self.nw, self.C = f.size1_in(2), f.size1_out(0)
        mode = ("thread", min(self.threads, self.S)) if self.threads > 1 else ("serial",)
        self._map = (jac if jacobian else f).map(self.S, *mode) if client is None else None
        self.calls = 0
        self.seconds = 0.0
        self._jacobians = []
        self.construct(MARGINS + ("_jac_all" if jacobian else "_all"), {})

    def get_n_in(self):
        return 2 if self.jacobian else 1

    def get_n_out(self):
        return 1

    def get_name_in(self, i):
        return ("w", "out_R")[i]

    def get_name_out(self, i):
        return "jac_R_w" if self.jacobian else "R"

    def get_sparsity_in(self, i):
        return ca.Sparsity.dense(self.nw, 1) if i == 0 else ca.Sparsity.dense(self.C, self.S)

    def get_sparsity_out(self, i):
        return ca.Sparsity.dense(self.C * self.S, self.nw) if self.jacobian else \
            ca.Sparsity.dense(self.C, self.S)

    def eval(self, arg):
        started = time.perf_counter()
        w = np.asarray(arg[0], dtype=float).ravel()
        if self.client is not None:
            futures = [self.client.submit(scenario_task, self.library, self.x0[:, s],
                                          self.p0[:, s], w, self.dt, self.jacobian, pure=False)
                       for s in range(self.S)]
            parts = self.client.gather(futures)
            out = np.vstack([J for _, J in parts]) if self.jacobian else \
                np.column_stack(parts)
        else:
            res = self._map(self.x0, self.p0, np.tile(w[:, None], (1, self.S)), self.dt)
            if self.jacobian:
                # scenario s's block (C × nw) holds rows s·C … s·C + C − 1 of ∂vec(R)/∂w
                J = np.asarray(res[1], dtype=float)
                out = np.vstack(np.hsplit(J, self.S))
            else:
                out = np.asarray(res, dtype=float)
        self.calls += 1
        self.seconds += time.perf_counter() - started
        return [ca.DM(out)]

    def has_jacobian(self):
        return not self.jacobian

    def get_jacobian(self, name, inames, onames, opts):
        # CasADi may ask more than once (for each derivative Function it builds); every
        # Callback handed out must outlive the Functions that call it
        jac = ScenarioRatios(self.library, self.x0, self.p0, self.dt, self.threads,
                             self.client, jacobian=True)
        self._jacobians.append(jac)
        return jac

    @property
    def jacobian_calls(self) -> tuple:
        """(calls, seconds) of the Jacobian evaluations so far."""
        return (sum(j.calls for j in self._jacobians),
                sum(j.seconds for j in self._jacobians))
