"""Monte Carlo campaigns: the pass-rate interval against closed forms, the results store, small campaigns on a real
Dask LocalCluster (stopped and resumed, a run that raises), and ``flyby mc`` from the command line."""

from __future__ import annotations

import io
import os
import sqlite3
from pathlib import Path

import numpy as np
import pytest
from scipy import stats

from contracts.clock import SimClock
from contracts.exitcodes import EXIT_CHECK_FAILED, EXIT_CONFIG, EXIT_OK
from flyby.cli import main
from flyby.montecarlo.campaign import Campaign, RunResult, build_campaign, dispersions_file
from flyby.montecarlo.engine import dask_client, run_campaign
from flyby.montecarlo.progress import Progress
from flyby.montecarlo.statistics import clopper_pearson, pass_rates
from flyby.montecarlo.store import STORE_NAME, ResultStore, open_store
from scenario.dispersions import dispersed_run, drawn_values
from scenario.model import load_run_inputs

ROOT = Path(__file__).resolve().parents[2]
# the start of the nominal flyby (ACQUISITION at C/A-240 s, tracking) at centroid level: about a second a run
TINY = """\
name: tiny
seed: 4
universe:
  start_s: -132.0
  end_s: -50.0
  fidelity: centroid
ground:
  timeline_file: {timeline}
dispersions:
  - path: universe.spacecraft.initial_rate_deg_s
    normal: {{sigma: 0.05}}
  - path: universe.bodies.orbit_phase_deg
    normal: {{sigma: 5.0}}
"""


@pytest.fixture()
def tiny(tmp_path: Path) -> Path:
    """A tiny campaign scenario file."""
    path = tmp_path / "tiny.yaml"
    path.write_text(TINY.format(timeline=ROOT / "configs" / "timelines" / "flyby-imaging.yaml"))
    return path


def test_clopper_pearson_ends_are_closed_forms() -> None:
    """With no success the upper end is 1 - (alpha/2)^(1/n); with all, the lower end is (alpha/2)^(1/n)."""
    for n in (1, 10, 1000):
        assert clopper_pearson(0, n) == pytest.approx((0.0, 1 - 0.025 ** (1 / n)), rel=1e-9)
        assert clopper_pearson(n, n) == pytest.approx((0.025 ** (1 / n), 1.0), rel=1e-9)


@pytest.mark.parametrize(("k", "n"), [(1, 10), (5, 10), (990, 1000), (37, 200)])
def test_clopper_pearson_ends_solve_the_binomial_tails(k: int, n: int) -> None:
    """The lower end p has P(X >= k) = 2.5 % and the upper end P(X <= k) = 2.5 % (binomial tails, scipy.stats.binom)."""
    low, high = clopper_pearson(k, n)
    assert stats.binom.sf(k - 1, n, low) == pytest.approx(0.025, rel=1e-6)
    assert stats.binom.cdf(k, n, high) == pytest.approx(0.025, rel=1e-6)


def test_a_run_that_raised_fails_every_requirement() -> None:
    """Pass rates count a run that raised as failing each requirement; a not-assessed one is left out."""
    ok = {"status": "ok", "in_view_pass": 1, "pointing_pass": 1, "rate_pass": None, "centroid_pass": 1, "all_pass": 0}
    rates = {r.requirement: r for r in pass_rates([ok, {"status": "error"}])}
    assert (rates["in_view"].passed, rates["in_view"].assessed) == (1, 2)
    assert (rates["rate"].passed, rates["rate"].assessed) == (0, 1)
    assert (rates["all"].passed, rates["all"].assessed) == (0, 2)


def _result(k: int) -> RunResult:
    return RunResult(run=k, seed=10 + k, status="ok", error=None, wall_s=1.5, sim_s=72.0,
                     figures={"in_view_fraction": 0.5 + k / 10, "all_pass": 1, "modes": "ACQUISITION"},
                     values={"a[0]": float(k), "b": -float(k)})


def test_the_store_keeps_committed_rows_only(tmp_path: Path) -> None:
    """Rows and their drawn values come back as stored; a row whose transaction never committed (a writer killed
    mid-row) is not there, and --resume would run it again."""
    with open_store(tmp_path) as store:
        store.append(_result(0))
        store.append(_result(2))
    con = sqlite3.connect(tmp_path / STORE_NAME)
    con.execute("INSERT INTO runs (run, seed, status) VALUES (1, 11, 'ok')")  # never committed
    con.close()
    with open_store(tmp_path) as store:
        assert store.done() == {0, 2}
        rows = store.rows()
        assert [r["in_view_fraction"] for r in rows] == [0.5, 0.7] and rows[1]["modes"] == "ACQUISITION"
        assert store.values() == {0: {"a[0]": 0.0, "b": -0.0}, 2: {"a[0]": 2.0, "b": -2.0}}


def test_progress_line_counts_and_estimates() -> None:
    """Two of four runs done in 10 s of the clock: half the bar, 0.2 run/s, 10 s left."""
    clock = SimClock()
    out = io.StringIO()
    p = Progress(4, stream=out, clock=clock)
    clock.advance(5.0)
    p.update(ok=True, passed=True)
    clock.advance(5.0)
    p.update(ok=False)
    assert p.line() == f"[{'#' * 15}{'.' * 15}] 2/4 runs, 0 missed a requirement, 1 raised, 0.20 run/s, ETA 10 s"


def _campaign(path: Path) -> Campaign:
    return build_campaign(path)


def _comparable(store: ResultStore) -> list[dict]:
    return [{k: v for k, v in r.items() if k != "wall_s"} for r in store.rows()]


def test_a_campaign_stopped_and_resumed_equals_one_run_whole(tiny: Path, tmp_path: Path) -> None:
    """On a real LocalCluster, a campaign stopped after one stored run (as a kill would) and resumed stores exactly
    the rows and drawn values of the same campaign run whole."""
    campaign = _campaign(tiny)
    with dask_client(workers=1, processes=False) as client:
        with open_store(tmp_path / "whole") as whole:
            assert run_campaign(client, campaign, [0, 1, 2], whole, Progress(3, stream=io.StringIO())) == 3
            expected, values = _comparable(whole), whole.values()
        with open_store(tmp_path / "cut") as cut:
            assert run_campaign(client, campaign, [0, 1, 2], cut, Progress(3, stream=io.StringIO()), stop_after=1) == 1
            assert len(cut.done()) == 1
        with open_store(tmp_path / "cut") as cut:
            todo = [k for k in range(3) if k not in cut.done()]
            run_campaign(client, campaign, todo, cut, Progress(3, len(cut.done()), stream=io.StringIO()))
            assert _comparable(cut) == expected and cut.values() == values
    assert all(r["status"] == "ok" for r in expected)
    assert {r["run"] for r in expected} == {0, 1, 2} and len({r["seed"] for r in expected}) == 3
    assert all(r["in_view_fraction"] is not None and r["mode_changes"] >= 1 for r in expected)


def test_a_worker_freezes_its_heap_once(tiny: Path) -> None:
    """A process's first run moves what is alive then out of the collector's sight (full collections stop walking
    modules and compiled kernels); later runs freeze nothing more, so their garbage stays collectable."""
    import subprocess
    import sys
    code = ("import gc, sys\nfrom pathlib import Path\n"
            "from flyby.montecarlo.campaign import build_campaign, run_one\n"
            "p = build_campaign(Path(sys.argv[1])).to_json()\n"
            "before = gc.get_freeze_count()\nrun_one(p, 0)\nfirst = gc.get_freeze_count()\n"
            "run_one(p, 1)\nprint(before, first, gc.get_freeze_count())\n")
    out = subprocess.run([sys.executable, "-c", code, str(tiny)], cwd=ROOT, capture_output=True, text=True,
                         check=True, env={**os.environ, "PYTHONPATH": str(ROOT)})
    before, first, second = map(int, out.stdout.split())
    assert before == 0 and first > 10_000 and second == first


def test_a_run_that_raises_is_stored_with_its_traceback(tiny: Path, tmp_path: Path) -> None:
    """A draw that makes an invalid scenario fails its run, stored with the traceback naming the field; the
    campaign goes on."""
    bad = tmp_path / "bad.yaml"
    bad.write_text(tiny.read_text()
                   + "  - path: universe.bodies.dimorphos_diameter_m\n    uniform: {low: -2.0, high: -1.0}\n")
    with dask_client(workers=1, processes=False) as client, open_store(tmp_path / "c") as store:
        assert run_campaign(client, _campaign(bad), [0, 1], store, Progress(2, stream=io.StringIO())) == 2
        rows = store.rows()
        values = store.values()
    assert [r["status"] for r in rows] == ["error", "error"]
    assert all("ScenarioError" in r["error"] and "dimorphos_diameter_m" in r["error"] for r in rows)
    assert values[0]["universe.bodies.dimorphos_diameter_m"] < 0


def test_flyby_mc_campaign_report_resume_and_replay(tiny: Path, tmp_path: Path, capsys: pytest.CaptureFixture
                                                    ) -> None:
    """``flyby mc`` runs the campaign and writes mc.html with its pass rates; a second campaign into the same
    folder is refused without --resume, and with --resume when it differs; --replay K gives the stored figures
    and writes run K's scenario file, which loads as run K; the campaign exits 4 when a stored run missed a
    requirement."""
    out = tmp_path / "mc"
    code = main(["mc", str(tiny), "--runs", "2", "--out", str(out), "--threads", "--workers", "1"])
    with open_store(out) as store:
        all_passed = all(r["status"] == "ok" and r["all_pass"] == 1 for r in store.rows())
    assert code == (EXIT_OK if all_passed else EXIT_CHECK_FAILED)
    page = (out / "mc.html").read_text()
    assert 'id="pass-rates"' in page and "Clopper-Pearson" in page and "data:image/png;base64," in page
    assert main(["mc", str(tiny), "--runs", "2", "--out", str(out), "--threads"]) == EXIT_CONFIG
    assert "--resume" in capsys.readouterr().err
    assert main(["mc", str(tiny), "--runs", "3", "--out", str(out), "--threads", "--resume", "--seed", "5"]) == \
        EXIT_CONFIG
    assert "differs in seed" in capsys.readouterr().err
    assert main(["mc", "--out", str(out), "--replay", "1"]) == EXIT_OK
    assert "the replay gives the stored figures" in capsys.readouterr().out
    written, timeline = load_run_inputs(out / "scenarios" / "tiny-run00001.yaml")
    campaign = _campaign(tiny)
    expected = dispersed_run(campaign.scenario, 4, 1).scenario
    assert written.ground.timeline_file == "timeline.yaml" and timeline == campaign.timeline
    assert written.model_copy(update={"ground": expected.ground}) == expected
    with open_store(out) as store:
        assert store.done() == {0, 1} and all(r["wall_s"] > 0 for r in store.rows())
    assert main(["mc", "--out", str(tmp_path / "none"), "--report"]) == EXIT_CONFIG
    assert not (tmp_path / "none").exists()  # a mistyped folder is reported, not created
    assert np.isfinite([r["in_view_fraction"] for r in ResultStore(out / STORE_NAME).rows()]).all()


def test_flyby_mc_refuses_an_unknown_dispersion_path_before_running(tiny: Path, tmp_path: Path,
                                                                     capsys: pytest.CaptureFixture) -> None:
    """A dispersion of a field the scenario lacks exits 2 naming the path, with the problem count, and runs nothing."""
    bad = tmp_path / "bad.yaml"
    bad.write_text("dispersions:\n  - path: universe.bodies.orbit_phase\n    normal: {sigma: 1.0}\n")
    out = tmp_path / "mc"
    code = main(["mc", str(tiny), "--runs", "1", "--out", str(out), "--threads", "--dispersions", str(bad)])
    err = capsys.readouterr().err
    assert code == EXIT_CONFIG
    assert "invalid campaign (1 problem(s))" in err and "orbit_phase" in err
    assert not (out / "results.sqlite").exists()


def test_dispersions_of_several_files_follow_the_scenario_s_in_their_order(tiny: Path, tmp_path: Path) -> None:
    """``--dispersions A B`` appends A's entries, then B's, after the scenario's own; every run draws each of them, and
    the scenario's own draw the same values as without the files (each entry has its own stream)."""
    noise = tmp_path / "noise.yaml"
    noise.write_text("dispersions:\n  - path: universe.camera.read_noise_e\n    normal: {sigma: 0.2, relative: true}\n")
    files = [ROOT / "configs" / "dispersions" / "detector-stress.yaml", noise]
    alone = build_campaign(tiny)
    both = build_campaign(tiny, dispersions=files)
    expected = [d["path"] for f in files for d in dispersions_file(f)]
    paths = [d.path for d in both.scenario.dispersions]
    assert paths == [d.path for d in alone.scenario.dispersions] + expected
    _, data, values = drawn_values(both.scenario, both.seed, 3)
    _, _, own = drawn_values(alone.scenario, alone.seed, 3)
    assert all(values[key] == value for key, value in own.items())
    assert 5.0 <= data["universe"]["camera"]["cosmic_ray_flux_cm2_s"] <= 500.0
    assert 0 <= data["universe"]["camera"]["dead_column_count"] <= 8


def test_flyby_mc_takes_several_dispersions_files(tiny: Path, tmp_path: Path) -> None:
    """``flyby mc ... --dispersions A B`` runs with both files' entries: each stored run has a drawn value for each."""
    a, b = tmp_path / "a.yaml", tmp_path / "b.yaml"
    a.write_text("dispersions:\n  - path: universe.camera.read_noise_e\n    normal: {sigma: 0.2, relative: true}\n")
    b.write_text("dispersions:\n  - path: universe.camera.dead_column_count\n    uniform: {low: 0, high: 8}\n")
    out = tmp_path / "mc"
    assert main(["mc", str(tiny), "--runs", "1", "--out", str(out), "--threads", "--dispersions", str(a),
                 str(b)]) in (EXIT_OK, EXIT_CHECK_FAILED)
    drawn = ResultStore(out / STORE_NAME).values()[0]
    assert {"universe.camera.read_noise_e", "universe.camera.dead_column_count"} <= set(drawn)


def test_local_workers_keep_the_dynamic_heap(monkeypatch: pytest.MonkeyPatch) -> None:
    """The worker processes of a local campaign cluster run without Dask's MALLOC_TRIM_THRESHOLD_ (which maps every
    frame-sized array afresh), and still with one BLAS thread."""
    monkeypatch.delenv("MALLOC_TRIM_THRESHOLD_", raising=False)
    with dask_client(workers=1) as client:
        seen = client.run(lambda: (os.environ.get("MALLOC_TRIM_THRESHOLD_"), os.environ.get("OMP_NUM_THREADS")))
    assert list(seen.values()) == [(None, "1")]


def _busy_s(seconds: float) -> float:
    """Keep a worker's thread in Python for ``seconds`` of its CPU time (something a profiler would sample)."""
    import time
    end, x = time.thread_time() + seconds, 0.0
    while time.thread_time() < end:
        x += sum(i * 0.5 for i in range(200))
    return x


def test_local_workers_run_without_the_statistical_profiler() -> None:
    """A local campaign cluster's workers take no stack samples of a running task (Dask's profiler, every 10 ms by
    default, slowed a run by a sixth): a task busy for 0.5 s leaves the cluster's profile empty."""
    with dask_client(workers=1) as client:
        client.submit(_busy_s, 0.5, pure=False).result()
        assert client.profile()["count"] == 0


def test_the_remote_workers_configuration_is_the_local_clusters() -> None:
    """configs/dask/workers.yaml, which the README gives remote workers, sets what the LocalCluster sets (glibc's heap
    tuning, no profiler), and on top of Dask's defaults leaves the thread limits in place."""
    import dask.config
    import yaml

    from flyby.montecarlo.engine import WORKER_CONFIG
    shipped = yaml.safe_load((Path(__file__).resolve().parents[2] / "configs" / "dask" / "workers.yaml").read_text())
    for key, value in WORKER_CONFIG.items():
        assert dask.config.get(key, config=shipped) == value
    merged = dask.config.merge(dask.config.config, shipped)["distributed"]["nanny"]["pre-spawn-environ"]
    assert merged["MALLOC_TRIM_THRESHOLD_"] is None and merged["OMP_NUM_THREADS"] == 1
