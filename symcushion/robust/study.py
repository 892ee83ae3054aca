"""A design-for-the-envelope study: its file, and the sample–select–optimise–verify loop.

Owns :class:`RobustStudy` (read from a TOML file: an envelope study's tables
— scene, ranges, limits, sampling of the verification — plus ``[design]``
variables and a ``[robust]`` table) and :func:`run_robust_study`:

1. sample a pool of touchdowns (``robust.pool`` cases, seed ``robust.seed``)
   and run it on the starting design;
2. select ``robust.scenarios`` of them near and beyond the stable region's
   boundary (:mod:`.select`);
3. optimise the design for the risk measure of their margins
   (:class:`~.problem.EnvelopeDesign`);
4. verify: the envelope study itself (its own ``n`` and ``seed``, different
   from the pool's) on the starting design and on the optimum;
5. write the result directory (:mod:`.report`).

It must not state the NLP, classify, or plot.
"""
from __future__ import annotations

import copy
import time
from collections import Counter
from dataclasses import dataclass, field

from ..envelope.runner import run_envelope
from ..envelope.study import EnvelopeStudy, study_from_dict as envelope_from_dict
from ..optimise.study import read_design_table, _Fields
from ..scene import read_toml
from .problem import (DEFAULT_ALPHA, DEFAULT_HORIZON, DEFAULT_SATURATION, EnvelopeDesign, RISKS)
from .margins import DEFAULT_SHARPNESS
from .select import DEFAULT_FAIL_SHARE, DEFAULT_WORST_MARGIN, select_scenarios

__all__ = ["RobustStudy", "robust_study_from_dict", "load_robust_study", "run_robust_study"]

#: Pool size and seed when ``[robust]`` does not give them.
DEFAULT_POOL = 2000
DEFAULT_POOL_SEED = 1
#: Scenarios optimised when ``robust.scenarios`` is not given.
DEFAULT_SCENARIOS = 24


@dataclass
class RobustStudy:
    """A design-for-the-envelope study.

    Attributes
    ----------
    name, description, source : str
    envelope : EnvelopeStudy
        Scene (tuned curves ``tunable = true``), distribution, limits; its
        ``n`` and ``seed`` are those of the verification.
    variables : list of DesignVariable
    shapes : list of CurveShape
    geometry : list of GeometryVariable
    practical : PracticalLimits, optional
    pool, pool_seed : int
        Size and seed of the sampled pool the scenarios come from.
    scenarios : int
    fail_share, worst_margin : float
        Selection (:func:`~.select.select_scenarios`).
    horizon, alpha, saturation, sharpness : float
    risk : str
    ipopt : dict
    """

    name: str
    envelope: EnvelopeStudy
    variables: list
    shapes: list = field(default_factory=list)
    geometry: list = field(default_factory=list)
    practical: object = None
    pool: int = DEFAULT_POOL
    pool_seed: int = DEFAULT_POOL_SEED
    scenarios: int = DEFAULT_SCENARIOS
    fail_share: float = DEFAULT_FAIL_SHARE
    worst_margin: float = DEFAULT_WORST_MARGIN
    horizon: float | None = DEFAULT_HORIZON
    risk: str = "cvar"
    alpha: float = DEFAULT_ALPHA
    saturation: float = DEFAULT_SATURATION
    sharpness: float = DEFAULT_SHARPNESS
    ipopt: dict = field(default_factory=dict)
    description: str = ""
    source: str = "<dict>"


def robust_study_from_dict(data: dict, source: str = "<dict>") -> RobustStudy:
    """Build a :class:`RobustStudy` from the parsed contents of a study TOML file."""
    data = copy.deepcopy(data)
    design = data.pop("design", None)
    robust = data.pop("robust", {})
    if design is None:
        raise ValueError(f"{source}: no `[design]` table; give `[[design.variables]]` (the "
                         "tunable curve parameters to design, docs/optimise.md).")
    envelope = envelope_from_dict(data, source)
    variables, shapes, geometry, practical = read_design_table(_Fields(design, "design",
                                                                       source))
    if not isinstance(robust, dict):
        raise ValueError(f"{source}: `robust` must be a table, got {robust!r}.")
    rb = _Fields(robust, "robust", source)
    out = RobustStudy(
        name=envelope.name, envelope=envelope, variables=variables, shapes=shapes,
        geometry=geometry, practical=practical,
        pool=rb.get("pool", DEFAULT_POOL, kind="int"),
        pool_seed=rb.get("seed", DEFAULT_POOL_SEED, kind="int"),
        scenarios=rb.get("scenarios", DEFAULT_SCENARIOS, kind="int"),
        fail_share=rb.get("fail_share", DEFAULT_FAIL_SHARE, nonnegative=True),
        worst_margin=rb.get("worst_margin", DEFAULT_WORST_MARGIN),
        horizon=rb.get("horizon", envelope.scene.duration, positive=True),
        risk=rb.get("risk", "cvar", kind="string", choices=RISKS),
        alpha=rb.get("alpha", DEFAULT_ALPHA, nonnegative=True),
        saturation=rb.get("saturation", DEFAULT_SATURATION, positive=True),
        sharpness=rb.get("sharpness", DEFAULT_SHARPNESS, positive=True),
        ipopt=dict(rb.get("ipopt", {}, kind="any")), description=envelope.description,
        source=source)
    rb.finish()
    for key in ("pool", "scenarios"):
        if getattr(out, key) < 1:
            raise ValueError(f"{source}: `robust.{key}` must be ≥ 1, got {getattr(out, key)}.")
    if out.pool_seed < 0:
        raise ValueError(f"{source}: `robust.seed` must be ≥ 0, got {out.pool_seed}.")
    if out.pool_seed == envelope.seed:
        raise ValueError(f"{source}: `robust.seed` = {out.pool_seed} equals `sampling.seed`: "
                         "the scenarios would come from the verification's own samples; "
                         "give the pool another seed.")
    if not 0 <= out.alpha < 1:
        raise ValueError(f"{source}: `robust.alpha` must be in [0, 1), got {out.alpha!r}.")
    if out.saturation <= 1:
        raise ValueError(f"{source}: `robust.saturation` must be > 1, got {out.saturation!r}.")
    if out.fail_share > 1:
        raise ValueError(f"{source}: `robust.fail_share` must be in [0, 1], got "
                         f"{out.fail_share!r}.")
    return out


def _write_geometry(result, out_dir):
    """``geometry.json``: the legs' geometry at the start and the optimum, and the
    practical-limit rows' values (docs/optimise.md, "Geometry as design variables")."""
    import json
    from pathlib import Path

    from ..results import atomic_write_text, jsonable
    path = Path(out_dir) / "geometry.json"
    atomic_write_text(path, json.dumps(jsonable(result.geometry), indent=2,
                                       ensure_ascii=False) + "\n")
    return path


def load_robust_study(path) -> RobustStudy:
    """Load a design-for-the-envelope study file (format: docs/optimise.md)."""
    return robust_study_from_dict(read_toml(path, "design study"), str(path))


def run_robust_study(study: RobustStudy, out_dir=None, *, threads: int | None = None,
                     client=None, dask: bool = False, scheduler: str | None = None,
                     verify: bool = True, check_gradient: bool = False, cache_dir=None,
                     progress: bool = True) -> dict:
    """Sample, select, optimise and verify; write ``out_dir`` if given.

    Parameters
    ----------
    study : RobustStudy
    out_dir : str or Path, optional
        Result directory (:func:`~.report.write_report`).
    threads : int, optional
        Threads for the envelope runs and the scenarios (default every core).
    client : distributed.Client, optional
        Evaluate the scenarios of the optimisation as Dask tasks.
    dask, scheduler :
        Run the envelope runs on Dask (:func:`~symcushion.envelope.run_envelope`).
    verify : bool
        Run the verification envelopes (before and after).
    check_gradient : bool
        Compare the NLP's Jacobian with central differences at the start and
        at the optimum (:meth:`EnvelopeDesign.check_gradient`).

    Returns
    -------
    dict
        ``pool``, ``indices``, ``problem``, ``result`` (RobustResult),
        ``before``/``after`` (EnvelopeResult or None), ``gradient``, ``seconds``.
    """
    started = time.perf_counter()
    say = (lambda msg: print(msg, flush=True)) if progress else (lambda msg: None)
    env = dict(threads=threads, dask=dask, scheduler=scheduler, cache_dir=cache_dir,
               progress=progress, plots=False)
    seconds = {}
    t0 = time.perf_counter()
    say(f"{study.name}: 1/4 pool of {study.pool:,} touchdowns (seed {study.pool_seed}) on "
        "the starting design")
    pool = run_envelope(study.envelope.with_(n=study.pool, seed=study.pool_seed), **env)
    seconds["pool"] = time.perf_counter() - t0
    idx = select_scenarios(pool.columns, study.scenarios, fail_share=study.fail_share,
                           worst=study.worst_margin)
    if idx.size == 0:
        raise ValueError(f"{study.name}: the pool has no case to design for (no failure "
                         "within `robust.worst_margin` and no stable case); widen the ranges "
                         "or the pool.")
    conditions = {k: v[idx] for k, v in pool.conditions.items()}
    names = [f"case{i}_{pool.columns['class'][i]}" for i in idx]
    say(f"{study.name}: 2/4 {idx.size} scenarios selected: "
        + ", ".join(f"{c} {n}" for c, n in Counter(map(str, pool.columns["class"][idx])).items()))
    t0 = time.perf_counter()
    problem = EnvelopeDesign(study.envelope, conditions, study.variables, names=names,
                             horizon=study.horizon, risk=study.risk, alpha=study.alpha,
                             saturation=study.saturation, sharpness=study.sharpness,
                             shapes=study.shapes, geometry=study.geometry,
                             practical=study.practical, threads=threads, client=client,
                             cache_dir=cache_dir, progress=progress)
    seconds["build"] = time.perf_counter() - t0
    gradient = {}
    if check_gradient:
        gradient["start"] = problem.check_gradient()
    say(f"{study.name}: 3/4 optimising {problem.n_variables} variables over {idx.size} "
        f"scenarios of {problem.horizon:g} s ({study.risk}"
        + (f", α = {study.alpha:g}" if study.risk == "cvar" else "") + ")")
    t0 = time.perf_counter()
    result = problem.solve(ipopt=study.ipopt, progress=progress)
    seconds["optimise"] = time.perf_counter() - t0
    say(f"{study.name}: {result.return_status} after {result.iterations} iterations; "
        f"scenarios within every limit {result.scenarios_within('start')} → "
        f"{result.scenarios_within()} of {idx.size}")
    if check_gradient:
        gradient["optimum"] = problem.check_gradient(result.theta)
    before = after = None
    if verify:
        t0 = time.perf_counter()
        say(f"{study.name}: 4/4 verification: {study.envelope.n:,} fresh touchdowns (seed "
            f"{study.envelope.seed}), starting design and optimum")
        before = run_envelope(study.envelope, **env)
        if problem.designs_geometry:
            # the optimum's geometry is a scene of its own (its legs rebuilt)
            curves = {k: v for k, v, is_curve in zip(result.var_names, result.theta,
                                                    problem._is_curve) if is_curve}
            after = run_envelope(study.envelope.with_(
                scene=problem.scene_at(result.theta, study.envelope.scene)), design=curves,
                **env)
        else:
            after = run_envelope(study.envelope, design=result.design, **env)
        seconds["verify"] = time.perf_counter() - t0
        for label, r in (("before", before), ("after", after)):
            ps = r.p_stable()
            say(f"  {label}: P(stable) = {ps['p']:.3f} [{ps['low']:.3f}, {ps['high']:.3f}]")
    seconds["total"] = time.perf_counter() - started
    run = dict(study=study, pool=pool, indices=idx, problem=problem, result=result,
               before=before, after=after, gradient=gradient, seconds=seconds)
    if out_dir is not None:
        from .report import write_report  # matplotlib only when writing
        run["files"] = write_report(run, out_dir)
        if result.geometry:
            run["files"]["geometry"] = _write_geometry(result, out_dir)
    return run

