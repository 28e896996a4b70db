"""The plant on the second example matrix (``dbc/examples/dct_fd``: other IDs and names, Motorola byte order, other
scalings and offsets, CAN FD messages of 12 and 16 bytes, AUTOSAR E2E Profile 5 on the TCU's frames and 11 on the
sensor frames, a multiplexed message) runs the default creep in lock-step in one process, by its binding alone.
ecu-stub speaks the shipped DBC, so it answers through a gateway (:class:`MatrixGateway`) that decodes each frame
with one matrix and encodes it in the other, keeping each side's counters and the multiplexed pages' last values
(a frame of the shipped matrix sent once all its values are known): the plant's truth is the shipped pair's, one oil
cycle later."""

from __future__ import annotations

import collections
import itertools
from collections import deque
from importlib import resources
from pathlib import Path

import can
import pytest

from dsg_hil.protocol import Codec
from dsg_hil.protocol.binding import Binding, check_binding, load_binding
from dsg_hil.protocol.logs import decoded_frames, log_codec
from dsg_hil.sim.run import RunConfig, open_run
from ecu_stub.runner import TCU_USES, TcuRunner

EXAMPLE = resources.files("dsg_hil") / "data" / "examples" / "dct_fd"
DBC, BINDING = Path(str(EXAMPLE / "dct_fd.dbc")), Path(str(EXAMPLE / "dct_fd.binding.toml"))
DURATION = 8.0  # s of the default creep: the TCU engages CL and creeps
_channels = itertools.count()


def _roles(binding: Binding) -> dict[tuple[str, str], tuple[str, float, float]]:
    """(message, signal) -> (role, factor, offset): a quantity's name, or the lock-step signal's."""
    roles = {key: (quantity, factor, binding.offsets.get(key, 0.0)) for key, (quantity, factor)
             in binding.signals.items()}
    roles[binding.sync] = ("tick", 1.0, 0.0)
    roles[binding.echo] = ("echo", 1.0, 0.0)
    return roles


class MatrixGateway(can.BusABC):
    """ecu-stub's end of the bus, in the shipped matrix: each frame from the bus (the example matrix) decoded, its
    quantities converted and encoded in the shipped matrix, and back. Each side's frames get the gateway's own
    counters (the two matrices' counters count differently: 4 bits, Profile 11's 0..14, Profile 5's 8 bits); a
    frame repeated byte for byte (a lock-step re-send) gives the frame it gave before; a multiplexed message's
    signals of the pages not in a frame keep their last values."""

    def __init__(self, bus: can.BusABC, shipped: Binding, other: Binding) -> None:
        super().__init__(channel="gateway")
        self.bus = bus
        self.codecs = {"shipped": log_codec(shipped.db), "other": log_codec(other.db, other.protection)}
        roles = {"shipped": _roles(shipped), "other": _roles(other)}
        self.by_role = {side: {role: (m, s, f, o) for (m, s), (role, f, o) in table.items()}
                        for side, table in roles.items()}
        self.roles = roles
        self.counters: dict[str, int] = {}
        self.needed = {side: collections.Counter(m for m, _, _, _ in table.values())
                       for side, table in self.by_role.items()}  # by side, by message: its signals with a role
        # by side, by message: the message of the other side whose frame sends it (the last of its sources, in
        # the order the plant sends them): one frame per cycle, as the receiver's lock-step expects
        self.emitter: dict[str, dict[str, str]] = {"shipped": {}, "other": {}}
        for side, source, binding in (("shipped", "other", other), ("other", "shipped", shipped)):
            for message in [*binding.tx, *binding.rx, binding.sync[0]]:
                for (m, _), (role, _, _) in roles[source].items():
                    if m == message:
                        self.emitter[side][self.by_role[side][role][0]] = message
        self.last: dict[int, tuple[bytes, list[can.Message]]] = {}  # by frame ID: the last frame in, the ones it gave
        self.queue: deque[can.Message] = deque()  # translated frames not yet received
        self.values: dict[str, dict[str, float]] = {}  # by message of the target side: its last values

    def _translate(self, msg: can.Message, source: str, target: str) -> list[can.Message]:
        """The frames of the target side that carry what ``msg`` carries (a sensor frame of one matrix may feed
        two messages of the other: one frame of each, its signals from other frames their last values)."""
        data = bytes(msg.data)
        last = self.last.get(msg.arbitration_id)
        if last is not None and last[0] == data:
            return last[1]
        frame = self.codecs[source].decode(msg.arbitration_id, data)
        names: list[str] = []
        for signal, value in frame.values.items():
            if (frame.name, signal) not in self.roles[source]:
                continue  # (a multiplexer)
            role, factor, offset = self.roles[source][frame.name, signal]
            name, new_signal, new_factor, new_offset = self.by_role[target][role]
            self.values.setdefault(name, {})[new_signal] = (value * factor + offset - new_offset) / new_factor
            if name not in names:
                names.append(name)
        codec, out = self.codecs[target], []
        t_ms = round(msg.timestamp * 1000)  # simulated time (lock-step stamps, preserved by the virtual bus)
        for name in names:
            if self.emitter[target].get(name, frame.name) != frame.name or t_ms % codec.cycle_time_ms(name) \
                    or len(self.values[name]) < self.needed[target][name]:
                continue  # (sent with the last of its sources, at its own cycle, once every value is known)
            modulus = codec.protection(name).counter_modulus or 1
            counter = self.counters[name] = (self.counters.get(name, -1) + 1) % modulus
            frame_id = codec.frame_id(name)
            out.append(can.Message(arbitration_id=frame_id, data=codec.encode(name, self.values[name], counter),
                                   is_extended_id=False, is_fd=frame_id in codec.fd,
                                   bitrate_switch=codec.fd.get(frame_id, False), timestamp=msg.timestamp))
        self.last[msg.arbitration_id] = (data, out)
        return out

    def send(self, msg: can.Message, timeout: float | None = None) -> None:
        for out in self._translate(msg, "shipped", "other"):
            self.bus.send(out, timeout)

    def _recv_internal(self, timeout: float | None) -> tuple[can.Message | None, bool]:
        while not self.queue:  # (a frame that gives none, e.g. a multiplexed page not sent on: the next one)
            msg = self.bus.recv(timeout)
            if msg is None:
                return None, False
            self.queue.extend(self._translate(msg, "other", "shipped"))
        return self.queue.popleft(), False


def test_the_example_passes_binding_check():
    binding, problems = check_binding(BINDING, dbc=DBC)
    assert problems == [] and binding is not None
    db = binding.db
    fd = {m.name: m.length for m in db.messages if m.is_fd}
    assert max(fd.values()) > 8 and len(fd) >= 2
    assert all(s.byte_order == "big_endian" for m in db.messages for s in m.signals)
    assert any(m.is_multiplexed() for m in db.messages if m.name in binding.tx)
    profiles = {name: table["profile"] for name, table in binding.protection.items()}
    assert profiles["TCU_Demand"] == profiles["TCU_Info"] == "P05"
    assert {profiles[name] for name in binding.tx if not name.startswith("SIM_")} == {"P11"}


def test_the_example_shares_nothing_with_the_shipped_matrix():
    shipped, other = load_binding(), load_binding(BINDING, dbc=DBC)
    assert {m.frame_id for m in other.db.messages}.isdisjoint(m.frame_id for m in shipped.db.messages)
    assert {m.name for m in other.db.messages}.isdisjoint(m.name for m in shipped.db.messages)
    assert {s for _, s in other.signals}.isdisjoint(s for _, s in shipped.signals)

    def scaling(binding: Binding) -> dict[str, tuple[float, float, str]]:
        out = {}
        for (message, signal), (quantity, _) in binding.signals.items():
            found = binding.db.get_message_by_name(message).get_signal_by_name(signal)
            out[quantity] = (found.scale, found.offset, binding.units[quantity])
        return out
    a, b = scaling(shipped), scaling(other)
    same = sorted(q for q in a if a[q] == b[q] and a[q][:2] != (1, 0))
    assert same == [] and len(a) == len(b) == 36
    assert sum(a[q][2] != b[q][2] for q in a) >= 12  # other units (1/min, rad/s, km/h, bar, K, kW ...)


@pytest.fixture(scope="module")
def runs(tmp_path_factory):
    with open_run(RunConfig(duration=DURATION, capture=True, truth=True)) as run:
        shipped_summary = run.run().as_json()
    shipped, other = load_binding(), load_binding(BINDING, dbc=DBC)
    gateways: list[MatrixGateway] = []

    def tcu(db, bus):
        gateways.append(MatrixGateway(bus, shipped, other))
        return TcuRunner(Codec(shipped.db, TCU_USES), gateways[-1])

    log = tmp_path_factory.mktemp("dct_fd") / "creep.blf"
    bus = {"interface": "virtual", "channel": f"dct-fd-{next(_channels)}", "preserve_timestamps": True}
    config = RunConfig(duration=DURATION, dbc=DBC, binding=BINDING, capture=True, truth=True, tcu=tcu, log=log,
                       bus=bus, direct=False)
    with open_run(config) as run:
        other_summary = run.run().as_json()
    for gateway in gateways:
        gateway.shutdown()
    return shipped_summary, (other, run.frames, other_summary, log)


def test_the_creep_on_the_example_matrix_is_the_shipped_one(runs):
    """The same creep as on the shipped matrix, shifted by one oil cycle: the TCU's first complete oil reading
    takes both pages of the multiplexed message (page 1 at 50 ms), which the gateway hands on at the shipped
    message's next cycle (100 ms), so the TCU engages CL exactly 0.1 s later. The plant's truth differs by no more
    than 0.1 s of the shipped run's slip gives (its mean friction power, its mean heating rate of the plates) and
    the commands' and sensors' quantisation; nothing is rejected."""
    a, (_, _, b, _) = runs
    assert b["frames"]["rejected"] == b["frames"]["unanswered_ticks"] == 0 and b["frames"]["received"] > 800
    assert [p["clutch"] for p in b["phases"]] == [p["clutch"] for p in a["phases"]] == ["CL"]
    (pa,), (pb,) = a["phases"], b["phases"]
    shift = 0.1  # s: the shipped PLANT_OIL_TEMP's cycle
    assert pb["start_s"] == pytest.approx(pa["start_s"] + shift, abs=1e-9)
    assert b["creep_time_s"] == pytest.approx(a["creep_time_s"] - shift, abs=1e-9)
    assert b["standstill_time_s"] == pytest.approx(a["standstill_time_s"] + shift, abs=1e-9)
    power = a["friction_energy_kj"]["CL"] / pa["duration_s"]  # kW: the shipped slip's mean friction power
    start = a["max_plate_temp_c"]["CH"]  # degC: the plates' temperature at the start (CH never slips)
    heating = (a["max_plate_temp_c"]["CL"] - start) / pa["duration_s"]  # K/s: the shipped slip's mean heating
    assert abs(b["friction_energy_kj"]["CL"] - a["friction_energy_kj"]["CL"]) <= power * shift
    assert abs(b["max_plate_temp_c"]["CL"] - a["max_plate_temp_c"]["CL"]) <= heating * shift
    assert b["max_plate_temp_c"]["CH"] == a["max_plate_temp_c"]["CH"]  # (CH never slips)
    assert b["max_predicted_temp_c"]["CH"] == pytest.approx(a["max_predicted_temp_c"]["CH"], abs=0.5)  # 0.5 K steps


def test_every_frame_is_in_its_message_s_format(runs):
    _, (other, frames, _, _) = runs
    seen = {}
    for msg in frames:
        message = other.db.get_message_by_frame_id(msg.arbitration_id)
        seen.setdefault(message.name, set()).add((msg.is_fd, msg.bitrate_switch, len(msg.data)))
    assert seen["TCM_ShaftSpeeds"] == {(True, True, 12)} and seen["TCU_Demand"] == {(True, True, 16)}
    assert seen["SIM_ClutchA"] == {(True, False, 16)} and seen["EMS_TorqueSpeed"] == {(False, False, 8)}
    pages = [other.db.get_message_by_name("TCM_OilTemps").decode(bytes(m.data))["OilTemp_Page"] for m in frames
             if m.arbitration_id == 0x0E1]
    assert {str(p) for p in pages} == {"ClutchOil", "SumpCooler"}


def test_the_log_of_the_example_run_decodes_with_its_binding(runs):
    _, (other, frames, _, log) = runs
    counts: dict[str, int] = {}
    names = {frame.name for _, frame in decoded_frames(log, log_codec(other.db, other.protection), counts)
             if frame is not None}
    assert counts["rejected"] == counts["unknown"] == 0 and counts["decoded"] == len(frames)
    assert names == set(other.uses)


def test_the_report_s_log_reader_reads_the_example_run(runs):
    """``dsg-hil report --from-log --dbc --binding``'s reader on the run's .blf log (CAN FD frames, Profile 5 and 11,
    the multiplexed oil temperatures): the creep time of the run's own summary, the plate temperature's peak of the
    truth frames it sent."""
    from dsg_hil.paper.report.log import read_log
    from dsg_hil.sim.plant_io import from_binding

    _, (other, frames, summary, log) = runs
    record = read_log(log, other.db, from_binding(other), other.protection)
    assert record.frames == {"decoded": len(frames), "rejected": 0, "unknown": 0} and record.has_status
    assert record.metrics["creep_time_s"] == pytest.approx(summary["creep_time_s"], abs=0.02)
    truth = other.db.get_message_by_name("SIM_ClutchA")
    sent = max(float(truth.decode(bytes(m.data)[:truth.length])["T_PlateA"]) for m in frames
               if m.arbitration_id == truth.frame_id) - 273.15  # the truth frames' own peak (every 100 ms)
    assert record.metrics["max_plate_temp_c"]["CL"] == pytest.approx(sent, abs=0.01)
    predicted = record.columns["T_CL_pred"]  # TCU_Info's, in K on the bus
    assert predicted.size > 700 and float(predicted[20:].min()) > 0.0  # (no NaN after the first status)
    assert float(predicted.max()) == pytest.approx(summary["max_predicted_temp_c"]["CL"], abs=0.01)


@pytest.mark.parametrize("message, signal, value", [("TCU_Demand", "PressReqA", 500.0),
                                                    ("TCM_ShaftSpeeds", "GbxOutSpd", 12.5)])
def test_faults_on_the_example_s_fd_frames(message, signal, value):
    """Profile 5 over the 16-byte TCU_Demand and Profile 11 over the 12-byte TCM_ShaftSpeeds: each fault kind on a
    CAN FD frame gives a CAN FD frame of its length that the receiver rejects for the fault's cause (a frozen
    counter: a repeat, once the frame before it was taken), or takes with the stuck value."""
    from dsg_hil.protocol.faults import FaultInjector
    from dsg_hil.protocol.faults.spec import parse_fault
    from dsg_hil.protocol.frame import data_frame
    from dsg_hil.protocol.validity import NEW, REJECTED, RxMonitor

    other = load_binding(BINDING, dbc=DBC)
    codec = Codec(other.db, other.uses, protection=other.protection)
    frame_id, length = codec.frame_id(message), codec.message(message).length

    def frames(n: int) -> list[can.Message]:
        return [data_frame(frame_id, codec.encode(message, {signal: value + k}, k), 0.01 * k, fd=codec.fd)
                for k in range(n)]  # (the values change: a frozen counter's frames are no byte-identical repeat)

    for fault, expected in ((f"corrupt_crc:{message}", ["crc"]), (f"freeze_counter:{message}", ["counter"]),
                            (f"stuck:{message}.{signal},value=100", [])):
        injector = FaultInjector(other.db, [parse_fault(fault)], protections=codec.protections())
        rx = RxMonitor(codec, [message])
        statuses = []
        for k, msg in enumerate(frames(3)):
            (out,) = injector.apply(msg, 0.01 * k)
            assert out.is_fd and out.bitrate_switch and len(out.data) == length
            status, frame = rx.take(out, 0.01 * k)
            statuses.append(status)
            if fault.startswith("stuck") and frame is not None:
                assert frame.values[signal] == pytest.approx(100.0)
        assert sorted(rx.rejected) == expected, fault
        assert statuses == ([NEW, NEW, NEW] if not expected else
                            [REJECTED] * 3 if expected == ["crc"] else [NEW, REJECTED, REJECTED])
