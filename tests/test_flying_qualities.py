"""Flying qualities (``flightid.export.flying_qualities``): the MIL-F-8785C limits table
against hand-written expectations, level verdicts with σ at the boundaries, CAP from n/α."""

from __future__ import annotations

import contextlib
import io
import json
import math
import tomllib

import numpy as np
import pytest

from data_paths import DATA, ROOT, needs_data
from flightid.cases.spec import CaseError, parse_case
from flightid.cli.main import main
from flightid.errors import InputError
from flightid.export.flying_qualities import (
    AIRPLANE_CLASSES,
    LIMITS,
    FlyingQualitiesError,
    flying_qualities,
    limits_for,
    load_factor_per_alpha,
)
from flightid.model.linearization import linearize
from flightid.model.modes import Mode, Modes
from flightid.numbers import format_with_sigma
from test_predict import short_period

NAN = math.nan


def bounds(criterion, cls, cat):
    return {lvl: (lim.minimum, lim.maximum) for lvl, lim in limits_for(criterion, cls, cat).items()}


DRF = "dutch_roll_damping_frequency"
# hand-written from MIL-F-8785C 3.2.2.1.2, 3.2.2.1.1, 3.3.1.1, 3.3.1.2, 3.3.1.3
EXPECTED = [
    ("short_period_damping", "IV", "A", {1: (0.35, 1.30), 2: (0.25, 2.0), 3: (0.15, None)}),
    ("short_period_damping", "II-L", "C", {1: (0.35, 1.30), 2: (0.25, 2.0), 3: (0.15, None)}),
    ("short_period_damping", "III", "B", {1: (0.30, 2.0), 2: (0.20, 2.0), 3: (0.15, None)}),
    ("cap", "IV", "A", {1: (0.28, 3.6), 2: (0.16, 10.0), 3: (None, None)}),
    ("dutch_roll_damping", "I", "A", {1: (0.19, None), 2: (0.02, None), 3: (0.0, None)}),
    ("dutch_roll_damping", "III", "C", {1: (0.08, None), 2: (0.02, None), 3: (0.0, None)}),
    ("dutch_roll_frequency", "IV", "A", {1: (1.0, None), 2: (0.4, None), 3: (0.4, None)}),
    ("dutch_roll_frequency", "II", "A", {1: (0.4, None), 2: (0.4, None), 3: (0.4, None)}),
    ("dutch_roll_frequency", "II-C", "C", {1: (1.0, None), 2: (0.4, None), 3: (0.4, None)}),
    (DRF, "IV", "A", {1: (0.35, None), 2: (0.05, None), 3: (None, None)}),
    (DRF, "II-L", "C", {1: (0.10, None), 2: (0.05, None), 3: (None, None)}),
    (DRF, "I", "B", {1: (0.15, None), 2: (0.05, None), 3: (None, None)}),
    ("roll_time_constant", "IV", "A", {1: (None, 1.0), 2: (None, 1.4), 3: (None, 10.0)}),
    ("roll_time_constant", "III", "A", {1: (None, 1.4), 2: (None, 3.0), 3: (None, 10.0)}),
    ("roll_time_constant", "I", "B", {1: (None, 1.4), 2: (None, 3.0), 3: (None, 10.0)}),
    ("roll_time_constant", "II-C", "C", {1: (None, 1.0), 2: (None, 1.4), 3: (None, 10.0)}),
    ("roll_time_constant", "II-L", "C", {1: (None, 1.4), 2: (None, 3.0), 3: (None, 10.0)}),
    ("spiral_time_to_double", "IV", "A", {1: (12.0, None), 2: (8.0, None), 3: (4.0, None)}),
    ("spiral_time_to_double", "III", "B", {1: (20.0, None), 2: (8.0, None), 3: (4.0, None)}),
    ("spiral_time_to_double", "I", "C", {1: (12.0, None), 2: (8.0, None), 3: (4.0, None)}),
]  # fmt: skip


@pytest.mark.parametrize(("criterion", "cls", "cat", "expected"), EXPECTED)
def test_limits_table_lookups(criterion, cls, cat, expected):
    assert bounds(criterion, cls, cat) == expected


def test_every_limit_names_its_paragraph_and_the_unverified_say_why():
    for limit in LIMITS:
        assert limit.source.startswith("MIL-F-8785C 3.")
        assert limit.verified or limit.why
    unverified = {(lim.criterion, lim.level) for lim in LIMITS if not lim.verified}
    assert ("spiral_time_to_double", 2) in unverified
    assert ("dutch_roll_damping", 3) in unverified
    assert ("cap", 3) in unverified
    spiral = {(lim.classes, lim.categories): lim.verified for lim in LIMITS
              if lim.criterion == "spiral_time_to_double" and lim.level == 1}  # fmt: skip
    # by category and by class, the reproductions agree only here
    assert spiral[(("I", "IV"), ("A",))] and spiral[(AIRPLANE_CLASSES, ("B",))]
    assert not spiral[(AIRPLANE_CLASSES, ("C",))]


def test_class_and_category_errors_are_named():
    with pytest.raises(FlyingQualitiesError, match="II-C"):
        limits_for("roll_time_constant", "II", "C")
    with pytest.raises(FlyingQualitiesError, match="airplane_class"):
        limits_for("roll_time_constant", "V", "A")
    with pytest.raises(FlyingQualitiesError, match="category"):
        limits_for("roll_time_constant", "IV", "D")
    with pytest.raises(FlyingQualitiesError, match="criterion"):
        limits_for("phugoid", "IV", "A")
    assert issubclass(FlyingQualitiesError, InputError)


def oscillatory(name, wn, zeta, s_wn=NAN, s_zeta=NAN, s_re=NAN):
    lam = complex(-zeta * wn, wn * math.sqrt(1 - zeta**2))
    return Mode(
        name, lam, (s_re, NAN), wn, s_wn, zeta, s_zeta, NAN, NAN, NAN, NAN, NAN, NAN, {"q": 1.0}
    )


def real(name, re, s_re):
    return Mode(name, complex(re, 0.0), (s_re, 0.0), NAN, NAN, NAN, NAN,
                -1 / re, NAN, NAN, NAN, NAN, NAN, {"p": 1.0})  # fmt: skip


def level(modes, criterion, cls="IV", cat="A", **kw):
    return flying_qualities(Modes(tuple(modes), ("x",)), cls, cat, **kw)[criterion]


@pytest.mark.parametrize(
    ("sigma", "expected"),
    # 0.40 − 1.645·0.030 = 0.3507 ≥ 0.35: Level 1; 0.40 − 1.645·0.031 = 0.349: Level 2;
    # 0.40 − 1.645·0.10 = 0.2355 < 0.25: Level 3; 0.40 − 1.645·0.16 = 0.137 < 0.15: none
    [(0.030, 1), (0.031, 2), (0.10, 3), (0.16, None)],
)
def test_short_period_damping_level_at_95_percent(sigma, expected):
    row = level([oscillatory("short period", 3.0, 0.40, s_zeta=sigma)], "short_period_damping")
    assert row.level == expected
    assert row.level_nominal == 1
    assert row.judged


def overdamped_short_period(zeta, s_zeta):
    return Mode("short period", complex(-1.25, 0.1), (NAN, NAN), 1.0, NAN, zeta, s_zeta,
                NAN, NAN, NAN, NAN, NAN, NAN, {"q": 1.0})  # fmt: skip


@pytest.mark.parametrize(("sigma", "expected"), [(0.03, 1), (0.032, 2)])
def test_short_period_damping_upper_bound_with_sigma(sigma, expected):
    # 1.25 + 1.645·0.030 = 1.299 ≤ 1.30: Level 1;  1.25 + 1.645·0.032 = 1.303 > 1.30: Level 2
    row = level([overdamped_short_period(1.25, sigma)], "short_period_damping")
    assert row.level == expected


def test_dutch_roll_criteria_each_with_its_sigma():
    # ω = 1.2, ζ = 0.3: ζω = 0.36; σ(Re λ) = 0.005: 0.36 − 0.0082 = 0.3518 ≥ 0.35 → Level 1
    dr = oscillatory("Dutch roll", 1.2, 0.3, s_wn=0.05, s_zeta=0.02, s_re=0.005)
    fq = flying_qualities(Modes((dr,), ("beta", "r")), "IV", "A")
    assert fq["dutch_roll_damping_frequency"].value == pytest.approx(0.36)
    assert fq["dutch_roll_damping_frequency"].level == 1
    # ω − 1.645·0.05 = 1.118 ≥ 1.0 → Level 1;  ζ − 1.645·0.02 = 0.267 ≥ 0.19 → Level 1
    assert fq["dutch_roll_frequency"].level == 1
    assert fq["dutch_roll_damping"].level == 1
    dr = oscillatory("Dutch roll", 1.2, 0.3, s_wn=0.15, s_zeta=0.02, s_re=0.01)
    fq = flying_qualities(Modes((dr,), ("beta", "r")), "IV", "A")
    # 1.2 − 1.645·0.15 = 0.953 < 1.0 → Level 2 (≥ 0.4);  0.36 − 0.01645 < 0.35 → Level 2
    assert fq["dutch_roll_frequency"].level == 2
    assert fq["dutch_roll_damping_frequency"].level == 2


@pytest.mark.parametrize(
    ("re", "sigma", "expected"),
    # Class IV, A: τ ≤ 1.0 ⇔ λ ≤ −1;  −1.2 + 1.645·0.10 = −1.0355 → Level 1
    # −1.2 + 1.645·0.13 = −0.986 > −1 → Level 2 (λ ≤ −1/1.4 = −0.714)
    # −0.2 + 1.645·0.07 = −0.085 > −0.1 (τ ≤ 10 s) → none
    [(-1.2, 0.10, 1), (-1.2, 0.13, 2), (-0.2, 0.07, None)],
)
def test_roll_time_constant_judged_on_the_eigenvalue(re, sigma, expected):
    row = level([real("roll subsidence", re, sigma)], "roll_time_constant")
    assert row.level == expected
    assert row.value == pytest.approx(-1 / re)
    assert row.std == pytest.approx(sigma / re**2)


def test_spiral_time_to_double_and_the_unverified_level_2():
    # a stable spiral never doubles: every level
    stable = level([real("spiral", -0.01, 0.005)], "spiral_time_to_double")
    assert stable.level == 1 and math.isinf(stable.value)
    # T_2 = 15 s (λ = ln2/15): Category A needs T_2 ≥ 12 s → Level 1
    lam = math.log(2) / 15
    assert level([real("spiral", lam, 0.001)], "spiral_time_to_double").level == 1
    # Category B needs 20 s; Level 2 (8 s) is unverified and skipped → Level 3 (4 s)
    row = level([real("spiral", lam, 0.001)], "spiral_time_to_double", cat="B")
    assert row.level == 3 and "Level 2 not judged" in row.note
    with_all = level(
        [real("spiral", lam, 0.001)], "spiral_time_to_double", cat="B", include_unverified=True
    )
    assert with_all.level == 2


def test_cap_from_a_linear_model_closed_form():
    values = {"Za": -1.2, "Zde": -0.15, "Ma": -6.0, "Mq": -1.8, "Mde": -8.0}
    cov = np.diag([0.02, 0.005, 0.08, 0.04, 0.1]) ** 2
    linear = linearize(short_period(values), [0.0, 0.0], [0.0], covariance=cov)
    speed = 120.0
    # n/α = −V Z_α / g
    n_alpha = -speed * values["Za"] / 9.80665
    assert load_factor_per_alpha(linear, speed) == pytest.approx(n_alpha, rel=1e-8)
    fq = flying_qualities(linear, "IV", "A", speed_m_s=speed)
    # ω_sp² = Z_α M_q − M_α
    wn2 = values["Za"] * values["Mq"] - values["Ma"]
    assert fq["cap"].value == pytest.approx(wn2 / n_alpha, rel=1e-8)
    # σ: CAP = (Z_α M_q − M_α)·g/(−V Z_α): gradient over (Za, Zde, Ma, Mq, Mde) by hand
    za, ma = values["Za"], values["Ma"]
    k = 9.80665 / speed
    # CAP = −k M_q + k M_α/Z_α,  k = g/V
    grad = np.array([-k * ma / za**2, 0.0, k / za, -k, 0.0])
    assert fq["cap"].std == pytest.approx(math.sqrt(grad @ cov @ grad), rel=1e-4)
    # CAP = 0.47 ± 0.011, in 0.28–3.6 → Level 1
    assert fq["cap"].level == 1


def test_cap_from_a_given_n_alpha_and_the_unjudged_category():
    sp = oscillatory("short period", 2.0, 0.5, s_wn=0.1, s_zeta=0.02)
    modes = Modes((sp,), ("alpha", "q"))
    fq = flying_qualities(modes, "IV", "A", n_alpha=(10.0, 0.5))
    assert fq["cap"].value == pytest.approx(0.4)
    # σ/CAP = √((2·0.1/2)² + (0.5/10)²)
    assert fq["cap"].std == pytest.approx(0.4 * math.sqrt(0.1**2 + 0.05**2))
    # Category C: every CAP limit unverified → not judged, no level
    row = flying_qualities(modes, "IV", "C", n_alpha=10.0)["cap"]
    assert row.level is None and not row.judged
    assert "not judged" in flying_qualities(modes, "IV", "C", n_alpha=10.0).summary()
    # without n/α and without the linear model: no CAP row, a note says why
    fq = flying_qualities(modes, "IV", "A")
    assert [r.criterion for r in fq.criteria] == ["short_period_damping"]
    assert any("CAP not judged" in n for n in fq.notes)
    with pytest.raises(FlyingQualitiesError, match="n_alpha"):
        flying_qualities(modes, "IV", "A", n_alpha=-1.0)


def test_to_dict_carries_limits_sources_and_levels():
    sp = oscillatory("short period", 2.0, 0.5, s_wn=0.1, s_zeta=0.02)
    entry = flying_qualities(Modes((sp,), ("alpha", "q")), "IV", "A").to_dict()
    row = entry["criteria"][0]
    assert row["criterion"] == "short_period_damping" and row["level"] == 1
    assert row["limits"]["1"] == {
        "minimum": 0.35, "maximum": 1.3, "source": "MIL-F-8785C 3.2.2.1.2",
        "verified": True, "why": "",
    }  # fmt: skip


def test_a_model_holding_measured_states_is_not_judged():
    roll = real("roll subsidence", -2.0, 0.01)
    note = "inputs ['beta'] are measured states: A holds the dynamics of ['p', 'r'] ..."
    fq = flying_qualities(Modes((roll,), ("p", "r"), (note,)), "IV", "A")
    row = fq["roll_time_constant"]
    assert row.level is None and not row.judged and "measured states" in row.note


# ---------------------------------------------------------------- the case table and a run
CASE = ROOT / "examples" / "cases" / "hfb320_longitudinal.toml"


def _raw_case(table):
    raw = tomllib.loads(CASE.read_text(encoding="utf-8"))
    raw["model"]["module"] = str(ROOT / "examples" / "models" / "hfb320.py")
    if table is not None:
        raw["flying_qualities"] = table
    return raw


def test_case_table_is_checked_with_named_errors():
    case = parse_case(_raw_case({"class": "IV", "category": "A", "speed": 100}), CASE)
    assert case.flying_qualities == {"class": "IV", "category": "A", "speed": 100.0}
    assert parse_case(_raw_case(None), CASE).flying_qualities == {}
    bad = [
        ({"class": "IV"}, "flying_qualities.category: missing"),
        ({"class": "V", "category": "A"}, "flying_qualities.class: expected one of"),
        ({"class": "IV", "category": "D"}, "flying_qualities.category: expected one of"),
        ({"class": "II", "category": "C"}, "II-C"),
        ({"class": "IV", "category": "A", "speed": -3}, "flying_qualities.speed"),
        ({"class": "IV", "category": "A", "levels": 2}, "flying_qualities.levels: unknown key"),
        ({"class": "IV", "category": "A", "include_unverified": "yes"}, "include_unverified"),
    ]
    for table, message in bad:
        with pytest.raises(CaseError, match=message.replace(".", r"\.")):
            parse_case(_raw_case(table), CASE)


@needs_data("fvsysid/hfb320_1_10.asc")
@pytest.mark.filterwarnings("ignore:.*outlier")
def test_hfb320_run_prints_modes_and_writes_them_to_results_json(tmp_path):
    text = CASE.read_text(encoding="utf-8").replace(
        '"../models/hfb320.py"', repr(str(ROOT / "examples" / "models" / "hfb320.py"))
    )
    case = tmp_path / "hfb320.toml"
    case.write_text(text + '\n[flying_qualities]\nclass = "II-L"\ncategory = "C"\n', "utf-8")
    out = tmp_path / "run"
    stream = io.StringIO()
    with contextlib.redirect_stdout(stream):
        code = main(["run", str(case), "--out", str(out), "--accuracy", "none",
                     "--data-dir", str(DATA)])  # fmt: skip
    assert code == 0
    printed = stream.getvalue()
    assert "short period" in printed and "phugoid" in printed
    assert "short-period damping ratio" in printed and "Level 1" in printed
    entry = json.loads((out / "results.json").read_text(encoding="utf-8"))["results"][0]
    modes = {m["name"]: m for m in entry["modes"]["modes"]}
    # regression values of this estimate (tests/test_modes.py pins them against a Monte Carlo)
    assert modes["short period"]["omega_n_rad_per_s"] == pytest.approx(2.05, abs=0.02)
    assert modes["short period"]["zeta"] == pytest.approx(0.41, abs=0.01)
    assert modes["short period"]["zeta_std"] > 0
    quality = {c["criterion"]: c for c in entry["modes"]["flying_qualities"]["criteria"]}
    # ζ_sp = 0.41 ± 0.025: 0.41 − 1.645·0.025 = 0.369 ≥ 0.35 → Level 1 (Category C)
    assert quality["short_period_damping"]["level"] == 1
    # Category C CAP limits are unverified: not judged
    assert quality["cap"]["judged"] is False and quality["cap"]["level"] is None
    html = (out / "report.html").read_text(encoding="utf-8")
    assert html.index("<h2>Convergence</h2>") < html.index("<h2>Modes and flying qualities</h2>")


@needs_data("fvsysid")
@pytest.mark.filterwarnings("ignore:.*outlier")
def test_a_linear_models_summary_shows_its_modes():
    from flightid.cases.run import run_case

    run = run_case(ROOT / "examples" / "cases" / "attas_short_period.toml", accuracy="none")
    text = run.estimate.summary()
    assert "modes (± 1σ) at the initial state, inputs 0 (the model is linear)" in text
    mode = run.estimate.linearize().modes()["short period"]
    value, sigma = format_with_sigma(mode.natural_frequency, mode.natural_frequency_std)
    assert f"{value} ± {sigma}" in text
    assert "modes" in run.to_dict() and run.to_dict()["modes"]["flying_qualities"] is None


@needs_data("fvsysid/hfb320_1_10.asc")
def test_docs_measured_block_matches_what_the_script_prints():
    import importlib.util

    path = ROOT / "docs" / "flying_qualities_numbers.py"
    spec = importlib.util.spec_from_file_location("flying_qualities_numbers", path)
    script = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(script)
    # every number of docs/flying_qualities.md's block to 1e-3 relative (the script's check)
    problems = script.check(script.block(DATA))
    assert not problems, "\n".join(problems)


def test_summary_block_says_why_when_the_modes_cannot_be_computed():
    from types import SimpleNamespace

    from flightid.export.modal import summary_block
    from flightid.model.parameters import Parameters
    from flightid.model.statespace import StateSpaceModel

    def f(t, x, u, th):
        # undefined at the linearity test's second point x = 1.5: math.log raises ValueError
        return np.array([th[0] * math.log(1.2 - float(x[0]))])

    def h(t, x, u, th):
        return np.array([x[0]])

    model = StateSpaceModel(("x",), ("u",), ("x",), f, h, Parameters({"a": 1.0}), x0=(1.0,))
    estimate = SimpleNamespace(model=model, values=model.parameters.values)
    assert summary_block(estimate).startswith("modes: not computed (")
    no_states = SimpleNamespace(model=SimpleNamespace(states=()))
    assert summary_block(no_states) == ""
