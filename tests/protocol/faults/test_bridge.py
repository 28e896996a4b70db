"""dsg-hil bridge: frames from --from reach --to through the faults, frames back are unchanged."""

from __future__ import annotations

import can

from dsg_hil.cli import main
from dsg_hil.cli.bridge_cmd import bridge
from dsg_hil.protocol.faults import FaultInjector, parse_fault
from dsg_hil.protocol import Codec, TxScheduler, load_dbc


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
