"""dsg-hil: a CAN-bus hardware-in-the-loop plant of a DSG (dual wet clutch) creeping in traffic."""

__version__ = "0.1.0"
