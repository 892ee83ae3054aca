"""Which Δt does the example envelope need on the absorbers with memory?

Question: at which Δt do fewer than 0.5 % of the example study's cases
(studies/envelope_lander.toml: the memory law, dampers on every element,
``events = "none"``, ``slip = "midpoint"``) change class when Δt is halved,
the project's aim for the envelope (docs/envelope.md, "Method and Δt")?

Method: the study's first 2,000 Sobol points (its seed, 2024) are run, each
for the study's 2 s, with the study file's scene at Δt = 2, 1, 0.5 and
0.25 ms (``symcushion.envelope.evaluate``: one compiled ``envelope_case`` per
Δt, cached in build/envelope, on every core) and classified against the
study's limits. For each halving Δt → Δt/2 the share of cases whose class
differs is given, with its 95 % Wilson interval and the most frequent
changes, and P(stable) at each Δt. The CPU per case is this process's CPU
time over the run (the build excluded), on a shared machine.

Output: the table on stdout (the one in docs/envelope.md, "Class changes on
the absorbers with memory"), and every run's columns in
``out/envelope_dt/classes.npz`` (one array per column and Δt, keyed
``<column>@<dt in ms>``) for later comparisons.

With ``--rebounds``: why the example rebounds more than the printed-law
example did (docs/envelope.md, "The example"). Three flat-ground rebounds of
the study (:data:`REBOUND_CASES`) are simulated alone for 0.4 s, on the
CasADi VM, with the study's scene and with variants (the printed law with the
stroke lock as the example was before, a ten times stiffer elastic line, no
dampers, stiffer hinges); the table gives each one's largest upward speed.

    python studies/envelope_dt.py [--n 2000] [--dt 2e-3 1e-3 5e-4 2.5e-4]
    python studies/envelope_dt.py --rebounds
"""
from __future__ import annotations

import argparse
import copy
import os
import resource
import time
from collections import Counter
from pathlib import Path

import numpy as np

from symcushion.envelope import (case_params, evaluate, initial_states, load_study,
    sample_conditions, study_from_dict, wilson_interval)
from symcushion.layout.vectors import state_layout
from symcushion.model.scene import read_toml
from symcushion.scheme.touchdown import build_model

from bench_envelope import CACHE, ROOT, STUDY   # a script beside this one

OUT = ROOT / "out" / "envelope_dt"
#: Cases compared and the aim: fewer than this share change class at a halving.
CASES = 2000
AIM = 0.005
DTS = (2e-3, 1e-3, 5e-4, 2.5e-4)
#: Class pairs listed per halving, the most frequent first.
PAIRS = 5


#: Cases of the study (its Sobol points) that rebound on flat ground: the first
#: three with class "rebound" and a slope below 3°.
REBOUND_CASES = (0, 39, 58)
REBOUND_TIME = 0.4


def _variants() -> list:
    """(label, study) of the rebound comparison, from the study file's tables."""
    raw = read_toml(STUDY)

    def variant(change):
        data = copy.deepcopy(raw)
        change(data)
        return study_from_dict(data, str(STUDY))

    def printed(d):          # the example before: printed law, stroke lock, 20-mm rise
        d["scene"].update(hysteresis="sign", events="lock", dt=1.25e-4)
        d["legs"]["S"]["x"] = [-0.30, -0.02, 0.0]
        for name in ("S", "M_beta", "M_gamma"):
            d["legs"][name].pop("damping", None)

    def stiffer_line(d):     # k_e = 1e7 N/m (a 0.2-mm rise), the same τ
        d["legs"]["S"]["x"] = [-0.30, -0.0002, 0.0]
        d["legs"]["S"]["damping"] *= 10

    def no_dampers(d):
        for name in ("S", "M_beta", "M_gamma"):
            d["legs"][name].pop("damping", None)

    def stiffer_hinges(d):   # 2e6 N·m/rad, the same τ
        for name in ("M_beta", "M_gamma"):
            d["legs"][name]["stiffness"] *= 10
            d["legs"][name]["damping"] *= 10

    return [("the example", variant(lambda d: None)),
            ("the printed law with the lock (the example before, 0.125 ms)", variant(printed)),
            ("the example with an elastic line of 1e7 N/m (0.2-mm rise, τ kept)",
             variant(stiffer_line)),
            ("the example without dampers", variant(no_dampers)),
            ("the example with hinge springs of 2e6 N·m/rad", variant(stiffer_hinges))]


def rebounds() -> str:
    """Largest upward speed (along the true vertical) over REBOUND_TIME of each
    rebound case, in each variant: a Markdown table."""
    conditions = sample_conditions(load_study(STUDY).with_(n=max(REBOUND_CASES) + 1))
    cases = {k: np.asarray(v)[list(REBOUND_CASES)] for k, v in conditions.items()}
    rows = ["| run | " + " | ".join(f"case {i}" for i in REBOUND_CASES) + " |",
            "|---|" + "---:|" * len(REBOUND_CASES)]
    for label, study in _variants():
        model, dt = build_model(study.scene), study.scene.dt
        layout = state_layout(len(study.scene.legs))
        x0, gravity = initial_states(study, cases)
        p = case_params(study.scene, cases["mu"], gravity)
        cells = []
        for j in range(len(REBOUND_CASES)):
            up = -gravity[:, j] / np.linalg.norm(gravity[:, j])
            x, best = x0[:, j], 0.0
            for _ in range(int(round(REBOUND_TIME / dt))):
                x = np.asarray(model.step(x, p[:, j], dt)[0]).ravel()
                best = max(best, float(np.asarray(layout.get(x, "velocity")).ravel() @ up))
            cells.append(f"{best:.3f}")
        rows.append(f"| {label} | " + " | ".join(cells) + " |")
        print(rows[-1], flush=True)
    return "\n".join(rows)


def _cpu() -> float:
    use = resource.getrusage(resource.RUSAGE_SELF)
    return use.ru_utime + use.ru_stime


def run(n: int = CASES, dts=DTS) -> dict:
    """Columns of every case at each Δt, and (wall s, CPU s per case) of each run."""
    base = load_study(STUDY).with_(n=n)
    conditions = sample_conditions(base)
    threads = os.cpu_count() or 1
    columns, cost = {}, {}
    for dt in dts:
        study = base.with_(scene=base.scene.with_(dt=dt))
        started = time.perf_counter()
        evaluate(study, {k: v[:1] for k, v in conditions.items()}, cache_dir=CACHE,
                 progress=True)                     # build (or load) the library first
        build = time.perf_counter() - started
        cpu, wall = _cpu(), time.perf_counter()
        columns[dt] = evaluate(study, conditions, threads=threads, cache_dir=CACHE)
        cost[dt] = (time.perf_counter() - wall, (_cpu() - cpu) / n)
        print(f"dt = {dt * 1e3:g} ms: {cost[dt][0]:.1f} s of run on {threads} threads, "
              f"{1e3 * cost[dt][1]:.1f} ms CPU per case, {build:.1f} s to build or load, "
              f"load average {os.getloadavg()[0]:.1f}", flush=True)
    return {"columns": columns, "cost": cost, "n": n, "seed": base.seed, "threads": threads}


def table(res: dict, dts=DTS) -> str:
    n, columns, cost = res["n"], res["columns"], res["cost"]
    rows = ["| Δt → Δt/2 | cases changing class | 95 % Wilson | most frequent changes (Δt → Δt/2) |",
            "|---|---:|---|---|"]
    for a, b in zip(dts, dts[1:]):
        ca, cb = columns[a]["class"], columns[b]["class"]
        k = int(np.sum(ca != cb))
        _, lo, hi = wilson_interval(k, n)
        moves = Counter(f"{x} → {y}" for x, y in zip(ca, cb) if x != y)
        mark = " (< 0.5 %)" if k / n < AIM else ""
        rows.append(f"| {a * 1e3:g} → {b * 1e3:g} ms | {k / n:.2%} ({k}){mark} | "
                    f"{100 * lo:.2f}–{100 * hi:.2f} % | "
                    + (", ".join(f"{m} {c}" for m, c in moves.most_common(PAIRS)) or "—") + " |")
    rows += ["", "| Δt | P(stable), 95 % Wilson | classes | CPU ms per case |", "|---|---|---|---:|"]
    for dt in dts:
        cls = columns[dt]["class"]
        p, lo, hi = wilson_interval(int(np.sum(cls == "stable")), n)
        counts = ", ".join(f"{c} {v}" for c, v in Counter(cls).most_common())
        rows.append(f"| {dt * 1e3:g} ms | {p:.3f} [{lo:.3f}, {hi:.3f}] | {counts} | "
                    f"{1e3 * cost[dt][1]:.1f} |")
    return "\n".join(rows)


def save(res: dict, folder: Path = OUT):
    folder.mkdir(parents=True, exist_ok=True)
    arrays = {}
    for dt, cols in res["columns"].items():
        for name, values in cols.items():
            values = np.asarray(values)
            arrays[f"{name}@{dt * 1e3:g}"] = values.astype(str) if values.dtype == object \
                else values
    np.savez(folder / "classes.npz", **arrays)


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--n", type=int, default=CASES)
    parser.add_argument("--dt", type=float, nargs="+", default=list(DTS))
    parser.add_argument("--rebounds", action="store_true",
                        help="the rebound comparison instead of the class changes")
    args = parser.parse_args(argv)
    if args.rebounds:
        print(rebounds())
        return
    dts = tuple(sorted(args.dt, reverse=True))
    res = run(args.n, dts)
    save(res)
    print()
    print(f"The first {res['n']:,} cases of studies/envelope_lander.toml (seed {res['seed']}), "
          f"{res['threads']} threads, load average {os.getloadavg()[0]:.1f} at the end:")
    print()
    print(table(res, dts))


if __name__ == "__main__":
    main()
