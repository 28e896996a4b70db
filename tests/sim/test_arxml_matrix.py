"""The plant on an ARXML system description through cantools (dbc/examples/arxml/): the database loads as a DBC
does, the E2E protection of each message comes from the ARXML's END-TO-END-PROTECTION set (Profile 5 on the TCU's
frames, 11 on the plant's; the binding declares none), ``dsg-hil binding check`` passes, and a short lock-step
creep with ecu-stub on the same pair is the shipped pair's: the same truth, nothing rejected. Profile 5 frames are
checked against cantools' own ``autosar.end_to_end`` helper, given the ARXML's message."""

from __future__ import annotations

from importlib import resources
from pathlib import Path

import pytest

from dsg_hil.cli import main
from dsg_hil.protocol import load_dbc
from dsg_hil.protocol.binding import load_binding
from dsg_hil.protocol.profiles import ProtectionSpec, protection_for
from dsg_hil.sim.run import RunConfig, open_run

end_to_end = pytest.importorskip("cantools.autosar.end_to_end")

EXAMPLE = Path(str(resources.files("dsg_hil") / "data" / "examples" / "arxml"))
ARXML, BINDING = EXAMPLE / "tcu.arxml", EXAMPLE / "tcu.binding.toml"
DURATION = 8.0  # s of the shipped creep: the TCU engages CL and creeps


def test_the_example_is_made_from_the_shipped_dbc():
    """tcu.arxml is tests/sim/arxml_example.py's text of today's shipped DBC (regenerate it there if the DBC moves)."""
    from tests.sim.arxml_example import arxml_from_dbc

    assert ARXML.read_text(encoding="utf-8") == arxml_from_dbc(load_dbc())


def test_cantools_reads_the_arxml_with_its_e2e_data_and_cycle_times():
    db = load_dbc(ARXML)
    command, engine = db.get_message_by_name("TCU_CMD"), db.get_message_by_name("PLANT_ENGINE")
    assert ProtectionSpec.from_autosar(command) == ProtectionSpec.from_table(
        {"profile": "P05", "data_id": 0x1200, "data_length": 64}, "TCU_CMD")
    assert ProtectionSpec.from_autosar(engine) == ProtectionSpec.from_table(
        {"profile": "P11", "data_id": 0x0100, "data_length": 64}, "PLANT_ENGINE")
    assert (command.cycle_time, db.get_message_by_name("PLANT_OIL_TEMP").cycle_time) == (10, 100)
    state = db.get_message_by_name("TCU_STATUS").get_signal_by_name("State")
    assert state.choices is not None and {str(c) for c in state.choices.values()} >= {"IDLE", "CREEP", "HANDOVER"}
    binding = load_binding(BINDING, db=db)
    assert "decel_request" not in binding.units  # optional: the ARXML's TCU_CMD has no signal for it
    assert not binding.protection  # every protection is the ARXML's
    assert {m: protection_for(db.get_message_by_name(m)).profile for m in (*binding.tx, *binding.rx)} == {
        **dict.fromkeys(["PLANT_ENGINE", "PLANT_SPEEDS", "PLANT_VEHICLE", "PLANT_PRESSURE", "PLANT_OIL_TEMP",
                         "DRIVER"], "P11"),
        "SIM_TRUTH_CL": "dsg-hil", "SIM_TRUTH_CH": "dsg-hil", "TCU_CMD": "P05", "TCU_STATUS": "P05"}


def test_binding_check_passes_on_the_arxml(capsys):
    assert main(["binding", "check", str(ARXML), str(BINDING)]) == 0
    out = capsys.readouterr().out
    assert "TCU_CMD.P_CL_Cmd" in out and "P05" in out and "P11" in out and out.rstrip().endswith("no problem")


@pytest.fixture(scope="module")
def runs():
    with open_run(RunConfig(duration=DURATION)) as run:
        shipped = run.run().as_json()
    with open_run(RunConfig(duration=DURATION, dbc=ARXML, binding=BINDING, capture=True)) as run:
        arxml = run.run().as_json()
    return shipped, arxml, run.frames


def test_a_lockstep_creep_on_the_arxml_is_the_shipped_one(runs):
    shipped, arxml, _ = runs
    for key in ("creep_time_s", "standstill_time_s", "slip_time_s", "max_plate_temp_c", "friction_energy_kj",
                "phases"):
        assert arxml[key] == shipped[key], key
    assert arxml["max_plate_temp_c"]["CL"] > 100.0  # it crept
    frames = arxml["frames"]
    assert frames["rejected"] == frames["unanswered_ticks"] == frames["lost"] == 0
    assert frames["by_message"]["TCU_CMD"]["taken"] == 100 * DURATION
    assert frames["by_message"]["TCU_STATUS"]["taken"] == 10 * DURATION


def test_the_tcus_frames_carry_the_arxmls_profile_5(runs):
    """Every TCU_CMD frame of the run passes cantools' Profile 5 check with the ARXML's data ID, and fails ours under
    another data ID (the data ID is the ARXML's, not a default)."""
    *_, captured = runs
    db = load_dbc(ARXML)
    command = db.get_message_by_name("TCU_CMD")
    frames = [bytes(f.data) for f in captured if f.arbitration_id == command.frame_id]
    assert len(frames) >= 100 * DURATION
    assert all(end_to_end.check_profile5_crc(f, command) for f in frames)
    other = protection_for(command, {"profile": "P05", "data_id": 0x1201})
    assert all(other.cause(f) == "crc" for f in frames)


def test_a_fault_on_the_arxml_takes_its_side_from_the_binding():
    """The ARXML names no PLANT or TCU node: a fault's side is the binding's (read: the TCU's, sent: the plant's);
    without a binding it must be given."""
    from dsg_hil.protocol.faults import FaultError, check_faults, parse_fault

    db = load_dbc(ARXML)
    binding = load_binding(BINDING, db=db)
    faults = [parse_fault("corrupt_crc:TCU_CMD@5-5.05"), parse_fault("drop:PLANT_SPEEDS@1-2")]
    by_side = check_faults(faults, binding.db, binding.sides)
    assert [f.message for f in by_side["tcu"]] == ["TCU_CMD"] and [f.message for f in by_side["plant"]] == [
        "PLANT_SPEEDS"]
    with pytest.raises(FaultError, match="names no sender PLANT or TCU for TCU_CMD: give side"):
        check_faults(faults[:1], db)
