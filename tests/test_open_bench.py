"""The open benchmark's parts: success rules, intervals, paired tests, suites, method specs, `bench compare`."""

import json

import numpy as np
import pytest

from hvs_sim.bench.compare import compare
from hvs_sim.bench.servo import episode_offset, parse_method, portable_method
from hvs_sim.bench.splits import split_of
from hvs_sim.bench.stats import episode_success, mcnemar, median_ci, rate, wilcoxon, wilson
from hvs_sim.bench.suites import SUITES, describe, get_suite
from hvs_sim.cli import main
from hvs_sim.errors import ConfigError
from hvs_sim.manifest import MANIFEST_NAME, record
from hvs_sim.viz.figures import method_colour


def _episode(t, r, t0=80.0, r0=10.0, held=True, px=0.1, converged=True):
    return {"final_pose_error_mm": t, "final_pose_error_deg": r, "initial_pose_error_mm": t0,
            "initial_pose_error_deg": r0, "held_to_end": held, "final_error_px": px, "converged": converged}


@pytest.mark.parametrize("ep, expected", [
    (_episode(0.4, 0.3), {"hvs_sim": True, "cns": True, "felton": True, "visp": True}),
    (_episode(7.0, 0.6), {"hvs_sim": True, "cns": True, "felton": True, "visp": False}),
    (_episode(9.0, 1.2, t0=200.0, r0=20.0), {"hvs_sim": True, "cns": True, "felton": True, "visp": False}),
    (_episode(15.0, 2.0, t0=80.0, r0=12.0), {"hvs_sim": True, "cns": False, "felton": False, "visp": False}),
    (_episode(0.3, 0.2, held=False), {"hvs_sim": False, "cns": True, "felton": True, "visp": True}),
    (_episode(0.3, 0.2, px=1.5), {"hvs_sim": False, "cns": True, "felton": True, "visp": True}),
])
def test_the_four_success_rules(ep, expected):
    assert episode_success(ep, 1.0) == expected


def test_wilson_interval_and_rates():
    lo, hi = wilson(0, 20)
    assert lo == 0.0 and hi == pytest.approx(0.1611, abs=1e-4)  # the textbook value for 0 of 20
    lo, hi = wilson(19, 20)
    assert lo == pytest.approx(0.7639, abs=1e-4) and hi == pytest.approx(0.9911, abs=1e-4)
    r = rate([True] * 19 + [False])
    assert r["rate"] == 0.95 and r["n"] == 20 and r["ci95"][0] < 0.95 < r["ci95"][1]


def test_median_interval_is_seeded_and_covers_the_median():
    v = np.random.default_rng(1).lognormal(1, 0.5, 40)
    a, b = median_ci(v), median_ci(v)
    assert a == b and a["ci95"][0] <= a["median"] <= a["ci95"][1]
    assert median_ci([None, None])["median"] is None


def test_paired_tests():
    a = [True] * 10 + [False] * 10
    b = [True] * 2 + [False] * 18
    m = mcnemar(a, b)
    assert (m["only_a"], m["only_b"]) == (8, 0) and m["p_value"] == pytest.approx(2 * 0.5 ** 8)
    assert mcnemar(a, a)["p_value"] == 1.0
    w = wilcoxon(np.arange(1, 11) + 5.0, np.arange(1, 11))
    assert w["median_difference"] == 5.0 and w["p_value"] < 0.01
    assert wilcoxon([1, 2], [1, 2])["p_value"] == 1.0


@pytest.mark.parametrize("spec, parsed", [
    ("hybrid", ("hybrid", None, "ibvs", None)),
    ("hybrid:homography/pbvs", ("hybrid", "homography", "pbvs", None)),
    ("none/dvs", ("none", None, "dvs", None)),
    ("{pkg.track:make}:homography/{pkg.law:make}", ("pkg.track:make", "homography", "pkg.law:make", None)),
    ("{pkg.track:make}/{pkg.law:make}", ("pkg.track:make", None, "pkg.law:make", None)),
    ("{path/to/t.py:make}", ("path/to/t.py:make", None, "ibvs", None)),
    ("policy={pkg.net:make}", ("none", None, "ibvs", "pkg.net:make")),
    ("policy=mine", ("none", None, "ibvs", "mine")),
])
def test_method_specs(spec, parsed):
    assert parse_method(spec) == parsed


@pytest.mark.parametrize("bad", ["pkg.track:make", "hybrid:affine", "ground_truth:homography", "{x", "policy=", ""])
def test_bad_method_specs(bad):
    with pytest.raises(ConfigError):
        parse_method(bad)


def test_portable_method_spells_references_for_workers():
    assert portable_method("hybrid:homography/pbvs") == "hybrid:homography/pbvs"
    assert portable_method("klt_homography:homography/plain_ibvs") == "klt_homography:homography/plain_ibvs"
    assert portable_method("{hvs_test_plugins.track:make}") == "{hvs_test_plugins.track:make}/ibvs"


def test_four_dof_starts_draw_no_tilt_and_six_dof_draws_are_unchanged():
    six = episode_offset(200, 0.8, 0)
    four = episode_offset(200, 0.8, 0, tilt=0.0)
    assert four[4] == four[5] == 0.0 and four[:4] == six[:4]
    rng = np.random.default_rng([200, 11, 0])  # the draw the committed results used
    lo = [-0.1, -0.1, (1 - 1.4) * 0.8, -np.radians(60), -np.radians(15), -np.radians(15)]
    hi = [0.1, 0.1, (1 - 0.7) * 0.8, np.radians(60), np.radians(15), np.radians(15)]
    assert six == tuple(float(v) for v in rng.uniform(lo, hi))


def test_suites_are_listed_and_frozen(capsys):
    assert {"quick", "occlusion-v1", "occlusion-4dof-v1", "track-occlusion-v1", "occlusion-v2", "occlusion-4dof-v2",
            "track-occlusion-v2"} <= set(SUITES)
    assert get_suite("occlusion-v1", "servo").seeds("dev") == tuple(range(200, 220))
    with pytest.raises(ConfigError, match="retired.*--split dev.*occlusion-v2"):
        get_suite("occlusion-v1", "servo").seeds("test")
    for suite in SUITES.values():  # dev and test disjoint; the test seeds lie in the benchmark's test split
        assert not set(suite.dev_seeds) & set(suite.test_seeds)
        assert set(suite.test_seeds) <= set(split_of(suite.kind).test)
        assert set(suite.dev_seeds) <= set(split_of(suite.kind).dev)
    with pytest.raises(ConfigError, match="accepted: quick, occlusion-v2"):
        get_suite("occlusion-v9", "servo")
    assert main(["bench", "suites"]) == 0
    out = capsys.readouterr().out
    assert "occlusion-4dof-v1 (servo)" in out and "quick" in describe()
    assert "seeds: test 1000–1019 (20), dev 200–219 (20)" in out and "none (retired)" in out
    assert main(["bench", "servo", "--suite", "quick", "--seeds", "3"]) == 2
    assert "changes what suite quick fixes" in capsys.readouterr().err


def test_method_colours_are_stable_and_distinct():
    specs = ["ground_truth", "ground_truth/pbvs", "hybrid:homography", "hybrid:homography/pbvs", "hybrid", "none/dvs"]
    assert len({method_colour(s) for s in specs}) == len(specs)
    assert method_colour("{my.pkg:make}") == method_colour("{my.pkg:make}")


def _results(folder, suite="occlusion-v1", methods=("a", "b"), errors=None, camera="phone_handheld",
             scenarios=("walk_by",)):
    folder.mkdir(parents=True)
    eps = []
    for m in methods:
        for scen in scenarios:
            for seed in range(20):
                t = errors[m][seed] if errors else 5.0
                eps.append({**_episode(float(t), 0.5, held=bool(t < 10)), "method": m, "scenario": scen,
                            "episode_seed": seed})
    data = {"schema": "hvs_sim.servo-results/2", "suite": suite, "commit": "abc",
            "config": {"trackers": list(methods), "scenarios": list(scenarios), "camera": camera, "people": "textured",
                       "width": 640, "height": 480, "tilt_deg": 15.0, "extra_steps": 60, "steps": None,
                       "success_px": 1.0},
            "episodes": eps}
    (folder / "summary.json").write_text(json.dumps(data))
    return folder


def test_bench_compare_pairs_episodes_and_refuses_other_suites(tmp_path, capsys):
    rng = np.random.default_rng(0)
    good = {"a": rng.uniform(1, 5, 20)}
    bad = {"b": np.r_[rng.uniform(12, 30, 12), rng.uniform(1, 5, 8)]}
    A = _results(tmp_path / "A", methods=("a",), errors=good)
    B = _results(tmp_path / "B", methods=("b",), errors=bad)
    res = compare(A, B)  # one method each: those two are paired; one scenario: no "all" row repeating it
    assert [r["scenario"] for r in res["rows"]] == ["walk_by"]
    row = res["rows"][0]
    assert row["episodes"] == 20 and row["mcnemar"]["only_a"] == 12 and row["mcnemar"]["p_value"] < 0.001
    assert row["pose_error_mm"]["p_value"] < 0.05 and row["pose_error_mm"]["median_difference"] < 0
    out = tmp_path / "cmp"
    assert main(["bench", "compare", str(A), str(B), "--out", str(out)]) == 0
    assert {p.name for p in out.iterdir()} == {"compare.json", "compare.md", "compare.png", MANIFEST_NAME}
    assert "McNemar" in capsys.readouterr().out
    record([A / "summary.json"])  # as the benchmark that wrote it would have: still never removed as an input
    assert main(["bench", "compare", str(A), str(B), "--out", str(A), "--overwrite"]) == 0
    assert json.loads((A / "summary.json").read_text())["suite"] == "occlusion-v1" and (A / "compare.md").is_file()
    C = _results(tmp_path / "C", suite="quick", methods=("b",), errors=bad)
    with pytest.raises(ConfigError, match="suite 'occlusion-v1'.*suite 'quick'"):
        compare(A, C)
    D = _results(tmp_path / "D", methods=("b",), errors=bad, camera="ideal")
    with pytest.raises(ConfigError, match="differ in camera"):
        compare(A, D)
    E = _results(tmp_path / "E", methods=("b",), errors=bad)
    summary = json.loads((E / "summary.json").read_text())
    summary["config"]["arm"] = "panda"  # the same seeds on another arm are other episodes (no arm: the Jaco)
    (E / "summary.json").write_text(json.dumps(summary))
    with pytest.raises(ConfigError, match="differ in arm"):
        compare(A, E)
    assert main(["bench", "compare", str(A)]) == 2


def test_bench_compare_pairs_methods_by_name_labels_runs_by_folder_and_draws_a_readable_figure(tmp_path, capsys):
    """A method in both runs is compared with itself (not with every other), the runs are named by their folders,
    "all" rows appear only over several scenarios, and the figure (a panel per measure, a row per method) stays
    at most 1600 px wide."""
    from PIL import Image

    methods, scenarios = ("m1", "m2", "m3"), ("clear", "walk_by")
    mine = _results(tmp_path / "mine", methods=methods, scenarios=scenarios)
    ref = _results(tmp_path / "reference", methods=methods, scenarios=scenarios)
    res = compare(mine, ref)
    assert {(r["a"], r["b"]) for r in res["rows"]} == {(m, m) for m in methods}
    assert [r["scenario"] for r in res["rows"] if r["a"] == "m1"] == ["clear", "walk_by", "all"]
    assert (res["label_a"], res["label_b"]) == ("mine", "reference")
    explicit = compare(mine, ref, methods_a=["m1"], methods_b=["m3"])
    assert {(r["a"], r["b"]) for r in explicit["rows"]} == {("m1", "m3")}
    other = _results(tmp_path / "other", methods=("x", "y"), scenarios=scenarios)
    with pytest.raises(ConfigError, match="share no method name.*--methods MA MB"):
        compare(mine, other)
    out = tmp_path / "cmp"
    assert main(["bench", "compare", str(mine), str(ref), "--out", str(out)]) == 0
    printed = capsys.readouterr().out
    assert "method A (mine)" in printed and "method B (reference)" in printed
    with Image.open(out / "compare.png") as img:
        assert img.width <= 1600 and img.height < img.width
    again = _results(tmp_path / "x" / "run", methods=("m1",))
    same_name = _results(tmp_path / "y" / "run", methods=("m1",))
    assert compare(again, same_name)["label_a"] == "x/run"  # folders named alike: with their parents


def test_compare_refuses_results_from_before_the_schema(tmp_path):
    old = tmp_path / "old"
    old.mkdir()
    (old / "summary.json").write_text(json.dumps({"config": {}, "episodes": []}))
    new = _results(tmp_path / "new", methods=("a",))
    with pytest.raises(ConfigError, match="schema hvs_sim.servo-results/2"):
        compare(new, old)
    (old / "summary.json").write_text("[1, 2]")
    with pytest.raises(ConfigError, match="schema"):
        compare(old, new)
    # an interrupted run's summary (bench/pool.collect_jobs) is named as such, not as an old schema
    (old / "summary.json").write_text(json.dumps({"interrupted": True, "completed_jobs": 23, "total_jobs": 60}))
    with pytest.raises(ConfigError, match="interrupted run's partial summary \\(23 of 60 episodes.*--resume"):
        compare(new, old)
    (old / "summary.json").unlink()  # killed outright: records, no summary
    (old / "episodes").mkdir()
    with pytest.raises(ConfigError, match="killed.*--resume"):
        compare(new, old)


def test_dvs_refuses_a_goal_without_texture():
    from hvs_sim.control.laws.dvs import DVSController
    from hvs_sim.errors import InputError
    from hvs_sim.render.camera import intrinsics

    flat = np.full((240, 320, 3), 128, np.uint8)
    with pytest.raises(InputError, match="too little texture"):
        DVSController(intrinsics(320, 240, 45), flat, (100, 80, 100, 80), 0.8)
