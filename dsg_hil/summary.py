"""What a run did, from the plant's truth and the TCU's status frames: the JSON of ``dsg-hil run --summary``."""

from __future__ import annotations

from dataclasses import dataclass, field

from .plant import PlantOutputs

CLUTCHES = {1: "CL", 2: "CH"}
STATES = {0: "IDLE", 1: "ENGAGE", 2: "CREEP", 3: "HANDOVER", 4: "STOPPED_OVERHEAT", 5: "FAULT"}
SLIP_MIN = 0.5  # rad/s: below this a clutch counts as not slipping
TORQUE_MIN = 5.0  # N m: a clutch transmitting less is open


@dataclass
class RunSummary:
    """Accumulates the run, step by step and status frame by status frame."""

    dt: float
    creep_time_s: float = 0.0
    slip_time_s: dict[str, float] = field(default_factory=lambda: {"CL": 0.0, "CH": 0.0})
    max_plate_temp_c: dict[str, float] = field(default_factory=lambda: {"CL": -1e9, "CH": -1e9})
    handovers: list[dict] = field(default_factory=list)
    stop_reason: str = "scenario_end"
    stop_time_s: float | None = None
    tcu_state: str = "IDLE"
    active_clutch: str = "NONE"
    fallback_events: int = 0
    fallback_time_s: float = 0.0
    max_predicted_temp_c: dict[str, float] = field(default_factory=lambda: {"CL": -1e9, "CH": -1e9})
    realtime_factor: float | None = None  # simulated s per wall s of a real-time run
    wall_time_s: float | None = None  # of the run itself (after the lockstep handshake)
    command_latency_s: list[float] = field(default_factory=list)  # real time: TCU_CMD on the bus -> used
    _sq_speed_error: float = 0.0
    _creep_samples: int = 0

    def on_step(self, out: PlantOutputs, creeping: bool, fallback: bool, desired_speed: float = 0.0) -> None:
        slipping = {"CL": abs(out.omega_in - out.omega_CL) > SLIP_MIN and abs(out.M_CL) > TORQUE_MIN,
                    "CH": abs(out.omega_in - out.omega_CH) > SLIP_MIN and abs(out.M_CH) > TORQUE_MIN}
        for name, slips in slipping.items():
            if slips:
                self.slip_time_s[name] += self.dt
        self.max_plate_temp_c["CL"] = max(self.max_plate_temp_c["CL"], out.T_CL)
        self.max_plate_temp_c["CH"] = max(self.max_plate_temp_c["CH"], out.T_CH)
        if creeping and self.tcu_state in ("ENGAGE", "CREEP", "HANDOVER"):
            self.creep_time_s += self.dt
        if creeping and self.tcu_state == "CREEP":
            self._sq_speed_error += (out.v - desired_speed) ** 2
            self._creep_samples += 1
        if fallback:
            self.fallback_time_s += self.dt

    def on_status(self, t: float, values: dict[str, float], truth: PlantOutputs) -> None:
        state = STATES.get(int(values["State"]), f"UNKNOWN_{int(values['State'])}")
        active = CLUTCHES.get(int(values["ActiveClutch"]), "NONE")
        if active != self.active_clutch and self.active_clutch in ("CL", "CH") and active in ("CL", "CH"):
            self.handovers.append({"t_s": round(t, 3), "from": self.active_clutch, "to": active,
                                   "T_CL_c": round(truth.T_CL, 2), "T_CH_c": round(truth.T_CH, 2),
                                   "T_CL_pred_c": round(values["T_CL_Pred"], 1),
                                   "T_CH_pred_c": round(values["T_CH_Pred"], 1)})
        if state == "STOPPED_OVERHEAT" and self.stop_time_s is None:
            self.stop_reason, self.stop_time_s = "STOPPED_OVERHEAT", round(t, 3)
        self.tcu_state, self.active_clutch = state, active
        for name, key in (("CL", "T_CL_Pred"), ("CH", "T_CH_Pred")):
            self.max_predicted_temp_c[name] = max(self.max_predicted_temp_c[name], values[key])

    def as_json(self, frames: dict[str, int], scenario: str, mode: str, interface: str, duration_s: float) -> dict:
        return {
            "scenario": scenario, "mode": mode, "interface": interface, "duration_s": round(duration_s, 3),
            "creep_time_s": round(self.creep_time_s, 3),
            "slip_time_s": {k: round(v, 3) for k, v in self.slip_time_s.items()},
            "max_plate_temp_c": {k: round(v, 2) for k, v in self.max_plate_temp_c.items()},
            "max_predicted_temp_c": {k: round(v, 1) for k, v in self.max_predicted_temp_c.items()},
            "speed_error_rms_mps": round((self._sq_speed_error / self._creep_samples) ** 0.5, 4)
            if self._creep_samples else None,
            "handovers": self.handovers,
            "stop_reason": self.stop_reason,
            "stop_time_s": self.stop_time_s,
            "command_fallback": {"events": self.fallback_events, "time_s": round(self.fallback_time_s, 3)},
            "frames": frames,
            "realtime_factor": None if self.realtime_factor is None else round(self.realtime_factor, 3),
            "run_wall_time_s": None if self.wall_time_s is None else round(self.wall_time_s, 3),
            "command_latency_ms": _percentiles(self.command_latency_s),
        }


def _percentiles(samples: list[float]) -> dict | None:
    if not samples:
        return None
    s = sorted(samples)
    pick = lambda q: s[min(len(s) - 1, int(q * (len(s) - 1) + 0.5))]  # noqa: E731
    return {"n": len(s), "p50": round(1000 * pick(0.5), 3), "p99": round(1000 * pick(0.99), 3),
            "max": round(1000 * s[-1], 3)}
