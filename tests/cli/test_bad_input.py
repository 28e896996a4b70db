"""Bad input: exit 2 and one line naming the file, key or option and what is wrong, nothing written; the same
exit codes for dsg-hil, ecu-stub and python -m ecu_stub.identify (one main: dsg_hil.common.cli.run_main; the tree
of errors: tests/common/test_errors.py). Each case was a crash or a silent acceptance before."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import can
import pytest

from dsg_hil.cli import COMMANDS, main
from dsg_hil.physics.params import DEFAULT_PARAMS_PATH, ParameterError, parse_params
from dsg_hil.protocol import Codec, load_dbc
from dsg_hil.protocol.binding import DEFAULT_BINDING
from dsg_hil.protocol.codec import DEFAULT_DBC, signal_range
from dsg_hil.sim.scenario import ScenarioError, load_scenario
from ecu_stub.cli import main as ecu_stub_main

from ..sim.test_binding_run import write_renamed_pair

SCENARIO = "duration_s = 1.0\n[[driver]]\nt_s = 0.0\n"


def one_error_line(capsys, *needles: str) -> str:
    err = capsys.readouterr().err.strip().splitlines()
    assert err and "error: " in err[-1], err  # "error: ..." (argparse: "PROG: error: ...")
    assert all(needle in err[-1] for needle in needles), err[-1]
    assert not any("Traceback" in line for line in err)
    return err[-1]


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


@pytest.mark.parametrize("binding", [None, "renamed.binding.toml"])
@pytest.mark.parametrize("dbc, said", [("nosuch.dbc", "DBC file not found"), ("bad.toml", "cannot load DBC (")])
def test_ecu_stub_names_a_dbc_it_cannot_read_alone(tmp_path, capsys, monkeypatch, dbc, said, binding):
    """``ecu-stub --dbc FILE`` that cannot be read: the one line names the DBC and what is wrong with it, not a
    binding it does not fit (it said 'does not fit the shipped binding' before, when no --binding was given)."""
    write_inputs(tmp_path)
    monkeypatch.chdir(tmp_path)
    assert ecu_stub_main(["-i", "virtual", "--dbc", dbc, *(["--binding", binding] if binding else [])]) == 2
    line = one_error_line(capsys, f"{dbc}: {said}")
    assert line.startswith(f"error: {dbc}: {said}") and "binding" not in line, line


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


@pytest.mark.slow
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


# Every command line, as a user runs it (a subprocess in a directory of its own): a bad option value and a bad or
# missing input file each exit 2 before anything runs, with nothing written and one line on stderr:
#   ERROR: exactly the line 'error: ...' (the command's own check: dsg_hil.common.cli.run_main);
#   USAGE: argparse's usage, then 'PROG: error: argument ...' (a value its type rejects), the only 'error:' line.
ERROR, USAGE = "error", "usage"
PROGRAMS = {"dsg-hil": ["-m", "dsg_hil"], "ecu-stub": ["-m", "ecu_stub"], "identify": ["-m", "ecu_stub.identify"]}
BUS = ["-i", "virtual"]
OUT = ["--summary", "s.json", "--log", "r.log"]
# (program, argv, bad: 'option' or 'file', form, needle). In the directory: bad.toml (not TOML), garbage.log,
# notblf.blf (text), short.log (a log of this DBC without the data a fit needs), afile (a file), outdir/ (an empty
# directory), small.dbc (a DBC without the plant's messages), space.toml (a sweep space), badkey.toml and noctl.toml
# (bad ones), nodid.toml (a diagnostic description whose DID lacks its id), nocmd.binding.toml (the shipped
# binding without a quantity the plant needs), noaccel.binding.toml (without one only ecu-stub reads), renamed.dbc
# and renamed.binding.toml (another matrix and its binding: tests/sim/test_binding_run.py), simclash.binding.toml
# (that binding adding SIM_SYNC on an ID of the matrix's), long.dbc (the shipped DBC with a 9-byte classic message),
# badvalues.binding.toml (the shipped binding naming a state its DBC's value table lacks), sampled/ and searched/
# (a sampled sweep's and a search's results: their sweep.json).
CASES = [
    ("dsg-hil", ["run", *BUS, "--duration", "-1", *OUT], "option", ERROR, "--duration: must be within"),
    ("dsg-hil", ["run", *BUS, "--scenario", "nosuch.toml", *OUT], "file", ERROR, "nosuch.toml: cannot read scenario"),
    ("dsg-hil", ["plant", *BUS, "--reply-timeout", "0", *OUT], "option", USAGE,
     "argument --reply-timeout: must be a positive finite number, got 0"),
    ("dsg-hil", ["plant", *BUS, "--dbc", "bad.toml", *OUT], "file", ERROR, "bad.toml: cannot load DBC"),
    ("dsg-hil", ["bridge", "--from-interface", "virtual", "--from-channel", "a", "--to-interface", "virtual",
                 "--to-channel", "b", "--fault", "explode:TCU_CMD"], "option", ERROR, "kind must be one of"),
    ("dsg-hil", ["bridge", "--from-interface", "virtual", "--from-channel", "a", "--to-interface", "virtual",
                 "--to-channel", "b", "--dbc", "nosuch.dbc"], "file", ERROR, "nosuch.dbc: DBC file not found"),
    ("dsg-hil", ["dbc", "--bitrate", "-3"], "option", USAGE, "argument --bitrate: must be a positive finite number"),
    ("dsg-hil", ["dbc", "--dbc", "nosuch.dbc"], "file", ERROR, "nosuch.dbc: DBC file not found"),
    ("dsg-hil", ["vcan", "--duration", "-5", "--outdir", "o"], "option", USAGE,
     "argument --duration: must be a positive finite number, got -5"),
    ("dsg-hil", ["vcan", "--load", "-1", "--outdir", "o"], "option", USAGE, "argument --load: must be >= 0, got -1"),
    ("dsg-hil", ["vcan", "--kernel", "nosuch", "--outdir", "o"], "file", ERROR, "--kernel nosuch: no such file"),
    ("dsg-hil", ["validate", "--dt=-1", "--json", "v.json"], "option", USAGE,
     "argument --dt: must be a positive finite number"),
    ("dsg-hil", ["validate", "--params", "nosuch.toml", "--json", "v.json"], "file", ERROR,
     "nosuch.toml: cannot read parameter file"),
    ("dsg-hil", ["calibrate", "--scenario", "bad.toml"], "option", ERROR, "bad.toml: not valid TOML"),
    ("dsg-hil", ["calibrate", "--params", "nosuch.toml"], "file", ERROR, "nosuch.toml: cannot read parameter file"),
    ("dsg-hil", ["params", "--source", "nosuch"], "option", USAGE, "argument --source: invalid choice: 'nosuch'"),
    ("dsg-hil", ["params", "--params", "bad.toml"], "file", ERROR, "bad.toml: not valid TOML"),
    ("dsg-hil", ["report", "--out", "afile"], "option", ERROR, "--out afile: not a writable directory"),
    ("dsg-hil", ["report", "--from-log", "garbage.log", "--out", "outdir"], "file", ERROR,
     "garbage.log:1: cannot read the log line 'garbage'"),
    # issue 20, items 2 and 4: checked before the run, the line naming the option or fault
    ("dsg-hil", ["run", *BUS, "--log", "/proc/nope/r.log", "--summary", "s.json"], "option", ERROR,
     "--log /proc/nope/r.log: /proc is not a writable directory"),
    ("dsg-hil", ["run", *BUS, "--summary", "nodir/x/"], "option", ERROR,
     "--summary nodir/x/: ends in a path separator: give a file name"),
    ("dsg-hil", ["run", *BUS, "--fault", "stuck:PLANT_VEHICLE.VehicleSpeed@1-2,value=1000", *OUT], "option", ERROR,
     "stuck value 1000 m/s cannot be encoded in PLANT_VEHICLE.VehicleSpeed: its bits carry -32.768 to 32.767 m/s"),
    ("dsg-hil", ["validate", "--json", "/proc/nope/v.json"], "option", ERROR,
     "--json /proc/nope/v.json: /proc is not a writable directory"),
    ("ecu-stub", [*BUS, "--fault", "offset:TCU_CMD.P_CL_Cmd@1-2,value=1e6", "--log", "t.log"], "option", ERROR,
     "offset value 1e+06 MPa cannot be encoded in TCU_CMD.P_CL_Cmd"),
    ("dsg-hil", ["sweep", "bad.toml", "--n", "x"], "option", USAGE, "argument --n: not a whole number: 'x'"),
    ("dsg-hil", ["sweep", "bad.toml", "--out", "outdir"], "file", ERROR, "bad.toml: not valid TOML"),
    ("dsg-hil", ["fmu", "export", "--out", "plant.zip"], "option", ERROR, "--out plant.zip: an FMU's file name ends"),
    ("dsg-hil", ["fmu", "export", "--params", "nosuch.toml"], "file", ERROR, "nosuch.toml: cannot read parameter"),
    ("dsg-hil", ["run", *BUS, "--controller", "nosuch.fmu", *OUT], "file", ERROR, "--controller nosuch.fmu: no such"),
    ("ecu-stub", [*BUS, "--idle-exit", "0", "--log", "t.log"], "option", ERROR,
     "--idle-exit: must be a positive number of seconds"),
    ("ecu-stub", [*BUS, "--calibration", "nosuch.toml", "--log", "t.log"], "file", ERROR,
     "nosuch.toml: cannot read calibration"),
    ("identify", ["short.log", "--write", "outdir"], "option", ERROR, "--write outdir: is a directory"),
    ("dsg-hil", ["completion", "fish"], "option", USAGE, "argument shell: invalid choice: 'fish'"),
    ("dsg-hil", ["plot", "short.log", "-o", "outdir"], "option", ERROR, "--output outdir: is a directory"),
    ("dsg-hil", ["plot", "garbage.log", "-o", "p.png"], "file", ERROR,
     "garbage.log:1: cannot read the log line 'garbage'"),
    ("dsg-hil", ["plot", "bad.toml", "-o", "p.png"], "file", ERROR, "bad.toml: cannot read the log"),
    ("identify", ["nosuch.log", "--write", "cal.toml"], "file", ERROR, "nosuch.log: cannot read the log"),
    ("identify", ["garbage.log", "--write", "cal.toml"], "file", ERROR,
     "garbage.log:1: cannot read the log line 'garbage'"),
    ("identify", ["notblf.blf", "--write", "cal.toml"], "file", ERROR, "notblf.blf: cannot read the log"),
    ("identify", ["short.log", "--write", "/proc/nope/cal.toml"], "option", ERROR,  # before the fit, not after
     "--write /proc/nope/cal.toml: /proc is not a writable directory"),
    ("identify", ["short.log", "--write", "cal.toml"], "file", ERROR,
     "short.log: thermal fit: no plate temperature record"),  # no usable data
    # issue 35, items 3 and 5-8: each a pass with nothing run, a raw exit 1 or a file left behind before
    ("dsg-hil", ["sweep", "space.toml", "--n", "0", "--out", "o"], "option", USAGE,
     "argument --n: must be >= 1, got 0"),
    ("dsg-hil", ["sweep", "space.toml", "--workers", "0", "--out", "o"], "option", USAGE,
     "argument --workers: must be >= 1, got 0"),
    ("dsg-hil", ["sweep", "badkey.toml", "--out", "o"], "file", ERROR,  # the key itself, not the first input
     "badkey.toml: inputs.params.vehicle.mass: no parameter 'vehicle.mass'"),
    ("dsg-hil", ["sweep", "noctl.toml", "--out", "o"], "file", ERROR,
     "noctl.toml: controller.target 'nosuch_module:make': cannot import"),
    ("dsg-hil", ["sweep", "space.toml", "--out", "sampled", "--search", "--resume"], "option", ERROR,
     "--resume --search: sampled holds a sampled sweep, not a search: give another --out"),
    ("dsg-hil", ["sweep", "space.toml", "--out", "searched", "--resume"], "option", ERROR,
     "--resume: searched holds a search: resume it with --search, or give another --out"),
    ("dsg-hil", ["run", *BUS, "--dbc", "small.dbc", *OUT], "file", ERROR,
     "small.dbc: message PLANT_ENGINE is not in the DBC"),
    ("dsg-hil", ["plant", *BUS, "--dbc", "small.dbc", *OUT], "file", ERROR,
     "small.dbc: message PLANT_ENGINE is not in the DBC"),
    ("dsg-hil", ["run", *BUS, "--binding", "nosuch.toml", *OUT], "file", ERROR, "nosuch.toml: binding file not found"),
    ("dsg-hil", ["plant", *BUS, "--binding", "bad.toml", *OUT], "file", ERROR, "bad.toml: not TOML"),
    ("dsg-hil", ["run", *BUS, "--binding", "nocmd.binding.toml", *OUT], "file", ERROR,
     "nocmd.binding.toml: quantities: P_CL_cmd is not mapped (the plant needs it)"),
    ("dsg-hil", ["plant", *BUS, "--dbc", "small.dbc", "--binding", "nocmd.binding.toml", *OUT], "file", ERROR,
     "nocmd.binding.toml: send: message PLANT_ENGINE is not in the database"),
    ("dsg-hil", ["report", "--binding", "nosuch.toml", "--out", "outdir"], "file", ERROR,
     "nosuch.toml: binding file not found"),
    ("dsg-hil", ["run", *BUS, "--binding", "noaccel.binding.toml", *OUT], "file", ERROR,
     "noaccel.binding.toml: quantities.a_x: not mapped, and ecu-stub reads it"),
    # ecu-stub on a matrix: the same pair of files as the plant's, checked before the bus opens
    ("ecu-stub", [*BUS, "--binding", "nosuch.toml", "--log", "t.log"], "file", ERROR,
     "nosuch.toml: binding file not found"),
    ("ecu-stub", [*BUS, "--binding", "noaccel.binding.toml", "--log", "t.log"], "file", ERROR,
     "noaccel.binding.toml: quantities.a_x: not mapped, and ecu-stub reads it"),
    ("ecu-stub", [*BUS, "--dbc", "nosuch.dbc", "--log", "t.log"], "file", ERROR, "nosuch.dbc: DBC file not found"),
    ("ecu-stub", [*BUS, "--dbc", "bad.toml", "--log", "t.log"], "file", ERROR, "bad.toml: cannot load DBC ("),
    ("ecu-stub", [*BUS, "--dbc", "renamed.dbc", "--log", "t.log"], "file", ERROR,
     "renamed.dbc: does not fit the shipped binding: give its own (--binding);"),
    ("ecu-stub", [*BUS, "--dbc", "small.dbc", "--binding", "renamed.binding.toml", "--log", "t.log"], "file", ERROR,
     "renamed.binding.toml: send: message EMS_Engine is not in the database"),
    ("dsg-hil", ["binding", "check", "nosuch.dbc", "nocmd.binding.toml"], "file", ERROR,
     "nosuch.dbc: DBC file not found"),
    ("dsg-hil", ["binding", "check", "small.dbc", "nosuch.toml"], "file", ERROR,
     "nosuch.toml: binding file not found"),
    ("dsg-hil", ["binding", "check", "long.dbc", str(DEFAULT_BINDING)], "file", ERROR,
     "message PLANT_OIL_TEMP: 9 bytes on classic CAN (at most 8): a CAN FD message needs VFrameFormat CAN_FD"),
    ("dsg-hil", ["binding", "check", str(DEFAULT_DBC), "badvalues.binding.toml"], "file", ERROR,
     "badvalues.binding.toml: quantities.tcu_state.values.CREEP: 'CREEPING' is not in the value table of "
     "TCU_STATUS.State (IDLE, ENGAGE, CREEP, HANDOVER, STOPPED_OVERHEAT, FAULT)"),
    ("dsg-hil", ["binding", "check", "renamed.dbc", "simclash.binding.toml"], "file", ERROR,
     "simclash.binding.toml: simulation.ids.SIM_SYNC: 0xC0 is the ID of EMS_Engine in the matrix"),
    ("dsg-hil", ["binding", "list", "small.dbc", "nosuch.toml"], "option", USAGE,
     "argument action: invalid choice: 'list'"),
    ("dsg-hil", ["binding", "init", "nosuch.dbc"], "file", ERROR, "nosuch.dbc: DBC file not found"),
    ("dsg-hil", ["binding", "init", "small.dbc", "nocmd.binding.toml"], "option", USAGE, "init takes DBC only"),
    ("dsg-hil", ["binding", "check", "small.dbc"], "option", USAGE, "check takes DBC and BINDING"),
    ("dsg-hil", ["run", "-i", "udp_multicast", "-c", "239.255.1.2", "--bus-kwargs", "port=abc", *OUT], "option",
     ERROR, "--bus-kwargs port=abc: Port config must be a number!"),
    ("dsg-hil", ["plant", "-i", "udp_multicast", "-c", "239.255.1.2", "--bus-kwargs", "port=99999999", *OUT],
     "option", ERROR, "--bus-kwargs port=99999999: Port config must be inside 0-65535 range!"),
    ("ecu-stub", ["-i", "udp_multicast", "-c", "239.255.1.2", "--bus-kwargs", "port=-1", "--log", "t.log"],
     "option", ERROR, "--bus-kwargs port=-1: Port config must be inside 0-65535 range!"),
    ("dsg-hil", ["bridge", "--from-interface", "udp_multicast", "--from-channel", "239.255.1.2", "--from-bus-kwargs",
                 "port=abc", "--to-interface", "virtual", "--to-channel", "b"], "option", ERROR,
     "--bus-kwargs port=abc: Port config must be a number!"),
    ("dsg-hil", ["plot", "short.log", "-o", "p.xyz"], "option", ERROR,
     "--output p.xyz: the image's extension is one of"),
    # issue 39: dsg-hil diag checks everything before it opens the bus (nothing sent)
    ("dsg-hil", ["diag", "read", "nosuch", *BUS], "option", ERROR, "DID 'nosuch': not in the description"),
    ("dsg-hil", ["diag", "dtc", *BUS, "--request-id", "0x800"], "option", USAGE,
     "argument --request-id: an 11-bit CAN ID must be 0x0-0x7FF, got 0x800"),
    ("dsg-hil", ["diag", "dtc", *BUS, "--json", "/proc/nope/d.json"], "option", ERROR,
     "--json /proc/nope/d.json: /proc is not a writable directory"),
    ("dsg-hil", ["diag", "dtc", *BUS, "--description", "bad.toml"], "file", ERROR, "bad.toml: not valid TOML"),
    ("dsg-hil", ["diag", "dtc", *BUS, "--description", "nodid.toml"], "file", ERROR,
     "nodid.toml: did[0]: id must be an integer 0-65535, not None"),
    ("dsg-hil", ["diag", "dtc", *BUS, "--dbc", "small.dbc"], "file", ERROR,
     "small.dbc: no network attribute DiagRequestId"),
    # ecu-stub's XCP slave: its IDs checked before the bus opens or the A2L is written
    ("ecu-stub", [*BUS, "--xcp", "--xcp-ids", "0x7D0", "--log", "t.log"], "option", USAGE,
     "argument --xcp-ids: give two CAN IDs as CRO,DTO (e.g. 0x7D0,0x7D1), got '0x7D0'"),
    ("ecu-stub", [*BUS, "--xcp", "--xcp-ids", "0x7D0,0x800", "--log", "t.log"], "option", USAGE,
     "argument --xcp-ids: an 11-bit CAN ID must be 0x0-0x7FF, got 0x800"),
    ("ecu-stub", [*BUS, "--xcp", "--xcp-ids", "0x200,0x7D1", "--log", "t.log"], "option", ERROR,
     "--xcp-ids 0x200,0x7D1: 0x200 is the ID of TCU_CMD in the DBC"),
    ("ecu-stub", [*BUS, "--xcp-ids", "0x7D2,0x7D3", "--log", "t.log"], "option", ERROR,
     "--xcp-ids: serves nothing without --xcp (or --a2l)"),
    ("ecu-stub", ["--a2l", "t.a2l", "--xcp-ids", "0x7D0,0x7E9"], "option", ERROR,
     "--xcp-ids 0x7D0,0x7E9: 0x7E9 is the DBC's diagnostic response ID"),
    ("ecu-stub", ["--a2l", "afile/t.a2l"], "option", ERROR, "--a2l afile/t.a2l: afile is not a writable directory"),
    ("ecu-stub", ["--a2l", "t.a2l", "--dbc", "nosuch.dbc"], "file", ERROR, "nosuch.dbc: DBC file not found"),
    # the gain fault: a factor no frame can carry, refused before the run
    ("dsg-hil", ["run", *BUS, "--fault", "gain:PLANT_SPEEDS.ClutchInputSpeed@0-,value=1e6", *OUT], "option", ERROR,
     "gain value 1e+06 cannot be encoded in PLANT_SPEEDS.ClutchInputSpeed"),
    ("dsg-hil", ["sweep", "badlatent.toml", "--out", "o"], "file", ERROR,  # a sweep's latent faults: the key named
     "badlatent.toml: latent.per_run: must lie within 0-2, got [0, 3]"),
    # every option naming a file has its case (tests/docs/test_site.py checks that against the parsers)
    ("dsg-hil", ["run", *BUS, "--params", "nosuch.toml", *OUT], "file", ERROR, "nosuch.toml: cannot read parameter"),
    ("dsg-hil", ["run", *BUS, "--calibration", "nosuch.toml", *OUT], "file", ERROR, "nosuch.toml: cannot read calib"),
    ("dsg-hil", ["run", *BUS, "--controller-map", "bad.toml", *OUT], "option", ERROR,  # ignored (and run) before
     "--controller-map bad.toml: maps a controller FMU's variables: give --controller FMU too"),
    ("dsg-hil", ["plant", *BUS, "--scenario", "bad.toml", *OUT], "file", ERROR, "bad.toml: not valid TOML"),
    ("dsg-hil", ["plant", *BUS, "--params", "nosuch.toml", *OUT], "file", ERROR, "nosuch.toml: cannot read parameter"),
    ("dsg-hil", ["validate", "--plots", "afile", "--json", "v.json"], "option", ERROR,
     "--plots afile: not a writable directory"),
    ("dsg-hil", ["report", "--scenario", "bad.toml", "--out", "outdir"], "file", ERROR, "bad.toml: not valid TOML"),
    ("dsg-hil", ["report", "--dbc", "small.dbc", "--out", "outdir"], "file", ERROR,  # after the validation before
     "small.dbc: message PLANT_ENGINE is not in the DBC"),
    ("dsg-hil", ["report", "--params", "nosuch.toml", "--out", "outdir"], "file", ERROR,
     "nosuch.toml: cannot read parameter"),
    ("dsg-hil", ["plot", "short.log", "--binding", "nosuch.toml", "-o", "p.png"], "file", ERROR,
     "nosuch.toml: binding file not found"),
    ("dsg-hil", ["plot", "short.log", "--binding", "nocmd.binding.toml", "-o", "p.png"], "file", ERROR,
     "nocmd.binding.toml: quantities: P_CL_cmd is not mapped (the plant needs it)"),
    ("dsg-hil", ["run", *BUS, "--fault", "wrong_dlc:TCU_CMD@1-2,dlc=12", *OUT], "option", ERROR,
     "dlc 12 is a CAN FD length, and TCU_CMD is a classic CAN message (0-8)"),
    ("ecu-stub", [*BUS, "--fault", "wrong_dlc:TCU_CMD@1-2,dlc=10", "--log", "t.log"], "option", ERROR,
     "dlc must be a frame length: 0-8, or on a CAN FD message 12, 16, 20, 24, 32, 48 or 64, got 10"),
    ("dsg-hil", ["plot", "short.log", "--dbc", "nosuch.dbc", "-o", "p.png"], "file", ERROR,
     "nosuch.dbc: DBC file not found"),
    ("identify", ["short.log", "--calibration", "nosuch.toml", "--write", "cal.toml"], "file", ERROR,
     "nosuch.toml: cannot read calibration"),
    ("identify", ["short.log", "--map-only", "garbage.log", "--write", "cal.toml"], "file", ERROR,
     "garbage.log:1: cannot read the log line 'garbage'"),
    ("identify", ["short.log", "--dbc", "nosuch.dbc", "--write", "cal.toml"], "file", ERROR,
     "nosuch.dbc: DBC file not found"),
]


def write_inputs(where: Path) -> None:
    (where / "bad.toml").write_text("x = = 1\n", encoding="utf-8")
    (where / "garbage.log").write_text("garbage\n", encoding="utf-8")
    (where / "notblf.blf").write_text("not a BLF file\n", encoding="utf-8")
    (where / "afile").write_text("a file, not a directory\n", encoding="utf-8")
    (where / "outdir").mkdir()
    (where / "small.dbc").write_text('VERSION ""\n\nBU_: A\n\nBO_ 100 X: 8 A\n SG_ S : 0|8@1+ (1,0) [0|255] "" A\n',
                                     encoding="utf-8")  # a DBC, without the plant's messages
    (where / "long.dbc").write_text(DEFAULT_DBC.read_text(encoding="utf-8").replace(
        "BO_ 272 PLANT_OIL_TEMP: 8 ", "BO_ 272 PLANT_OIL_TEMP: 9 "), encoding="utf-8")  # 9 bytes, not CAN FD
    _, renamed = write_renamed_pair(where)  # renamed.dbc, renamed.binding.toml: another matrix, the plant bound to it
    (where / "simclash.binding.toml").write_text(renamed.read_text(encoding="utf-8") + "\n[simulation]\n"
                                                 "ids = { SIM_SYNC = 0x0C0 }\n", encoding="utf-8")  # EMS_Engine's ID
    (where / "noaccel.binding.toml").write_text(DEFAULT_BINDING.read_text(encoding="utf-8").replace(
        'a_x = "PLANT_VEHICLE.LongAccel"\n', ""), encoding="utf-8")  # without a quantity only ecu-stub reads
    (where / "badvalues.binding.toml").write_text(DEFAULT_BINDING.read_text(encoding="utf-8").replace(
        'tcu_state = "TCU_STATUS.State"\n', 'tcu_state = { signal = "TCU_STATUS.State", values = { IDLE = "IDLE", '
        'ENGAGE = "ENGAGE", CREEP = "CREEPING", HANDOVER = "HANDOVER", STOPPED_OVERHEAT = "STOPPED_OVERHEAT", '
        'FAULT = "FAULT" } }\n'), encoding="utf-8")  # a state's name the value table lacks
    (where / "nocmd.binding.toml").write_text(DEFAULT_BINDING.read_text(encoding="utf-8").replace(
        'P_CL_cmd = "TCU_CMD.P_CL_Cmd"\n', ""), encoding="utf-8")  # the shipped binding without a command
    space = 'name = "t"\nn = 2\nduration_s = 1.0\n[inputs]\ngrade_rad = {uniform = [-0.15, 0.1]}\n'
    (where / "space.toml").write_text(space, encoding="utf-8")  # a good sweep space
    (where / "badkey.toml").write_text(space + '"params.vehicle.mass" = {uniform = [1000.0, 2000.0]}\n',
                                       encoding="utf-8")  # a sweep space drawing a parameter that is none
    (where / "badlatent.toml").write_text(space + "[latent]\nper_run = [0, 3]\n", encoding="utf-8")  # 3 at once
    for folder, kind in (("sampled", {}), ("searched", {"search": True})):  # what a sweep and a search leave
        (where / folder).mkdir()
        (where / folder / "sweep.json").write_text(json.dumps({"space": "t", "digest": "0123456789abcdef", "n": 2,
                                                               **kind}), encoding="utf-8")
    (where / "nodid.toml").write_text('[[did]]\nname = "x"\n', encoding="utf-8")  # a DID description without its id
    (where / "noctl.toml").write_text(space + '[controller]\nkind = "python"\ntarget = "nosuch_module:make"\n',
                                      encoding="utf-8")  # a controller that cannot be imported
    codec = Codec(load_dbc(), {"PLANT_SPEEDS": ("ClutchInputSpeed", "CLOutputSpeed", "CHOutputSpeed")})
    with can.Logger(str(where / "short.log")) as log:  # 2 s of speeds, nothing else
        for k in range(200):
            data = codec.encode("PLANT_SPEEDS", {"ClutchInputSpeed": 800.0, "CLOutputSpeed": 0.0,
                                                 "CHOutputSpeed": 0.0}, k % 16)
            log.on_message_received(can.Message(timestamp=k * 0.01, arbitration_id=codec.frame_id("PLANT_SPEEDS"),
                                                data=data, is_extended_id=False))


def run_bad(where: Path, program: str, argv: list[str]) -> tuple[subprocess.CompletedProcess, list[str]]:
    """Run the command in ``where``; its result and the lines on stderr, after checking that it wrote nothing."""
    before = sorted(where.rglob("*"))
    proc = subprocess.run([sys.executable, *PROGRAMS[program], *argv], cwd=where, capture_output=True, text=True,
                          timeout=120)
    assert sorted(where.rglob("*")) == before, "the command wrote something"
    return proc, proc.stderr.strip().splitlines()


@pytest.mark.slow
@pytest.mark.parametrize("program, argv, bad, form, needle", CASES,
                         ids=[f"{c[0]} {' '.join(c[1][:1])} {c[2]}: {c[4][:30]}" for c in CASES])
def test_every_command_line_rejects_bad_input_with_exit_2_and_one_line(tmp_path, program, argv, bad, form, needle):
    write_inputs(tmp_path)
    proc, err = run_bad(tmp_path, program, argv)
    assert proc.returncode == 2 and proc.stdout == "", (proc.returncode, proc.stdout, err)
    assert "Traceback" not in proc.stderr and [line for line in err if "error:" in line] == err[-1:], err
    if form == ERROR:
        assert len(err) == 1 and err[0].startswith("error: ") and needle in err[0], err
    else:
        assert err[0].startswith("usage: ") and f": error: {needle}" in err[-1], err


NO_FILE = {"completion"}  # commands that read no file


def test_the_cases_cover_every_command_line_with_an_option_and_a_file():
    covered = {(c[0] if c[0] != "dsg-hil" else c[1][0], c[2]) for c in CASES}
    for command in [*COMMANDS, "ecu-stub", "identify"]:
        kinds = {"option"} if command in NO_FILE else {"option", "file"}
        assert {(command, kind) for kind in kinds} <= covered, command


def test_a_bad_parameter_file_writes_no_log(tmp_path):
    write_inputs(tmp_path)
    proc, err = run_bad(tmp_path, "dsg-hil", ["plant", *BUS, "--params", "nosuch.toml", *OUT])
    assert proc.returncode == 2 and err == ["error: nosuch.toml: cannot read parameter file (No such file or "
                                            "directory)"]


@pytest.mark.slow
def test_report_makes_no_output_directory_for_bad_input(tmp_path):
    write_inputs(tmp_path)
    proc, err = run_bad(tmp_path, "dsg-hil", ["report", "--from-log", "garbage.log", "--out", "new"])
    assert proc.returncode == 2 and len(err) == 1


@pytest.mark.slow
def test_report_checks_its_options_before_the_validation(tmp_path):
    write_inputs(tmp_path)
    proc, err = run_bad(tmp_path, "dsg-hil", ["report", "--duration", "-1", "--out", "outdir"])
    assert proc.returncode == 2 and err == ["error: --duration: must be within [0.001, 1e6] s, got -1.0"]
