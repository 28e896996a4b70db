"""Plant and TCU as two processes with no vcan: python-can's udp_multicast, on a group and port of the run's own."""

from __future__ import annotations

import argparse
import ipaddress
import json
import re
import subprocess
import sys

import can
import pytest

from dsg_hil.protocol.bus import UDP_MULTICAST, add_bus_arguments, bus_args, bus_config, fresh_udp_group, open_bus


def _parse(argv: list[str]) -> argparse.Namespace:
    parser = argparse.ArgumentParser()
    add_bus_arguments(parser)
    return parser.parse_args(argv)


@pytest.mark.slow
def test_run_on_udp_multicast_starts_the_tcu_as_a_process_that_answers(tmp_path):
    summary = tmp_path / "s.json"
    proc = subprocess.run([sys.executable, "-m", "dsg_hil", "run", "-i", UDP_MULTICAST, "--duration", "3",
                           "--summary", str(summary)], capture_output=True, text=True, timeout=300)
    assert proc.returncode == 0, proc.stderr
    plant_bus = re.search(r"lockstep on (udp_multicast:\S+ port \d+)", proc.stderr)
    assert plant_bus, proc.stderr
    assert f"ecu-stub: listening on {plant_bus.group(1)}" in proc.stderr  # printed by the ecu-stub process
    data = json.loads(summary.read_text())
    assert data["frames"]["received"] > 0 and data["frames"]["rejected"] == 0
    assert data["command_fallback"]["events"] == 0
    assert data["creep_time_s"] > 0 and data["slip_time_s"]["CL"] > 0
    assert data["speed_error_rms_mps"] is not None  # the TCU reached CREEP


def test_fresh_group_is_local_scope_and_only_its_own_port_hears_it():
    a, b = fresh_udp_group(), fresh_udp_group()
    assert ipaddress.ip_address(a["channel"]) in ipaddress.ip_network("239.255.0.0/16")
    assert a["port"] != b["port"]
    config = {"interface": UDP_MULTICAST, **a}
    sender, same, other = open_bus(config), open_bus(config), open_bus({"interface": UDP_MULTICAST, **b})
    try:
        sender.send(can.Message(arbitration_id=0x100, data=bytes(8), is_extended_id=False))
        assert same.recv(timeout=2.0) is not None
        assert other.recv(timeout=0.3) is None
    finally:
        for bus in (sender, same, other):
            bus.shutdown()


def test_bus_args_reproduce_the_resolved_config():
    config = bus_config(_parse(["-i", UDP_MULTICAST, "-b", "500000", "--bus-kwargs", "hop_limit=2"]), fresh_udp=True)
    assert config["channel"] and config["port"] and config["bitrate"] == 500000
    assert bus_config(_parse(bus_args(config))) == config
    timing = ["--timing", "f_clock=8000000", "brp=1", "tseg1=5", "tseg2=2", "sjw=1", "nof_samples=1"]
    config = bus_config(_parse(["-i", "socketcan", "-c", "vcan0", *timing]))
    assert bus_config(_parse(bus_args(config))) == config


def test_tcu_without_the_group_says_what_to_pass():
    proc = subprocess.run([sys.executable, "-m", "ecu_stub", "-i", UDP_MULTICAST, "--duration", "0.1"],
                          capture_output=True, text=True)
    assert proc.returncode == 2 and "Traceback" not in proc.stderr
    assert proc.stderr.startswith("error: ") and "--bus-kwargs port=" in proc.stderr


@pytest.mark.slow
def test_virtual_is_per_process_and_says_so():
    proc = subprocess.run([sys.executable, "-m", "ecu_stub", "-i", "virtual", "--duration", "0.1"],
                          capture_output=True, text=True)
    assert proc.returncode == 0 and "warning: python-can's 'virtual' interface lives inside one process" in proc.stderr
    proc = subprocess.run([sys.executable, "-m", "dsg_hil", "plant", "-i", "virtual", "--mode", "lockstep",
                           "--startup-timeout", "0.5"], capture_output=True, text=True)
    last = proc.stderr.strip().splitlines()[-1]
    assert proc.returncode == 1 and last.startswith("error: no TCU answered")
    assert "inside one process" in last and f"-i {UDP_MULTICAST}" in last and "vcan0" in last
