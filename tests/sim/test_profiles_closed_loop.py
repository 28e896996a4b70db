"""The lock-step closed loop with both ends on AUTOSAR E2E profiles instead of the dsg-hil scheme: the shipped DBC's
Counter (bits 48-51) and CRC (byte 7) carry Profile 1 (1A) on the plant's frames, 11C on TCU_CMD and 1C on
TCU_STATUS, each message its own data ID; nothing is rejected on either side, and the frames on the bus are the
profiles' (the dsg-hil scheme's check refuses them)."""

from __future__ import annotations

import threading

import can

from dsg_hil.physics.params import load_params
from dsg_hil.physics.plant import Plant
from dsg_hil.protocol import Codec, load_dbc
from dsg_hil.protocol.e2e import Protection
from dsg_hil.sim.plant_io import PLANT_USES
from dsg_hil.sim.runner import PlantRunner
from dsg_hil.sim.scenario import load_scenario
from ecu_stub.runner import TCU_USES, TcuRunner

AT = {"crc_offset": 56, "counter_offset": 48, "data_id_nibble_offset": 52}
PROTECTION = {
    **{name: {"profile": "P01", "variant": "1A", "data_id": 0x100 + k, **AT} for k, name in enumerate(
        ("PLANT_ENGINE", "PLANT_SPEEDS", "PLANT_VEHICLE", "PLANT_PRESSURE", "PLANT_OIL_TEMP", "DRIVER"))},
    "TCU_CMD": {"profile": "P11", "variant": "11C", "data_id": 0x200, **AT},
    "TCU_STATUS": {"profile": "P01", "variant": "1C", "data_id": 0x210, **AT},
}


def test_a_lockstep_run_on_e2e_profiles_has_no_rejects():
    db = load_dbc()
    plant_bus, tcu_bus, tap = (can.Bus(interface="virtual", channel="e2e-profiles") for _ in range(3))
    tcu = TcuRunner(Codec(db, TCU_USES, protection={n: t for n, t in PROTECTION.items() if n in TCU_USES}), tcu_bus)
    done, errors = threading.Event(), []

    def serve():
        try:
            tcu.run(should_stop=done.is_set)
        except Exception as exc:  # noqa: BLE001 - reported below
            errors.append(exc)

    thread = threading.Thread(target=serve, daemon=True)
    thread.start()
    plant_codec = Codec(db, PLANT_USES, protection=PROTECTION)
    runner = PlantRunner(Plant(load_params()), load_scenario().with_duration(3.0), plant_codec, plant_bus)
    try:
        summary = runner.run_lockstep(reply_timeout=5.0)
    finally:
        done.set()
        thread.join(5)
        frames = []
        while (msg := tap.recv(0)) is not None:
            frames.append(msg)
        for bus in (plant_bus, tcu_bus, tap):
            bus.shutdown()
    assert not errors and tcu.lockstep
    assert summary.tcu_state in ("ENGAGE", "CREEP")
    assert runner.frames()["rejected"] == 0 and tcu.rx.rejected_total == 0
    by_name = {db.get_message_by_frame_id(m.arbitration_id).name: bytes(m.data) for m in frames}
    for name, table in PROTECTION.items():
        data = by_name[name]
        assert plant_codec.protection(name).profile == table["profile"] and plant_codec.protection(name).cause(data) \
            is None, name
        assert not Protection.of(db.get_message_by_name(name)).check(data), name  # (lock-step: the same frames always)
