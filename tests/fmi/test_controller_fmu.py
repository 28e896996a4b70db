"""A controller FMU as the TCU: ecu-stub's own controller, exported as an FMU (Real, Integer and Boolean ports),
gives the bundled ecu-stub's frames bit for bit in lock-step; variables that match no DBC signal are one error
naming them; the plant FMU and the controller FMU co-simulated in FMPy give the creep of 'dsg-hil run'."""

from __future__ import annotations

import subprocess
import sys

import numpy as np
import pytest

from dsg_hil.cli import main
from dsg_hil.fmi.controller import FmuError, load_mapping, open_controller
from dsg_hil.sim.run import RunConfig, open_run

from .conftest import run_python

HANDOVER_BY_S = 40.0  # the shipped creep hands CL over to CH at 33 s: the runs below cover it


@pytest.mark.slow
def test_ecu_stub_s_controller_as_an_fmu_gives_the_same_frames_bit_for_bit(fmus, tmp_path):
    ref, fmu, summary = tmp_path / "ecu_stub.log", tmp_path / "fmu.log", tmp_path / "fmu.json"
    common = ["-i", "virtual", "--duration", f"{HANDOVER_BY_S:g}"]
    # the FMU in a process of its own (conftest.py)
    done = subprocess.run([sys.executable, "-m", "dsg_hil", "run", *common, "--controller", str(fmus["tcu"]),
                           "--log", str(fmu), "--summary", str(summary)], capture_output=True, text=True, timeout=300)
    assert done.returncode == 0, done.stderr[-2000:]
    assert main(["run", *common, "--log", str(ref)]) == 0
    frames = ref.read_bytes()
    assert fmu.read_bytes() == frames
    assert frames.count(b"\n") > 20_000 and '"handovers": [\n    {' in summary.read_text()  # a handover is in it


def test_a_variable_that_matches_no_dbc_signal_is_one_error_naming_it(fmus, capsys):
    # the plant FMU has the TCU's commands as inputs: not what a controller reads
    assert main(["run", "-i", "virtual", "--controller", str(fmus["plant"])]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("error: ") and "input variable 'P_CL_Cmd'" in err[0], err


def test_a_mapping_renames_and_is_checked(fmus, tmp_path):
    with pytest.raises(FmuError, match=r"the mapping's DBC signal 'Mode' \(for output variable 'State'\) matches no"):
        open_controller(fmus["tcu"], {"State": "Mode"})
    with pytest.raises(FmuError, match="the mapping's key 'Stat' is no input or output variable of the FMU"):
        open_controller(fmus["tcu"], {"Stat": "State"})  # a misspelt key: an error, not ignored
    mapping = tmp_path / "map.toml"
    mapping.write_text('[signals]\nEngineSpeed = "VehicleSpeed"\n', encoding="utf-8")
    assert load_mapping(mapping) == {"EngineSpeed": "VehicleSpeed"}
    with pytest.raises(FmuError, match="'EngineSpeed' and 'VehicleSpeed' both map to the DBC signal 'VehicleSpeed'"):
        open_controller(fmus["tcu"], mapping)
    with open_controller(fmus["tcu"], {"State": "State"}) as fmu:  # opened, not instantiated: no instance here
        assert set(fmu.outputs) == {"P_CL_Cmd", "P_CH_Cmd", "DecelRequest", "State", "ActiveClutch", "BrakeRequest",
                                    "T_CL_Pred", "T_CH_Pred", "FaultBits"}
        assert "PlantValid" in fmu.inputs and "EngineSpeed" in fmu.inputs
        # Integer and Boolean ports (as Simulink exports a state or a flag): ecu-stub's FMU has both
        assert fmu.outputs["State"][0] == "Integer" and fmu.outputs["BrakeRequest"][0] == "Boolean"
        assert fmu.inputs["CreepRequest"][0] == "Boolean" and fmu.inputs["RxFaultBits"][0] == "Integer"


COSIMULATE = """
import json, sys
from dsg_hil.fmi.cosim import cosimulate
r = cosimulate(sys.argv[1], sys.argv[2], duration=float(sys.argv[3]))
print(json.dumps({"t": r.t, "T_CL": r.T_CL, "T_CH": r.T_CH, "handovers": r.handovers}))
"""


@pytest.mark.slow
def test_plant_fmu_and_controller_fmu_in_fmpy_give_the_creep_of_dsg_hil_run(fmus):
    """A shortened creep (to the first handover and past it: the full 240 s take about a minute in FMPy)."""
    cosim = run_python(COSIMULATE, str(fmus["plant"]), str(fmus["tcu"]), f"{HANDOVER_BY_S:g}")
    with open_run(RunConfig(duration=HANDOVER_BY_S, truth=True)) as run:
        summary = run.run()
    truth = run.truth()  # the plant at each tick, before the period: the co-simulation's period ends one later
    assert np.allclose(truth["t"][1:], cosim["t"][:-1], rtol=0.0, atol=1e-9)
    for plate in ("T_CL", "T_CH"):
        assert np.abs(np.array(cosim[plate][:-1]) - truth[plate][1:]).max() < 0.1
    assert max(cosim["T_CL"]) - cosim["T_CL"][0] > 50.0  # the clutch heated: a creep, not two idle models
    assert [tuple(h) for h in cosim["handovers"]] == [(h["t_s"], h["from"], h["to"]) for h in summary.handovers]
    assert len(summary.handovers) == 1


@pytest.mark.slow
def test_the_pytest_fixture_runs_a_controller_fmu_by_its_path(fmus, tmp_path):
    """dsg_hil_run("my_tcu.fmu") (run_plant, which the fixture calls): ecu-stub's controller as an FMU gives the
    bundled ecu-stub's frames, bit for bit, and the same summary."""
    test = tmp_path / "test_my_tcu.py"
    test.write_text(
        "import json, sys\n\n"
        "def test_my_tcu(dsg_hil_run):\n"
        f"    run = dsg_hil_run({str(fmus['tcu'])!r}, duration=5.0, log=None)\n"
        "    frames = [(m.timestamp, m.arbitration_id, bytes(m.data).hex()) for m in run.frames]\n"
        f"    open({str(tmp_path / 'fmu.json')!r}, 'w').write(json.dumps({{'frames': frames, "
        "'stop': run.summary['stop_reason']}))\n")
    # a pytest of its own: one FMU instance per process (conftest.py)
    done = subprocess.run([sys.executable, "-m", "pytest", "-q", "-p", "no:cacheprovider", str(test)],
                          capture_output=True, text=True, timeout=300, cwd=tmp_path)
    assert done.returncode == 0, done.stdout[-3000:]
    import json

    from dsg_hil.testing import run_plant

    ref = run_plant(None, duration=5.0, log=None)
    got = json.loads((tmp_path / "fmu.json").read_text())
    assert got["frames"] == [[m.timestamp, m.arbitration_id, bytes(m.data).hex()] for m in ref.frames]
    assert len(got["frames"]) > 1000 and got["stop"] == ref.summary["stop_reason"]
