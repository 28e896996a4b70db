"""The thermal safety monitor: a check apart from the creep strategy that every control cycle bounds each plate's
temperature until the clutch could be released, and overrides the strategy's pressure commands before that bound
reaches ``T_safe`` (the safety argument with its numbers: ``docs/safety.md``).

For clutch c, with the pressures the strategy proposes this cycle,

    B_c = T_pred_c + e + Q_w,c * tau / C_c

* ``T_pred_c``: the TCU's plate prediction (C dT/dt = Q - K (T - T_oil_out), :mod:`ecu_stub.clutch_model`);
* ``e``: ``strategy.prediction_error_k``, the predictor's error bound (identified: worst truth minus prediction);
* ``Q_w,c``: :func:`worst_heat_w`, the friction power (4) at the highest pressure the clutch may still see (the
  command or the measured pressure, the larger: the piston lags) and the worst slip until the release (the present
  slip or the clutch input speed, the larger: a vehicle braked to rest slips the whole input speed);
* ``tau``: :func:`release_time_s`, full-power time of the fastest release: a linear ramp out over
  ``stop_release_s`` (half of it at full power), the hydraulic lag, and one control period (the decision is applied
  one cycle later). Cooling is neglected (conservative).

Overrides (:meth:`ThermalMonitor.check`): a clutch whose bound exceeds ``T_safe`` gets its pressure limited to the
largest that keeps the bound at ``T_safe`` (a torque limit; for an off-going clutch in a handover, a faster
release); if that clutch carries the vehicle, the monitor also demands a stop (STOPPED_OVERHEAT: brake, the
clutches ramp out over ``stop_release_s``, which ``tau`` covers). The strategy's handover margin
(:meth:`ecu_stub.controller.CreepController.limit`) uses the same formula: at least the same worst-case term, and
the crossover's heat at the same pressure and the crossover's slip (:func:`crossover_heat_w`), so in normal
operation the strategy hands over before the monitor has to act.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

from dsg_hil.common.units import CV

from .calibration import TcuCalibration
from .clutch_model import friction_heat, mu_lookup

__all__ = ["MonitorVerdict", "ThermalMonitor", "crossover_heat_w", "crossover_slip_rpm", "release_time_s",
           "worst_heat_w", "worst_slip_rpm"]

_MPA_TO_PA, _RPM_TO_RAD_S = CV.MPA_TO_PA, CV.RPM_TO_RAD_S
_BISECTIONS = 30  # pressure limit to 1.5 MPa / 2^30: far below the DBC's 1-kPa resolution


def worst_slip_rpm(slip_rpm: float, clutch_in_rpm: float) -> float:
    """Largest slip until the clutch is released [r/min]: the present one, or the input speed (vehicle at rest)."""
    return max(abs(slip_rpm), abs(clutch_in_rpm))


def worst_heat_w(cal: TcuCalibration, clutch: str, T_c: float, slip_rpm: float, clutch_in_rpm: float,
                 P_mpa: float) -> float:
    """Friction power (4) [W] at pressure ``P_mpa`` and the worst slip (:func:`worst_slip_rpm`), by the TCU's model."""
    return friction_heat(cal.friction, cal.clutch(clutch), T_c, worst_slip_rpm(slip_rpm, clutch_in_rpm), P_mpa)


def crossover_slip_rpm(cal: TcuCalibration, clutch: str, slip_rpm: float, clutch_in_rpm: float,
                       v_target_mps: float) -> float:
    """Slip of a torque crossover [r/min]: the slip at the target speed, ``|n_in - v_target / (r_c omega)|``
    (the speed controller carries the vehicle there), or the present one if smaller (a vehicle at or over its
    target). Not a bound on the slip: a vehicle kept slower than its target slips more, and the monitor's bound
    (:func:`worst_slip_rpm`) covers that."""
    out_rpm = v_target_mps / cal.clutch(clutch).speed_ratio_m / _RPM_TO_RAD_S
    return min(abs(slip_rpm), abs(clutch_in_rpm - out_rpm))


def crossover_heat_w(cal: TcuCalibration, clutch: str, T_c: float, slip_rpm: float, clutch_in_rpm: float,
                     v_target_mps: float, P_mpa: float) -> float:
    """Friction power (4) [W] of an off-going clutch through a crossover at its full share, by the TCU's model: the
    monitor's formula (:func:`worst_heat_w`) at the same pressure ``P_mpa`` (the highest it may see: the torque the
    controller commands) but at the crossover's slip (:func:`crossover_slip_rpm`) instead of the worst one."""
    return friction_heat(cal.friction, cal.clutch(clutch), T_c,
                         crossover_slip_rpm(cal, clutch, slip_rpm, clutch_in_rpm, v_target_mps), P_mpa)


def release_time_s(cal: TcuCalibration, dt: float) -> float:
    """Full-power time of the fastest release [s]: ramp out over stop_release_s (half), hydraulic lag, one period."""
    s = cal.strategy
    return 0.5 * s.stop_release_s + s.hydraulic_lag_s + dt


@dataclass(slots=True)
class MonitorVerdict:
    """What the monitor decided this cycle: the bound per clutch [degC] (with the pressures as limited), the
    pressure limits it set [MPa] (only where it acted), and whether the vehicle must be stopped."""

    bound_c: dict[str, float]
    P_limit_mpa: dict[str, float]
    stop: bool

    def __init__(self, bound_c: dict[str, float], P_limit_mpa: dict[str, float], stop: bool) -> None:
        # (written out as ecu_stub.controller.TcuInputs')
        self.bound_c, self.P_limit_mpa, self.stop = bound_c, P_limit_mpa, stop


class ThermalMonitor:
    """The check of the module docstring. Holds no state: every cycle is judged on its own inputs."""

    def __init__(self, cal: TcuCalibration) -> None:
        self.cal = cal

    def bound_c(self, clutch: str, T_pred_c: float, slip_rpm: float, clutch_in_rpm: float, P_mpa: float,
                dt: float, error_k: float | None = None, heat_scale: float = 1.0) -> float:
        """B_c [degC] if the clutch may see pressure ``P_mpa`` until a release that starts now; ``error_k``: ``e``
        (default ``strategy.prediction_error_k``), ``heat_scale``: Q_w's factor for its undetected error."""
        s, C = self.cal.strategy, self.cal.clutch(clutch).C_plate_j_k
        Q = worst_heat_w(self.cal, clutch, T_pred_c, slip_rpm, clutch_in_rpm, P_mpa) * heat_scale
        return T_pred_c + (s.prediction_error_k if error_k is None else error_k) + Q * release_time_s(self.cal, dt) / C

    def check(self, T_pred: dict[str, float], slip_rpm: dict[str, float], clutch_in_rpm: float,
              P_cmd: dict[str, float], P_meas: dict[str, float], carrying: str, dt: float,
              error_k: dict[str, float] | None = None, heat_scale: dict[str, float] | None = None) -> MonitorVerdict:
        """Judge the commands ``P_cmd`` [MPa] (``P_meas``: measured [MPa]; ``carrying``: the clutch that holds the
        vehicle, or "NONE"). Limits a command where its bound passes ``T_safe`` (to zero if even the measured
        pressure alone passes it: the release starts at once); a stop if that is the carrying clutch. ``error_k``,
        ``heat_scale``: each clutch's ``e`` and Q_w's factor (:meth:`bound_c`; the strategy's margin for the
        sensor errors its checks let through, ``CreepController.margin_k``)."""
        cal = self.cal
        s = cal.strategy
        T_safe, mu_of = s.T_safe_c, mu_lookup(cal.friction)
        tau = 0.5 * s.stop_release_s + s.hydraulic_lag_s + dt  # release_time_s
        bounds, limits, stop = {}, {}, False
        for c, clutch in (("CL", cal.CL), ("CH", cal.CH)):
            # B = bound(P_cmd[c]): bound_c, worst_heat_w, friction_heat and heat_w written out (every cycle, for both
            # clutches), the same operations in the same order; max() as comparisons (the same floats)
            T, P, P_m, slip, n_in = T_pred[c], P_cmd[c], P_meas[c], abs(slip_rpm[c]), abs(clutch_in_rpm)
            if P_m > P:
                P = P_m
            if P < 0.0:
                P = 0.0
            slip = abs(n_in if n_in > slip else slip)
            e = s.prediction_error_k if error_k is None else error_k[c]
            scale = 1.0 if heat_scale is None else heat_scale[c]
            Q = mu_of(T, slip, P) * clutch.k_geom_m3 * _MPA_TO_PA * P * slip * _RPM_TO_RAD_S * scale
            B = T + e + Q * tau / clutch.C_plate_j_k
            if B > T_safe:
                def bound(P: float, c: str = c, e: float = e, scale: float = scale) -> float:
                    return self.bound_c(c, T_pred[c], slip_rpm[c], clutch_in_rpm, max(P, P_meas[c]), dt, e, scale)
                limits[c] = P = self._largest_safe(bound, P_cmd[c], T_safe)
                B = bound(P)
                stop = stop or c == carrying
            bounds[c] = B
        return MonitorVerdict(bounds, limits, stop)

    @staticmethod
    def _largest_safe(bound: Callable[[float], float], P_hi: float, T_safe: float) -> float:
        """Largest P in [0, P_hi] with bound(P) <= T_safe (bisection: the bound rises with P); 0 if none."""
        lo, hi = 0.0, P_hi
        if bound(lo) > T_safe:
            return 0.0
        for _ in range(_BISECTIONS):
            mid = 0.5 * (lo + hi)
            lo, hi = (mid, hi) if bound(mid) <= T_safe else (lo, mid)
        return lo
