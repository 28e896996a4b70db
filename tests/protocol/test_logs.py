"""The one log reader of dsg-hil report and ecu_stub.identify: frames decoded in file order, counts, one error."""

from __future__ import annotations

import can
import pytest

from dsg_hil.common.errors import LogError
from dsg_hil.protocol import Codec, load_dbc
from dsg_hil.protocol.logs import decoded_frames, log_codec


@pytest.fixture(scope="module")
def db():
    return load_dbc()


def test_every_data_frame_in_order_decoded_or_none_and_counted(tmp_path, db):
    codec = log_codec(db)
    good = can.Message(timestamp=1.0, arbitration_id=db.get_message_by_name("DRIVER").frame_id,
                       data=Codec(db, {"DRIVER": ["CreepRequest", "BrakePedal", "DesiredCreepSpeed"]}).encode(
                           "DRIVER", {"CreepRequest": 1.0, "BrakePedal": 0.0, "DesiredCreepSpeed": 0.2}, 0),
                       is_extended_id=False)
    corrupt = can.Message(timestamp=1.01, arbitration_id=good.arbitration_id, data=bytes(good.data[:-1]) + b"\x00",
                          is_extended_id=False)
    unknown = can.Message(timestamp=1.02, arbitration_id=0x123, data=b"\x01", is_extended_id=False)
    error = can.Message(timestamp=1.03, is_error_frame=True)
    path = tmp_path / "run.log"
    with can.Logger(str(path)) as writer:
        for msg in (good, corrupt, unknown, error):
            writer.on_message_received(msg)
    counts: dict[str, int] = {}
    frames = list(decoded_frames(path, codec, counts))
    assert [t for t, _ in frames] == pytest.approx([1.0, 1.01, 1.02])
    assert frames[0][1] is not None and frames[0][1].values["DesiredCreepSpeed"] == pytest.approx(0.2, abs=1e-3)
    assert frames[1][1] is None and frames[2][1] is None
    assert counts == {"decoded": 1, "rejected": 1, "unknown": 1}


@pytest.mark.parametrize(("content", "needle"), [(None, "log file not found"), ("not a CAN log\n", "cannot read")])
def test_a_missing_or_garbled_log_is_one_log_error_naming_the_file(tmp_path, db, content, needle):
    path = tmp_path / "bad.log"
    if content is not None:
        path.write_text(content)
    with pytest.raises(LogError, match=f"{path}(:1)?: .*{needle}"):  # (the line, where there is one)
        list(decoded_frames(path, log_codec(db)))


def candump_lines(tmp_path, db, n: int = 5) -> list[str]:
    """``n`` lines of a candump -L log of DRIVER frames, each with its line end."""
    codec = Codec(db, {"DRIVER": ["CreepRequest", "BrakePedal", "DesiredCreepSpeed"]})
    path = tmp_path / "whole.log"
    with can.Logger(str(path)) as writer:
        for k in range(n):
            data = codec.encode("DRIVER", {"CreepRequest": 1.0, "BrakePedal": 0.0, "DesiredCreepSpeed": 0.2}, k)
            writer.on_message_received(can.Message(timestamp=k * 0.1, arbitration_id=codec.frame_id("DRIVER"),
                                                   data=data, is_extended_id=False))
    return path.read_text().splitlines(keepends=True)


def test_a_candump_log_cut_mid_line_is_read_up_to_the_cut_with_a_warning(tmp_path, db, caplog):
    """What a logger killed mid-write leaves: the last line cut short, no line end. Read to there, warned with the
    file and line (issue 20, item 7: the whole log was rejected, no line named)."""
    lines = candump_lines(tmp_path, db)
    path = tmp_path / "cut.log"
    path.write_text("".join(lines[:4]) + lines[4][:9])
    counts: dict[str, int] = {}
    with caplog.at_level("WARNING", logger="dsg_hil.protocol.logs"):
        frames = list(decoded_frames(path, log_codec(db), counts))
    assert len(frames) == 4 and counts["decoded"] == 4
    assert [r.getMessage() for r in caplog.records] == [
        f"{path}:5: the last line is cut short ({lines[4][:9]!r}: a logger stopped mid-write?): read up to it"]


@pytest.mark.parametrize("where", [1, 4])
def test_a_bad_line_not_at_a_cut_is_an_error_naming_file_and_line(tmp_path, db, where):
    """A line it cannot read mid-file, or a last line that ends as lines do: not a cut, the log is bad."""
    lines = candump_lines(tmp_path, db)
    lines[where] = "(0.2) vcan0\n"
    path = tmp_path / "bad.log"
    path.write_text("".join(lines))
    with pytest.raises(LogError, match=rf"^{path}:{where + 1}: cannot read the log line '\(0\.2\) vcan0'"):
        list(decoded_frames(path, log_codec(db)))
