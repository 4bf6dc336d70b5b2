"""Sweep specs: errors name the file and key; dotted keys, ops and the case expansions."""

import numpy as np
import pytest

from gyrohost.sweep.errors import SpecError
from gyrohost.sweep.spec import apply, cases, load_spec, targets

HEAD = """
[sweep]
name = "t"
scene = "dbar-gyro"
{sweep}
"""
SPIN = """
[[axes]]
name = "spin_rad_s"
key = "bars.*.wheel.spin"
op = "magnitude"
{values}
"""


def write(tmp_path, text, name="s.toml"):
    path = tmp_path / name
    path.write_text(text)
    return path


def spec_text(sweep="", values="values = [10.0, 20.0]", extra=""):
    return HEAD.format(sweep=sweep) + SPIN.format(values=values) + extra


@pytest.mark.parametrize(
    "sweep, values, extra, key, says",
    [
        ("colour = 1", "values = [1.0]", "", "sweep.colour", "unknown key"),
        ("", "values = []", "", "axes[0].values", "non-empty list"),
        ("", 'values = ["x"]', "", "axes[0].values[0]", "finite number"),
        ("", "range = { start = 1.0, stop = 2.0 }", "", "axes[0].range.num", "whole number"),
        ('sampling = "lhs"\ncases = 4', "values = [1.0]", "", "axes[0]", "intervals"),
        ('sampling = "lhs"', "range = { start = 1.0, stop = 2.0 }", "", "sweep.cases", ">= 1"),
        ('record = ["tilt"]', "values = [1.0]", "", "sweep.record[0]", "no such metric"),
        ('record = ["energy:median"]', "values = [1.0]", "", "sweep.record[0]", "reducer"),
        ("", "values = [1.0]", '[integrator]\nintegrator = "euler"', "integrator.integrator", ""),
        ("", "values = [1.0]", '[plots]\nheatmap = "wall_time"', "plots.heatmap", "not an axis"),
        ("", "values = [1.0]", '[pareto]\ncost = "spin_rad_s"\ngoal = "wall_s"', "pareto", ""),
    ],
)
def test_spec_errors_name_the_file_and_key(tmp_path, sweep, values, extra, key, says):
    path = write(tmp_path, spec_text(sweep, values, extra), "bad-spec.toml")
    with pytest.raises(SpecError) as err:
        load_spec(path)
    assert str(err.value).startswith(f"bad-spec.toml: {key}: ")
    assert says in str(err.value)


def test_an_axis_key_not_in_the_scene_names_the_part_and_where(tmp_path):
    text = HEAD.format(sweep="") + SPIN.format(values="values = [1.0]").replace("spin", "spn", 1)
    text = text.replace('key = "bars.*.wheel.spin"', 'key = "bars.*.wheel.spn"')
    with pytest.raises(SpecError, match=r"s.toml: axes\[0\].key: .*no key 'spn' in bars.\*.wheel"):
        load_spec(write(tmp_path, text))


def test_an_op_that_cannot_change_the_value_is_an_error(tmp_path):
    text = spec_text().replace('key = "bars.*.wheel.spin"', 'key = "bars.0.wheel"')
    with pytest.raises(SpecError, match=r"axes\[0\].op: 'magnitude' cannot change"):
        load_spec(write(tmp_path, text))


def test_a_missing_spec_lists_the_shipped_ones():
    with pytest.raises(SpecError, match="shipped: .*dbar-turn"):
        load_spec("no-such-spec")


def test_the_shipped_dbar_turn_spec_has_200_cases():
    spec = load_spec("dbar-turn")
    assert len(list(cases(spec))) == 200
    assert [a.name for a in spec.axes] == ["spin_rad_s", "closure_s"]


def test_magnitude_keeps_the_spin_pattern_and_stretch_ends_the_schedule_at_the_value():
    spec = load_spec("dbar-turn")
    data = apply(spec.scene, spec.axes, (10.0, 6.0))
    base = [b["wheel"]["spin"] for b in spec.scene["bars"]]
    spins = [b["wheel"]["spin"] for b in data["bars"]]
    assert spins == [np.copysign(10.0, s) for s in base]
    for old, new in zip(spec.scene["strings"], data["strings"], strict=True):
        t0, t1 = old["rest_length"]["t"], new["rest_length"]["t"]
        assert t1[-1] == 6.0 and t1[0] == 0.0
        np.testing.assert_allclose(np.array(t1) / 6.0, np.array(t0) / t0[-1], rtol=1e-15)
        assert new["rest_length"]["value"] == old["rest_length"]["value"]
    assert spec.scene["bars"][0]["wheel"]["spin"] == base[0]  # the base is never changed


def test_a_part_may_name_an_element_by_its_name_or_index():
    data = {"strings": [{"name": "s13", "k": 1.0}, {"name": "s24", "k": 2.0}]}
    assert targets(data, "strings.s24.k") == [(data["strings"][1], "k")]
    assert targets(data, "strings.0.k") == [(data["strings"][0], "k")]
    with pytest.raises(KeyError, match="'s99' is no index"):
        targets(data, "strings.s99.k")


def test_latin_hypercube_is_seeded_and_stratified(tmp_path):
    lhs = 'sampling = "lhs"\ncases = 8\nseed = {seed}'
    rng = "range = { start = 10.0, stop = 50.0 }"
    first = list(cases(load_spec(write(tmp_path, spec_text(lhs.format(seed=3), rng)))))
    again = list(cases(load_spec(write(tmp_path, spec_text(lhs.format(seed=3), rng)))))
    other = list(cases(load_spec(write(tmp_path, spec_text(lhs.format(seed=4), rng)))))
    assert first == again and first != other
    strata = sorted(int((v[0] - 10.0) / 40.0 * 8) for v in first)
    assert strata == list(range(8))  # one point in each eighth of the interval


def test_grid_is_the_product_of_the_axes(tmp_path):
    closure = """
[[axes]]
name = "closure_s"
key = "strings.*.rest_length.t"
op = "stretch"
range = { start = 1.0, stop = 3.0, num = 3 }
"""
    spec = load_spec(write(tmp_path, spec_text(extra=closure)))
    assert list(cases(spec)) == [(a, b) for a in (10.0, 20.0) for b in (1.0, 2.0, 3.0)]
