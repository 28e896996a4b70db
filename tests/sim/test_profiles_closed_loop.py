"""The lock-step closed loop with both ends on AUTOSAR E2E profiles instead of the dsg-hil scheme: the shipped DBC's
Counter (bits 48-51) and CRC (byte 7) carry Profile 1 (1A) on the plant's frames, 11C on TCU_CMD and 1C on
TCU_STATUS, each message its own data ID; nothing is rejected on either side, and the frames on the bus are the
profiles' (the dsg-hil scheme's check refuses them)."""

from __future__ import annotations

from dsg_hil.protocol import Codec, load_dbc
from dsg_hil.protocol.e2e import Protection
from dsg_hil.sim.plant_io import PLANT_USES
from ecu_stub.runner import TCU_USES

from .test_closed_loop import lockstep_with_tcu_loop

AT = {"crc_offset": 56, "counter_offset": 48, "data_id_nibble_offset": 52}
PROTECTION = {
    **{name: {"profile": "P01", "variant": "1A", "data_id": 0x100 + k, **AT} for k, name in enumerate(
        ("PLANT_ENGINE", "PLANT_SPEEDS", "PLANT_VEHICLE", "PLANT_PRESSURE", "PLANT_OIL_TEMP", "DRIVER"))},
    "TCU_CMD": {"profile": "P11", "variant": "11C", "data_id": 0x200, **AT},
    "TCU_STATUS": {"profile": "P01", "variant": "1C", "data_id": 0x210, **AT},
}


def test_a_lockstep_run_on_e2e_profiles_has_no_rejects():
    db = load_dbc()
    plant_codec = Codec(db, PLANT_USES, protection=PROTECTION)
    tcu_codec = Codec(db, TCU_USES, protection={n: t for n, t in PROTECTION.items() if n in TCU_USES})
    runner, tcu, summary, frames = lockstep_with_tcu_loop(plant_codec, tcu_codec, "e2e-profiles")
    assert tcu.lockstep and summary.tcu_state in ("ENGAGE", "CREEP")
    assert runner.frames()["rejected"] == 0 and tcu.rx.rejected_total == 0
    by_name = {db.get_message_by_frame_id(m.arbitration_id).name: bytes(m.data) for m in frames}
    for name, table in PROTECTION.items():
        data = by_name[name]
        assert plant_codec.protection(name).profile == table["profile"] and plant_codec.protection(name).cause(data) \
            is None, name
        assert not Protection.of(db.get_message_by_name(name)).check(data), name  # (lock-step: the same frames always)


def test_a_binding_s_protection_reaches_the_plant_s_frames_and_its_faults(tmp_path):
    """The same profiles given per message in a binding file (the plant's side) run the creep with no reject, and a
    plant-side fault re-seals its frames with the message's profile: a frozen counter reaches the TCU as repeated
    counters, never as CRC errors."""
    import json

    from dsg_hil.protocol.binding import DEFAULT_BINDING
    from dsg_hil.sim.run import RunConfig, open_run
    from ecu_stub.runner import TcuRunner

    def inline(table):  # a TOML inline table
        return "{ " + ", ".join(f"{key} = {json.dumps(value)}" for key, value in table.items()) + " }"

    tables = "".join(f"\n[messages.{name}]\nprotection = {inline(table)}\n" for name, table in PROTECTION.items())
    binding = tmp_path / "e2e.binding.toml"
    binding.write_text(DEFAULT_BINDING.read_text(encoding="utf-8") + tables, encoding="utf-8")
    tcus = []

    def tcu(db, bus):
        tcus.append(TcuRunner(Codec(db, TCU_USES, protection={n: t for n, t in PROTECTION.items() if n in TCU_USES}),
                              bus))
        return tcus[-1]

    with open_run(RunConfig(duration=3.0, binding=binding, tcu=tcu, faults=["freeze_counter:PLANT_SPEEDS@1-1.1"],
                            capture=True)) as run:
        summary = run.run().as_json()
    assert run.runner.codec.protection("PLANT_SPEEDS").profile == "P01"
    rx = tcus[0].rx.counts()["PLANT_SPEEDS"]
    assert summary["faults"]["injected"]["freeze_counter:PLANT_SPEEDS@1-1.1"] >= 9
    assert set(rx["rejected"]) == {"counter"} and rx["rejected"]["counter"] >= 9, rx  # (re-sealed by the dsg-hil
    # scheme instead: the CRC fails, {"crc": 30})
    assert summary["frames"]["rejected"] == 0
