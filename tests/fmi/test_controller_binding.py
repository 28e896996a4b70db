"""A controller FMU on a binding's matrix (``dsg-hil run --controller X.fmu --dbc D --binding B``): the bus side is
ecu-stub's on that matrix (its messages, units, E2E protection), and the FMU's State and ActiveClutch numbers are
the matrix's value tables'. ecu-stub's controller exported as an FMU then sends the bundled ecu-stub's frames on
dct_fd bit for bit (before: exit 2, "message PLANT_ENGINE is not in the DBC", the shipped DBC's messages)."""

from __future__ import annotations

import subprocess
import sys
from importlib import resources
from pathlib import Path

import pytest

from dsg_hil.cli import main
from dsg_hil.fmi.tcu import ValueTables, tcu_outputs
from dsg_hil.protocol.binding import load_binding
from ecu_stub.tcu_io import TcuIO

from ..sim.test_second_matrix import renumbered
from .conftest import run_python

EXAMPLE = resources.files("dsg_hil") / "data" / "examples" / "dct_fd"
DBC, BINDING = Path(str(EXAMPLE / "dct_fd.dbc")), Path(str(EXAMPLE / "dct_fd.binding.toml"))
TCU_DEMAND = "1C4"  # dct_fd's command message (452), in an .asc log's ID column


def frames(log: Path) -> list[str]:
    """The log's lines after its first (an .asc log's header carries the wall-clock date there)."""
    return log.read_text(encoding="utf-8").splitlines()[1:]


@pytest.mark.slow
def test_a_controller_fmu_on_the_example_matrix_sends_ecu_stub_s_frames_bit_for_bit(fmus, tmp_path):
    ref, fmu = tmp_path / "ecu_stub.asc", tmp_path / "fmu.asc"
    common = ["-i", "virtual", "--duration", "2", "--dbc", str(DBC), "--binding", str(BINDING), "-q"]
    done = subprocess.run([sys.executable, "-m", "dsg_hil", "run", *common, "--controller", str(fmus["tcu"]),
                           "--log", str(fmu)], capture_output=True, text=True, timeout=300)
    assert done.returncode == 0, done.stderr[-2000:]
    assert main(["run", *common, "--log", str(ref)]) == 0
    sent = frames(fmu)
    assert sent == frames(ref)
    assert sum(f" {TCU_DEMAND} " in line for line in sent) >= 190  # the FMU's commands, every 10 ms, on dct_fd's ID


@pytest.mark.slow
def test_the_fmu_s_state_and_clutch_numbers_are_the_binding_s(fmus, tmp_path):
    """On a matrix numbering the states otherwise (the binding's ``values``), the adapter reads the FMU's State and
    ActiveClutch in the matrix's numbers: 'Creeping' is 3 there (CREEP is 2 in the shipped DBC)."""
    dbc, binding = renumbered(tmp_path)
    io = TcuIO(load_binding(binding, dbc=dbc))
    tables = ValueTables(states=io.state_values, clutches=io.clutch_values)
    outputs = {"P_CL_Cmd": 0.3, "P_CH_Cmd": 0.0, "State": 3.0, "ActiveClutch": 0.0, "BrakeRequest": 0.0,
               "T_CL_Pred": 90.0, "T_CH_Pred": 80.0, "FaultBits": 0.0}
    read = tcu_outputs(outputs, tables)
    assert (read.state, read.active_clutch) == ("CREEP", "CL")
    assert (tcu_outputs(outputs, ValueTables()).state, tcu_outputs(outputs, ValueTables()).active_clutch) == \
        ("HANDOVER", "NONE")  # the shipped numbers read the same FMU otherwise
    built = run_python("""
        import json, sys
        import can
        from dsg_hil.fmi.controller import open_controller
        from dsg_hil.protocol.binding import load_binding
        from ecu_stub.tcu_io import TcuIO

        loaded = load_binding(sys.argv[3], dbc=sys.argv[2])
        bus = can.Bus(interface="virtual", channel="fmibind")
        with open_controller(sys.argv[1]) as fmu:
            tcu = fmu.tcu_factory(loaded.db, bus, io=TcuIO(loaded))
            print(json.dumps({"states": fmu.tables.states, "clutches": fmu.tables.clutches, "cycle": fmu.cycle,
                              "command": tcu.io.names[2]}))
        bus.shutdown()
    """, str(fmus["tcu"]), str(dbc), str(binding))
    assert built == {"states": io.state_values, "clutches": io.clutch_values, "cycle": 0.01, "command": "TCU_Demand"}


@pytest.mark.slow
def test_a_binding_without_a_quantity_the_tcu_reads_stops_a_controller_fmu_at_start(fmus, tmp_path):
    """As for the bundled ecu-stub: exit 2, one line naming the binding file and the quantity, nothing written
    (before: "message PLANT_ENGINE is not in the DBC", the shipped DBC's messages looked for)."""
    binding = tmp_path / "noaccel.binding.toml"
    text = BINDING.read_text(encoding="utf-8")
    binding.write_text(text.replace('a_x = "ESP_WheelAccel.LongAcc"\n', ""), encoding="utf-8")
    assert "a_x" not in binding.read_text(encoding="utf-8")
    summary = tmp_path / "s.json"
    done = subprocess.run([sys.executable, "-m", "dsg_hil", "run", "-i", "virtual", "--controller", str(fmus["tcu"]),
                           "--dbc", str(DBC), "--binding", str(binding), "--summary", str(summary)],
                          capture_output=True, text=True, timeout=300)
    assert done.returncode == 2 and done.stdout == ""
    assert done.stderr.strip().splitlines() == [f"error: {binding}: quantities.a_x: not mapped, and ecu-stub reads it "
                                                f"(longitudinal acceleration (body + g sin(grade)))"]
    assert not summary.exists()
