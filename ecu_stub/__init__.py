"""ecu-stub: a transmission control unit with the paper's creep strategy (Fig. 7, Section V).

It knows the plant only through the DBC: it imports nothing from ``dsg_hil`` but its protocol layer, so a real
ECU can take its place on the bus.
"""
