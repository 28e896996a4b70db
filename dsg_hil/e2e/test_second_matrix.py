"""The second example matrix on vcan0 with its FD MTU: ``dsg-hil plant`` and ``ecu-stub`` as two processes, each
given only the dct_fd pair (``--dbc dct_fd.dbc --binding dct_fd.binding.toml``: other IDs and names, Motorola byte
order, CAN FD messages of 12 and 16 bytes, AUTOSAR E2E Profiles 5 and 11, a multiplexed message), in lock-step.
candump records the frames in their formats (CAN FD with and without bit-rate switch, classic), its log decodes
with the pair (every frame's protection checked), and the plant's summary is the creep: nothing rejected at either
end, CL engaged."""

from __future__ import annotations

import json
import subprocess
from importlib import resources
from pathlib import Path

from ..protocol.binding import Binding, load_binding
from ..protocol.codec import bitrate_switch
from ..protocol.logs import decoded_frames, log_codec
from .conftest import BUS, TCU_IDLE_EXIT, Candump, console, finish_while_progressing

EXAMPLE = resources.files("dsg_hil") / "data" / "examples" / "dct_fd"
DBC, BINDING = Path(str(EXAMPLE / "dct_fd.dbc")), Path(str(EXAMPLE / "dct_fd.binding.toml"))
SECONDS = 4.0  # of the creep: CL engages at 1.05 s


def candump_formats(log: Path) -> dict[int, set[tuple[bool, int, int]]]:
    """By frame ID, the (CAN FD, bit-rate switch, data length) of its frames in a ``candump -L`` log (a CAN FD
    frame is written ``ID##<flags>DATA``, flag 1 the bit-rate switch)."""
    formats: dict[int, set[tuple[bool, int, int]]] = {}
    for line in log.read_text().splitlines():
        parts = line.split()
        if len(parts) < 3 or "#" not in parts[2]:
            continue
        head, _, data = parts[2].partition("#")
        fd = data.startswith("#")
        flags = int(data[1], 16) if fd else 0
        formats.setdefault(int(head, 16), set()).add((fd, flags & 1, len(bytes.fromhex(data[2:] if fd else data))))
    return formats


def check_dct_fd_log(log: Path, binding: Binding) -> dict[str, int]:
    """Every message of the pair the plant or the TCU sends is on the wire in its DBC format (a CAN FD message:
    CAN FD frames of its length, its bit-rate switch as the database says; a classic one: classic frames of 8
    bytes), and the log decodes with the pair, nothing rejected or unknown; the decoded-log reader's counts."""
    formats = candump_formats(log)
    for name in binding.uses:
        message = binding.db.get_message_by_name(name)
        if name == binding.sync[0] and message.frame_id not in formats:
            continue  # (the tick: lock-step only)
        brs = int(message.is_fd and bitrate_switch(message, binding.db))
        assert formats.get(message.frame_id) == {(message.is_fd, brs, message.length)}, name
    counts: dict[str, int] = {}
    for _ in decoded_frames(log, log_codec(binding.db, binding.protection), counts):
        pass
    assert counts["rejected"] == counts["unknown"] == 0, counts
    return counts


def test_plant_and_ecu_stub_on_the_second_matrix_over_vcan0(outdir: Path):
    binding = load_binding(BINDING, dbc=DBC)
    fd = {m.name: m.length for m in binding.db.messages if m.is_fd and m.name in binding.uses}
    assert len(fd) >= 3 and max(fd.values()) > 8
    pair = ["--dbc", str(DBC), "--binding", str(BINDING)]
    dump = Candump(outdir / "dct_fd.candump.log")
    summary = outdir / "dct_fd.summary.json"
    tcu = subprocess.Popen([console("ecu-stub"), *BUS, *pair, "--idle-exit", TCU_IDLE_EXIT], stderr=subprocess.PIPE,
                           text=True)
    try:
        plant = subprocess.Popen([console("dsg-hil"), "plant", *BUS, *pair, "--mode", "lockstep", "--duration",
                                  f"{SECONDS:g}", "--reply-timeout", "60", "--summary", str(summary)],
                                 stderr=subprocess.PIPE, text=True)
        plant_err = finish_while_progressing(plant, dump.path)
        assert plant.returncode == 0, plant_err
        tcu_err = tcu.communicate(timeout=120)[1]
        assert tcu.returncode == 0, tcu_err
    finally:
        if tcu.poll() is None:
            tcu.kill()
        dump.stop()
    assert "rejected 0" in tcu_err, tcu_err  # ecu-stub's closing counts: it took the dct_fd frames
    result = json.loads(summary.read_text())
    assert result["frames"]["rejected"] == result["frames"]["unanswered_ticks"] == 0
    assert [p["clutch"] for p in result["phases"]] == ["CL"]
    counts = check_dct_fd_log(dump.path, binding)
    assert counts["decoded"] > 100 * SECONDS  # (plant's frames every 10 ms)
