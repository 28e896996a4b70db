"""A deliberately unsafe controller (the planted violation of the search test): it holds CL at a fixed pressure
whatever happens, so with the brake held CL slips at the engine's speed and heats without end."""

from __future__ import annotations

from collections.abc import Mapping

__all__ = ["Slipper"]


class Slipper:
    """``step``: CL at 0.8 MPa, CH open, always."""

    def step(self, t: float, inputs: Mapping[str, Mapping[str, float]]) -> Mapping[str, float]:
        return {"P_CL_Cmd": 0.8, "P_CH_Cmd": 0.0}
