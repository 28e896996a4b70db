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
        derivative = 0.0 if self.last_error is None else (error - self.last_error) / dt
        self.last_error = error
        candidate = self.integral + self.ki * error * dt
        unclamped = self.kp * error + candidate + self.kd * derivative
        # anti-windup: integrate only while the output is not saturated in the direction of the error
        if self.out_min < unclamped < self.out_max or (unclamped >= self.out_max and error < 0) or \
                (unclamped <= self.out_min and error > 0):
            self.integral = min(max(candidate, self.out_min), self.out_max)
        out = min(max(self.kp * error + self.integral + self.kd * derivative, self.out_min), self.out_max)
        step = self.rate_limit * dt
        out = min(max(out, self.last_output - step), self.last_output + step)
        self.last_output = out
        return out
