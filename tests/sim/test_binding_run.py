"""The plant on another communication matrix by configuration alone: a copy of the shipped DBC with every message
and signal renamed, every ID moved and scalings changed (vehicle speed in km/h, the clutch pressures in kPa, the
TCU's predicted plate temperatures in K), with its binding, runs the shipped creep in lock-step. ecu-stub speaks
the shipped DBC only, so it answers through a gateway that decodes each frame with one matrix and encodes it with
the other (:class:`Gateway`, quantities converted by the two bindings): the plant's frames, decoded with the
renamed DBC and its binding, carry the physical values of the shipped pair's run."""

from __future__ import annotations

import itertools
import re
from pathlib import Path

import can
import pytest

from dsg_hil.protocol import Codec, DecodedFrame, load_dbc
from dsg_hil.protocol.binding import DEFAULT_BINDING, Binding, load_binding
from dsg_hil.protocol.e2e import COUNTER, CRC
from dsg_hil.protocol.logs import log_codec
from dsg_hil.sim.run import RunConfig, open_run
from ecu_stub.runner import TCU_USES, TcuRunner

DURATION = 8.0  # s of the shipped creep: the TCU engages CL and creeps
NEW = {  # shipped message -> (renamed, new ID)
    "PLANT_ENGINE": ("EMS_Engine", 0x0C0), "PLANT_SPEEDS": ("TCM_Speeds", 0x0C8),
    "PLANT_VEHICLE": ("ESP_Vehicle", 0x0D0), "PLANT_PRESSURE": ("TCM_Pressure", 0x0D8),
    "PLANT_OIL_TEMP": ("TCM_OilTemp", 0x0E0), "DRIVER": ("DRV_Request", 0x0E8),
    "TCU_CMD": ("TCU_Command", 0x1A0), "TCU_STATUS": ("TCU_State", 0x1B0),
    "SIM_TRUTH_CL": ("SIM_TruthA", 0x7A0), "SIM_TRUTH_CH": ("SIM_TruthB", 0x7A1), "SIM_HEAT": ("SIM_HeatDiss", 0x7A2),
    "SIM_SYNC": ("SIM_Step", 0x7E0),
}
# (message, signal) -> (k, offset, unit): the value in the new unit is k times the shipped one plus offset. The same
# raw values: the plant's commands (TCU_CMD) keep their scaling, so the plant reads bit for bit the commands of the
# shipped pair's run and both runs are one closed loop (the unit conversions' last bits feed no physics)
RESCALED = {("PLANT_VEHICLE", "VehicleSpeed"): (3.6, 0.0, "km/h"), ("PLANT_PRESSURE", "P_CL"): (1e3, 0.0, "kPa"),
            ("PLANT_PRESSURE", "P_CH"): (1e3, 0.0, "kPa"), ("TCU_STATUS", "T_CL_Pred"): (1.0, 273.15, "K"),
            ("TCU_STATUS", "T_CH_Pred"): (1.0, 273.15, "K")}
_channels = itertools.count()


def renamed(signal: str) -> str:
    return signal if signal in (COUNTER, CRC) else "s" + signal


def write_renamed_pair(tmp_path: Path) -> tuple[Path, Path]:
    """The renamed DBC and its binding (the shipped binding's text with the new names)."""
    from cantools.database.conversion import BaseConversion  # noqa: PLC0415

    db = load_dbc()
    for message in db.messages:
        for signal in message.signals:
            if (message.name, signal.name) in RESCALED:
                k, offset, unit = RESCALED[message.name, signal.name]
                signal.conversion = BaseConversion.factory(scale=signal.scale * k, offset=signal.offset * k + offset,
                                                           is_float=False)
                assert signal.minimum is not None and signal.maximum is not None
                signal.minimum, signal.maximum = signal.minimum * k + offset, signal.maximum * k + offset
                signal.unit = unit
            signal.name = renamed(signal.name)
        message.name, message.frame_id = NEW[message.name]
    db.refresh()
    dbc = tmp_path / "renamed.dbc"
    dbc.write_text(db.as_dbc_string(), encoding="utf-8")
    text = DEFAULT_BINDING.read_text(encoding="utf-8")
    text = re.sub(r'"([A-Z_]+)\.(\w+)"', lambda m: f'"{NEW[m[1]][0]}.{renamed(m[2])}"', text)
    text = re.sub(r'"([A-Z_]+)"', lambda m: f'"{NEW[m[1]][0]}"', text)
    binding = tmp_path / "renamed.binding.toml"
    binding.write_text(text, encoding="utf-8")
    return dbc, binding


def _roles(binding: Binding) -> dict[tuple[str, str], tuple[str, float, float]]:
    """(message, signal) -> (role, factor, offset): a quantity's name, or the lock-step signal's."""
    roles = {key: (quantity, factor, binding.offsets.get(key, 0.0)) for key, (quantity, factor)
             in binding.signals.items()}
    roles[binding.sync] = ("tick", 1.0, 0.0)
    roles[binding.echo] = ("echo", 1.0, 0.0)
    return roles


class Gateway(can.BusABC):
    """ecu-stub's end of the bus, in the shipped DBC: frames from the bus (the renamed matrix) decoded, their
    quantities converted and encoded in the shipped matrix (the counter kept, the CRC the shipped one's), and back."""

    def __init__(self, bus: can.BusABC, shipped: Binding, other: Binding) -> None:
        super().__init__(channel="gateway")
        self.bus = bus
        self.codecs = {"shipped": log_codec(shipped.db), "other": log_codec(other.db)}
        roles = {"shipped": _roles(shipped), "other": _roles(other)}
        self.by_role = {side: {role: (m, s, f, o) for (m, s), (role, f, o) in table.items()}
                        for side, table in roles.items()}
        self.roles = roles

    def _translate(self, msg: can.Message, source: str, target: str) -> can.Message:
        codec = self.codecs[source]
        try:
            frame: DecodedFrame = codec.decode(msg.arbitration_id, bytes(msg.data))
        except Exception:  # noqa: BLE001 - not a frame of the matrix: as it is
            return msg
        values: dict[str, float] = {}
        name = None
        for signal, value in frame.values.items():
            role, factor, offset = self.roles[source][frame.name, signal]
            name, new_signal, new_factor, new_offset = self.by_role[target][role]
            values[new_signal] = (value * factor + offset - new_offset) / new_factor
        assert name is not None
        data = self.codecs[target].encode(name, values, frame.counter)
        return can.Message(arbitration_id=self.codecs[target].frame_id(name), data=data, is_extended_id=False,
                           timestamp=msg.timestamp)

    def send(self, msg: can.Message, timeout: float | None = None) -> None:
        self.bus.send(self._translate(msg, "shipped", "other"), timeout)

    def _recv_internal(self, timeout: float | None) -> tuple[can.Message | None, bool]:
        msg = self.bus.recv(timeout)
        return (None if msg is None else self._translate(msg, "other", "shipped")), False


def quantities(frames: list[can.Message], binding: Binding) -> dict[str, list[tuple[float, float]]]:
    """By quantity, its (time, value in SI) of every frame (decoded with the binding's DBC)."""
    out: dict[str, list[tuple[float, float]]] = {}
    for msg in frames:
        try:
            message = binding.db.get_message_by_frame_id(msg.arbitration_id)
        except KeyError:
            continue
        decoded = message.decode(bytes(msg.data), decode_choices=False)
        assert isinstance(decoded, dict)
        for signal, value in decoded.items():
            if (message.name, signal) in binding.signals:
                quantity, factor = binding.signals[message.name, signal]
                out.setdefault(quantity, []).append(
                    (msg.timestamp, float(value) * factor  # type: ignore[arg-type]
                     + binding.offsets.get((message.name, signal), 0.0)))
    return out


@pytest.fixture(scope="module")
def runs(tmp_path_factory):
    dbc, binding_path = write_renamed_pair(tmp_path_factory.mktemp("renamed"))
    with open_run(RunConfig(duration=DURATION, capture=True, truth=True)) as run:
        shipped_summary = run.run().as_json()
    shipped_frames = run.frames
    shipped, other = load_binding(), load_binding(binding_path, dbc=dbc)

    gateways: list[Gateway] = []

    def tcu(db, bus):
        gateways.append(Gateway(bus, shipped, other))
        return TcuRunner(Codec(load_dbc(), TCU_USES), gateways[-1])

    config = RunConfig(duration=DURATION, dbc=dbc, binding=binding_path, capture=True, truth=True, tcu=tcu,
                       bus={"interface": "virtual", "channel": f"binding-run-{next(_channels)}"}, direct=False)
    with open_run(config) as run:
        other_summary = run.run().as_json()
    for gateway in gateways:
        gateway.shutdown()
    return (shipped, shipped_frames, shipped_summary), (other, run.frames, other_summary)


def test_the_renamed_matrix_moves_every_id_and_name(runs):
    (shipped, shipped_frames, _), (other, other_frames, _) = runs
    assert {m.frame_id for m in other.db.messages}.isdisjoint(m.frame_id for m in shipped.db.messages)
    assert {msg.arbitration_id for msg in other_frames} == {m.frame_id for m in other.db.messages
                                                            if m.name in other.uses}
    assert (other.units["v"], other.units["P_CL"], other.units["T_CL_pred"]) == ("km/h", "kPa", "K")
    status = NEW["TCU_STATUS"][0]
    assert other.offsets == {(status, "sT_CL_Pred"): -273.15, (status, "sT_CH_Pred"): -273.15}
    assert len(other_frames) == len(shipped_frames) > 1000


def test_the_plant_on_the_renamed_matrix_sends_and_reads_the_same_physical_values(runs):
    """Each quantity's every frame, the plant's and the TCU's: the same time, the same value but for the last bits
    of the unit conversions (the rescaled signals carry the same raw values)."""
    (shipped, shipped_frames, _), (other, other_frames, _) = runs
    a, b = quantities(shipped_frames, shipped), quantities(other_frames, other)
    assert set(a) == set(b) and len(a) == len(shipped.signals)
    for quantity in a:
        assert [t for t, _ in a[quantity]] == [t for t, _ in b[quantity]], quantity
        for (_, x), (_, y) in zip(a[quantity], b[quantity]):
            assert abs(x - y) <= 1e-9 * max(1.0, abs(x)), (quantity, x, y)


def test_the_creep_on_the_renamed_matrix_is_the_shipped_one(runs):
    """The summary: the plant's truth the same, and the TCU's status read through the renamed binding (its
    predictions in K) the same within half their 0.1 K step."""
    (_, _, a), (_, _, b) = runs
    assert [p["clutch"] for p in a["phases"]] == ["CL"] and b["phases"] == a["phases"]
    for key in ("creep_time_s", "standstill_time_s", "slip_time_s", "max_plate_temp_c", "friction_energy_kj"):
        assert b[key] == a[key], key
    for clutch in ("CL", "CH"):
        assert b["max_predicted_temp_c"][clutch] == pytest.approx(a["max_predicted_temp_c"][clutch], abs=0.05)
    assert a["max_predicted_temp_c"]["CL"] > 120.0  # the TCU's status was read (it predicts the heating)
    assert b["frames"]["rejected"] == b["frames"]["unanswered_ticks"] == 0 and b["frames"]["received"] > 800


@pytest.mark.parametrize("timeout_ms, events", [(None, 1), (50, 0)])
def test_a_binding_s_timeout_is_the_command_s_deadline(tmp_path, timeout_ms, events):
    """TCU_CMD lost for 4 control periods (40 ms): past the default deadline (3 cycle times, 30 ms) the hydraulics
    fall back; with the binding's 50 ms they hold the last command."""
    binding = None
    if timeout_ms is not None:
        binding = tmp_path / "timeout.binding.toml"
        binding.write_text(DEFAULT_BINDING.read_text(encoding="utf-8")
                           + f"\n[messages.TCU_CMD]\ntimeout_ms = {timeout_ms}\n", encoding="utf-8")
    with open_run(RunConfig(duration=2.0, binding=binding, faults=["drop:TCU_CMD@1-1.04"])) as run:
        summary = run.run().as_json()
    assert summary["frames"]["unanswered_ticks"] == 4
    assert summary["command_fallback"]["events"] == events
