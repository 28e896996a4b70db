"""The controller under test, from the space's ``[controller]`` (plain data, built in the worker):

* ``ecu-stub``: the bundled TCU in the worker's process, optionally with a calibration (its TOML text);
* ``python``: ``target = "module:factory"``, a class or function called with no argument giving an object with
  ``step(t, inputs)`` (:class:`dsg_hil.testing.Controller`), one per run, run in the worker's process;
* ``command``: ``argv``, a command line started per run on a ``udp_multicast`` group and port of the run's own
  (``"{bus_args}"`` and ``{channel}``/``{port}`` as :class:`dsg_hil.testing.ControllerProcess` takes them).
"""

from __future__ import annotations

import importlib
from collections.abc import Mapping
from typing import TYPE_CHECKING, Any

from ..common.errors import InputError
from ..protocol import Codec
from ..protocol.bus import UDP_MULTICAST, fresh_udp_group
from ..sim.run import ECU_STUB

if TYPE_CHECKING:
    from .space import Space

__all__ = ["check_importable", "config_for"]


def _import(target: str) -> Any:
    module, _, name = target.partition(":")
    try:
        return getattr(importlib.import_module(module), name)
    except (ImportError, AttributeError) as exc:
        raise InputError(f"controller.target {target!r}: cannot import ({exc})") from exc


def check_importable(space: Space) -> None:
    """A ``python`` controller's ``module:factory`` imports here (:class:`InputError` naming the space file and
    key): before a local cluster starts, whose workers would each find it missing in every run."""
    try:
        _import(space.controller["target"])
    except InputError as exc:
        raise InputError(f"{space.origin}: {exc}") from None


def config_for(controller: Mapping[str, Any]) -> dict[str, Any]:
    """The :class:`~dsg_hil.sim.run.RunConfig` fields (``tcu``, ``bus``) that put ``controller`` on the bus."""
    kind = controller["kind"]
    if kind == "ecu-stub" and "calibration" not in controller:
        return {"tcu": ECU_STUB}
    if kind == "ecu-stub":
        from ecu_stub.calibration import parse_calibration  # noqa: PLC0415 - the TCU in the worker
        from ecu_stub.controller import CreepController  # noqa: PLC0415
        from ecu_stub.runner import TCU_USES, TcuRunner  # noqa: PLC0415

        cal = parse_calibration(controller["calibration"], controller.get("calibration_file", "calibration"))
        return {"tcu": lambda db, bus: TcuRunner(Codec(db, TCU_USES), bus, CreepController(cal))}
    if kind == "python":
        from ecu_stub.runner import TCU_USES  # noqa: PLC0415

        from ..testing.controllers import PythonControllerTcu  # noqa: PLC0415

        factory = _import(controller["target"])
        return {"tcu": lambda db, bus: PythonControllerTcu(Codec(db, TCU_USES), bus, factory())}
    from ..testing.controllers import ControllerProcess  # noqa: PLC0415

    return {"tcu": ControllerProcess(list(controller["argv"])), "bus": {"interface": UDP_MULTICAST,
                                                                          **fresh_udp_group()}}
