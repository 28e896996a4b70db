"""CAN FD on vcan0 with its FD MTU: the shipped DBC with three messages made CAN FD (one 10 bytes long, sent in a
12-byte frame; one without bit-rate switch), the plant and a TCU on two SocketCAN sockets opened for CAN FD, in
lock-step; candump records the frames in their formats, and the decoded-log reader decodes its log."""

from __future__ import annotations

import re
import subprocess
import threading
import time
from pathlib import Path

import pytest

from ..physics.params import load_params
from ..physics.plant import Plant
from ..protocol import Codec, load_dbc
from ..protocol.bus import has_fd, open_bus
from ..protocol.codec import DEFAULT_DBC
from ..protocol.logs import decoded_frames, log_codec
from ..sim.plant_io import PLANT_RX, PLANT_USES
from ..sim.runner import PlantRunner
from ..sim.scenario import load_scenario
from .conftest import RCVBUF
from ecu_stub.runner import TCU_RX, TCU_USES, TcuRunner

pytestmark = pytest.mark.vcan

FD = {"PLANT_OIL_TEMP": (272, 10, 1), "TCU_CMD": (512, 8, 1), "PLANT_SPEEDS": (257, 8, 0)}  # ID, length, CANFD_BRS
FRAME_FORMAT = ('BA_DEF_ BO_ "VFrameFormat" ENUM "StandardCAN","ExtendedCAN","reserved","reserved","reserved",'
                '"reserved","reserved","reserved","reserved","reserved","reserved","reserved","reserved","reserved",'
                '"StandardCAN_FD","ExtendedCAN_FD";\nBA_DEF_ BO_ "CANFD_BRS" ENUM "0","1";\n')
SECONDS = 3.0


def fd_dbc_text() -> str:
    text = DEFAULT_DBC.read_text(encoding="utf-8")
    for name, (_, length, _) in FD.items():
        text = re.sub(rf"^BO_ (\d+) {name}: 8 ", rf"BO_ \1 {name}: {length} ", text, flags=re.M)
    text = text.replace('BA_DEF_ BO_ "GenMsgCycleTime"', FRAME_FORMAT + 'BA_DEF_ BO_ "GenMsgCycleTime"', 1)
    text = text.replace('BA_DEF_DEF_ "GenMsgCycleTime" 0;', 'BA_DEF_DEF_ "GenMsgCycleTime" 0;\n'
                        'BA_DEF_DEF_ "VFrameFormat" "StandardCAN";\nBA_DEF_DEF_ "CANFD_BRS" "1";', 1)
    attributes = "".join(f'BA_ "VFrameFormat" BO_ {ident} 14;\nBA_ "CANFD_BRS" BO_ {ident} {brs};\n'
                         for ident, _, brs in FD.values())
    return text.replace('BA_ "GenMsgCycleTime" BO_ 256 10;', attributes + 'BA_ "GenMsgCycleTime" BO_ 256 10;', 1)


def test_lockstep_on_vcan0_with_fd_frames(outdir: Path):
    dbc = outdir / "dsg_hil_fd.dbc"
    dbc.write_text(fd_dbc_text(), encoding="utf-8")
    db = load_dbc(dbc)
    assert has_fd(db.messages)
    config = {"interface": "socketcan", "channel": "vcan0"}
    log = outdir / "can_fd.candump.log"
    with log.open("w") as out:
        dump = subprocess.Popen(["candump", "-L", "-r", str(RCVBUF), "vcan0"], stdout=out, stderr=subprocess.PIPE)
        time.sleep(0.3)
        plant_bus = open_bus(config, receive=[db.get_message_by_name(n) for n in PLANT_RX], fd=True)
        tcu_bus = open_bus(config, receive=[db.get_message_by_name(n) for n in TCU_RX], fd=True)
        tcu = TcuRunner(Codec(db, TCU_USES), tcu_bus)
        done, errors = threading.Event(), []

        def serve():
            try:
                tcu.run(should_stop=done.is_set)
            except Exception as exc:  # noqa: BLE001 - reported below
                errors.append(exc)

        thread = threading.Thread(target=serve, daemon=True)
        thread.start()
        runner = PlantRunner(Plant(load_params()), load_scenario().with_duration(SECONDS), Codec(db, PLANT_USES),
                             plant_bus)
        try:
            summary = runner.run_lockstep(reply_timeout=60.0)
        finally:
            done.set()
            thread.join(30)
            plant_bus.shutdown()
            tcu_bus.shutdown()
            time.sleep(0.3)
            dump.terminate()
            dump.wait(10)
    assert not errors
    assert runner.frames()["rejected"] == 0 and tcu.rx.rejected_total == 0
    assert summary.tcu_state in ("ENGAGE", "CREEP")
    formats: dict[int, set[tuple[bool, int, int]]] = {}
    for line in log.read_text().splitlines():  # candump -L: "(t) vcan0 ID#DATA", CAN FD "ID##<flags>DATA"
        frame = line.split()[2]
        head, _, data = frame.partition("#")
        fd = data.startswith("#")
        flags = int(data[1], 16) if fd else 0
        formats.setdefault(int(head, 16), set()).add((fd, flags & 1, len(bytes.fromhex(data[2:] if fd else data))))
    for name, (ident, length, brs) in FD.items():
        assert formats[ident] == {(True, brs, 12 if length == 10 else length)}, name
    assert formats[256] == {(False, 0, 8)}
    counts: dict[str, int] = {}
    for _ in decoded_frames(log, log_codec(db), counts):
        pass
    assert counts["rejected"] == counts["unknown"] == 0 and counts["decoded"] > 10 * SECONDS
