"""ecu-stub's diagnostics in the closed loop, read by the real tester side (udsoncan over can-isotp): each fault
of README's fault table sets its DTC, confirmed after its debounce, with a freeze frame matching the plant's truth;
clearing clears; lock-step re-sends count once; UDS during the run on python-can's virtual bus leaves the run's
frames bit for bit those of a run nobody talks to."""

from __future__ import annotations

import math
import threading
import time

import can
import numpy as np
import pytest

from dsg_hil.protocol.bus import UDP_MULTICAST, fresh_udp_group
from dsg_hil.protocol.diag import load_description
from dsg_hil.protocol.diag_client import clear_dtcs, read_dids, read_dtcs, uds_client
from dsg_hil.sim.run import RunConfig, open_run

from ..test_safety_scenarios import V_CREEP, worst_case

DESCRIPTION = load_description()
CONFIRMED = 0x08
RPM = 60.0 / (2.0 * math.pi)
# freeze-frame field: (truth key, factor to the field's unit, how old the TCU's value may be [s], DBC step)
TRUTH = {"EngineSpeed": ("omega_e", RPM, 0.05, 0.25), "ClutchInputSpeed": ("omega_in", RPM, 0.05, 0.1),
         "CLOutputSpeed": ("omega_CL", RPM, 0.05, 0.1), "CHOutputSpeed": ("omega_CH", RPM, 0.05, 0.1),
         "VehicleSpeed": ("v", 1.0, 0.05, 0.001), "P_CL": ("P_CL", 1e-6, 0.05, 1e-4),
         "P_CH": ("P_CH", 1e-6, 0.05, 1e-4), "T_OilCL": ("T_oil_CL", 1.0, 0.15, 0.1),
         "T_OilCH": ("T_oil_CH", 1.0, 0.15, 0.1), "T_Sump": ("T_sump", 1.0, 0.15, 0.1)}
START = 2.0


def confirmed(result):
    with result.uds() as client:
        return {r.code: r for r in read_dtcs(client, DESCRIPTION, CONFIRMED)}


def assert_matches_truth(frame, truth, skip=()):
    """Each field the TCU read lies within its DBC step of the plant's truth over the time its value may be old."""
    t = frame["t"]
    for name, (key, factor, age, step) in TRUTH.items():
        if name in skip:
            continue
        window = (truth["t"] >= t - age - 1e-9) & (truth["t"] <= t + 1e-9)
        values = truth[key][window] * factor
        assert values.min() - 2 * step <= frame[name] <= values.max() + 2 * step, (name, frame[name], values)


# fault -> the DTCs it confirms; the signal it falsifies (the TCU's value of it is its own replacement, not the
# truth); by when after the fault began [s] the check must have failed for its debounce: a timeout 3 cycle times +
# 1 period, an E2E failure 3 rejected frames, the speed vote and the speed check at the first frames, the oil check
# within its 100-ms frames, the pressure check once its integral (0.075 MPa s) is filled by the 0.3-MPa offset
# beyond its tolerance (about 0.3 s), an output speed out-voted once the vote's distance (0.04 m) is filled by its
# +30 r/min beyond 3 % of the 0.2-m/s creep (CL: 0.108 m/s at the wheel, 0.39 s; CH: 0.187 m/s, 0.22 s), + 3 periods
FAULTS = [
    ("drop:PLANT_VEHICLE@2-2.5", {"U1103"}, None, 0.05),
    ("corrupt_crc:PLANT_SPEEDS@2-2.5", {"U1102", "U1202"}, None, 0.05),
    ("freeze_counter:PLANT_PRESSURE@2-2.5", {"U1104", "U1204"}, None, 0.05),
    ("out_of_range:PLANT_ENGINE.EngineSpeed@2-2.5", {"U1101", "U1201"}, None, 0.05),
    ("wrong_dlc:DRIVER@2-2.5", {"U1106", "U1206"}, None, 0.07),
    ("stuck:PLANT_VEHICLE.VehicleSpeed@2-2.5,value=0", {"P1710"}, "VehicleSpeed", 0.15),
    ("offset:PLANT_PRESSURE.P_CL@2-2.5,value=0.3", {"P1712"}, "P_CL", 0.4),
    ("stuck:PLANT_SPEEDS.ClutchInputSpeed@2-2.5,value=0", {"P1714"}, "ClutchInputSpeed", 0.15),
    ("stuck:PLANT_OIL_TEMP.T_OilCL@2-2.5,value=20", {"P1715"}, "T_OilCL", 0.25),
    ("offset:PLANT_SPEEDS.CLOutputSpeed@2-2.5,value=30", {"P1717"}, "CLOutputSpeed", 0.45),
    ("offset:PLANT_SPEEDS.CHOutputSpeed@2-2.5,value=30", {"P1718"}, "CHOutputSpeed", 0.3),
    ("delay:PLANT_SPEEDS@2-2.5,delay_s=0.02", set(), None, 0.0),
    ("duplicate:PLANT_SPEEDS@2-2.5", set(), None, 0.0),
    ("flood@2-2.5,rate=2", set(), None, 0.0),
]


@pytest.mark.parametrize(("fault", "codes", "falsified", "within_s"), FAULTS, ids=[f[0].split("@")[0] for f in FAULTS])
def test_each_fault_sets_its_dtc_with_a_freeze_frame_of_the_plants_truth(dsg_hil_run, fault, codes, falsified,
                                                                         within_s):
    result = dsg_hil_run(faults=[fault], duration=3.0, log=None)
    dtcs = confirmed(result)
    assert set(dtcs) == codes
    for code, report in dtcs.items():
        debounce = next(d.debounce for d in DESCRIPTION.dtcs if d.code == code)
        frame = report.freeze_frame
        assert report.status & CONFIRMED and frame is not None
        # confirmed no sooner than its debounce allows after the fault began, and in time
        assert START + (debounce - 1) * 0.01 - 1e-9 <= frame["t"] <= START + within_s
        assert_matches_truth(frame, result.truth, skip=(falsified,))


def test_an_oil_sensor_low_from_key_on_confirms_its_dtc_at_once(dsg_hil_run):
    """The key-on check (docs/safety.md) flags T_OilCL on the first cycle; its DTC is confirmed after its
    debounce, 3 periods (the first period's count is the monitor's reference)."""
    result = dsg_hil_run(faults=["offset:PLANT_OIL_TEMP.T_OilCL@0-,value=-30"], duration=1.0, log=None)
    dtcs = confirmed(result)
    assert set(dtcs) == {"P1715"} and dtcs["P1715"].freeze_frame["t"] <= 0.05
    assert_matches_truth(dtcs["P1715"].freeze_frame, result.truth, skip=("T_OilCL",))


@pytest.mark.slow
def test_overheat_stop_and_vehicle_hold(dsg_hil_run):
    hot = dsg_hil_run(scenario=worst_case(10.0, [(1.0, True, 0.0, V_CREEP)], T_CL=228.0, T_CH=247.0, T_oil=130.0),
                      log=None)
    assert hot.summary["stop_reason"] == "STOPPED_OVERHEAT"
    dtcs = confirmed(hot)
    assert "P1701" in dtcs and dtcs["P1701"].freeze_frame["State"] == 4  # STOPPED_OVERHEAT
    assert_matches_truth(dtcs["P1701"].freeze_frame, hot.truth)
    held = dsg_hil_run(scenario=worst_case(9.0, [(1.0, True, 0.0, V_CREEP)]), faults=["drop:TCU_CMD@5-7"], log=None)
    dtcs = confirmed(held)
    assert "P1702" in dtcs and 5.0 <= dtcs["P1702"].freeze_frame["t"] <= 7.0
    # held because the measured pressures disagree with the lost commands: the TCU's P_CL/P_CH are its replacements
    assert_matches_truth(dtcs["P1702"].freeze_frame, held.truth, skip=("P_CL", "P_CH"))


def test_clear_and_read_dids(dsg_hil_run):
    result = dsg_hil_run(faults=["drop:PLANT_VEHICLE@1-1.2"], duration=1.5, log=None)
    with result.uds() as client:
        assert [r.code for r in read_dtcs(client, DESCRIPTION, CONFIRMED)] == ["U1103"]
        values = read_dids(client, DESCRIPTION, [0x0101, 0x0102, 0xF189, 0xF804])
        clear_dtcs(client)
        every = read_dtcs(client, DESCRIPTION, 0xFF, snapshots=False)
        assert len(every) == len(DESCRIPTION.dtcs) and {r.status for r in every} == {0x50}  # not completed since
        after = client.get_number_of_dtc_by_status_mask(0x2F).service_data.dtc_count
    assert after == 0
    last = result.tcu.last  # the TCU's outputs of the run's last control period, which the DIDs hold
    assert values["plate_temperatures_pred"]["T_CL_Pred"] == pytest.approx(last.T_CL_pred_c, abs=0.05)
    assert values["plate_temperatures_pred"]["T_CH_Pred"] == pytest.approx(last.T_CH_pred_c, abs=0.05)
    assert values["state"]["State"] == result.tcu.states[last.state]
    assert values["software_version"].startswith("dsg-hil ") and len(values["calibration_id"]) == 16


def test_lockstep_re_sends_do_not_count_twice(dsg_hil_run):
    """TCU_CMD dropped over the ticks of a CRC fault on PLANT_SPEEDS: the plant re-sends each tick's frames, the
    corrupted ones too (more rejections), yet the DTC is confirmed once, at the same period as without re-sends
    (its freeze frame's pressures differ: the late commands changed the plant)."""
    alone = dsg_hil_run(faults=["corrupt_crc:PLANT_SPEEDS@2-2.5"], duration=2.6, log=None)
    resent = dsg_hil_run(faults=["corrupt_crc:PLANT_SPEEDS@2-2.5", "drop:TCU_CMD@1.99-2.02"], duration=2.6, log=None)
    counts = [r.tcu.frame_counts()["by_message"]["PLANT_SPEEDS"]["rejected"]["crc"] for r in (alone, resent)]
    assert counts[1] > counts[0]
    records = [r.tcu.diag.memory.records["PLANT_SPEEDS_e2e"] for r in (alone, resent)]
    assert [r.occurrences for r in records] == [1, 1]
    assert records[0].failed_at == records[1].failed_at == 2.02  # the third period with a rejected frame
    assert records[0].status == records[1].status


def _capture(bus=None, talk=None, answers=()):
    """The frames of a 3-s lock-step run of the default scenario: on the direct in-process bus, or on ``bus`` (a
    python-can configuration: ecu-stub in this process on ``virtual``, else as a process) with ``talk(ready, done)``
    run in a thread meanwhile. The run starts once the tester is ready to ask (its bus and client open), and each
    control period waits 20 ms of wall time until the tester has done its ``ROUNDS`` (a compiled loop runs the 3 s
    in a fraction of a second, less than a tester's round trips take; the server answers in control periods, so a
    run slower than real time answers a request in flight before the run ends): the plant is the time master, so
    the wait changes no frame."""
    def pace(runner):
        if len(answers) < ROUNDS:
            time.sleep(0.02)

    run = open_run(RunConfig(duration=3.0, bus=bus, direct=bus is None, capture=True,
                             on_period=None if talk is None else pace))
    with run:
        if talk is None:
            run.run()
        else:
            ready, done = threading.Event(), threading.Event()
            thread = threading.Thread(target=talk, args=(ready, done))
            thread.start()
            try:
                assert ready.wait(60.0), "the tester did not start"
                run.run()
            finally:
                done.set()
                thread.join()
    return [(m.arbitration_id, bytes(m.data), m.timestamp) for m in run.frames]


ROUNDS = 20  # the tester's requests in a run (each a DID read and a TesterPresent)


def _talker(bus_config, answers, errors):
    """A tester reading DIDs and keeping the session alive until the run is done (at most ``ROUNDS``); requests
    before the TCU first answers (a TCU process still starting) and one the run's end left unanswered are no
    errors."""
    from udsoncan.exceptions import NegativeResponseException, TimeoutException

    def talk(ready, done):
        # asked every 0.2 s until the TCU first answers (a TCU process starts within the run: a request it did not
        # hear, or one answered 0x22 before its first control period, must not leave a short run without a
        # tester), then given 5 s per request (a loaded machine's threads)
        with can.Bus(**bus_config) as bus, uds_client(bus, DESCRIPTION, 0x7E1, 0x7E9, timeout=0.2) as client:
            ready.set()
            while not done.is_set() and len(answers) < ROUNDS:
                try:
                    answers.append(read_dids(client, DESCRIPTION, [0x0101, 0x0110]))
                    for key in ("request_timeout", "p2_timeout", "p2_star_timeout"):
                        client.set_config(key, 5.0)
                    client.tester_present()
                except NegativeResponseException as exc:
                    if answers or exc.response.code != 0x22:  # conditionsNotCorrect: no control period yet
                        errors.append(exc)
                        return
                except TimeoutException as exc:
                    if answers and not done.is_set():
                        errors.append(exc)
                        return
    return talk


@pytest.mark.slow
@pytest.mark.parametrize("interface", ["virtual", "udp_multicast"])
def test_uds_while_the_creep_runs_leaves_its_frames_bit_for_bit(interface):
    """A tester talks to ecu-stub during a lock-step run (in this process on python-can's virtual bus; as a process
    on udp_multicast): it is answered, and the run's frames are those of a run nobody talks to, bit for bit."""
    bus = {"interface": "virtual", "channel": f"uds-during-run-{id(object()):x}"} if interface == "virtual" \
        else {"interface": UDP_MULTICAST, **fresh_udp_group()}
    answers: list[dict] = []
    errors: list[Exception] = []
    quiet = _capture()
    talked = _capture(bus, _talker(bus, answers, errors), answers)
    assert not errors
    assert answers  # the TCU answered while the run ran
    assert all(np.isfinite(a["speeds"]["VehicleSpeed"]) for a in answers)
    assert talked == quiet
