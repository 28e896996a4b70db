"""The benchmarks run and print what issue 9 asks of them (``bench/``, short durations; no timing is asserted:
speed belongs in the benchmarks' figures, not in tests)."""

from __future__ import annotations

import json
import math
import os
import subprocess
import sys
from pathlib import Path

import pytest

BENCH = Path(__file__).resolve().parents[1] / "bench"

pytestmark = pytest.mark.slow


def bench_json(script: str, *args: str) -> dict:
    # a script's own directory first on sys.path (bench/, no package in it: its siblings), as run by hand
    env = {key: value for key, value in os.environ.items() if key != "PYTHONSAFEPATH"}
    proc = subprocess.run([sys.executable, str(BENCH / script), "--json", *args], capture_output=True, text=True,
                          timeout=600, cwd=BENCH, env=env)
    assert proc.returncode == 0, proc.stderr[-2000:]
    return json.loads(proc.stdout)


def positive(x: object) -> bool:
    return isinstance(x, (int, float)) and math.isfinite(x) and x > 0


def test_closed_loop_speed_figures():
    out = bench_json("closed_loop_speed.py", "--seconds", "0.5", "--udp-seconds", "0.5", "--rounds", "1")
    now, before = out["closed_loop"], out["closed_loop_baseline"]
    assert positive(out["closed_loop_sim_s_per_wall_s"]) and positive(out["closed_loop_baseline_sim_s_per_wall_s"])
    assert now["frames_sent"] == before["frames_sent"] > 0  # the same loop on both paths
    assert len(now["rounds"]) == len(before["rounds"]) == 1
    assert now["physics_us_per_period"] + now["rest_us_per_period"] == pytest.approx(now["period_us"], abs=0.2)
    split = now["split_cpu_us"]
    assert set(split) == {"physics", "plant_io", "results", "tcu"}
    # physics, TCU and results are timed where they run; plant_io is the rest of the periods' CPU time, which is
    # estimated (set-up taken out in proportion to wall time): a 0.5-s run on a loaded machine can put it below zero
    assert all(positive(split[k]) for k in ("physics", "results", "tcu")) and math.isfinite(split["plant_io"])
    assert sum(split.values()) == pytest.approx(now["period_cpu_us"], abs=0.3)
    assert positive(now["runs_per_core_hour"]) and positive(now["loop_peak_rss_mb"])
    udp = out["udp_multicast"]
    assert "error" not in udp and udp["rejected"] == 0 and positive(out["udp_multicast_sim_s_per_wall_s"])
    assert all(positive(v) for v in out["udp_multicast_primitives"].values())
    assert set(out["peak_rss_mb"]) == {"dsg-hil run", "dsg-hil run -i udp_multicast (plant, ecu-stub)"}
    assert all(positive(v) for v in out["peak_rss_mb"].values())
    assert out["peak_rss_mb_max"] == max(out["peak_rss_mb"].values())
    assert {"dsg-hil --help", "ecu-stub --help", "dsg-hil run --help", "dsg-hil calibrate --help"} <= set(
        out["startup_s"])
    assert out["startup_max_s"] == max(out["startup_s"].values())


def test_plant_speed_figures():
    # short cases: the figures' keys and cases, not their values (the solve_ivp references of the vehicle and creep
    # cases, Radau at rtol 1e-10 and 1e-8, took most of this test's 88 s; the vehicle case at 2 s)
    out = bench_json("plant_speed.py", "--seconds", "1", "--cosim-seconds", "0.2", "--creep-seconds", "0.5",
                     "--fine-seconds", "1")
    for key in ("plant_sim_s_per_wall_s", "solve_ivp_ratio", "plant_step_per_call_sim_s_per_wall_s"):
        assert positive(out[key]), key
    names = [c["name"] for c in out["cases"]]
    assert names == ["vehicle", "rig1", "rig2", "rig3", "rig4", "creep", "creep_fine"]
    assert out["max_plate_error_c"] == max(c["max_plate_error_c"] for c in out["cases"])
    assert out["max_speed_error_fs"] == max(c["max_speed_error_fs"] for c in out["cases"])
    study = out["step_study"]
    assert [c["name"] for c in study] == ["step 1 ms", "step 0.5 ms", "step 0.25 ms", "step 0.1 ms"]
    assert all(math.isfinite(c["max_plate_error_c"]) and math.isfinite(c["max_speed_error_rpm"]) for c in study)
    assert out["cosim"]["solve_ivp"] is not None  # a tolerance reached the plant's accuracy


def test_sweep_scaling_figures():
    """1 and 2 workers on Dask, one round of 1 run per worker (2 simulated s): the figures issue 17 item 6 names."""
    out = bench_json("sweep_scaling.py", "--runs-per-worker", "1", "--duration", "2", "--rounds", "1")
    one, two = out["configurations"]["1"], out["configurations"]["2"]
    assert (one["runs"], two["runs"]) == (1, 2) and one["efficiency"] == 1.0 and positive(two["efficiency"])
    assert two["efficiency"] == pytest.approx(two["runs_per_min"] / (2 * one["runs_per_min"]), abs=1e-3)
    assert len(one["worker_peak_rss_mb"]) == 1 and len(two["worker_peak_rss_mb"]) == 2
    assert out["worker_peak_rss_mb_max"] == max(one["worker_peak_rss_mb"] + two["worker_peak_rss_mb"]) > 0
    assert out["runs_per_core_hour"] == round(60 * one["runs_per_min"])


def test_matrix_speed_figures_and_the_same_frames_on_the_same_tree():
    """Every matrix timed and its frames digested; this checkout as its own baseline: the same frames, bit for bit."""
    out = bench_json("matrix_speed.py", "--seconds", "0.5", "--rounds", "1", "--baseline-tree", str(BENCH.parent))
    assert [c["case"] for c in out["cases"]] == [c["case"] for c in out["baseline"]] == ["shipped", "arxml", "dct_fd"]
    for case in out["cases"]:
        assert positive(case["wall_s_per_10_s"]) and positive(case["cpu_s_per_10_s"]) and positive(case["vs_shipped"])
        assert case["frames"] > 0 and case["rejected"] == 0 and case["frames_equal_baseline"] is True, case
    assert len({c["digest"] for c in out["cases"]}) == 3  # (three matrices: three sets of frames)


def test_judder_reference_the_fixed_step_plant_and_solve_ivp_judder_alike():
    """From r01753's plant in steady creep on CH, the inputs held for 0.3 s: CH sticks and slips in both (its slip
    touching 0), the vehicle speed's fast part at the same frequency and within 10 % of each other's amplitude."""
    out = bench_json("judder_reference.py", "r01753", "26.0", "--span", "0.3")
    steps, ref = out["steps"], out["solve_ivp"]
    assert out["stick_slip_changes"] > 10
    assert steps["slip_CH_rpm"][0] < 5.0 and ref["slip_CH_rpm"][0] < 5.0
    assert abs(steps["fast_hz"] - ref["fast_hz"]) <= 3.0
    assert steps["fast_pp_pct"] == pytest.approx(ref["fast_pp_pct"], rel=0.1) and ref["fast_pp_pct"] > 5.0


def test_latent_findings_counts_the_runs_by_their_latent_faults(tmp_path):
    """Two runs of the shipped space: every run in one group, each group's counts and hottest plate."""
    env = {key: value for key, value in os.environ.items() if key != "PYTHONSAFEPATH"}
    out = tmp_path / "findings.json"
    proc = subprocess.run([sys.executable, str(BENCH / "latent_findings.py"), "--n", "2", "--workers", "1",
                           "--json", str(out)], capture_output=True, text=True, timeout=600, cwd=BENCH, env=env)
    assert proc.returncode == 0, proc.stderr[-2000:]
    found = json.loads(out.read_text(encoding="utf-8"))
    assert found["runs"] == 2 and found["failed"] == 0 and positive(found["hottest_c"])
    assert sum(group["runs"] for group in found["groups"].values()) == 2
    assert set(found["groups"]) == {"beyond", "within", "none"}
    assert "runs with a latent fault beyond its detection threshold" in proc.stdout


def test_a_recorded_result_has_its_date_machine_command_and_figures(tmp_path):
    """bench/record.py keeps a script's --json output with what the performance page shows beside it."""
    proc = subprocess.run([sys.executable, str(BENCH / "record.py"), "stuck", "--out", str(tmp_path), "--note", "idle",
                           "--", "python", "bench/stuck_sensors.py", "--json", "none"],
                          capture_output=True, text=True, timeout=600)
    assert proc.returncode == 0, proc.stderr[-2000:]
    record = json.loads((tmp_path / "stuck.json").read_text(encoding="utf-8"))
    assert record["command"] == "python bench/stuck_sensors.py --json none" and record["machine"].endswith("; idle")
    assert len(record["date"]) == 10 and positive(record["wall_s"])
    (case,) = record["results"]["cases"]
    assert case["case"] == "none" and case["stop_reason"] == "STOPPED_OVERHEAT" and case["implausible"] == {}


def test_rerun_sweep_runs_replaces_the_latent_faults_only(tmp_path):
    """A 2-s run of the shipped space with a drawn latent fault and a frame fault, recorded as a sweep records it:
    ``--without-latent`` runs it again with the frame fault and without the latent one, ``--latent`` with another
    in its place; a latent fault that does not parse is exit 2, one line, nothing run."""
    from dsg_hil.protocol.faults import parse_fault
    from dsg_hil.sweep.space import SAFETY_SPACE, load_space
    from dsg_hil.sweep.worker import run_task
    from tests.sweep.test_latent import SHORT_CREEP, one_early_latent_fault

    space = load_space(SAFETY_SPACE)
    inputs = {**SHORT_CREEP, "fault": "drop:TCU_CMD", "fault_at_s": 1.0, "fault_duration_s": 0.5}
    index, values, latent = one_early_latent_fault(space, inputs)
    task = space.task(index, values)
    assert len(task["faults"]) == 2 and latent in task["faults"]
    then = run_task(task)["row"]
    (tmp_path / "runs").mkdir()
    (tmp_path / "runs" / f"{task['run_id']}.json").write_text(json.dumps({"run_id": task["run_id"], "row": then,
                                                                         "task": task}), encoding="utf-8")
    env = {key: value for key, value in os.environ.items() if key != "PYTHONSAFEPATH"}

    def rerun(*args: str) -> subprocess.CompletedProcess[str]:
        return subprocess.run([sys.executable, str(BENCH / "rerun_sweep_runs.py"), str(tmp_path), f"r{index:05d}",
                               "--keys", "in.latent,in.fault,faults", "--json", *args],
                              capture_output=True, text=True, timeout=600, cwd=BENCH, env=env)

    other = "offset:PLANT_VEHICLE.VehicleSpeed@0.5-,value=0.01"
    for args, now_latent in ((["--without-latent"], ""), (["--latent", other], other)):
        proc = rerun(*args)
        assert proc.returncode == 0, proc.stderr[-2000:]
        pair = json.loads(proc.stdout)
        assert pair["run_id"] == task["run_id"] and pair["then"]["in.latent"] == latent
        assert pair["now"]["in.latent"] == now_latent
        assert pair["now"]["in.fault"] == pair["then"]["in.fault"] == "drop:TCU_CMD"
        injected_then, injected_now = (json.loads(pair[k]["faults"])["injected"] for k in ("then", "now"))
        assert parse_fault(latent).describe() in injected_then and parse_fault(latent).describe() not in injected_now
        assert any(key.startswith("drop:TCU_CMD") for key in injected_now), injected_now
        assert (parse_fault(other).describe() in injected_now) == bool(now_latent), injected_now
    bad = rerun("--latent", "offset:PLANT_VEHICLE.VehicleSpeed@x-,value=1")
    assert bad.returncode == 2 and bad.stdout == "" and len(bad.stderr.strip().splitlines()) == 1
    assert bad.stderr.startswith("rerun_sweep_runs: --latent: ") and "start_s must be a number" in bad.stderr
