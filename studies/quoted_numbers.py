"""The numbers README.md and docs/tutorial.md quote from running the code.

Each such number sits between two HTML comments, invisible on GitHub::

    stable in <!--q:tutorial.envelope.p_stable-->0.309<!--/q--> of them

and this script is the only thing that writes it: it runs the computations
(the tutorial's ``simulate``, ``optimise`` and ``envelope`` commands, the
README's 1-D absorber design, ``symcushion reproduce``'s claims and the
step's graph sizes), formats each value and writes it between its markers.
A value that spans lines (a table) has its markers on lines of their own.
Numbers of studies too long to run here (the lander design, the example
envelope at 0.125 ms, the design for the envelope) are read from the result
files those studies commit in ``figures/``, so that the docs quote what the
committed results hold. Wall-clock times are not quoted this way: the docs
give them as measured, with the machine and the date.

Usage::

    python studies/quoted_numbers.py            # rewrite the docs' stale values
    python studies/quoted_numbers.py --check    # exit 1 naming each stale value
    python studies/quoted_numbers.py --only tutorial.lander readme.graph

``--only`` limits the run to the sources named (``--list`` shows them and
their keys). The whole run takes about a minute on two cores.
"""
from __future__ import annotations

import argparse
import csv
import json
import re
import sys
import tempfile
from dataclasses import dataclass
from pathlib import Path
from typing import Callable

import numpy as np

from symcushion.cli import main as cli
from symcushion.contact.dispatch import contact_step
from symcushion.run.driver import Trajectory
from symcushion.envelope import DEFAULT_REST_SPEED
from symcushion.envelope.statistics import wilson_interval
from symcushion.reproduce import claims_table, reproduce
from symcushion.run.output_files import atomic_write_text
from symcushion.model.scene import load_scene
from symcushion.scheme.touchdown import build_model

ROOT = Path(__file__).resolve().parents[1]
TUTORIAL = ROOT / "studies" / "tutorial"
#: The documents whose quoted numbers this script owns.
DOCS = ("README.md", "docs/tutorial.md")
#: A quoted value: ``<!--q:KEY-->VALUE<!--/q-->``. HTML comments render as
#: nothing on GitHub, and ``<!--q:`` is easy to grep for.
MARKER = re.compile(r"<!--q:(?P<key>[a-z0-9_.]+)-->(?P<value>.*?)<!--/q-->", re.S)
#: Compiled envelopes are cached here between runs (the envelope command's
#: own default folder, ignored by git): a second check skips the compiler.
BUILD_DIR = ROOT / "build" / "envelope"
#: Numbers at round-off (|x| below this) compare equal whatever their digits:
#: an alignment error of 3.3e-16 or 4.4e-16 depends on the order of the
#: floating-point operations, not on the model.
ROUNDOFF = 1e-12
_SCIENTIFIC = re.compile(r"[-+]?\d+(?:\.\d+)?e[-+]?\d+")
#: Standard gravity (m/s²), to state the tutorial's peak deceleration in g.
G0 = 9.80665
_HOPS = {0: "does not hop", 1: "hops once", 2: "hops twice"}
#: How the tutorial's sentence on the envelope's failures names each class
#: (the classes of docs/envelope.md); a class not listed is named by its key.
FAILURE_WORDS = {
    "tip_over": "tip over",
    "stroke": "run out of stroke",
    "deflection": "exceed a hinge deflection",
    "deceleration": "exceed the deceleration limit",
    "rebound": "rebound",
    "moving": "are still moving at the end of the run (within every limit, but not at rest)",
    "no_touchdown": "never touch down",
}


@dataclass(frozen=True)
class Source:
    """One computation and the keys it fills.

    Attributes
    ----------
    name : str
        The prefix of its keys (``--only`` takes it).
    keys : tuple of str
        The keys, without the prefix.
    compute : callable
        ``compute(work)`` with a scratch folder ``work`` returns a dict from
        each key (without the prefix) to its text.
    """

    name: str
    keys: tuple
    compute: Callable[[Path], dict]

    def run(self, work: Path) -> dict:
        """The texts of this source's keys, by full key."""
        values = self.compute(work)
        if set(values) != set(self.keys):
            raise RuntimeError(f"source `{self.name}` gave keys {sorted(values)}, "
                               f"declared {sorted(self.keys)}")
        return {f"{self.name}.{key}": text for key, text in values.items()}


def _run_cli(*args: str):
    """Run a ``symcushion`` command in this process; raise if it fails."""
    code = cli([str(a) for a in args])
    if code != 0:
        raise RuntimeError(f"`symcushion {' '.join(map(str, args))}` exited with {code}")


def _and(items) -> str:
    """``a``, ``a and b``, ``a, b and c``."""
    items = list(items)
    return items[0] if len(items) == 1 else ", ".join(items[:-1]) + " and " + items[-1]


def _times(events, kind: str, after: float = -np.inf) -> list:
    """Distinct times (s) of the run's events of one kind after ``after``, in order."""
    return sorted({e["time"] for e in events if e["kind"] == kind and e["time"] > after})


def _hops(in_contact: np.ndarray) -> int:
    """Flights after the first touchdown: runs of steps with no foot on the ground."""
    any_foot = in_contact.any(axis=1)
    first = int(np.argmax(any_foot))
    airborne = ~any_foot[first:]
    starts = airborne[1:] & ~airborne[:-1]
    return int(starts.sum())


def lander(work: Path) -> dict:
    """``symcushion simulate studies/tutorial/lander.toml`` (tutorial, section 3)."""
    _run_cli("simulate", TUTORIAL / "lander.toml", "--out", work, "--no-plots")
    traj = Trajectory.load(work / "lander")
    events = traj.events
    touchdowns = [e for e in events if e["kind"] == "touchdown"]
    first_time = touchdowns[0]["time"]
    first_legs = sorted(e["leg"] for e in touchdowns if e["time"] == first_time)
    later = [e for e in touchdowns if e["leg"] not in first_legs]
    lift_offs = _times(events, "lift-off")
    before_lift_off = traj.t < (lift_offs[0] if lift_offs else np.inf)
    crush = -traj.stroke[before_lift_off][:, first_legs].min()
    peak = traj.acceleration[before_lift_off, 2].max()
    speed = np.linalg.norm(traj.velocity, axis=1)
    moving = np.nonzero(speed > DEFAULT_REST_SPEED)[0]
    at_rest = traj.t[moving[-1] + 1] if moving.size and moving[-1] + 1 < traj.t.size else np.nan
    hops = _hops(np.asarray(traj.contact) > 0.5)
    return {
        "first_legs": _and(str(leg) for leg in first_legs),
        "crush_mm": f"{1e3 * crush:.0f}",
        "peak_g": f"{peak / G0:.1f}",
        "late_touchdown_s": f"{later[0]['time']:.3f}",
        "hops": _HOPS.get(hops, f"hops {hops} times"),
        "lift_off_s": _and(f"{t:.3f}" for t in lift_offs),
        "touchdown_again_s": _and(f"{t:.3f}" for t in _times(events, "touchdown",
                                                               lift_offs[0] if lift_offs else np.inf)),
        "rest_s": f"{at_rest:.2f}",
        "rest_speed_cm_s": f"{100 * DEFAULT_REST_SPEED:g}",
    }


def _optimise(study: Path, out: Path) -> dict:
    """Run ``symcushion optimise STUDY`` and return its result file."""
    _run_cli("optimise", study, "--out", out)
    return json.loads(out.read_text())


def leg_design(work: Path) -> dict:
    """``symcushion optimise studies/tutorial/leg_design.toml`` (tutorial, section 4)."""
    result = _optimise(TUTORIAL / "leg_design.toml", work / "leg_design.json")
    nominal = result["scenarios"]["nominal"]
    return {"status": result["return_status"], "iterations": str(result["iterations"]),
            "peak": f"{result['objective']:.1f}",
            "efficiency": f"{100 * result['efficiency']:.1f}",
            "ideal": f"{nominal['ideal_peak_deceleration']:.1f}"}


def envelope(work: Path) -> dict:
    """``symcushion envelope studies/tutorial/lander_envelope.toml`` (tutorial, section 5)."""
    out = work / "envelope"
    _run_cli("envelope", TUTORIAL / "lander_envelope.toml", "--out", out,
             "--build-dir", BUILD_DIR)
    summary = json.loads((out / "summary.json").read_text())
    p = summary["p_stable"]
    failures = [f"{n} {FAILURE_WORDS.get(name, name.replace('_', ' '))}"
                for name, n in summary["counts"].items() if name != "stable" and n]
    return {"stable": str(p["stable"]), "p_stable": f"{p['p']:.3f}",
            "interval": f"[{p['low']:.3f}, {p['high']:.3f}]", "failures": _and(failures)}


def absorber(work: Path) -> dict:
    """``symcushion optimise studies/absorber_1d.toml`` (README, "Design, C code, ...")."""
    result = _optimise(ROOT / "studies" / "absorber_1d.toml", work / "absorber_1d.json")
    return {"status": result["return_status"], "iterations": str(result["iterations"]),
            "efficiency": f"{100 * result['efficiency']:.1f}"}


def _block(text: str) -> str:
    """A multi-line value: blank lines inside its markers, so Markdown sees the block."""
    return f"\n\n{text}\n\n"


def claims(work: Path) -> dict:
    """``symcushion reproduce``'s claims table (README, "The paper's figures")."""
    results = reproduce(ROOT / "studies", work / "reproduce", verbose=False)
    fig3 = {c.method: c for c in results if c.scene == "fig3"}
    rebound = {abs(fig3[m].rebound_dv) for m in ("robust", "implicit")}
    if len({f"{r:.1e}" for r in rebound}) != 1:
        raise RuntimeError(f"the exact steps' Fig. 3 rebound errors differ: {rebound}")
    return {"table": _block(claims_table(results, {"fig3": 0.0, "fig4": 0.05})),
            "fig3_rebound": f"{rebound.pop():.1e}".replace("e-0", "e-")}


def _thousands(n: int) -> str:
    return f"{n:,}".replace(",", " ")


def graph_sizes(work: Path) -> dict:
    """The README's table of ``touchdown_step`` sizes (SX instructions)."""
    rows = ["| scene | method | 4 legs, plane at end | 4 legs, plane at start | "
            "2 legs, plane at end | contact step |", "|---|---|---|---|---|---|"]
    for name, title in (("fig3", "Fig. 3"), ("fig4", "Fig. 4")):
        base = load_scene(ROOT / "studies" / f"{name}.toml")
        for method in ("paper", "robust", "implicit"):
            scene = base.with_(method=method)
            sizes = [build_model(s).graph_size()["instructions"] for s in
                     (scene, scene.with_(tangent_plane="start"), scene.with_(legs=scene.legs[:2]))]
            sizes.append(contact_step(method, friction=scene.mu != 0).n_instructions())
            rows.append(f"| {title}, μ = {scene.mu:g} | {method} | "
                        + " | ".join(_thousands(n) for n in sizes) + " |")
    return {"table": _block("\n".join(rows))}


def recorded(work: Path) -> dict:
    """Results the long studies commit in figures/ (README, "Design, C code, ...")."""
    figures = ROOT / "figures"
    lander = json.loads((figures / "optimise_lander.json").read_text())
    wide = json.loads((figures / "design_for_envelope_wide_result.json").read_text())
    after = wide["after"]["p_stable"]
    with open(figures / "envelope_lander_pstable.csv", newline="") as fh:
        bands = [row for row in csv.DictReader(fh) if row["heading"] == "all headings"]
    stable = sum(int(row["stable"]) for row in bands)
    cases = sum(int(row["cases"]) for row in bands)
    p, low, high = (float(v) for v in wilson_interval(stable, cases))
    steepest = max(bands, key=lambda row: float(row["slope_hi_deg"]))
    return {
        "lander_status": lander["return_status"],
        "lander_iterations": str(lander["iterations"]),
        "lander_peak_before": f"{lander['initial_objective']:.1f}",
        "lander_peak_after": f"{lander['objective']:.1f}",
        "envelope_p_stable": f"{100 * p:.1f} % [{100 * low:.1f}, {100 * high:.1f}]",
        "envelope_cases": f"{cases:,}",
        "envelope_steepest": f"{100 * float(steepest['p']):.0f} %",
        "wide_before": f"{wide['before']['p_stable']['p']:.3f}",
        "wide_after": f"{after['p']:.3f} [{after['low']:.3f}, {after['high']:.3f}]",
    }


SOURCES = (
    Source("tutorial.lander", ("first_legs", "crush_mm", "peak_g", "late_touchdown_s", "hops",
                               "lift_off_s", "touchdown_again_s", "rest_s", "rest_speed_cm_s"),
           lander),
    Source("tutorial.design", ("status", "iterations", "peak", "efficiency", "ideal"), leg_design),
    Source("tutorial.envelope", ("stable", "p_stable", "interval", "failures"), envelope),
    Source("readme.absorber", ("status", "iterations", "efficiency"), absorber),
    Source("readme.claims", ("table", "fig3_rebound"), claims),
    Source("readme.graph", ("table",), graph_sizes),
    Source("readme.recorded", ("lander_status", "lander_iterations", "lander_peak_before",
                               "lander_peak_after", "envelope_p_stable", "envelope_cases",
                               "envelope_steepest", "wide_before", "wide_after"), recorded),
)


def all_keys(sources=SOURCES) -> set:
    """Every key the sources fill."""
    return {f"{s.name}.{key}" for s in sources for key in s.keys}


def quoted(root: Path = ROOT) -> list:
    """Every marker in the docs: (document, key, text) in document order."""
    return [(doc, m["key"], m["value"]) for doc in DOCS
            for m in MARKER.finditer((root / doc).read_text())]


def same(old: str, new: str) -> bool:
    """Whether two quoted texts agree, numbers at round-off (below ROUNDOFF) equal."""
    def normal(text):
        return _SCIENTIFIC.sub(lambda m: "~0" if abs(float(m[0])) < ROUNDOFF else m[0], text)
    return normal(old) == normal(new)


def stale(values: dict, root: Path = ROOT) -> list:
    """(document, key, old, new) of every marker whose text differs from its fresh value."""
    return [(doc, key, old, values[key]) for doc, key, old in quoted(root)
            if key in values and not same(old, values[key])]


def rewrite(values: dict, root: Path = ROOT) -> list:
    """Write fresh values between their markers (each document atomically); the changed docs."""
    changed = []
    for doc in DOCS:
        path = root / doc
        text = path.read_text()

        def fresh(m):
            key, old = m["key"], m["value"]
            new = values.get(key, old)
            return m[0] if same(old, new) else f"<!--q:{key}-->{new}<!--/q-->"

        updated = MARKER.sub(fresh, text)
        if updated != text:
            atomic_write_text(path, updated)
            changed.append(doc)
    return changed


def problems(sources=SOURCES, root: Path = ROOT) -> list:
    """Markers with no source, and keys of the sources that no document quotes."""
    known, found = all_keys(sources), {key for _, key, _ in quoted(root)}
    return ([f"{doc}: marker `{key}` is filled by no source" for doc, key, _ in quoted(root)
             if key not in known]
            + [f"key `{key}` is quoted in none of {', '.join(DOCS)}" for key in sorted(known - found)])


def difference(old: str, new: str) -> str:
    """``old -> new``; for a multi-line value, its first differing line and how many differ."""
    old_lines, new_lines = old.strip().splitlines(), new.strip().splitlines()
    if len(old_lines) == len(new_lines) == 1:
        return f"{old.strip()} -> {new.strip()}"
    pairs = [(i, a, b) for i, (a, b) in enumerate(zip(old_lines, new_lines)) if not same(a, b)]
    if not pairs:
        return f"{len(old_lines)} lines -> {len(new_lines)} lines"
    i, a, b = pairs[0]
    return f"{len(pairs)} of {len(new_lines)} lines differ; line {i + 1}: {a} -> {b}"


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--check", action="store_true",
                        help="compare without writing; exit 1 if a quoted value is stale")
    parser.add_argument("--only", nargs="+", metavar="SOURCE",
                        help="run only these sources (default: all; --list names them)")
    parser.add_argument("--list", action="store_true", help="list the sources and their keys")
    args = parser.parse_args(argv)
    if args.list:
        for s in SOURCES:
            print(f"{s.name}: {', '.join(s.keys)}")
        return 0
    names = [s.name for s in SOURCES]
    unknown = sorted(set(args.only or ()) - set(names))
    if unknown:
        parser.error(f"`--only` {', '.join(unknown)}: no such source; choose from {', '.join(names)}")
    errors = problems()
    for line in errors:
        print(f"error: {line}", file=sys.stderr)
    values = {}
    with tempfile.TemporaryDirectory(prefix="quoted-numbers-") as tmp:
        for s in SOURCES:
            if args.only is None or s.name in args.only:
                print(f"{s.name} ...", flush=True)
                values.update(s.run(Path(tmp) / s.name.replace(".", "_")))
    old = stale(values)
    for doc, key, before, after in old:
        print(f"{'stale' if args.check else 'updated'}: {doc}: {key}: "
              f"{difference(before, after)}")
    if not args.check:
        changed = rewrite(values)
        print(f"rewrote {', '.join(changed)}" if changed else "every quoted value is fresh")
    elif not old:
        print(f"{len(values)} quoted values fresh")
    return 2 if errors else (1 if args.check and old else 0)


if __name__ == "__main__":
    sys.exit(main())
