"""Bad input: exit 2 and one line naming the file, key or option and what is wrong, nothing written; the same
exit codes for dsg-hil and ecu-stub (dsg_hil.common.errors). Each case was a crash or a silent acceptance before."""

from __future__ import annotations

import pytest

from dsg_hil.cli import main
from dsg_hil.common.errors import (
    EXIT_BAD_INPUT,
    EXIT_OUT_OF_BAND,
    EXIT_RUN_FAILED,
    InputError,
    ResultError,
    RunError,
    exit_code,
)
from dsg_hil.protocol.faults import FaultError
from dsg_hil.physics.params import DEFAULT_PARAMS_PATH, ParameterError, parse_params
from dsg_hil.protocol import Codec, ProtocolError, load_dbc
from dsg_hil.protocol.codec import DEFAULT_DBC, signal_range
from dsg_hil.sim.runner import PeerLost
from dsg_hil.sim.scenario import ScenarioError, load_scenario
from ecu_stub.calibration import CalibrationError
from ecu_stub.cli import main as ecu_stub_main

SCENARIO = "duration_s = 1.0\n[[driver]]\nt_s = 0.0\n"


def one_error_line(capsys, *needles: str) -> str:
    err = capsys.readouterr().err.strip().splitlines()
    assert err and "error: " in err[-1], err  # "error: ..." (argparse: "PROG: error: ...")
    assert all(needle in err[-1] for needle in needles), err[-1]
    assert not any("Traceback" in line for line in err)
    return err[-1]


def test_one_hierarchy_and_its_exit_codes():
    for error in (ScenarioError, ParameterError, ProtocolError, FaultError, CalibrationError):
        assert issubclass(error, InputError) and issubclass(error, ValueError)
    assert issubclass(PeerLost, RunError)
    assert exit_code(ScenarioError("x")) == EXIT_BAD_INPUT == 2
    assert exit_code(PeerLost("x")) == exit_code(KeyError("a bug")) == EXIT_RUN_FAILED == 1
    assert exit_code(ResultError("x")) == EXIT_OUT_OF_BAND == 3


@pytest.mark.parametrize("text, needle", [
    ("duration_s = = 1", "not valid TOML"),
    ("duration_s = 1.0\ndriver = [1, 2]\n", "driver[0]: must be a table"),
    (SCENARIO + "[[fault]]\nkind = \"drop\"\ntarget = \"TCU_CMD\"\n[[fault]]\nkind = \"drop\"\ntarget = \"TCU_CMD\"\n"
                "probability = 2\n", "fault[1]: probability must be within [0, 1]"),
    (SCENARIO + "[[fault]]\nkind = \"drop\"\ntarget = \"TCU_CMD\"\nside = \"ecu\"\n", "fault[0]: side must be"),
    ("fault = 3\n" + SCENARIO, "fault: must be [[fault]] tables"),
])
def test_bad_scenario_is_exit_2_naming_the_key(tmp_path, capsys, text, needle):
    path = tmp_path / "s.toml"
    path.write_text(text, encoding="utf-8")
    with pytest.raises(ScenarioError):
        load_scenario(path)
    summary = tmp_path / "summary.json"
    assert main(["run", "-i", "virtual", "--scenario", str(path), "--summary", str(summary)]) == 2
    one_error_line(capsys, needle)
    assert not summary.exists()  # nothing written


def test_a_fault_naming_what_the_dbc_lacks_fails_at_start(tmp_path, capsys):
    path = tmp_path / "s.toml"
    path.write_text(SCENARIO + "[[fault]]\nkind = \"stuck\"\ntarget = \"TCU_CMD.NoSuch\"\n", encoding="utf-8")
    summary = tmp_path / "summary.json"
    assert main(["run", "-i", "virtual", "--scenario", str(path), "--summary", str(summary)]) == 2
    one_error_line(capsys, "fault[0]: signal 'TCU_CMD.NoSuch' is not in the DBC")
    assert not summary.exists()


@pytest.mark.parametrize("argv, needle", [
    (["run", "-i", "virtual", "--fault", "drop:TCU_CMD@2-1"], "--fault 'drop:TCU_CMD@2-1': window must satisfy"),
    (["run", "-i", "virtual", "--fault", "explode:TCU_CMD"], "kind must be one of"),
    (["plant", "-i", "virtual", "--fault", "drop:TCU_CMD"], "changes the TCU's frames: give it to ecu-stub"),
    (["run", "-i", "virtual", "--duration", "inf"], "--duration: must be within"),
    (["run", "-i", "virtual", "--duration", "nan"], "--duration: must be within"),
    (["run", "--config-context", "nosuch"], "--config-context nosuch: no section [nosuch]"),
    (["run", "-i", "pcan"], "-i pcan: needs a channel"),
])
def test_bad_options_are_exit_2(capsys, argv, needle):
    assert main(argv) == 2
    one_error_line(capsys, needle)


@pytest.mark.parametrize("argv, needle", [
    (["dbc", "--bitrate", "0"], "--bitrate: must be a positive finite number"),
    (["validate", "--dt=-1e-3"], "--dt: must be a positive finite number"),
    (["run", "--reply-timeout", "inf"], "--reply-timeout: must be a positive finite number"),
])
def test_bad_numbers_are_usage_errors(capsys, argv, needle):
    with pytest.raises(SystemExit) as exc:
        main(argv)
    assert exc.value.code == 2
    one_error_line(capsys, needle)


@pytest.mark.parametrize("argv, needle", [
    (["--duration", "-1"], "--duration: must be a positive number of seconds"),
    (["--idle-exit", "0"], "--idle-exit: must be a positive number of seconds"),
    (["--fault", "drop:PLANT_SPEEDS"], "changes the plant's frames"),
    (["--fault", "drop:TCU_CMD,p=x"], "probability must be a number"),
    (["--config-context", "nosuch"], "--config-context nosuch"),
])
def test_ecu_stub_bad_input_is_exit_2(capsys, argv, needle):
    assert ecu_stub_main(["-i", "virtual", *argv]) == 2
    one_error_line(capsys, needle)


def test_ecu_stub_log_is_checked_before_serving(tmp_path, capsys):
    (tmp_path / "afile").write_text("not a directory")
    assert ecu_stub_main(["-i", "virtual", "--log", str(tmp_path)]) == 2
    one_error_line(capsys, f"--log {tmp_path}: is a directory")
    assert ecu_stub_main(["-i", "virtual", "--log", str(tmp_path / "afile" / "tcu.log")]) == 2
    one_error_line(capsys, "--log", "not a writable directory")
    assert ecu_stub_main(["-i", "virtual", "--log", str(tmp_path / "tcu.nosuch")]) == 2
    one_error_line(capsys, "--log", "tcu.nosuch")


def test_non_utf8_files_name_the_file(tmp_path, capsys):
    path = tmp_path / "latin1.toml"
    path.write_bytes("name = \"Stra\xdfe\"\n".encode("latin-1"))
    for option in ("--scenario", "--params"):
        assert main(["run", "-i", "virtual", option, str(path)]) == 2
        one_error_line(capsys, str(path), "not UTF-8")
    assert ecu_stub_main(["-i", "virtual", "--calibration", str(path)]) == 2
    one_error_line(capsys, str(path), "not UTF-8")


def test_a_count_of_friction_surfaces_must_be_whole():
    text = DEFAULT_PARAMS_PATH.read_text(encoding="utf-8")
    assert "[clutch.CL]\nN = { value = 6," in text
    with pytest.raises(ParameterError, match=r"clutch\.CL\.N: must be a whole number"):
        parse_params(text.replace("[clutch.CL]\nN = { value = 6,", "[clutch.CL]\nN = { value = 2.5,"))


def test_unwritable_validate_outputs_fail_before_the_run(tmp_path, capsys):
    (tmp_path / "afile").write_text("not a directory")
    assert main(["validate", "--json", str(tmp_path)]) == 2
    one_error_line(capsys, f"--json {tmp_path}: is a directory")
    assert main(["validate", "--plots", str(tmp_path / "afile")]) == 2
    one_error_line(capsys, "--plots", "not a writable directory")


def test_a_dbc_signal_without_range_has_the_range_of_its_bits(tmp_path, capsys):
    """[0|0] is the common way to say "no range": cantools reads None; the codec clamps to and checks against
    what the bits carry (16 bits signed, scale 0.001: -32.768 .. 32.767 m/s) instead of crashing."""
    text = DEFAULT_DBC.read_text(encoding="utf-8")
    line = next(ln for ln in text.splitlines() if ln.startswith(" SG_ VehicleSpeed :"))
    dbc = tmp_path / "norange.dbc"
    dbc.write_text(text.replace(line, line[:line.index("[")] + "[0|0]" + line[line.index("]") + 1:]), encoding="utf-8")
    db = load_dbc(dbc)
    signal = db.get_message_by_name("PLANT_VEHICLE").get_signal_by_name("VehicleSpeed")
    assert (signal.minimum, signal.maximum) == (None, None)
    assert signal_range(signal) == pytest.approx((-32.768, 32.767))
    codec = Codec(db, {"PLANT_VEHICLE": ("VehicleSpeed",)})
    frame = codec.decode(codec.frame_id("PLANT_VEHICLE"), codec.encode("PLANT_VEHICLE", {"VehicleSpeed": 99.0}, 0))
    assert frame.values["VehicleSpeed"] == pytest.approx(32.767)  # clamped to what the bits carry
    assert main(["run", "-i", "virtual", "--dbc", str(dbc), "--duration", "0.2"]) == 0
