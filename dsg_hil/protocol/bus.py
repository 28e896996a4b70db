"""Opening the bus the python-can way: ``interface``/``channel`` from the flags, else ``can.rc``, else the
environment (``CAN_INTERFACE``, ``CAN_CHANNEL``), else the config files (``~/.canrc``, ``~/.can``,
``/etc/can.conf``), with ``context`` selecting a ``[section]``. Nothing of our own invented on top, except the
fallback when nothing is configured at all: ``socketcan``/``vcan0`` where vcan0 exists, else ``virtual``."""

from __future__ import annotations

import os
from pathlib import Path

import can

VIRTUAL_CHANNEL = "dsg_hil"


def vcan0_present() -> bool:
    return Path("/sys/class/net/vcan0").exists()


def resolve_bus_config(interface: str | None = None, channel: str | None = None,
                       context: str | None = None) -> dict:
    """The python-can configuration to open, with the flags overriding every other source."""
    given = {k: v for k, v in (("interface", interface), ("channel", channel)) if v is not None}
    try:
        config = dict(can.util.load_config(config=given, context=context))
    except can.CanInterfaceNotImplementedError as exc:
        if "interface" in given or "None" not in str(exc):
            raise ValueError(f"interface: {exc}") from None
        config = {"interface": None, "channel": given.get("channel", os.environ.get("CAN_CHANNEL"))}
    if not config.get("interface"):
        if vcan0_present():
            config.update(interface="socketcan", channel=config.get("channel") or "vcan0")
        else:
            config.update(interface="virtual", channel=config.get("channel") or VIRTUAL_CHANNEL)
    if config.get("channel") is None:
        config["channel"] = VIRTUAL_CHANNEL if config["interface"] == "virtual" else "vcan0"
    return config


def open_bus(config: dict) -> can.BusABC:
    """Open a bus from a resolved configuration; a failure is one readable ValueError."""
    try:
        return can.Bus(**{**config, "receive_own_messages": False})
    except (can.CanError, OSError, ValueError, ImportError) as exc:
        raise ValueError(f"cannot open CAN bus {config.get('interface')}:{config.get('channel')}: {exc}") from None
