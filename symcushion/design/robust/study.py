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
   With ``robust.rounds`` > 1 (the outer loop) each optimum is judged on
   held-out touchdowns of their own seed, the pool is run again on it, new
   scenarios are selected and the next round starts from it, until the
   held-out P(stable) stops rising; the best round's design is kept;
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

from symcushion.envelope.runner import run_envelope
from symcushion.envelope.study import EnvelopeStudy, study_from_dict as envelope_from_dict
from symcushion.design.optimise.gradient import gradient_verdict
from symcushion.design.optimise.study import read_design_table, StudyFields
from symcushion.model.scene import read_toml
from symcushion.design.robust.problem import EnvelopeDesign
from symcushion.design.robust.risk import (DEFAULT_ALPHA, DEFAULT_HORIZON, DEFAULT_SATURATION,
    DEFAULT_TIP_ENERGY, RISKS)
from symcushion.design.robust.margins import DEFAULT_SHARPNESS
from symcushion.design.robust.select import (ANY_DEPTH, DEFAULT_FAIL_SHARE, DEFAULT_WORST_MARGIN,
    left_out, select_scenarios)
from symcushion.run.output_files import atomic_write_text, jsonable

__all__ = ["RobustStudy", "robust_study_from_dict", "load_robust_study", "run_robust_study",
           "scenario_problem"]

#: Pool size and seed when ``[robust]`` does not give them.
DEFAULT_POOL = 2000
DEFAULT_POOL_SEED = 1
#: Scenarios optimised when ``robust.scenarios`` is not given.
DEFAULT_SCENARIOS = 24
#: Held-out touchdowns that judge each round of the outer loop: at 2,000 the
#: 95 % interval of a P(stable) near 0.9 is ±0.013, fine enough to see a
#: round that helps, at a fifth of the verification's cost.
DEFAULT_CHECK = 2000


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
    tip_energy : float or None
        Unit of the tip-over energy margin (m of lift;
        :data:`~.problem.DEFAULT_TIP_ENERGY`); None leaves the check out.
    rounds, check, check_seed : int
        The outer loop: at most ``rounds`` rounds of select–optimise, each
        judged on ``check`` held-out touchdowns (seed ``check_seed``, default
        the pool's + 1), stopping when P(stable) on them stops improving.
    risk : str
    ipopt : dict
    data : dict
        The study file as parsed: what :data:`DESIGNED_FILE` is written from.
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
    tip_energy: float | None = DEFAULT_TIP_ENERGY
    rounds: int = 1
    check: int = DEFAULT_CHECK
    check_seed: int | None = None
    ipopt: dict = field(default_factory=dict)
    description: str = ""
    source: str = "<dict>"
    data: dict = field(default_factory=dict, repr=False)


def robust_study_from_dict(data: dict, source: str = "<dict>") -> RobustStudy:
    """Build a :class:`RobustStudy` from the parsed contents of a study TOML file."""
    original = copy.deepcopy(data)
    data = copy.deepcopy(data)
    design = data.pop("design", None)
    robust = data.pop("robust", {})
    if design is None:
        raise ValueError(f"{source}: no `[design]` table; give `[[design.variables]]` (the "
                         "tunable curve parameters to design, docs/optimise.md).")
    envelope = envelope_from_dict(data, source)
    variables, shapes, geometry, practical = read_design_table(StudyFields(design, "design",
                                                                       source))
    if not isinstance(robust, dict):
        raise ValueError(f"{source}: `robust` must be a table, got {robust!r}.")
    rb = StudyFields(robust, "robust", source)
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
        tip_energy=rb.get("tip_energy", DEFAULT_TIP_ENERGY, positive=True),
        rounds=rb.get("rounds", 1, kind="int"), check=rb.get("check", DEFAULT_CHECK, kind="int"),
        check_seed=rb.get("check_seed", None, kind="int"),
        ipopt=dict(rb.get("ipopt", {}, kind="any")), description=envelope.description,
        source=source, data=original)
    rb.finish()
    if out.check_seed is None:                  # the next seed that is nobody else's
        out.check_seed = next(k for k in range(out.pool_seed + 1, out.pool_seed + 3)
                              if k != envelope.seed)
    if out.check_seed in (envelope.seed, out.pool_seed):
        raise ValueError(f"{source}: `robust.check_seed` = {out.check_seed} equals the "
                         "verification's or the pool's seed: the rounds must be judged on "
                         "touchdowns of their own; give it another seed.")
    for key in ("pool", "scenarios", "rounds", "check"):
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
    practical-limit rows' values (docs/design-geometry.md)."""
    import json
    from pathlib import Path

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
        ``pool``, ``indices``, ``problem``, ``result`` (RobustResult; the kept
        round's), ``before``/``after`` (EnvelopeResult or None), ``gradient``,
        ``seconds``, ``rounds`` (the outer loop's held-out check of the start
        and one row per round, or None for a single round).
    """
    started = time.perf_counter()
    say = (lambda msg: print(msg, flush=True)) if progress else (lambda msg: None)
    env = dict(threads=threads, dask=dask, scheduler=scheduler, cache_dir=cache_dir,
               progress=progress, plots=False)
    seconds = {}
    t0 = time.perf_counter()
    say(f"{study.name}: 1/4 pool of {study.pool:,} touchdowns (seed {study.pool_seed}) on "
        "the starting design")
    pool_study = study.envelope.with_(n=study.pool, seed=study.pool_seed)
    pool = run_envelope(pool_study, **env)
    seconds["pool"] = time.perf_counter() - t0
    solver = dict(threads=threads, client=client, cache_dir=cache_dir, progress=progress)
    looped = study.rounds > 1
    rounds, held_start = [], None
    if looped:
        held_start = _held_out(study, (study.envelope, None), env, say, "starting design")
    best = None
    for k in range(1, study.rounds + 1):
        if k > 1:
            t0 = time.perf_counter()
            say(f"{study.name}: round {k}: the pool again, on round {k - 1}'s design")
            at, curves = _at_design(pool_study, best["problem"], best["result"])
            pool = run_envelope(at, design=curves, **env)
            seconds["pool"] += time.perf_counter() - t0
        theta0 = None if best is None else best["result"].theta
        t0 = time.perf_counter()
        problem, idx = scenario_problem(study, pool, solver, say)
        seconds["build"] = seconds.get("build", 0.0) + time.perf_counter() - t0
        if k == 1 and check_gradient:
            gradient_start = problem.check_gradient()
            say(gradient_verdict(gradient_start, "the start")[1])
        say(f"{study.name}: 3/4 optimising {problem.n_variables} variables over {idx.size} "
            f"scenarios of {problem.horizon:g} s ({study.risk}"
            + (f", α = {study.alpha:g}" if study.risk == "cvar" else "") + ")"
            + (f", round {k} of at most {study.rounds}" if looped else ""))
        t0 = time.perf_counter()
        result = problem.solve(ipopt=study.ipopt, progress=progress, theta0=theta0)
        seconds["optimise"] = seconds.get("optimise", 0.0) + time.perf_counter() - t0
        say(f"{study.name}: {result.return_status} after {result.iterations} iterations; "
            f"scenarios within every limit {result.scenarios_within('start')} → "
            f"{result.scenarios_within()} of {idx.size}")
        this = dict(problem=problem, result=result, pool=pool, indices=idx)
        if not looped:
            best = this
            break
        held = _held_out(study, _at_design(study.envelope, problem, result), env, say,
                         f"round {k}'s design")
        rounds.append(_round_row(k, pool, idx, result, held))
        previous = held_start if best is None else best["held"]
        if held["p"] <= previous["p"]:
            say(f"{study.name}: round {k} did not raise the held-out P(stable) "
                f"({previous['p']:.3f} → {held['p']:.3f}): the loop stops"
                + ("; the starting design stays" if best is None else
                   f" with round {best['round']}'s design"))
            if best is None:
                best = dict(this, held=held, round=k)
            break
        best = dict(this, held=held, round=k)
    problem, result, pool, idx = best["problem"], best["result"], best["pool"], best["indices"]
    gradient = {}
    if check_gradient:
        gradient = dict(start=gradient_start, optimum=problem.check_gradient(result.theta))
        say(gradient_verdict(gradient["optimum"], "the optimum")[1])
        for check in gradient.values():
            check["passed"] = gradient_verdict(check, "")[0]
    before = after = None
    if verify:
        t0 = time.perf_counter()
        say(f"{study.name}: 4/4 verification: {study.envelope.n:,} fresh touchdowns (seed "
            f"{study.envelope.seed}), starting design and optimum")
        before = run_envelope(study.envelope, **env)
        at, curves = _at_design(study.envelope, problem, result)
        after = run_envelope(at, design=curves, **env)
        seconds["verify"] = time.perf_counter() - t0
        for label, r in (("before", before), ("after", after)):
            ps = r.p_stable()
            say(f"  {label}: P(stable) = {ps['p']:.3f} [{ps['low']:.3f}, {ps['high']:.3f}]")
    seconds["total"] = time.perf_counter() - started
    run = dict(study=study, pool=pool, indices=idx, problem=problem, result=result,
               before=before, after=after, gradient=gradient, seconds=seconds,
               rounds=dict(start=held_start, rounds=rounds) if looped else None)
    if out_dir is not None:
        from symcushion.design.robust.report import write_report  # matplotlib only when writing
        run["files"] = write_report(run, out_dir)
        if result.geometry:
            run["files"]["geometry"] = _write_geometry(result, out_dir)
    return run


def scenario_problem(study: RobustStudy, pool, solver: dict, say=lambda msg: None):
    """(problem, indices): the scenarios ``symcushion design`` selects from a classified
    ``pool`` (an envelope result of the study's pool) and their :class:`EnvelopeDesign`;
    ``solver`` holds its ``threads``, ``client``, ``cache_dir`` and ``progress``, ``say``
    prints the selection."""
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
    for line in _representation(pool.columns, study.worst_margin):
        say("  " + line)
    problem = EnvelopeDesign(study.envelope, conditions, study.variables, names=names,
                             horizon=study.horizon, risk=study.risk, alpha=study.alpha,
                             saturation=study.saturation, sharpness=study.sharpness,
                             tip_energy=study.tip_energy, shapes=study.shapes,
                             geometry=study.geometry, practical=study.practical, **solver)
    return problem, idx


def _at_design(envelope: EnvelopeStudy, problem, result) -> tuple:
    """The envelope study and the curves' design that run a result's design θ.

    A design of the curves only is the study's scene with the curves set
    (``design``); a design of the geometry is a scene of its own, its legs
    rebuilt at θ, with the curves' values as the design.
    """
    if not problem.designs_geometry:
        return envelope, result.design
    return (envelope.with_(scene=problem.scene_at(result.theta, envelope.scene)),
            problem.curve_design(result.theta))


def _held_out(study: RobustStudy, at: tuple, env: dict, say, label: str) -> dict:
    """P(stable) of ``at`` = (envelope study, design) on the outer loop's held-out touchdowns."""
    envelope, design = at
    run = run_envelope(envelope.with_(n=study.check, seed=study.check_seed), design=design,
                       **env)
    ps = run.p_stable()
    say(f"  held-out check ({study.check:,} touchdowns, seed {study.check_seed}), {label}: "
        f"P(stable) = {ps['p']:.3f} [{ps['low']:.3f}, {ps['high']:.3f}]")
    return dict(p=float(ps["p"]), low=float(ps["low"]), high=float(ps["high"]),
                counts=run.summary()["counts"])


def _round_row(k: int, pool, idx, result, held: dict) -> dict:
    """What result.json records of one round of the outer loop."""
    return dict(round=k, scenarios=dict(Counter(map(str, pool.columns["class"][idx]))),
                return_status=result.return_status, iterations=result.iterations,
                risk_start=result.objective_start, risk=result.objective,
                design=result.design, held_out=held)


def _representation(columns: dict, worst: float) -> list:
    """Lines saying which failures of the pool the scenarios stand for, and which not."""
    cls = [str(c) for c in columns["class"]]
    failures = Counter(c for c in cls if c not in ("stable", "no_touchdown"))
    if not failures:
        return ["the pool has no failure: the scenarios are its stable cases nearest a limit"]
    out = left_out(columns, worst=worst)
    lines = ["pool failures: " + ", ".join(f"{c} {n}" for c, n in sorted(failures.items()))]
    kept = [c for c in ANY_DEPTH if c in failures]
    if kept:
        lines.append("represented at every depth (their energy margin has a gradient): "
                     + ", ".join(kept))
    if out:
        lines.append(f"left out (worst margin below {worst:g}: over their limit by more than "
                     f"{-worst:.0%} of it, beyond what the design turns): "
                     + ", ".join(f"{c} {n}" for c, n in sorted(out.items()))
                     + "; set `robust.worst_margin` lower to include them")
    return lines
