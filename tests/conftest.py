"""Shared fixtures: the canonical scenes and the random contact-case generator.

The scenes are the study files of the repository (``studies/fig3.toml``,
``studies/fig4.toml``, ``studies/lander_slope.toml``) loaded once per test
session; tests that need a variant derive it with ``scene.with_(...)``, which
returns a new scene and leaves the shared one unchanged. A separately started Dask scheduler with two worker
processes (``dask_scheduler``) serves the tests of the cluster paths. The contact-case
generator is :func:`oracle_contact.random_cases` (pytest puts this folder on
``sys.path``, so the oracle module imports without path manipulation).

The research studies (``research/``, e.g. ``from research import event_order``)
and the benchmark scripts (``studies/``, e.g. ``from bench_contact import
plane_parallel_cases``) are not part of the installed package; this file puts the
repository root and ``studies/`` on ``sys.path`` so that the tests import them from
the checkout, the one place those paths are set.
"""
import subprocess
import sys
import time
from pathlib import Path

# research/ lives beside the package, not in it, and is never installed: the
# tests import it from this checkout (before any test module is collected); the
# scripts of studies/ share their case generators with the tests the same way.
ROOT = Path(__file__).resolve().parents[1]
for folder in (ROOT, ROOT / "studies"):
    if str(folder) not in sys.path:
        sys.path.insert(0, str(folder))

import numpy as np
import pytest

import oracle_contact
from symcushion.legs.characteristics import Linear
from symcushion.model.obstacles import Plane
from symcushion.model.scene import Body, Scene, load_scene, symmetric_legs

STUDIES = ROOT / "studies"


@pytest.fixture(scope="session")
def fig3_scene() -> Scene:
    """The Fig. 3 scene: 50 kg ball on four rigid rods, frictionless dome."""
    return load_scene(STUDIES / "fig3.toml")


@pytest.fixture(scope="session")
def fig4_scene() -> Scene:
    """The Fig. 4 scene: Fig. 3 with μ = 0.05."""
    return load_scene(STUDIES / "fig4.toml")


@pytest.fixture(scope="session")
def lander_scene() -> Scene:
    """A four-legged lander on a 10° slope (the 3-D scene of the speed study)."""
    return load_scene(STUDIES / "lander_slope.toml")


def make_sled(theta, mu, method="implicit") -> Scene:
    """Four vertical legs whose feet are level with the centre of mass (no pitching),
    standing on a plane inclined by ``theta`` (rad) with friction ``mu``."""
    legs = symmetric_legs(4, 0.4, 0.5, 0.5, (0, 0, -1), (-0.6, 0, -0.8), S=Linear(1e5),
                          M_beta=Linear(3e3), M_gamma=Linear(3e3), azimuth0=np.pi / 4)
    attitude = [np.cos(theta / 2), 0, np.sin(theta / 2), 0]   # body z along the slope normal
    body = Body(mass=40.0, inertia=[1e6, 1e6, 1e6], position=[0, 0, 0.01], attitude=attitude)
    return Scene(body, legs, [Plane.inclined(theta)], mu=mu, method=method, dt=1e-3,
                 duration=2.0)


@pytest.fixture(scope="session")
def sled_scene():
    """Factory ``sled_scene(theta, mu, method="implicit")`` of the sled on an incline."""
    return make_sled


@pytest.fixture(scope="session")
def random_contact_cases():
    """Factory ``random_contact_cases(seed, count, kind="mixed")`` of contact-step cases
    (dicts of P0, Dp, n, l, mu, u0; kinds as in :func:`oracle_contact.random_cases`)."""
    def make(seed, count, kind="mixed"):
        return oracle_contact.random_cases(np.random.default_rng(seed), count, kind)
    return make


#: Seconds to wait for a separately started Dask scheduler and its workers.
DASK_START_TIMEOUT = 60.0


@pytest.fixture(scope="session")
def dask_scheduler(tmp_path_factory):
    """Address of a Dask scheduler started as its own process, with two single-threaded
    worker processes (``dask scheduler`` and ``dask worker`` as on a cluster)."""
    distributed = pytest.importorskip("distributed", reason="the Dask paths need the optional "
                                                            "extra symcushion[dask]")
    folder = tmp_path_factory.mktemp("dask")
    info = folder / "scheduler.json"
    quiet = dict(stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, cwd=folder)
    procs = [subprocess.Popen([sys.executable, "-m", "distributed.cli.dask_scheduler",
                               "--scheduler-file", str(info), "--port", "0",
                               "--no-dashboard"], **quiet)]
    try:
        deadline = time.monotonic() + DASK_START_TIMEOUT
        while not info.exists():
            if time.monotonic() > deadline or procs[0].poll() is not None:
                pytest.fail("the Dask scheduler did not start")
            time.sleep(0.2)
        procs.append(subprocess.Popen([sys.executable, "-m", "distributed.cli.dask_worker",
                                       "--scheduler-file", str(info), "--nworkers", "2",
                                       "--nthreads", "1", "--no-dashboard"], **quiet))
        with distributed.Client(scheduler_file=str(info)) as client:
            client.wait_for_workers(2, timeout=DASK_START_TIMEOUT)
            address = client.scheduler.address
        yield address
    finally:
        for proc in reversed(procs):
            proc.terminate()
        for proc in procs:
            try:
                proc.wait(timeout=20)
            except subprocess.TimeoutExpired:
                proc.kill()


#: Simulated time of the shared tutorial run (s): both touchdowns, the crush and a lift-off.
TUTORIAL_RUN_DURATION = "0.3"


@pytest.fixture(scope="session")
def tutorial_result(tmp_path_factory):
    """The result folder of ``symcushion simulate studies/tutorial/lander.toml`` (0.3 s, no
    figures): trajectory.csv, .npz, .mat and run.json of a three-legged lander on a 5° plane."""
    from symcushion.cli import main

    out = tmp_path_factory.mktemp("tutorial")
    code = main(["simulate", str(STUDIES / "tutorial" / "lander.toml"), "--out", str(out),
                 "--duration", TUTORIAL_RUN_DURATION, "--no-plots"])
    assert code == 0
    return out / "lander"
