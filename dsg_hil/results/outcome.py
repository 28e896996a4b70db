"""What a finished run gives, typed: :class:`Summary`, the content of ``dsg-hil run --summary`` as a dataclass.

Built by :func:`dsg_hil.sim.run.open_run` only (the one place a run's summary is finished); ``as_json()`` gives
the JSON document, ``from_json()`` reads one back (e.g. the summaries of a sweep).
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field, fields
from typing import Any

from ..common.errors import InputError

__all__ = ["RUN_SPECIFIC", "Summary"]

# keys that differ between two runs of the same scenario by nature (where and how fast it ran), not by result
RUN_SPECIFIC = ("interface", "wall_time_s", "realtime_factor", "command_latency_ms")


@dataclass(frozen=True)
class Summary:
    """A run's summary. ``metrics``: the creep metrics of :class:`dsg_hil.results.summary.CreepMetrics`
    (creep and slip times, phases, peak plate temperatures, handovers, ``stop_reason`` ...), flat in the JSON;
    ``outside_range``: each input of the run outside the documented operating range
    (:mod:`dsg_hil.sim.operating_range`; in the JSON only when there is one); the other fields are the run's
    bookkeeping. ``stop_reason`` is the creep's (``vehicle_stopped``,
    ``STOPPED_OVERHEAT``, ``end_of_record``) or why the run ended early (``interrupted``, ``terminated``,
    ``peer_lost``, ``no_peer``); ``sim_time_s`` where it ended (below ``duration_s`` if cut short)."""

    scenario: str
    mode: str
    interface: str
    duration_s: float
    metrics: Mapping[str, Any]
    command_fallback: Mapping[str, Any]
    frames: Mapping[str, Any]
    realtime_factor: float | None
    wall_time_s: float | None
    command_latency_ms: Mapping[str, Any] | None
    sim_time_s: float
    faults: Mapping[str, Any]
    extra: Mapping[str, Any] = field(default_factory=dict)  # what a caller adds (e.g. a TCU's own counts)
    # each input outside the documented operating range (dsg_hil.sim.operating_range), "name=value (range ...)"
    outside_range: tuple[str, ...] = ()

    @property
    def stop_reason(self) -> str:
        return str(self.metrics["stop_reason"])

    @property
    def max_plate_temp_c(self) -> Mapping[str, float | None]:
        return self.metrics["max_plate_temp_c"]

    @property
    def handovers(self) -> list[Any]:
        return list(self.metrics["handovers"])

    def __getattr__(self, name: str) -> Any:
        """``summary.rollback_m``: every key of the JSON document is an attribute (the fields and the properties
        above, the creep metrics, what a caller added), as it is an item (``summary["rollback_m"]``)."""
        if not name.startswith("__"):  # (copy and pickle look up dunders before the fields are set)
            for table in (self.__dict__.get("metrics", {}), self.__dict__.get("extra", {})):
                if name in table:
                    return table[name]
        raise AttributeError(f"{type(self).__name__!r} object has no attribute {name!r}: not a key of its JSON "
                             f"document (as_json())")

    def __dir__(self) -> list[str]:
        return sorted({*super().__dir__(), *self.metrics, *self.extra})

    def as_json(self) -> dict[str, Any]:
        """The JSON document (``dsg-hil run --summary``): the bookkeeping around the flat creep metrics."""
        return {"scenario": self.scenario, "mode": self.mode, "interface": self.interface,
                "duration_s": self.duration_s, **self.metrics, "command_fallback": dict(self.command_fallback),
                "frames": dict(self.frames), "realtime_factor": self.realtime_factor,
                "wall_time_s": self.wall_time_s, "command_latency_ms": self.command_latency_ms,
                "sim_time_s": self.sim_time_s, "faults": dict(self.faults),
                **({"outside_range": list(self.outside_range)} if self.outside_range else {}), **self.extra}

    @classmethod
    def from_json(cls, data: Mapping[str, Any]) -> Summary:
        """A summary from its JSON document (the inverse of :meth:`as_json`)."""
        named = {f.name for f in fields(cls)} - {"metrics", "extra", "outside_range"}
        missing = sorted(named - set(data))
        if missing:
            raise InputError(f"not a dsg-hil summary: no {', '.join(missing)}")
        extra_keys = [k for k in data if k not in named | {"outside_range"} and k not in _METRIC_KEYS]
        return cls(**{k: data[k] for k in named}, metrics={k: v for k, v in data.items() if k in _METRIC_KEYS},
                   extra={k: data[k] for k in extra_keys},
                   outside_range=tuple(data.get("outside_range") or ()))  # (none in an older summary)

    def __getitem__(self, key: str) -> Any:
        """``summary["stop_reason"]``: a key of the JSON document."""
        return self.as_json()[key]


_METRIC_KEYS = frozenset((
    "creep_time_s", "standstill_time_s", "slip_time_s", "slip_overlap_s", "phases", "max_plate_temp_c",
    "time_above_limit_s", "friction_energy_kj", "speed_min_creeping_mps", "rollback_mps", "rollback_m",
    "speed_error_rms_mps", "stop_reason", "stop_time_s", "tcu_stop_time_s", "T_CL_at_stop_c",
    "T_CL_at_first_CH_limit_c", "mu_CH_first_slip", "P_CH_first_slip_mpa", "max_predicted_temp_c",
    "worst_prediction_error_c", "handovers", "max_speed_creep_mps", "overspeed_mps", "rollback_guarded_m",
    "fault_time_s", "min_margin_c", "status_unconfirmed", "handover_deviation_pct",
    "handover_deviation_unbraked_pct"))
