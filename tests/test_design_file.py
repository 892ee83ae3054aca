"""The design's own file (symcushion.design.scene_file) and a study's touchdown as a scene.

The file a design writes must build the designed lander exactly — its legs'
geometry and curves — whether the legs stay a ``[legs]`` pattern or need a
``[[leg]]`` table each; ``simulate --case N`` must run the envelope's case N.
"""
from __future__ import annotations

import copy
import math
import tomllib

import numpy as np
import pytest
from hypothesis import example, given, settings, strategies as st

from symcushion.cli import main
from symcushion.design.optimise import study_from_dict
from symcushion.design.scene_file import designed_data, write_designed_file
from symcushion.envelope.cases import case_scene
from symcushion.envelope.study import study_from_dict as envelope_from_dict
from symcushion.model.scene import read_toml, scene_from_dict
from symcushion.model.toml_text import toml_text

from test_geometry_design import GEOMETRY, PRACTICAL

#: Tables of an optimise study that a scene file does not have.
OPTIMISE_TABLES = ("study", "scenario", "design", "limits", "solver")


def _lander_data(geometry=GEOMETRY):
    data = read_toml("studies/optimise_lander.toml", "study")
    data["scene"]["duration"] = 0.12
    data["scenario"] = data["scenario"][:2]
    data["design"]["geometry"] = copy.deepcopy(geometry)
    data["design"]["limits"] = dict(PRACTICAL)
    return data


def _scene_only(data):
    return {k: v for k, v in data.items() if k not in OPTIMISE_TABLES}


def _same_legs(scene, pb, theta):
    p = pb.p_of(theta)
    for j, leg in enumerate(scene.legs):
        G = pb.leg_geometry(theta, j)
        for key in ("hinge", "e0", "en"):
            np.testing.assert_allclose(getattr(leg, key), G[key], rtol=0, atol=1e-14)
        assert leg.length == pytest.approx(G["length"], rel=1e-15)
        for el in leg.elements:
            want = [p[pb.param_names.index(f"leg{j}.{el.name}.{n}")]
                    for n in el.curve.param_names] if el.curve.tunable else None
            if want is not None:
                np.testing.assert_array_equal(el.curve.param_values, want)


def test_a_symmetric_design_is_written_as_the_legs_pattern():
    data = _lander_data()
    pb = study_from_dict(copy.deepcopy(data), "lander.toml").problem
    theta = pb.initial.copy()
    theta[pb.var_names.index("hinge_radius")] = 0.6312
    theta[pb.var_names.index("length")] = 0.7719
    theta[pb.var_names.index("splay")] = math.radians(13.7)
    theta[0] = -2817.25                            # a crush-curve knot
    out = designed_data(_scene_only(data), pb, theta)
    assert "leg" not in out and out["legs"]["radius"] == pytest.approx(0.6312, rel=1e-15)
    assert out["legs"]["S"]["f"][0] == -2817.25 or -2817.25 in out["legs"]["S"]["f"]
    scene = scene_from_dict(tomllib.loads(toml_text(out)), "designed.toml")
    _same_legs(scene, pb, theta)
    assert "design" not in out and "robust" not in out


def test_legs_that_differ_are_written_one_table_each():
    geometry = [dict(quantity="length", lower=0.6, upper=1.0, shared=False, legs=[0, 2]),
                dict(quantity="splay", lower_deg=10.0, upper_deg=30.0)]
    data = _lander_data(geometry)
    pb = study_from_dict(copy.deepcopy(data), "lander.toml").problem
    theta = pb.initial.copy()
    theta[pb.var_names.index("leg0.length")] = 0.7
    theta[pb.var_names.index("splay")] = math.radians(22.0)
    out = designed_data(_scene_only(data), pb, theta)
    assert "legs" not in out and len(out["leg"]) == 4
    assert [t["length"] for t in out["leg"]] == [0.7, 0.8, 0.8, 0.8]
    scene = scene_from_dict(tomllib.loads(toml_text(out)), "designed.toml")
    _same_legs(scene, pb, theta)


def test_a_file_that_builds_another_lander_is_not_written(tmp_path):
    data = _lander_data()
    pb = study_from_dict(copy.deepcopy(data), "lander.toml").problem
    path = tmp_path / "designed.toml"

    def wrong(d):                                   # a loader that moves the hinges
        d["legs"]["radius"] += 0.01
        return scene_from_dict(d, "x")

    with pytest.raises(ValueError, match="geometry in the written file is not the design's"):
        write_designed_file(path, _scene_only(data), pb, pb.initial, wrong)
    assert not path.exists()
    write_designed_file(path, _scene_only(data), pb, pb.initial,
                        lambda d: scene_from_dict(d, "x"), header="a header\nof two lines")
    assert path.read_text().startswith("# a header\n# of two lines\n")


_scalars = st.one_of(st.booleans(), st.integers(-10**12, 10**12),
                     st.floats(allow_nan=False), st.text(max_size=12))
_keys = st.text(alphabet=st.characters(codec="utf-8", exclude_categories=("Cs",)),
                min_size=1, max_size=8)
_values = st.one_of(_scalars, st.lists(st.floats(allow_nan=False), max_size=4))
_tables = st.recursive(st.dictionaries(_keys, _values, max_size=4),
                       lambda inner: st.dictionaries(_keys, st.one_of(
                           _values, inner, st.lists(inner, min_size=1, max_size=2)),
                           max_size=4), max_leaves=12)


@settings(max_examples=150, deadline=None)
@given(_tables)
@example({"0\n": False})              # a key ending in a newline is quoted, not bare
def test_toml_text_reads_back_to_the_same_values(data):
    assert tomllib.loads(toml_text(data)) == data


def test_the_gradient_verdict_fails_a_check_above_its_level():
    from symcushion.design.optimise.gradient import GRADIENT_PASS, gradient_verdict

    check = dict(relative=3.6e-4, objective=1e-12, nonsmooth_rows=3, rows=180)
    passed, line = gradient_verdict(check, "the start")
    assert not passed and "FAILED (above 1e-05)" in line and "3 of 180 rows" in line
    assert gradient_verdict(dict(check, relative=GRADIENT_PASS / 2), "x")[0]
    assert not gradient_verdict(dict(check, relative=1e-9, objective=1e-3), "x")[0]


def test_toml_text_refuses_what_toml_cannot_hold():
    with pytest.raises(TypeError, match=r"`a.b` = None has no TOML form"):
        toml_text({"a": {"b": None}})
    with pytest.raises(TypeError, match="must be a dict"):
        toml_text([1, 2])


# ---------------------------------------------------------------------------
# `simulate --case` (the compiled checks of designed.toml and of a case's run are in
# tests/test_robust.py, beside the design run they reuse)
# ---------------------------------------------------------------------------
def test_simulate_case_refuses_a_scene_and_needs_a_case(tmp_path, capsys):
    assert main(["simulate", "studies/fig3.toml", "--case", "2", "--out", str(tmp_path)]) != 0
    assert "`--case` = 2 needs an envelope or design study file" in capsys.readouterr().err
    assert main(["simulate", "studies/envelope_lander.toml", "--out", str(tmp_path)]) != 0
    assert "give `--case N`" in capsys.readouterr().err
    data = read_toml("studies/envelope_lander.toml")
    study = envelope_from_dict(data, "envelope_lander.toml")
    with pytest.raises(ValueError, match=r"`case` = 10000 is not a touchdown .* 0 to 9999"):
        case_scene(study, 10000)
    with pytest.raises(TypeError, match="`case` must be an integer"):
        case_scene(study, 1.5)
