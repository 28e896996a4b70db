"""FMI both ways (extra ``fmi``): the plant as an FMI 2.0 co-simulation FMU (:func:`~dsg_hil.fmi.export.export_fmu`,
``dsg-hil fmu export``), and a controller FMU as the TCU on the bus (:func:`~dsg_hil.fmi.controller.open_controller`,
``dsg-hil run --controller my_tcu.fmu``).

signals.py     the FMUs' variables: DBC names and units, one table per direction
slave.py       SignalSlave: PythonFMU's Fmi2Slave with Real variables and units (both FMUs' base)
plant.py       PlantSlave: the plant behind PythonFMU's Fmi2Slave
tcu.py         the conversions between ecu-stub's controller and the DBC signals of a controller FMU
tcu_slave.py   TcuSlave: ecu-stub's controller as an FMU (to test the controller direction with)
controller.py  a controller FMU run through FMPy behind ecu-stub's bus side
host.py        instantiate: an FMU instantiated through FMPy, PythonFMU's reference fault made good
cosim.py       the plant FMU and a controller FMU co-simulated in FMPy, without CAN
export.py      export_fmu: PythonFMU's builder, dsg-hil's shim compiled and put in as the linux64 binary
shim.c         the shim: PythonFMU's binary behind it, a call the slave refused returned as fmi2Error

pythonfmu and fmpy are imported only when an FMU is written or opened (the fmi extra); without them those calls
fail with one error naming the extra.
"""

__all__: list[str] = []
