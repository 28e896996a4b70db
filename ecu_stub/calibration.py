"""The TCU's calibration data: what a transmission ECU is flashed with. Its own numbers, not the plant's."""

from __future__ import annotations

from dataclasses import dataclass


@dataclass(frozen=True)
class TcuCalibration:
    # strategy
    T_safe_c: float = 250.0  # clutch safety temperature (Section V.A)
    takeover_margin_c: float = 10.0  # the other clutch takes over only if predicted below T_safe - margin
    handover_time_s: float = 1.0  # off-going pressure ramps down, on-coming up, over this time
    # pressure control (PI on vehicle speed, output in MPa)
    kp_mpa_per_mps: float = 1.5
    ki_mpa_per_m: float = 1.5
    kd_mpa_s2_per_m: float = 0.0
    P_min_mpa: float = 0.0
    P_max_mpa: float = 1.5
    P_rate_mpa_s: float = 2.0  # command rate limit
    engage_rate_mpa_s: float = 0.4  # ENGAGE: pressure ramp until the vehicle moves
    engage_speed_fraction: float = 0.3  # ENGAGE ends at this fraction of the desired speed
    # the TCU's model of its clutches: torque = mu_nom * k_geom * P; plate temperature predictor
    mu_nom: float = 0.065
    k_geom_m3: float = 6 * 0.0427 * 0.10670  # N * A_f * r_m of each clutch
    C_plate_j_k: float = 4200.0
    K_plate_oil_w_k: float = 800.0
    # gearbox ratios (for the bumpless handover from CL to CH pressure)
    i_L: float = 1.59
    i_H: float = 0.92
