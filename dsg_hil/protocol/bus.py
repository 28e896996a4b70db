"""Opening the bus the python-can way, for the plant and the TCU alike.

Options: python-can's own (``can.cli.add_bus_arguments``: ``-i``, ``-c``, ``-b``, ``--fd``, ``--data-bitrate``,
``--timing``, ``--bus-kwargs``, as in ``can.logger`` and ``cantools monitor``) plus ``--config-context``.
Configuration: the flags, else ``can.rc``, else the environment (``CAN_INTERFACE``, ``CAN_CHANNEL``), else the
config files (``~/.canrc``, ``~/.can``, ``/etc/can.conf``), ``--config-context`` selecting a ``[section]``.
Nothing of our own on top, except

* the fallback when no interface is configured at all: ``socketcan``/``vcan0`` where vcan0 exists, else
  ``virtual`` (which lives inside one process: :func:`per_process_warning`);
* ``udp_multicast`` with no channel: the plant picks a multicast group and port of its own
  (:func:`fresh_udp_group`, so two runs on one host never hear each other) and prints the options that reach
  it (:func:`bus_args`); the TCU must be given them.
"""

from __future__ import annotations

import argparse
import configparser
import importlib.util
import os
import random
import socket
from collections.abc import Iterable
from pathlib import Path
from typing import TYPE_CHECKING, Any

import can
import can.cli

from ..common.errors import InputError, RunError

if TYPE_CHECKING:
    from cantools.database.can import Message

__all__ = ["DEFAULT_CHANNELS", "FrameLog", "LOG_CHANNEL", "UDP_MULTICAST", "VIRTUAL_CHANNEL", "add_bus_arguments",
           "bus_args", "bus_config", "bus_name", "fresh_udp_group", "has_fd", "log_channel", "open_bus",
           "per_process_warning", "receive_filters", "require_mf4", "resolve_bus_config", "vcan0_present"]

VIRTUAL_CHANNEL = "dsg_hil"
UDP_MULTICAST = "udp_multicast"
DEFAULT_CHANNELS = {"virtual": VIRTUAL_CHANNEL, "socketcan": "vcan0"}  # a channel given by no option
LOG_CHANNEL = "vcan0"  # the channel name written to logs of runs that are not on socketcan (canplayer -I)
_FROM_FLAGS = ("interface", "channel", "bitrate", "fd", "data_bitrate", "timing")


def add_bus_arguments(parser: argparse.ArgumentParser, fresh_udp: bool = True) -> None:
    """python-can's bus options and ``--config-context``: the one definition for dsg-hil and ecu-stub
    (``fresh_udp`` as in :func:`bus_config`: True for the plant, False for the TCU)."""
    can.cli.add_bus_arguments(parser)
    udp = (f"-i {UDP_MULTICAST} without -c: the plant picks a multicast group and port for this run and prints "
           "the options that reach it" if fresh_udp else
           f"-i {UDP_MULTICAST} needs the plant's group and port: the options 'dsg-hil plant' prints")
    parser.add_argument(
        "--config-context", metavar="SECTION",
        help="section of the python-can config file. With no interface from the flags, can.rc, CAN_INTERFACE "
             "or the config file: socketcan on vcan0 where it exists, else virtual (one process only). " + udp)


def bus_config(args: argparse.Namespace, fresh_udp: bool = False, prefix: str = "") -> dict[str, Any]:
    """The python-can configuration from the options of :func:`add_bus_arguments` (``prefix``: those of
    ``can.cli.add_bus_arguments(parser, prefix=...)``, ``--PREFIX-interface`` ..., as ``dsg-hil bridge`` has).

    ``fresh_udp``: give ``udp_multicast`` without a channel a group of its own (the plant); else (the TCU) that
    is an error naming what to pass."""
    def option(key: str) -> Any:
        return getattr(args, f"{prefix}_{key}" if prefix else key, None)

    given = {key: option(key) for key in _FROM_FLAGS if option(key) is not None}
    given.update(option("bus_kwargs") or {})
    config = resolve_bus_config(context=getattr(args, "config_context", None), **given)
    if config["interface"] == UDP_MULTICAST and config.get("channel") is None:
        if not fresh_udp:
            raise InputError(f"-i {UDP_MULTICAST} needs the channel (multicast group) and port of the plant: "
                             f"start it with the options 'dsg-hil plant' prints, e.g. -i {UDP_MULTICAST} "
                             "-c 239.255.12.34 --bus-kwargs port=40000")
        config.update(fresh_udp_group())
    return config


def resolve_bus_config(interface: str | None = None, channel: str | None = None,
                       context: str | None = None, **extra: Any) -> dict[str, Any]:
    """The python-can configuration to open, with the given values overriding every other source."""
    given = {k: v for k, v in (("interface", interface), ("channel", channel)) if v is not None} | extra
    if context is not None and not _has_config_section(context):
        raise InputError(f"--config-context {context}: no section [{context}] in the python-can config file "
                         f"({', '.join(can.util.CONFIG_FILES)})")
    try:
        config = dict(can.util.load_config(config=given, context=context))
    except can.CanInterfaceNotImplementedError as exc:
        if "interface" in given or "None" not in str(exc):
            raise InputError(f"interface: {exc}") from None
        config = {**extra, "interface": None, "channel": given.get("channel", os.environ.get("CAN_CHANNEL"))}
    except (ValueError, TypeError) as exc:  # python-can checks port and state ("Port config must be a number!")
        bad = [f"{key}={extra[key]}" for key in ("port", "state") if key in extra]
        where = f"--bus-kwargs {' '.join(bad)}" if bad else "the python-can configuration"
        raise InputError(f"{where}: {exc}") from None
    if not config.get("interface"):
        if vcan0_present():
            config.update(interface="socketcan", channel=config.get("channel") or "vcan0")
        else:
            config.update(interface="virtual", channel=config.get("channel") or VIRTUAL_CHANNEL)
    if config.get("channel") is None and config["interface"] != UDP_MULTICAST:
        if config["interface"] not in DEFAULT_CHANNELS:
            raise InputError(f"-i {config['interface']}: needs a channel (-c CHANNEL, as python-can names it for "
                             f"that interface)")
        config["channel"] = DEFAULT_CHANNELS[config["interface"]]
    return config


def _has_config_section(section: str) -> bool:
    parser = configparser.ConfigParser()
    parser.read([os.path.expanduser(path) for path in can.util.CONFIG_FILES])
    return parser.has_section(section)


def fresh_udp_group() -> dict[str, Any]:
    """A multicast group in 239.255.0.0/16 (IPv4 local scope) and a UDP port free on this host, for one run.

    Both are needed: python-can binds the port on every address, and Linux delivers a datagram to every socket
    bound to its port that joined *any* group on the host, so only the port separates two runs."""
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as sock:
        sock.bind(("", 0))
        port = sock.getsockname()[1]
    rng = random.SystemRandom()
    return {"channel": f"239.255.{rng.randrange(256)}.{rng.randrange(1, 255)}", "port": port}


def bus_args(config: dict[str, Any]) -> list[str]:
    """Command-line options of :func:`add_bus_arguments` that open the bus of ``config`` (for ecu-stub)."""
    argv = ["-i", str(config["interface"]), "-c", str(config["channel"])]
    kwargs = []
    for key, value in config.items():
        if key in ("interface", "channel") or value is None:
            continue
        if isinstance(value, (can.BitTiming, can.BitTimingFd)):
            argv += ["--timing", *(f"{k}={v}" for k, v in value.items() if type(v) is int)]
        elif isinstance(value, (bool, int, float, str)) and str(value) and not any(c.isspace() for c in str(value)):
            kwargs.append(f"{key}={value}")
        else:
            raise InputError(f"bus option {key}={value!r} cannot be passed on the command line")
    return argv + (["--bus-kwargs", *kwargs] if kwargs else [])


def bus_name(config: dict[str, Any]) -> str:
    """``interface:channel`` (and the port of a udp_multicast bus) for messages."""
    port = f" port {config['port']}" if config["interface"] == UDP_MULTICAST and "port" in config else ""
    return f"{config['interface']}:{config['channel']}{port}"


def per_process_warning(config: dict[str, Any]) -> str | None:
    """Why a process alone on python-can's ``virtual`` interface will not meet one in another process."""
    if config["interface"] != "virtual":
        return None
    return (f"python-can's 'virtual' interface lives inside one process: a plant or TCU started as another "
            f"process does not hear this one. For two processes use -i {UDP_MULTICAST} (no setup; the plant "
            "prints the options for the TCU) or -i socketcan -c vcan0")


def log_channel(config: dict[str, Any]) -> str:
    """The channel written to logs: the socketcan interface's own, else ``vcan0`` (so ``canplayer -I`` replays
    a log of a virtual or udp_multicast run onto vcan0 with no mapping)."""
    return str(config["channel"]) if config["interface"] == "socketcan" else LOG_CHANNEL


def vcan0_present() -> bool:
    return Path("/sys/class/net/vcan0").exists()


def receive_filters(messages: Iterable[Message]) -> can.typechecking.CanFilters:
    """python-can receive filters passing exactly ``messages`` (the DBC messages a node reads): on SocketCAN the
    kernel applies them, so a node never wakes for the other frames of a busy bus (a flood of unknown IDs)."""
    return [{"can_id": m.frame_id, "can_mask": 0x1FFFFFFF if m.is_extended_frame else 0x7FF,
             "extended": bool(m.is_extended_frame)} for m in messages]


def open_bus(config: dict[str, Any], receive: Iterable[Message] | None = None, fd: bool = False) -> can.BusABC:
    """Open a bus from a resolved configuration, passing only the frames of ``receive`` when given (see
    :func:`receive_filters`); a failure is one readable RunError (the options were well formed, the interface or
    channel could not be had here: exit 1).

    ``fd``: the matrix has CAN FD messages (:func:`has_fd`): the bus is opened for CAN FD, ``fd=True`` as python-can
    takes it (socketcan: the FD MTU of 72 bytes, which vcan0 needs; udp_multicast: FD datagrams; a real interface
    also needs its data bit rate, e.g. ``--bus-kwargs data_bitrate=2000000`` or ``--timing``), the ``virtual``
    interface its CAN FD protocol. A ``fd`` the configuration gives is kept."""
    filters = None if receive is None else receive_filters(receive)
    extra: dict[str, Any] = {}
    if fd and "fd" not in config:
        extra = {"protocol": can.CanProtocol.CAN_FD} if config.get("interface") == "virtual" else {"fd": True}
    try:
        return can.Bus(**{**config, **extra, "receive_own_messages": False, "can_filters": filters})
    except (can.CanError, OSError, ValueError, ImportError) as exc:
        raise RunError(f"cannot open CAN bus {config.get('interface')}:{config.get('channel')}: {exc}") from None


def has_fd(messages: Iterable[Message]) -> bool:
    """Whether any of ``messages`` (the ones a node sends or reads) is CAN FD: its bus must be opened for CAN FD."""
    return any(message.is_fd for message in messages)


class FrameLog:
    """A listener writing frames to ``path`` through python-can's writer for its extension (``.log`` candump -L,
    ``.asc``, ``.blf``, ``.csv``, ``.mf4`` with asammdf ...), every frame on the one channel name ``channel`` (see
    :func:`log_channel`). A path python-can has no writer for is an :class:`InputError` naming ``option``."""

    def __init__(self, path: str, channel: str, option: str = "--log") -> None:
        if path.lower().endswith(".mf4"):
            require_mf4(f"{option} {path}")
        Path(path).parent.mkdir(parents=True, exist_ok=True)
        try:
            self.writer = can.Logger(path)
        except ValueError as exc:
            raise InputError(f"{option} {path}: {exc}") from None
        self.channel = channel

    def __call__(self, msg: can.Message) -> None:
        msg.channel = self.channel
        self.writer.on_message_received(msg)

    def stop(self) -> None:
        self.writer.stop()


def require_mf4(where: str) -> None:
    """ASAM MDF4 (``.mf4``) logs go through python-can's MF4 reader and writer, which need asammdf (the ``mf4``
    extra): an :class:`InputError` saying so, naming ``where``, when it is missing."""
    if importlib.util.find_spec("asammdf") is None:
        raise InputError(f"{where}: .mf4 (ASAM MDF4) logs need asammdf: pip install 'dsg-hil[mf4]'")
