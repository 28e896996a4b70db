"""dsg-hil bridge: frames from --from reach --to through the faults, frames back are unchanged."""

from __future__ import annotations

import threading

import can

from dsg_hil.cli import main
from dsg_hil.cli.bridge_cmd import bridge
from dsg_hil.protocol.faults import FaultInjector, parse_fault
from dsg_hil.protocol import Codec, TxScheduler, load_dbc
from dsg_hil.protocol.bus import fresh_udp_group


def one_round():
    """should_stop for bridge(): let it run one round."""
    calls = []
    return lambda: bool(calls) or bool(calls.append(1))


def test_bridge_drops_in_its_window_and_forwards_back_unchanged():
    db = load_dbc()
    codec = Codec(db, {"TCU_CMD": ("P_CL_Cmd",), "PLANT_SPEEDS": ("ClutchInputSpeed",)})
    ecu, source = can.Bus(interface="virtual", channel="bridge_a"), can.Bus(interface="virtual", channel="bridge_a")
    sink, plant = can.Bus(interface="virtual", channel="bridge_b"), can.Bus(interface="virtual", channel="bridge_b")
    try:
        tx = TxScheduler(codec, ["TCU_CMD", "PLANT_SPEEDS"])
        injector = FaultInjector(db, [parse_fault("drop:TCU_CMD@1-2")])
        results = []
        for t in (0.5, 1.5, 2.5):  # before, in, after the window
            for _ in range(5):
                ecu.send(tx.frame("TCU_CMD", {"P_CL_Cmd": 0.5}))
            plant.send(tx.frame("PLANT_SPEEDS", {"ClutchInputSpeed": 800.0}))
            results.append(bridge(source, sink, injector, lambda t=t: t, one_round()))
        at_plant = []
        while (msg := plant.recv(timeout=0.0)) is not None:
            at_plant.append(msg)
        at_ecu = []
        while (msg := ecu.recv(timeout=0.0)) is not None:
            at_ecu.append(msg)
    finally:
        for bus in (ecu, source, sink, plant):
            bus.shutdown()
    assert results == [(5, 1), (0, 1), (5, 1)] and injector.counts["drop:TCU_CMD@1-2"] == 5
    assert len(at_plant) == 10 and len(at_ecu) == 3


def test_bridge_command_runs_and_counts(capsys):
    assert main(["bridge", "--from-interface", "virtual", "--from-channel", "bridge_cli_a", "--to-interface",
                 "virtual", "--to-channel", "bridge_cli_b", "--duration", "0.2", "--fault", "drop:TCU_CMD"]) == 0
    err = capsys.readouterr().err
    assert "faults injected (frames hit): drop:TCU_CMD@0- 0" in err and "forwarded 0 frames, 0 back" in err


def test_bridge_takes_each_side_s_bus_kwargs_so_a_udp_multicast_run_s_port(capsys):
    """--from-bus-kwargs/--to-bus-kwargs as python-can's --bus-kwargs (issue 35, item 8: a udp_multicast side could
    not be given the port 'dsg-hil plant' prints): a frame sent to the from group and port reaches the to one."""
    ends = [fresh_udp_group() for _ in range(2)]
    argv = ["bridge", "--duration", "1.0"]
    for end, group in zip(("from", "to"), ends):
        argv += [f"--{end}-interface", "udp_multicast", f"--{end}-channel", group["channel"], f"--{end}-bus-kwargs",
                 f"port={group['port']}"]
    ecu, plant = (can.Bus(interface="udp_multicast", **group) for group in ends)
    try:
        worker = threading.Thread(target=main, args=(argv,))
        worker.start()
        while worker.is_alive():  # the bridge forwards for 1 s once both buses are open
            ecu.send(can.Message(arbitration_id=0x123, data=b"\x01", is_extended_id=False))
            worker.join(0.01)
        heard = [msg for msg in iter(lambda: plant.recv(timeout=0.1), None) if msg.arbitration_id == 0x123]
    finally:
        ecu.shutdown()
        plant.shutdown()
    err = capsys.readouterr().err
    assert f"udp_multicast:{ends[0]['channel']} port {ends[0]['port']} -> " in err, err
    assert heard and heard[0].data == b"\x01", err
