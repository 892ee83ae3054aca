"""Benchmark: memory of a long streamed run (10⁶ steps of the Fig. 3 scene).

Runs ``symcushion simulate studies/fig3.toml --duration 1000 --no-plots`` in a
subprocess (Δt = 1 ms: 10⁶ steps) and prints the subprocess's peak resident
memory (``resource.getrusage(RUSAGE_CHILDREN).ru_maxrss``), its wall time and
the size of what it wrote. The driver rolls out blocks of
``symcushion.run.driver.BLOCK_STEPS`` steps and appends each block to the files,
so the peak should not grow with the duration; the aim is under 300 MB.

Before the long run, the same command runs CHECK_SECONDS of the scene, and
its written trajectory (positions, velocities, attitudes, feet, forces) must be
finite and equal, bit for bit, to ``symcushion.simulate`` of the scene in this
process (``studies/bench_check.py``): the run that is measured is the scene's
simulation.

Usage: ``python studies/bench_long_run.py [--duration SECONDS] [--keep]``.
Timings on a shared machine are noisy: this prints measurements and asserts
nothing about them.
"""
from __future__ import annotations

import argparse
import os
import resource
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from bench_check import BITWISE, check_equal  # studies/bench_check.py
from symcushion import Trajectory, load_scene, simulate

ROOT = Path(__file__).resolve().parents[1]

#: The aim of the benchmark: peak resident memory of the run (MB).
RSS_AIM_MB = 300
#: Name of this benchmark in the messages of its checks.
BENCH = "bench_long_run"
#: The scene the benchmark runs.
SCENE = ROOT / "studies" / "fig3.toml"
#: Simulated time of the checked short run (s): the touchdown and the rebound,
#: where wrong parameters or a broken driver show, in a second of CPU.
CHECK_SECONDS = 0.5
#: Trajectory fields compared with the in-process run (the angle fields are
#: NaN by definition while a foot is free).
CHECKED_FIELDS = ("position", "velocity", "attitude", "angular_velocity", "foot", "force")


def run(duration: float, out: Path) -> dict:
    """Run the Fig. 3 scene for ``duration`` s in a subprocess; return its measurements."""
    env = dict(os.environ, PYTHONPATH=str(ROOT) + os.pathsep + os.environ.get("PYTHONPATH", ""))
    cmd = [sys.executable, "-m", "symcushion.cli", "simulate", str(SCENE),
           "--duration", repr(duration), "--no-plots", "--out", str(out)]
    started = time.perf_counter()
    done = subprocess.run(cmd, env=env, capture_output=True, text=True)
    wall = time.perf_counter() - started
    if done.returncode != 0:
        raise RuntimeError(f"{' '.join(cmd)} failed ({done.returncode}):\n{done.stderr}")
    peak_kb = resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss   # KiB on Linux
    files = {p.name: p.stat().st_size for p in (out / "fig3").iterdir()}
    return {"duration": duration, "wall": wall, "peak_mb": peak_kb / 1024, "files": files,
            "stdout": done.stdout}


def check_run(out: Path, duration: float = CHECK_SECONDS) -> None:
    """Run the command for ``duration`` s into ``out``; check what it wrote.

    The written trajectory's CHECKED_FIELDS must be finite and equal, bit for
    bit, to ``simulate`` of the same scene and duration in this process.
    """
    run(duration, out)
    written = Trajectory.load(out / "fig3")
    reference = simulate(load_scene(SCENE).with_(duration=duration))
    for name in CHECKED_FIELDS:
        check_equal(BENCH, f"`{name}` written by `symcushion simulate` ({duration:g} s)",
                    getattr(written, name), getattr(reference, name), rtol=BITWISE,
                    reference_name="symcushion.simulate of the scene")


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--duration", type=float, default=1000.0,
                        help="simulated time in s; 1000 s is 10^6 steps (default: %(default)s)")
    parser.add_argument("--keep", action="store_true", help="keep the written files")
    args = parser.parse_args(argv)
    with tempfile.TemporaryDirectory(prefix="bench_long_run-check-") as tmp:
        check_run(Path(tmp))
    with tempfile.TemporaryDirectory(prefix="bench_long_run-") as tmp:
        out = Path(tmp) if not args.keep else ROOT / "out" / "bench_long_run"
        result = run(args.duration, out)
    print(result["stdout"].strip())
    steps = round(args.duration / 1e-3)
    sizes = ", ".join(f"{name} {size / 1e6:.0f} MB" for name, size in result["files"].items())
    print(f"{steps:,} steps of the Fig. 3 scene in {result['wall']:.0f} s wall "
          f"({result['wall'] / steps * 1e6:.0f} µs per step, writing included); wrote {sizes}")
    print(f"peak RSS of the run: {result['peak_mb']:.0f} MB (aim: under {RSS_AIM_MB} MB) -> "
          f"{'met' if result['peak_mb'] < RSS_AIM_MB else 'NOT met'}")


if __name__ == "__main__":
    main()
