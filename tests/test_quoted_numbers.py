"""The numbers README.md and docs/tutorial.md quote are the code's (studies/quoted_numbers.py).

The fast tests check the markers against the script's keys and the
comparison and rewriting on a copy of the docs; the slow one runs every
computation behind the quoted numbers (about half a minute to a minute on
two cores) with ``--check``.
"""
import importlib.util
import os
import re
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
SCRIPT = ROOT / "studies" / "quoted_numbers.py"
#: Ceiling of the slow check's wall time (s): the whole run takes 25-60 s on
#: two cores; far more means a computation grew and belongs in a cheaper subset.
CHECK_SECONDS = 600


def _script():
    spec = importlib.util.spec_from_file_location("quoted_numbers", SCRIPT)
    module = importlib.util.module_from_spec(spec)
    sys.modules[spec.name] = module     # dataclasses look their module up by name
    spec.loader.exec_module(module)
    return module


qn = _script()


def test_every_marker_has_a_source_and_every_key_is_quoted():
    assert qn.problems() == []
    keys = [key for _, key, _ in qn.quoted()]
    assert set(keys) == qn.all_keys()


def test_markers_sit_inside_lines_and_blocks_on_their_own():
    """A marker opening a line would start an HTML block and swallow its line's Markdown."""
    for doc in qn.DOCS:
        text = (ROOT / doc).read_text()
        for m in qn.MARKER.finditer(text):
            line_start = text.rfind("\n", 0, m.start()) + 1
            before = text[line_start:m.start()]
            if m["value"].startswith("\n"):
                assert before == "" and m["value"].startswith("\n\n") \
                    and m["value"].endswith("\n\n"), (doc, m["key"])
            else:
                assert before.strip(), (doc, m["key"], "marker opens a line")
                assert "\n\n" not in m["value"], (doc, m["key"])


def test_markers_are_invisible_outside_code():
    """No marker inside a fenced code block, where GitHub would print it."""
    for doc in qn.DOCS:
        for block in re.findall(r"```.*?```", (ROOT / doc).read_text(), flags=re.S):
            assert "<!--q:" not in block, doc


@pytest.fixture()
def docs_copy(tmp_path):
    for doc in qn.DOCS:
        (tmp_path / doc).parent.mkdir(parents=True, exist_ok=True)
        shutil.copyfile(ROOT / doc, tmp_path / doc)
    return tmp_path


def test_a_changed_value_is_named_stale_and_rewritten(docs_copy):
    values = {key: text for _, key, text in qn.quoted(docs_copy)}
    assert qn.stale(values, docs_copy) == []
    values["tutorial.envelope.p_stable"] = "0.999"
    (stale,) = qn.stale(values, docs_copy)
    doc, key, _, new = stale
    assert (doc, key, new) == ("docs/tutorial.md", "tutorial.envelope.p_stable", "0.999")
    assert qn.rewrite(values, docs_copy) == ["docs/tutorial.md"]
    assert "<!--q:tutorial.envelope.p_stable-->0.999<!--/q-->" in \
        (docs_copy / "docs" / "tutorial.md").read_text()
    assert qn.stale(values, docs_copy) == []
    assert (docs_copy / "README.md").read_text() == (ROOT / "README.md").read_text()


def test_roundoff_digits_are_not_stale_but_other_digits_are():
    assert qn.same("| 3.33e-16 |", "| 4.44e-16 |")
    assert qn.same("excess 4.0e-16", "excess 2.2e-16")
    assert not qn.same("| 5.04e-06 |", "| 5.05e-06 |")
    assert not qn.same("0.535", "0.309")


def test_a_marker_without_a_source_is_reported(docs_copy):
    path = docs_copy / "README.md"
    path.write_text(path.read_text() + "\nsee <!--q:readme.nothing-->1<!--/q-->\n")
    assert qn.problems(root=docs_copy) == ["README.md: marker `readme.nothing` is filled by "
                                           "no source"]


@pytest.mark.slow
def test_quoted_numbers_are_fresh():
    """Run every computation behind the quoted numbers; fail naming each stale value."""
    env = dict(os.environ, PYTHONPATH=os.pathsep.join(
        [str(ROOT)] + [p for p in os.environ.get("PYTHONPATH", "").split(os.pathsep) if p]))
    run = subprocess.run([sys.executable, str(SCRIPT), "--check"], cwd=ROOT, env=env,
                         capture_output=True, text=True, timeout=CHECK_SECONDS)
    stale = [line for line in run.stdout.splitlines() if line.startswith("stale:")]
    assert run.returncode == 0, "\n".join(stale) or run.stdout[-2000:] + run.stderr[-2000:]
