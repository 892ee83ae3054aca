"""Screenshots of the viewer (docs/tutorial.md, "The viewer and MAT files"), into figures/viewer/.

Simulates the tutorial lander (``symcushion simulate studies/tutorial/lander.toml``, 1 s)
into a temporary folder, writes its page (``symcushion view``) and takes screenshots at
:data:`TIMES` in one headless Chromium (``symcushion.viz.viewer.screenshots``, which steps the
slider through the page's ``#t=`` hook). Needs the extra ``viewer`` (plotly) and Chromium;
under a minute.

Usage: ``python studies/tutorial/viewer_screenshots.py [--figures DIR]``.
"""
from __future__ import annotations

import argparse
import tempfile
from pathlib import Path

from symcushion.cli import main as cli
from symcushion.viz.viewer import screenshots

HERE = Path(__file__).resolve().parent
ROOT = HERE.parents[1]

#: Times shown (s): the uphill feet crushing as leg 0 lands, the hop (all feet free),
#: and the lander at rest.
TIMES = (0.03, 0.07, 0.6)


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--figures", type=Path, default=ROOT / "figures" / "viewer",
                        help="where the screenshots go (default: figures/viewer)")
    args = parser.parse_args(argv)
    args.figures.mkdir(parents=True, exist_ok=True)
    with tempfile.TemporaryDirectory(prefix="symcushion-viewer-") as tmp:
        assert cli(["simulate", str(HERE / "lander.toml"), "--out", tmp, "--no-plots"]) == 0
        page = Path(tmp) / "lander.html"
        assert cli(["view", str(Path(tmp) / "lander"), "--out", str(page)]) == 0
        pngs = [args.figures / f"lander_t{t:.2f}.png" for t in TIMES]
        screenshots(page, TIMES, pngs)
    print("wrote " + ", ".join(str(p) for p in pngs))


if __name__ == "__main__":
    main()
