"""Deliberately bad controllers: an unsafe one (the planted violation of the search test) holds CL at a fixed
pressure whatever happens, so with the brake held CL slips at the engine's speed and heats without end; a broken
one raises in its first step (runs that fail are not passes)."""

from __future__ import annotations

from collections.abc import Mapping

__all__ = ["Crasher", "Slipper"]


class Slipper:
    """``step``: CL at 0.8 MPa, CH open, always."""

    def step(self, t: float, inputs: Mapping[str, Mapping[str, float]]) -> Mapping[str, float]:
        return {"P_CL_Cmd": 0.8, "P_CH_Cmd": 0.0}


class Crasher:
    """``step`` raises: every run fails (the sweep cannot judge it)."""

    def step(self, t: float, inputs: Mapping[str, Mapping[str, float]]) -> Mapping[str, float]:
        raise RuntimeError("the controller under test crashed")
