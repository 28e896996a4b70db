"""ecu-stub: a transmission control unit with the paper's creep strategy (Fig. 7, Section V).

It knows the plant only through the DBC and its binding (the shipped pair, or another matrix's: ``--dbc``,
``--binding``; :mod:`ecu_stub.tcu_io`): it imports nothing from ``dsg_hil`` but its protocol layer, so a real ECU
can take its place on the bus.
"""
