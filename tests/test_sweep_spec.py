"""Sweep specs: every user mistake is one SpecError line naming the source and the key;
valid specs expand to the documented grid (product, zip, zip groups, seeds, ranges)."""

from __future__ import annotations

import copy
import math
from decimal import Decimal

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from test_sweep_run import TASKS, TOY  # noqa: F401  (registers the analyses "test.toy", "test.tasks")

from jaxloco.errors import SpecError
from jaxloco.sweep import expand, load_spec, spec_from_dict
from jaxloco.sweep.ranges import arange

BASE = {"sweep": {"analysis": "test.toy"}, "params": {"a": [1.0, 2.0]}}


def _with(change):
    d = copy.deepcopy(BASE)
    change(d)
    return d


def _sweep(**kw):
    return lambda d: d["sweep"].update(kw)


def _params(**kw):
    return lambda d: d["params"].update(kw)


def _fixed(**kw):
    return lambda d: d.setdefault("fixed", {}).update(kw)


def _both(*changes):
    def apply(d):
        for change in changes:
            change(d)

    return apply


ERRORS = [
    # (change to BASE, the start of the message after "<dict>: ")
    (_sweep(chunk_sise=3), "sweep.chunk_sise: unknown key (did you mean 'chunk_size'?)"),
    (lambda d: d.update(fixd={}), "fixd: unknown key"),
    (lambda d: d["sweep"].pop("analysis"), "sweep.analysis: required key is missing"),
    (lambda d: d.pop("sweep"), "sweep: required key is missing"),
    (_sweep(analysis="no.such"), "sweep.analysis: unknown analysis 'no.such'"),
    (_sweep(chunk_size=0), "sweep.chunk_size: must be >= 1, got 0"),
    (_sweep(chunk_size="big"), "sweep.chunk_size: expected an integer, got 'big'"),
    (_sweep(seeds=0), "sweep.seeds: a seed count must be >= 1"),
    (_sweep(seeds=[]), "sweep.seeds: empty list"),
    (_sweep(seeds=[1, 2, 1]), "sweep.seeds: duplicate seed 1"),
    (_sweep(seeds=[-1]), "sweep.seeds: seed -1 is outside"),
    (_sweep(seeds=["x"]), "sweep.seeds[0]: expected an integer, got 'x'"),
    (_sweep(combine="cross"), "sweep.combine: expected 'product' or 'zip', got 'cross'"),
    (_sweep(formats=["xlsx"]), "sweep.formats[0]: expected 'parquet' or 'csv', got 'xlsx'"),
    (_sweep(name=""), "sweep.name: must not be empty"),
    (_sweep(name="../../../tmp/x"), "sweep.name: '../../../tmp/x' contains a path separator; a name is letters, "
                                    "digits, _, - and . (choose the directory with output or --out)"),
    (_sweep(name="a\\b"), "sweep.name: 'a\\\\b' contains a path separator"),
    (_sweep(name=".."), "sweep.name: '..' is not a name; a name is letters, digits, _, - and ."),
    (_sweep(name="."), "sweep.name: '.' is not a name"),
    (_sweep(name="my sweep"), "sweep.name: 'my sweep' contains ' '; a name is letters, digits, _, - and ."),
    (_sweep(name="x" * 101), "sweep.name: is 101 characters long, more than 100"),
    (_params(a={"start": 0, "stop": 1, "num": "ten"}), "params.a.num: expected an integer, got 'ten'"),
    (_params(a={"start": 0, "stop": 1, "num": 0}), "params.a.num: must be >= 1, got 0"),
    (_params(a={"start": 0, "stop": 1, "step": 0}), "params.a.step: must be > 0"),
    (_params(a={"start": 0, "stop": 1, "step": -0.1}), "params.a.step: must be > 0"),
    (_params(a={"start": 0, "stop": 1, "num": 3, "scale": "log"}), "params.a.start: log scale needs a value > 0"),
    (_params(a={"start": 1, "stop": -1, "num": 3, "scale": "log"}), "params.a.stop: log scale needs a value > 0"),
    (_params(a={"start": 1, "stop": 2, "step": 1, "scale": "log"}), 'params.a.scale: "log" needs num'),
    (_params(a={"start": 1, "stop": 2, "num": 3, "scale": "ln"}), "params.a.scale: expected 'linear' or 'log'"),
    (_params(a={"start": 0, "stop": 1, "num": 3, "step": 1}), "params.a: give num or step, not both"),
    (_params(a={"start": 0, "stop": 1}), "params.a: a range needs num or step"),
    (_params(a={"start": 0, "num": 3}), "params.a.stop: required key is missing"),
    (_params(a={"start": 0, "stop": 1, "nmu": 3}), "params.a.nmu: unknown key (did you mean 'num'?)"),
    (_params(a={"start": 1, "stop": 0, "step": 0.1}), "params.a: empty range"),
    (_params(a={"start": -math.inf, "stop": 1, "num": 2}), "params.a.start: expected a finite number"),
    (_params(a={"start": 0, "stop": 1, "num": 10**9}), "params.a.num: 1,000,000,000 is more than the limit"),
    (_params(a=[]), "params.a: empty list"),
    (_params(a=[0.0, 2.1, 11.0]), "params.a[2]: 11 m is outside [-10, 10]"),
    (_params(a=[0.0, "x"]), "params.a[1]: expected a number, got 'x'"),
    (_params(a=[math.nan]), "params.a[0]: expected a finite number"),
    (_params(a={"start": 5, "stop": 25, "num": 3}), "params.a[1]: 15 m is outside"),
    (_params(a=0.5), "params.a: expected a list of values or a range"),
    (_params(zz=[1.0]), "params.zz: unknown parameter 'zz' for analysis 'test.toy'"),
    (_params(n=[1, 2]), "params.n: 'n' cannot be swept"),
    (_params(label=["x", "y"]), "params.label: 'label' is a string parameter without choices; a swept string needs"),
    (_params(flag={"start": 0, "stop": 1, "num": 2}), "params.flag: a range needs a numeric parameter"),
    (_params(m={"start": 0, "stop": 3, "num": 3}), "params.m[1]: expected an integer, got 1.5"),
    (_params(m=[1, 2.5]), "params.m[1]: expected an integer, got 2.5"),
    (_params(flag=[1]), "params.flag[0]: expected true or false, got 1"),
    (lambda d: d.update(params=[1]), "params: expected a table, got [1]"),
    (_fixed(zz=1.0), "fixed.zz: unknown parameter 'zz'"),
    (_fixed(a=0.5), "params.a: 'a' is also set in [fixed]"),
    (_fixed(n=0), "fixed.n: 0 is outside [1, 16]"),
    (_fixed(flag=1), "fixed.flag: expected true or false, got 1"),
    (_fixed(label=3), "fixed.label: expected a string, got 3"),
    (
        _both(_params(b=[1.0]), _sweep(zip=[["a", "b"]])),
        "sweep.zip[0]: zipped parameters need equal lengths, got a: 2, b: 1",
    ),
    (_sweep(zip=[["a", "zz"]]), "sweep.zip[0][1]: unknown parameter 'zz'"),
    (_sweep(zip=[["a", "flag"]]), "sweep.zip[0][1]: 'flag' is not swept"),
    (_sweep(zip=[[]]), "sweep.zip[0]: empty group"),
    (_sweep(zip=["a"]), "sweep.zip[0]: expected a list, got 'a'"),
    (_both(_params(b=[1.0, 2.0]), _sweep(zip=[["a", "b"], ["b"]])), "sweep.zip[1][0]: 'b' is already in sweep.zip[0]"),
    (_sweep(combine="zip", zip=[["a"]]), 'sweep.zip: only allowed with combine = "product"'),
    (_both(_params(b=[1.0]), _sweep(combine="zip")), "params.b: has 1 value but params.a has 2 values"),
    (
        _params(a={"start": 0, "stop": 1, "num": 10**4}, b={"start": 0, "stop": 1, "num": 10**5}),
        "params: the sweep has",
    ),
]


@pytest.mark.parametrize(
    "change, message", ERRORS, ids=[m.split(":")[0] + "-" + str(i) for i, (_, m) in enumerate(ERRORS)]
)
def test_spec_errors_name_the_key(change, message):
    with pytest.raises(SpecError) as info:
        spec_from_dict(_with(change))
    text = str(info.value)
    assert text.startswith("<dict>: " + message), text
    assert "\n" not in text


TASK_ERRORS = [
    # (analysis, params, the whole message after "<dict>: ")
    ("test.tasks", {"task": ["walk", "run"]}, "params.task[1]: 'run' is not one of 'walk', 'climb', 'swim'"),
    ("test.tasks", {"task": ["walk", 3]}, "params.task[1]: expected a string, got 3"),
    ("test.tasks", {"task": []}, "params.task: empty list; give at least one value"),
    (
        "test.tasks",
        {"task": "walk"},
        (
            "params.task: expected a list of values or a range {start, stop, num} / {start, stop, step}, got 'walk';"
            " a single value belongs in [fixed]"
        ),
    ),
    (
        "test.tasks",
        {"task": {"start": 0, "stop": 1, "num": 2}},
        (
            "params.task: a range needs a numeric parameter; 'task' is a string: list its values"
            " (one of 'walk', 'climb', 'swim')"
        ),
    ),
    (
        "test.tasks",
        {"note": ["x", "y"]},
        "params.note: 'note' is a string parameter without choices; a swept string needs choices; set it in [fixed]",
    ),
    (
        "test.tasks",
        {"mode": ["a", "b"]},
        "params.mode: 'mode' cannot be swept (it changes the compiled program); set it in [fixed]",
    ),
    (
        "test.tasks_jax",
        {"task": ["walk"]},
        (
            "params.task: 'task' is a string parameter and this analysis runs under JAX (executor 'jax'),"
            " which cannot take strings; set it in [fixed]"
        ),
    ),
]


@pytest.mark.parametrize("analysis, params, message", TASK_ERRORS, ids=[m.split(":")[0] for *_, m in TASK_ERRORS])
def test_string_param_errors_are_one_line(analysis, params, message):
    with pytest.raises(SpecError) as info:
        spec_from_dict({"sweep": {"analysis": analysis}, "params": params})
    assert str(info.value) == "<dict>: " + message


def test_string_params_from_toml(tmp_path):
    path = tmp_path / "tasks.toml"
    path.write_text('[sweep]\nanalysis = "test.tasks"\n[fixed]\nnote = "hi"\n'
                    '[params]\ntask = ["swim", "climb"]\nspeed = [1.0, 2.0, 3.0]\n')
    spec = load_spec(path)
    assert spec.swept == {"task": ("swim", "climb"), "speed": (1.0, 2.0, 3.0)} and spec.fixed["note"] == "hi"
    assert spec.n_rows == 6 and expand(spec).columns["task"].tolist() == ["swim"] * 3 + ["climb"] * 3

    def from_dict(tasks):
        d = {
            "sweep": {"analysis": "test.tasks"},
            "fixed": {"note": "hi"},
            "params": {"task": tasks, "speed": [1, 2, 3.0]},
        }
        return spec_from_dict(d)

    assert from_dict(np.array(["swim", "climb"])).hash == spec.hash  # a numpy array of str is a list
    assert from_dict(["climb", "swim"]).hash != spec.hash  # the order of the values is the row order


def test_file_errors(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    (tmp_path / "sweeps").mkdir()
    cases = {
        "sweeps/missing.toml": "sweeps/missing.toml: no such file",
        "sweeps": "sweeps: is a directory",
    }
    (tmp_path / "sweeps" / "bad.toml").write_text('[sweep]\nanalysis = "test.toy"\nx = = 3\n')
    cases["sweeps/bad.toml"] = "sweeps/bad.toml: invalid TOML: Invalid value (at line 3, column 5)"
    (tmp_path / "sweeps" / "bin.toml").write_bytes(b"\xff\xfe[sweep]")
    cases["sweeps/bin.toml"] = "sweeps/bin.toml: not UTF-8 text"
    (tmp_path / "sweeps" / "x.toml").write_text('[sweep]\nanalysis = "test.toy"\n[params]\na = [2.1, 12.0]\n')
    cases["sweeps/x.toml"] = "sweeps/x.toml: params.a[1]: 12 m is outside [-10, 10]"
    for path, message in cases.items():
        with pytest.raises(SpecError) as info:
            load_spec(path)
        assert str(info.value).startswith(message), str(info.value)


def test_load_spec_defaults(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    (tmp_path / "my_sweep.toml").write_text('[sweep]\nanalysis = "test.toy"\n')
    spec = load_spec("my_sweep.toml")
    assert spec.name == "my_sweep"
    assert str(spec.output) == "results/my_sweep"
    assert spec.chunk_size == 256 and spec.seeds == (0,) and spec.combine == "product"
    assert spec.formats == ("parquet",)
    assert spec.swept == {} and spec.factors == () and spec.n_rows == 1
    # every non-swept parameter, in the analysis' order, with its default
    assert dict(spec.fixed) == {"a": 1.0, "b": 0.0, "m": 0, "n": 3, "flag": False, "label": "toy"}
    assert spec.source == "my_sweep.toml"


def test_plain_names_are_accepted():
    for name in ("a", "snake_kv-v2.1", "...", "x" * 100):
        assert spec_from_dict(_with(_sweep(name=name))).output.parts == ("results", name)


def test_default_name_from_an_odd_file_stem(tmp_path, monkeypatch):
    """The file stem is the default name with other characters replaced by "_"; a stem
    that still is no name ("..") asks for `name`."""
    monkeypatch.chdir(tmp_path)
    (tmp_path / "my sweep (v2).toml").write_text('[sweep]\nanalysis = "test.toy"\n')
    spec = load_spec("my sweep (v2).toml")
    assert spec.name == "my_sweep_v2_" and str(spec.output) == "results/my_sweep_v2_"
    (tmp_path / "...toml").write_text('[sweep]\nanalysis = "test.toy"\n')  # stem ".."
    with pytest.raises(SpecError) as info:
        load_spec("...toml")
    assert str(info.value) == ("...toml: sweep.name: not given, and the file's stem '..' cannot be the name ('..' is "
                               "not a name; a name is letters, digits, _, - and .); set name in [sweep]")
    (tmp_path / "named.toml").write_text('[sweep]\nanalysis = "test.toy"\nname = "fine"\n')
    assert load_spec("named.toml").name == "fine"


def test_full_toml_example(tmp_path):
    path = tmp_path / "ex.toml"
    path.write_text(
        """
[sweep]
analysis = "test.toy"
name = "ex"
output = "elsewhere/ex"
chunk_size = 128
seeds = 3
zip = [["a", "b"]]
formats = ["parquet", "csv"]

[fixed]
n = 5
label = "x"

[params]
a = { start = -0.5, stop = 0.5, num = 101 }
flag = [true, false]
b = { start = 1.0, stop = 100.0, num = 101, scale = "log" }
m = { start = 2, stop = 10, step = 2 }
"""
    )
    spec = load_spec(path)
    assert spec.factors == (("a", "b"), ("flag",), ("m",))
    assert spec.n_rows == 101 * 2 * 5 * 3
    assert spec.seeds == (0, 1, 2) and spec.chunk_size == 128 and str(spec.output) == "elsewhere/ex"
    assert spec.formats == ("parquet", "csv")
    assert spec.swept["m"] == (2, 4, 6, 8, 10)
    assert all(type(v) is int for v in spec.swept["m"])
    assert spec.fixed == {"n": 5, "label": "x"}


def test_linspace_values_are_the_decimal_ones():
    spec = spec_from_dict(_with(_params(a={"start": -0.5, "stop": 0.5, "num": 101})))
    values = spec.swept["a"]
    assert len(values) == 101 and values[0] == -0.5 and values[-1] == 0.5
    assert values[60] == 0.1 and values[37] == -0.13
    assert values == tuple(float(Decimal("-0.5") + Decimal("0.01") * i) for i in range(101))
    single = spec_from_dict(_with(_params(a={"start": 0.3, "stop": 0.7, "num": 1})))
    assert single.swept["a"] == (0.3,)


def test_log_and_step_ranges():
    log = spec_from_dict(_with(_params(a={"start": 0.01, "stop": 10.0, "num": 4, "scale": "log"}))).swept["a"]
    assert log[0] == 0.01 and log[-1] == 10.0 and log == pytest.approx((0.01, 0.1, 1.0, 10.0), rel=1e-12)
    step = spec_from_dict(_with(_params(a={"start": 0.02, "stop": 0.1, "step": 0.02}))).swept["a"]
    assert step == (0.02, 0.04, 0.06, 0.08, 0.1)
    short = spec_from_dict(_with(_params(a={"start": 0.0, "stop": 1.0, "step": 0.3}))).swept["a"]
    assert short == (0.0, 0.3, 0.6, 0.9)
    third = 1.0 / 3.0
    lands = spec_from_dict(_with(_params(a={"start": 0.0, "stop": 1.0, "step": third}))).swept["a"]
    assert len(lands) == 4 and lands[-1] == 1.0
    just_over = spec_from_dict(_with(_params(a={"start": 0.0, "stop": 1.0 + 1e-12, "step": 0.5}))).swept["a"]
    assert just_over == (0.0, 0.5, 1.0 + 1e-12)
    not_quite = spec_from_dict(_with(_params(a={"start": 0.0, "stop": 1.0 - 1e-6, "step": 0.5}))).swept["a"]
    assert not_quite == (0.0, 0.5)


@settings(max_examples=60, deadline=None)
@given(
    start=st.floats(-1e3, 1e3, allow_nan=False),
    step=st.floats(1e-3, 10.0, allow_nan=False),
    count=st.integers(0, 200),
)
def test_arange_hits_a_stop_that_lies_on_a_step(start, step, count):
    stop = start + count * step
    values = arange(start, stop, step)
    assert len(values) == count + 1
    assert values[0] == start and values[-1] == stop
    assert all(b > a for a, b in zip(values, values[1:]))


def test_product_order_seeds_innermost():
    spec = spec_from_dict(_with(_both(_params(a=[1.0, 2.0], flag=[True, False]), _sweep(seeds=[7, 3]))))
    grid = expand(spec)
    cols = grid.columns
    assert cols["a"].tolist() == [1.0] * 4 + [2.0] * 4
    assert cols["flag"].tolist() == [True, True, False, False] * 2
    assert cols["seed"].tolist() == [7, 3] * 4
    assert cols["a"].dtype == np.float64 and cols["flag"].dtype == np.bool_ and cols["seed"].dtype == np.int64
    part, seed_pos = grid.rows(3, 6)
    assert part["a"].tolist() == [1.0, 2.0, 2.0] and seed_pos.tolist() == [1, 0, 1]


def test_combine_zip():
    spec = spec_from_dict(_with(_both(_params(a=[1.0, 2.0, 3.0], b=[10.0, 20.0, 30.0]), _sweep(combine="zip"))))
    cols = expand(spec).columns
    assert list(zip(cols["a"].tolist(), cols["b"].tolist())) == [(1.0, 10.0), (2.0, 20.0), (3.0, 30.0)]


def test_zip_groups_then_product_in_params_order():
    change = _both(
        lambda d: d.update(params={"flag": [True, False], "a": [1.0, 2.0, 3.0], "m": [5, 6], "b": [10.0, 20.0, 30.0]}),
        _sweep(zip=[["b", "a"]]),
    )
    spec = spec_from_dict(_with(change))
    assert spec.factors == (("flag",), ("a", "b"), ("m",))
    cols = expand(spec).columns
    assert len(cols["a"]) == 2 * 3 * 2
    rows = list(zip(cols["flag"].tolist(), cols["a"].tolist(), cols["b"].tolist(), cols["m"].tolist()))
    assert rows[:4] == [(True, 1.0, 10.0, 5), (True, 1.0, 10.0, 6), (True, 2.0, 20.0, 5), (True, 2.0, 20.0, 6)]
    assert rows[-1] == (False, 3.0, 30.0, 6)
    assert cols["m"].dtype == np.int64


def test_hash_covers_what_decides_rows_only():
    def h(change=lambda d: None):
        return spec_from_dict(_with(change)).hash

    base = h()
    assert base == h()
    assert base == h(_sweep(output="x/y", name="other", formats=["csv"]))
    assert base != h(_params(a=[1.0, 2.5]))
    assert base != h(_sweep(seeds=2))
    assert base != h(_sweep(chunk_size=7))
    assert base != h(_fixed(b=0.5))
    assert base == h(_fixed(b=0.0))  # the default, written out
    two = _params(a=[1.0, 2.0], b=[3.0, 4.0])
    assert h(_both(two, _sweep(combine="zip"))) == h(_both(two, _sweep(zip=[["a", "b"]])))
    assert h(_both(two, _sweep(combine="zip"))) != h(two)


def test_with_options_and_numpy_values():
    spec = spec_from_dict(
        {"sweep": {"analysis": "test.toy", "seeds": np.int64(2)}, "params": {"a": np.linspace(0, 1, 3)}}
    )
    assert spec.swept["a"] == (0.0, 0.5, 1.0) and spec.seeds == (0, 1)
    changed = spec.with_options(output="o", chunk_size=5, csv=True)
    assert (str(changed.output), changed.chunk_size, changed.formats) == ("o", 5, ("parquet", "csv"))
    assert changed.with_options(csv=False).formats == ("parquet",)
    with pytest.raises(SpecError, match="--chunk-size: must be an integer >= 1"):
        spec.with_options(chunk_size=0)
