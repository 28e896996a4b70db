"""``dsg-hil diag`` against a real ecu-stub process on python-can's udp_multicast: a lock-step plant (this process)
with a stuck VehicleSpeed made the TCU confirm its DTC; the command prints it with its status bits and freeze frame,
reads DIDs, clears, and then finds none. A user's description and IDs; a refused DID by its NRC name; an ECU that
does not answer; bad input sends nothing."""

from __future__ import annotations

import json
import subprocess
import sys

import can
import pytest

from dsg_hil.cli import main
from dsg_hil.cli.diag_cmd import DEFAULT_MASK
from dsg_hil.protocol.bus import UDP_MULTICAST, fresh_udp_group
from dsg_hil.protocol.diag import load_description

pytest.importorskip("udsoncan", reason="the extra 'diag'")

DESCRIPTION = load_description()
FAULT_START, FAULT_END = 1.0, 1.3
FAULT = f"stuck:PLANT_VEHICLE.VehicleSpeed@{FAULT_START}-{FAULT_END},value=1"  # the clutch outputs say ~0 m/s
CONFIRMED, PENDING = 0x08, 0x04


def error_line(capsys) -> tuple[str, str]:
    """stdout, and the one ``error:`` line on stderr (no traceback, no other error line)."""
    captured = capsys.readouterr()
    errors = [line for line in captured.err.splitlines() if "error" in line.lower()]
    assert len(errors) == 1 and errors[0].startswith("error: "), captured.err
    assert "Traceback" not in captured.err
    return captured.out, errors[0]


@pytest.fixture(scope="module")
def ecu(tmp_path_factory):
    """Bus options reaching an ecu-stub process that ran a 1.5-s lock-step creep with :data:`FAULT` (the plant in
    this process) and, the plant gone, still serves UDS (until its --idle-exit)."""
    group = fresh_udp_group()
    bus = ["-i", UDP_MULTICAST, "-c", group["channel"], "--bus-kwargs", f"port={group['port']}"]
    log = tmp_path_factory.mktemp("ecu") / "ecu-stub.txt"
    with log.open("w") as out:
        tcu = subprocess.Popen([sys.executable, "-m", "ecu_stub", *bus, "--idle-exit", "300"], stdout=out,
                               stderr=subprocess.STDOUT)
    try:
        assert main(["plant", *bus, "--mode", "lockstep", "--duration", "1.5", "--fault", FAULT, "-q"]) == 0
        yield bus
    finally:
        tcu.terminate()
        tcu.wait(timeout=60)


@pytest.mark.slow
def test_dtc_with_status_and_freeze_frame_read_clear_and_none_left(ecu, capsys, tmp_path):
    out_json = tmp_path / "dtcs.json"
    assert main(["diag", "dtc", *ecu, "--json", str(out_json)]) == 0
    table = capsys.readouterr().out
    data = json.loads(out_json.read_text())
    assert data["mask"] == f"0x{DEFAULT_MASK:02X}"
    assert [d["code"] for d in data["dtcs"]] == ["P1710"]  # VehicleSpeed disagrees with both clutch outputs
    dtc = data["dtcs"][0]
    status = int(dtc["status"], 16)
    assert status & CONFIRMED and status & PENDING and {"confirmed", "pending"} <= set(dtc["bits"])
    debounce = next(d.debounce for d in DESCRIPTION.dtcs if d.code == "P1710")
    frame = dtc["freeze_frame"]
    # confirmed after its debounce (control periods of 10 ms), while the fault lasted
    assert FAULT_START + (debounce - 1) * 0.01 - 1e-9 <= frame["t"] <= FAULT_END
    assert set(frame) == {f.name for did in DESCRIPTION.snapshot for f in DESCRIPTION.dids[did].fields}
    # the table shows the same: code, name, status byte, bits, every freeze-frame field with its unit
    lines = table.splitlines()
    head = next(line for line in lines if line.startswith("P1710"))
    assert "VehicleSpeed_implausible" in head and dtc["status"] in head and "confirmed" in head
    shown = {line.split()[0]: line.split()[1:] for line in lines if line.startswith(" " * 10)}
    assert set(shown) == set(frame)
    assert float(shown["t"][0]) == pytest.approx(frame["t"]) and shown["t"][1] == "s"
    assert shown["EngineSpeed"][1] == "rpm" and shown["T_Sump"][1] == "degC" and shown["P_CL"][1] == "MPa"

    out_json = tmp_path / "dids.json"
    assert main(["diag", "read", "software_version", "state", "0x0101", *ecu, "--json", str(out_json)]) == 0
    table = capsys.readouterr().out
    dids = json.loads(out_json.read_text())
    assert list(dids["dids"]) == ["software_version", "state", "plate_temperatures_pred"] and not dids["refused"]
    assert dids["dids"]["software_version"].startswith("dsg-hil ")
    assert 0 <= dids["dids"]["state"]["State"] <= 7  # TCU_STATUS.State's value table
    assert 20.0 < dids["dids"]["plate_temperatures_pred"]["T_CL_Pred"] < 300.0  # degC, a warm clutch
    assert "0xF189  software_version  'dsg-hil " in table and "0x0101  plate_temperatures_pred" in table
    assert any(line.split()[:1] == ["T_CL_Pred"] and line.endswith("degC") for line in table.splitlines())

    assert main(["diag", "clear", *ecu]) == 0
    assert "cleared DTC group 0xFFFFFF" in capsys.readouterr().out
    assert main(["diag", "dtc", *ecu]) == 0
    assert capsys.readouterr().out.strip() == f"no DTC matches status mask 0x{DEFAULT_MASK:02X}"
    out_json = tmp_path / "all.json"
    assert main(["diag", "dtc", *ecu, "--mask", "0xFF", "--no-snapshots", "--json", str(out_json)]) == 0
    every = json.loads(out_json.read_text())["dtcs"]  # every DTC, not completed since the clear, none failed
    assert len(every) == len(DESCRIPTION.dtcs) and {d["status"] for d in every} == {"0x50"}
    assert all(d["freeze_frame"] is None for d in every)


def test_a_users_description_and_ids_and_a_refused_did(ecu, capsys, tmp_path):
    """A description giving its own IDs and a DID ecu-stub does not serve: that one is refused with the
    standard's NRC name (exit 1), the others are read."""
    path = tmp_path / "my_ecu.toml"
    path.write_text('request_id = 0x7E1\nresponse_id = 0x7E9\n'
                    '[[did]]\nid = 0x1234\nname = "mine"\nfields = [{ name = "x", type = "u8" }]\n'
                    '[[did]]\nid = 0x0102\nname = "state"\n'
                    'fields = [{ name = "State", type = "u8" }, { name = "ActiveClutch", type = "u8" }]\n')
    out_json = tmp_path / "dids.json"
    argv = ["diag", "read", "mine", "state", *ecu, "--description", str(path), "--dbc", "nosuch.dbc"]
    assert main(argv) == 2  # the DBC is read when given, even though the description has the IDs
    assert "nosuch.dbc" in error_line(capsys)[1]
    assert main([*argv[:-2], "--json", str(out_json)]) == 1
    out, error = error_line(capsys)
    assert "0x1234  mine  refused: RequestOutOfRange (0x31)" in out and "ActiveClutch" in out
    assert error.endswith("0x1234 mine refused: RequestOutOfRange (0x31)") and "0x7E1/0x7E9" in error
    data = json.loads(out_json.read_text())
    assert data["refused"] == {"mine": "RequestOutOfRange (0x31)"} and set(data["dids"]) == {"state"}


def test_a_description_that_does_not_fit_the_ecu_is_exit_1_in_one_line(ecu, capsys, tmp_path):
    """The description gives software_version 8 bytes; ecu-stub sends 16."""
    path = tmp_path / "short.toml"
    path.write_text('[[did]]\nid = 0xF189\nname = "sw"\nkind = "ascii"\nlength = 8\n')
    assert main(["diag", "read", "sw", *ecu, "--description", str(path)]) == 1
    assert "ReadDataByIdentifier 0xF189" in (error := error_line(capsys)[1])
    assert error.endswith("(is the DID's size in the description the ECU's?)")


def test_an_ecu_that_does_not_answer_is_exit_1_in_one_line(ecu, capsys):
    """ecu-stub is on the bus, but not at these IDs."""
    assert main(["diag", "dtc", *ecu, "--request-id", "0x7E0", "--response-id", "0x7E8", "--timeout", "0.3"]) == 1
    error = error_line(capsys)[1]
    assert "ECU 0x7E0/0x7E8 on udp_multicast" in error and "no response to ReadDTCInformation within 0.3 s" in error


@pytest.mark.parametrize(("argv", "needle"), [
    (["read", "nosuch"], "DID 'nosuch': not in the description"),
    (["read", "0x1234"], "DID '0x1234': not in the description"),
    (["dtc", "state"], "DID 'state': DIDs are for 'dsg-hil diag read', not 'dtc'"),
    (["clear", "--json", "c.json"], "--json: 'clear' reads nothing to write"),
    (["dtc", "--request-id", "0x7E9"], "--request-id/--response-id: the request and response IDs are both 0x7E9"),
])
def test_bad_input_is_exit_2_and_sends_nothing(capsys, argv, needle):
    channel = f"diag-bad-{id(argv):x}"
    with can.Bus(interface="virtual", channel=channel) as listener:
        assert main(["diag", *argv, "-i", "virtual", "-c", channel, "--timeout", "0.2"]) == 2
        assert needle in error_line(capsys)[1]
        assert listener.recv(timeout=0.3) is None


def test_without_the_diag_extra_exit_2_and_nothing_sent(capsys, monkeypatch):
    monkeypatch.setitem(sys.modules, "udsoncan", None)  # import udsoncan raises ImportError
    with can.Bus(interface="virtual", channel="diag-no-extra") as listener:
        assert main(["diag", "dtc", "-i", "virtual", "-c", "diag-no-extra"]) == 2
        assert "needs the extra 'diag' (pip install 'dsg-hil[diag]')" in error_line(capsys)[1]
        assert listener.recv(timeout=0.3) is None
