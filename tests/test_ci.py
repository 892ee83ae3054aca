"""CI installs what the tests need: the README's test command is the one .ci/run runs, with
every optional extra, and Chromium for the viewer's browser test."""
import re
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


def test_ci_runs_the_readme_test_command_with_every_extra_and_chromium():
    readme = (ROOT / "README.md").read_text()
    quick_start = re.search(r"```bash\n(.*?)```", readme, flags=re.S).group(1).splitlines()
    assert len(quick_start) == 2
    ci = (ROOT / ".ci" / "run").read_text()
    assert ci.rstrip().splitlines()[-1] == quick_start[1]
    extras = re.search(r"\.\[([a-z,]+)\]", quick_start[1]).group(1).split(",")
    pyproject = (ROOT / "pyproject.toml").read_text()
    for extra in extras:
        assert re.search(rf"^{extra} = \[", pyproject, flags=re.M), extra
    assert {"test", "peers", "dask", "viewer", "fmu"} <= set(extras)
    assert "apt-get install -y -qq chromium" in ci and "command -v chromium" in ci
