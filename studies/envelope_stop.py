"""Does stopping decided cases change any class of the example envelope?

Question: the envelope stops a case once its class is decided
(``symcushion.envelope.cases.study_stop``): once its tilt passes the tip-over
limit (tip-over outranks every other class) or once it has stood on at least
three feet, none slipping, moving slower than 0.4 × ``limits.rest_speed``
for 50 ms. Does any case of the example study (studies/envelope_lander.toml)
end in another class than when it runs the whole 2 s, and how much of the
run does the stop save?

Method: the study's cases (its seed, 2024; ``--n`` of them) are run twice on
every core through ``run_envelope`` (no files written), with
``stop_decided`` off and on, and their classes compared case by case. The
table gives, per class, the cases and the mean time each ran, and both runs'
``run_seconds`` (the compiled cases only, on a shared machine: their ratio is
the saving, measured in one process).

Output: the table on stdout (docs/envelope.md, "Stopping decided cases").

    python studies/envelope_stop.py [--n 10000]
"""
from __future__ import annotations

import argparse

import numpy as np

from symcushion.envelope import CLASSES, build_envelope, load_study, run_envelope

from bench_envelope import CACHE, STUDY   # a script beside this one


def compare(n: int) -> str:
    study = load_study(STUDY).with_(n=n)
    build_envelope(study.scene, CACHE, progress=True)
    runs = {}
    for stop in (False, True):
        result = run_envelope(study.with_(stop=stop), cache_dir=CACHE, progress=True,
                              plots=False)
        runs[stop] = (result.columns, result.timings["run_seconds"])
    full, stopped = runs[False][0], runs[True][0]
    changed = np.flatnonzero(full["class"] != stopped["class"])
    lines = [f"{study.name}: {n:,} cases, Δt = {study.scene.dt * 1e3:g} ms, "
             f"duration {study.scene.duration:g} s",
             f"cases whose class changes when decided cases stop: {len(changed)}"]
    lines += [f"  case {i}: {full['class'][i]} -> {stopped['class'][i]}" for i in changed[:10]]
    lines += ["", "| class | cases | mean time run (s), stopped | stopped early |",
              "|---|---:|---:|---:|"]
    end = stopped["end_time"]
    early = end < study.scene.duration - study.scene.dt / 2
    for name in CLASSES:
        mask = stopped["class"] == name
        if mask.any():
            lines.append(f"| {name} | {mask.sum():,} | {end[mask].mean():.3f} | "
                         f"{early[mask].mean():.1%} |")
    lines.append(f"| all | {n:,} | {end.mean():.3f} | {early.mean():.1%} |")
    seconds_full, seconds_stop = runs[False][1], runs[True][1]
    lines += ["", f"run_seconds: whole duration {seconds_full:.1f} s, stopped {seconds_stop:.1f} s "
              f"(ratio {seconds_full / seconds_stop:.2f}; steps run "
              f"{study.scene.duration / end.mean():.2f}x fewer)"]
    return "\n".join(lines)


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--n", type=int, default=10_000, help="cases (default 10,000)")
    args = parser.parse_args(argv)
    print(compare(args.n))


if __name__ == "__main__":
    main()
