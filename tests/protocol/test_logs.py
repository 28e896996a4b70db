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
    with pytest.raises(LogError, match=f"{path}: .*{needle}"):
        list(decoded_frames(path, log_codec(db)))
