"""PI(D) controller with explicit time step, output limits, anti-windup by clamping and an output rate limit."""

from __future__ import annotations

from dataclasses import dataclass

__all__ = ["PID"]


@dataclass
class PID:
    kp: float
    ki: float
    kd: float = 0.0
    out_min: float = 0.0
    out_max: float = 1.0
    rate_limit: float = float("inf")  # per second
    integral: float = 0.0
    last_error: float | None = None
    last_output: float = 0.0

    def reset(self, output: float) -> None:
        """Bumpless start: the next output continues from ``output``."""
        self.integral = min(max(output, self.out_min), self.out_max)
        self.last_error = None
        self.last_output = self.integral

    def update(self, error: float, dt: float) -> float:
        if not dt > 0.0:
            raise ValueError(f"dt must be positive, got {dt}")
        # (every control cycle: min() and max() written out as comparisons, the same floats)
        last_error, out_min, out_max, kp = self.last_error, self.out_min, self.out_max, self.kp
        derivative = 0.0 if last_error is None else (error - last_error) / dt
        self.last_error = error
        candidate = self.integral + self.ki * error * dt
        unclamped = kp * error + candidate + self.kd * derivative
        # anti-windup: integrate only while the output is not saturated in the direction of the error
        if out_min < unclamped < out_max or (unclamped >= out_max and error < 0) or \
                (unclamped <= out_min and error > 0):
            self.integral = _clamp(candidate, out_min, out_max)
        out = _clamp(kp * error + self.integral + self.kd * derivative, out_min, out_max)
        step = self.rate_limit * dt
        last_output = self.last_output
        out = _clamp(out, last_output - step, last_output + step)
        self.last_output = out
        return out


def _clamp(x: float, lo: float, hi: float) -> float:
    """``min(max(x, lo), hi)``, the same float (max keeps x unless lo > x; min keeps that unless hi < it)."""
    if lo > x:
        x = lo
    return hi if hi < x else x
