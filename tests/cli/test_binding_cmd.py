"""``dsg-hil binding check DBC BINDING``: every problem of a binding on its database, one line each, exit 2; with
none, the mapping as a table, exit 0."""

from __future__ import annotations

from pathlib import Path

import pytest

from dsg_hil.cli import main
from dsg_hil.protocol.binding import DEFAULT_BINDING, load_binding
from dsg_hil.protocol.codec import DEFAULT_DBC

DBC = DEFAULT_DBC.read_text(encoding="utf-8")
BINDING = DEFAULT_BINDING.read_text(encoding="utf-8")


def check(tmp_path: Path, capsys, dbc: str = DBC, binding: str = BINDING) -> tuple[int, list[str], list[str]]:
    (tmp_path / "m.dbc").write_text(dbc, encoding="utf-8")
    (tmp_path / "b.toml").write_text(binding, encoding="utf-8")
    code = main(["binding", "check", str(tmp_path / "m.dbc"), str(tmp_path / "b.toml")])
    out, err = capsys.readouterr()
    return code, out.splitlines(), err.splitlines()


def test_the_shipped_pair_prints_its_mapping(tmp_path, capsys):
    code, out, err = check(tmp_path, capsys)
    assert code == 0 and err == []
    assert out[0].split() == ["quantity", "dir", "message.signal", "unit", "resolution", "cycle", "ms", "protection",
                            "frame"]
    rows = {line.split()[0]: line.split() for line in out[1:-1]}
    assert len(rows) == len(load_binding().signals) + 1  # + the tick; the echo's row is "(lock-step echo)"
    assert rows["omega_e"] == ["omega_e", "send", "PLANT_ENGINE.EngineSpeed", "rpm", "0.25", "10", "dsg-hil", "CAN(8)"]
    assert rows["T_CL_pred"] == ["T_CL_pred", "read", "TCU_STATUS.T_CL_Pred", "degC", "0.1", "100", "dsg-hil", "CAN(8)"]
    assert out[-1].endswith("36 quantities on 10 messages sent, 2 read: no problem")


PLATE = ' SG_ T_Plate : 0|12@1+ (0.1,-40) [-40|369.5] "degC" TCU'
SPEED = ' SG_ EngineSpeed : 0|16@1+ (0.25,0) [0|16000] "rpm" TCU'
PRED = ' SG_ T_CL_Pred : 8|12@1+ (0.1,-40) [-40|369.5] "degC" PLANT'
# (change to the DBC, change to the binding, a line expected on stderr)
PROBLEMS = [
    ((SPEED, SPEED.replace("EngineSpeed", "EngineSpd")),
     None, "quantities.omega_e: signal PLANT_ENGINE.EngineSpeed is not in the database"),
    ((SPEED, SPEED.replace('"rpm"', '"V"')),
     None, "quantities.omega_e: unit 'V' of PLANT_ENGINE.EngineSpeed does not convert to rad/s"),
    ((PLATE, PLATE.replace("369.5", "200")), None,
     "quantities.T_CL: SIM_TRUTH_CL.T_Plate carries -40..200 degC, T_CL needs -40..350 degC"),
    ((PRED, PRED.replace("(0.1,-40)", "(1,-40)")), None,
     "quantities.T_CL_pred: TCU_STATUS.T_CL_Pred carries steps of 1 degC, T_CL_pred needs 0.5 degC or finer"),
    (None, ('T_CH_pred = "TCU_STATUS.T_CH_Pred"\n', ""),
     "quantities: T_CH_pred is not mapped (the plant needs it)"),
    (('BA_ "GenMsgCycleTime" BO_ 528 100;\n', ""), None,
     "message TCU_STATUS has no cycle time in the database: give messages.TCU_STATUS.cycle_time_ms"),
    (None, ("[quantities]", '[messages.TCU_STATUS]\nprotection = { profile = "P01", data_id = 0x12, crc_offset = 56, '
                            'counter_offset = 48, data_length = 32 }\n[quantities]'),
     "messages.TCU_STATUS.protection: TCU_STATUS: the P01 counter field (bits 48..51) does not fit the 32 bits "
     "covered of the 8-byte frame"),
]


@pytest.mark.parametrize("dbc_change, binding_change, expected", PROBLEMS, ids=[p[2][:40] for p in PROBLEMS])
def test_each_problem_is_one_line_and_exit_2(tmp_path, capsys, dbc_change, binding_change, expected):
    dbc, binding = DBC, BINDING
    if dbc_change is not None:
        assert dbc_change[0] in dbc
        dbc = dbc.replace(*dbc_change, 1)
    if binding_change is not None:
        assert binding_change[0] in binding
        binding = binding.replace(*binding_change, 1)
    code, out, err = check(tmp_path, capsys, dbc, binding)
    assert code == 2 and out == []
    assert err == [f"error: {tmp_path / 'b.toml'}: {expected}"], err


def test_every_problem_is_listed(tmp_path, capsys):
    dbc = DBC.replace(PLATE, PLATE.replace("369.5", "200")).replace('BA_ "GenMsgCycleTime" BO_ 528 100;\n', "")
    code, out, err = check(tmp_path, capsys, dbc, BINDING.replace('T_CH_pred = "TCU_STATUS.T_CH_Pred"\n', ""))
    assert code == 2 and out == [] and len(err) == 4, err  # the two plates, T_CH_pred, TCU_STATUS's cycle time
    assert all(line.startswith(f"error: {tmp_path / 'b.toml'}: ") for line in err)


def test_values_print_the_numbers_of_the_tcu_s_states_and_clutches(tmp_path, capsys):
    """dct_fd renumbered, its binding naming the TCU's states and clutches in its value tables
    (tests/sim/test_second_matrix.py): after the mapping, each of the TCU's names, its number, the matrix's number
    and name (CREEP 2 -> 3 'Creeping', CL 1 -> 0 'ClutchA'); the shipped pair, which gives none, prints no such
    table."""
    from tests.sim.test_second_matrix import renumbered

    dbc, binding = renumbered(tmp_path)
    assert main(["binding", "check", str(dbc), str(binding)]) == 0
    out = capsys.readouterr().out.splitlines()
    start = out.index("") + 1
    assert out[start].split() == ["values", "TCU", "number", "matrix", "name"]
    rows = [line.split() for line in out[start + 1:-1]]
    assert rows == [["tcu_state", "IDLE", "0", "->", "1", "Idle"], ["tcu_state", "ENGAGE", "1", "->", "2", "Engaging"],
                    ["tcu_state", "CREEP", "2", "->", "3", "Creeping"],
                    ["tcu_state", "HANDOVER", "3", "->", "4", "Handover"],
                    ["tcu_state", "STOPPED_OVERHEAT", "4", "->", "5", "ThermalStop"],
                    ["tcu_state", "FAULT", "5", "->", "0", "Fault"],
                    ["active_clutch", "NONE", "0", "->", "2", "Open"],
                    ["active_clutch", "CL", "1", "->", "0", "ClutchA"],
                    ["active_clutch", "CH", "2", "->", "1", "ClutchB"]]
    assert out[-1].endswith("no problem")
    code, shipped, _ = check(tmp_path, capsys)
    assert code == 0 and "" not in shipped and not any(line.startswith("values") for line in shipped)
